"""The static armel ev3-agent (the EV3 build, $EV3_ARM_BIN/ev3-agent) under qemu-arm against the
native ev3-master: it syncs, keeps its heartbeat, and runs the wait behaviour."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from ev3net import Program, assert_static_armel, free_ports, read_status, wait_until


@pytest.fixture
def arm_agent_exe() -> Path:
    d = os.environ.get("EV3_ARM_BIN")
    assert d, "EV3_ARM_BIN is not set: run this through `make test-blackbox` (it builds `make arm` first)"
    p = Path(d) / "ev3-agent"
    assert p.is_file(), f"{p} is missing: build it with `make arm`"
    assert shutil.which("qemu-arm"), "qemu-arm is missing (make deps installs qemu-user)"
    return p


def test_armel_agent_syncs_and_beats_under_qemu(arm_agent_exe, master_exe, programs, tmp_path):
    assert_static_armel(arm_agent_exe)
    mport, aport = free_ports(2)
    status = tmp_path / "status.json"
    script = tmp_path / "script.txt"
    script.write_text("wait 1.5\nbehaviour 2 wait seconds=0.5\nwait 0.3\nstart 2\n")
    m = Program(master_exe, ["--port", str(mport), "--bind", "127.0.0.1", "--broadcast", f"127.0.0.1:{aport}",
                             "--status-json", str(status), "--agent-timeout-ms", "3000", "--script", str(script)],
                tmp_path, "master")
    programs.append(m)
    a = Program(Path(shutil.which("qemu-arm")), [str(arm_agent_exe), "--port", str(aport), "--bind", "127.0.0.1",
                                                 "--broadcast", f"127.0.0.1:{mport}", "--heartbeat-ms", "100",
                                                 "--master-timeout-ms", "1500", "--log-level", "3"],
                tmp_path, "arm-agent")
    programs.append(a)

    def agent(state):
        s = read_status(status)
        xs = [x for x in (s or {}).get("agents", []) if x["state"] == state]
        return xs[0] if xs else None
    wait_until(lambda: agent("ACTIVE"), 10, "the armel agent ACTIVE in the master's status")
    wait_until(lambda: "ACTION_OK 0" in m.stdout(), 10, "ACTION_OK from the armel agent's wait")
    # The heartbeat keeps going: last heard stays well under the master timeout.
    for _ in range(3):
        s = wait_until(lambda: agent("WORKING"), 3, "WORKING")
        assert s["last_heard_ms_ago"] < 1000
    assert "state WORKING" in a.stderr()
