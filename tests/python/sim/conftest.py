"""Fixtures of the ev3-sim tests: the program ($EV3_BIN/ev3-sim) and FUSE. Without /dev/fuse these
tests fail (they never skip): ev3-sim cannot serve a tree without it."""

from __future__ import annotations

import pytest

from ev3sim_proc import Sims, cannot_run


@pytest.fixture
def start_sim(tmp_path):
    """start_sim(world, robots=[("robot1", "x,y,h")], args=[...]) -> Sim; each is stopped at the
    end of the test (SIGTERM, must exit 0, nothing left mounted)."""
    why = cannot_run()
    if why:
        pytest.fail(why, pytrace=False)
    sims = Sims(tmp_path)
    yield sims.start
    bad = sims.stop_all()
    assert not bad, f"ev3-sim did not exit 0 on SIGTERM: {bad}"
