"""Fixtures of the black-box tests: the programs under test ($EV3_BIN/ev3-agent, ev3-master;
$EV3_ARM_BIN/ev3-agent for the armel test), started on free loopback ports with short timers and
stopped (SIGTERM, must exit 0) at the end of each test."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from ev3net import HB, LOSS, PAUSED, SYNC, Program, TestMaster, free_ports

REPO = Path(__file__).resolve().parents[3]


def _bin(name: str) -> Path:
    p = Path(os.environ.get("EV3_BIN") or REPO / "build" / "bin") / name
    if not (p.is_file() and os.access(p, os.X_OK)):
        pytest.fail(f"{p} is missing: build it with `make build` (or set EV3_BIN)", pytrace=False)
    return p


@pytest.fixture
def agent_exe() -> Path:
    return _bin("ev3-agent")


@pytest.fixture
def master_exe() -> Path:
    return _bin("ev3-master")


@pytest.fixture
def programs():
    """Collects started programs; at the end each is stopped with SIGTERM and must exit 0."""
    started: list[Program] = []
    yield started
    codes = {}
    try:
        for p in started:
            codes[p.name] = p.stop()
    finally:
        for p in started:
            p.close()
    bad = {n: c for n, c in codes.items() if c != 0}
    assert not bad, f"programs did not exit 0 on SIGTERM: {bad}"


@pytest.fixture
def tm():
    """A Python test master on a free port."""
    m = TestMaster()
    yield m
    m.close()


@pytest.fixture
def start_agent(agent_exe, programs, tmp_path, tm):
    """Starts ev3-agent broadcasting to the test master, with short timers."""
    def start(*extra: str, name: str = "agent", exe: Path | None = None, prefix: list[str] | None = None):
        port = free_ports(1)[0]
        args = ["--port", str(port), "--bind", "127.0.0.1", "--broadcast", f"127.0.0.1:{tm.port}",
                "--heartbeat-ms", str(HB), "--master-timeout-ms", str(LOSS),
                "--paused-timeout-ms", str(PAUSED), "--sync-timeout-ms", str(SYNC),
                "--log-level", "4", "--log-file", str(tmp_path / f"{name}.log"), *extra]
        if prefix:
            p = Program(Path(prefix[0]), prefix[1:] + [str(exe or agent_exe)] + args, tmp_path, name)
        else:
            p = Program(exe or agent_exe, args, tmp_path, name)
        programs.append(p)
        tm.agent_port = port
        return p
    return start
