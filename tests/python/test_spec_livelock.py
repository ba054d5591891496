"""A spec change that livelocks a model makes `make spec` fail within minutes, naming the model: the
run limit of tools/spec.py (docs/spec.md "Commands"). Planted here: the master resyncs an agent on
any PANIC of it, not only on one newer than the last msgid it heard from it (MasterLogic
MasterSync's `m.msgid > x.hi`), so a late copy of an old PANIC resyncs the agent again, for ever:
fleet_late's msgids and depth grow without bound and TLC never finishes."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SPEC = REPO / "spec" / "tla"
FRESHNESS = '/\\ m.msgid > x.hi /\\ BUG # "NoPanicResync"'


@pytest.mark.tlc
def test_a_livelocked_model_fails_naming_it_within_its_limit(tmp_path):
    spec = tmp_path / "tla"
    shutil.copytree(SPEC, spec, ignore=shutil.ignore_patterns("states", "*.tlacov"))
    logic = spec / "MasterLogic.tla"
    text = logic.read_text()
    assert text.count(FRESHNESS) == 1
    logic.write_text(text.replace(FRESHNESS, '/\\ BUG # "NoPanicResync"'))
    # the limit: 1.5 times fleet_late's time in manifest.json (11 s), at least 10 s
    env = dict(os.environ, SPEC_LIMIT_FACTOR="1.5", SPEC_LIMIT_FLOOR="10", SPEC_JOBS="1")
    t0 = time.monotonic()
    p = subprocess.run([sys.executable, str(REPO / "tools" / "spec.py"), "check", "--spec", str(spec),
                        "--only", "fleet_late"], cwd=REPO, env=env, capture_output=True, text=True, timeout=300)
    took = time.monotonic() - t0
    assert p.returncode == 1, p.stdout + p.stderr
    assert "FAIL fleet_late: no verdict within" in p.stdout and "livelock" in p.stdout, p.stdout
    assert took < 60, f"took {took:.0f} s"


def test_check_refuses_an_unknown_model_and_a_directory_that_is_no_spec(tmp_path):
    tool = [sys.executable, str(REPO / "tools" / "spec.py"), "check"]
    p = subprocess.run(tool + ["--only", "fleet_nosuch"], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert p.returncode == 1 and "--only: fleet_nosuch: no such model in manifest.json" in p.stderr
    p = subprocess.run(tool + ["--spec", str(tmp_path), "--only", "fleet_late"], cwd=REPO, capture_output=True,
                       text=True, timeout=60)
    assert p.returncode == 1 and "not a copy of spec/tla" in p.stderr
