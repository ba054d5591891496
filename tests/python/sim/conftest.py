"""Fixtures of the ev3-sim tests: the program ($EV3_BIN/ev3-sim) and FUSE. Without /dev/fuse these
tests fail (they never skip): ev3-sim cannot serve a tree without it."""

from __future__ import annotations

import os

import pytest

from ev3sim_proc import Sim, ev3_sim_path


@pytest.fixture
def start_sim(tmp_path):
    """start_sim(world, robots=[("robot1", "x,y,h")], args=[...]) -> Sim; each is stopped at the
    end of the test (SIGTERM, must exit 0, nothing left mounted)."""
    exe = ev3_sim_path()
    if not (exe.is_file() and os.access(exe, os.X_OK)):
        pytest.fail(f"{exe} is missing: build it with `make build` (or set EV3_BIN)", pytrace=False)
    if not os.path.exists("/dev/fuse") or not os.access("/dev/fuse", os.R_OK | os.W_OK):
        pytest.fail("/dev/fuse is missing or not usable: ev3-sim serves the ev3dev tree through FUSE, "
                    "so its tests cannot run (load the fuse module, or give the container --device "
                    "/dev/fuse)", pytrace=False)
    started: list[Sim] = []
    count = 0

    def start(world: str, robots=None, args=None) -> Sim:
        nonlocal count
        count += 1
        d = tmp_path / f"sim{count}"
        d.mkdir()
        sim = Sim(d, world, robots or [("robot1", None)], args)
        started.append(sim)
        return sim

    yield start
    codes = {}
    try:
        for s in started:
            codes[str(s.tmp)] = (s.stop(), s)
    finally:
        for s in started:
            s.cleanup()
    bad = {k: (code, s.log_text()) for k, (code, s) in codes.items() if code != 0}
    assert not bad, f"ev3-sim did not exit 0 on SIGTERM: {bad}"
