"""A master and two agents each in a network namespace of their own, on one bridge (netns.Lan),
every node on the same port and reaching the others by the subnet's broadcast address, as on a
Wi-Fi network: the agents sync; one agent's link goes down (a partition): it declares its master
lost and the master drops it; the link comes back: it syncs again. Root only (CI runs as root);
elsewhere the test is skipped, saying why."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import netns
from ev3net import Program, read_status, wait_until

PORT = 12345
HB, LOSS = 100, 600


@pytest.fixture
def lan():
    why = netns.available()
    if why:
        pytest.skip(why)
    lan = netns.Lan(3)
    yield lan
    lan.close()


def log(tmp: Path, name: str) -> str:
    p = tmp / f"{name}.log"
    return p.read_text(errors="replace") if p.exists() else ""


def test_agents_in_namespaces_sync_by_broadcast_and_a_partition_heals(lan, master_exe, agent_exe, programs, tmp_path):
    bcast = f"{lan.broadcast()}:{PORT}"
    status = tmp_path / "status.json"
    programs.append(Program(Path("ip"), lan.argv(0, [str(master_exe), "--port", str(PORT), "--broadcast", bcast,
                                                     "--agent-timeout-ms", "1500", "--status-json", str(status),
                                                     "--log-file", str(tmp_path / "master.log")])[1:],
                            tmp_path, "master"))
    for i in (1, 2):
        programs.append(Program(Path("ip"), lan.argv(i, [
            str(agent_exe), "--port", str(PORT), "--broadcast", bcast, "--heartbeat-ms", str(HB),
            "--master-timeout-ms", str(LOSS), "--sysfs-root", str(tmp_path / "nosys"),
            "--log-file", str(tmp_path / f"agent{i}.log"), "--log-level", "2"])[1:], tmp_path, f"agent{i}"))

    def active() -> dict:
        s = read_status(status)
        return {a["id"]: a["state"] for a in (s or {}).get("agents", []) if a["state"] == "ACTIVE"}
    ids = wait_until(lambda: len(active()) == 2 and active(), 10, "both agents ACTIVE at the master")
    # Each agent synced with the master at its own address, across the bridge.
    for i in (1, 2):
        assert re.search(r"state ACTIVE \(id \d+\)", log(tmp_path, f"agent{i}")), log(tmp_path, f"agent{i}")
    assert len(ids) == 2

    lan.link(2, False)  # agent 2 cut off
    wait_until(lambda: "state PANIC" in log(tmp_path, "agent2"), 5, "agent 2 to declare its master lost")
    wait_until(lambda: len(active()) == 1, 5, "the master to drop agent 2")

    lan.link(2, True)   # healed
    wait_until(lambda: len(active()) == 2, 15, "agent 2 ACTIVE at the master again")
    assert log(tmp_path, "agent1").count("state PANIC") == 0  # the other agent never lost its master
