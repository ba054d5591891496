"""tools/spec.py distributed: the cfg its TLC server gets (docs/spec.md "Distributed mode"): the
model's PROPERTIES left out, said so, the rest as it is; --bug sets the BUG constant. (make spec
runs the mode itself on reports_three.)"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SPEC = REPO / "spec" / "tla"


def _spec_tool():
    loader = importlib.util.spec_from_file_location("spec_tool_distributed", REPO / "tools" / "spec.py")
    module = importlib.util.module_from_spec(loader)
    loader.loader.exec_module(module)
    return module


def test_properties_are_left_out_and_the_rest_kept():
    tool = _spec_tool()
    text = (SPEC / "MCReports.cfg").read_text()
    out, left_out = tool.safety_cfg(text)
    assert left_out
    assert "PROPERTIES" not in out and "EverythingRecorded" not in out
    assert "INVARIANTS" in out and "InOrderInv" in out and "SPECIFICATION FairSpec" in out
    assert [l for l in out.splitlines() if "=" in l] == [l for l in text.splitlines() if "=" in l]


def test_a_safety_cfg_is_unchanged_and_a_bug_is_set():
    tool = _spec_tool()
    text = (SPEC / "MCReportsThree.cfg").read_text()
    out, left_out = tool.safety_cfg(text)
    assert not left_out and out.splitlines() == text.splitlines()
    out, _ = tool.safety_cfg(text, "GapAsDrop")
    assert '    BUG = "GapAsDrop"' in out.splitlines() and 'BUG = "none"' not in out


def test_a_bug_needs_a_bug_constant():
    with pytest.raises(ValueError, match="no BUG constant"):
        _spec_tool().safety_cfg("CONSTANTS\n    N = 2\nINVARIANTS\n    TypeOK\n", "X")
