"""Programs each in a network namespace of their own, on one bridge (netns.Lan), every node on the
same port and reaching the others by the subnet's broadcast address, as on a Wi-Fi network: a
master and two agents sync; one agent's link goes down (a partition): it declares its master lost
and the master drops it; the link comes back: it syncs again. And the PC master killed: three
agents with --election elect one of them. Root only (CI runs as root): another user is skipped,
saying so; as root, namespaces that cannot be made fail the tests. conftest validates every program's trace against the spec, as for loopback."""

from __future__ import annotations

import re
import signal
from pathlib import Path

import pytest

import netns
from ev3net import Program, read_status, wait_until

PORT = 12345
HB, LOSS = 100, 600


@pytest.fixture
def lan():
    yield from netns.lan_or_skip(3)


@pytest.fixture
def lan4():
    yield from netns.lan_or_skip(4)


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


def test_the_master_killed_agents_in_namespaces_elect_one(lan4, master_exe, agent_exe, programs, tmp_path):
    """The PC master and three agents with --election, each in its namespace: once every agent
    knows the membership the PC is killed (SIGKILL); over the bridge the agents elect exactly one of
    them (the lowest score, when they noticed the loss together), and the others follow it."""
    bcast = f"{lan4.broadcast()}:{PORT}"
    status = tmp_path / "status.json"
    master = Program(Path("ip"), lan4.argv(0, [str(master_exe), "--port", str(PORT), "--broadcast", bcast,
                                               "--election", "--state-file", str(tmp_path / "m.state"),
                                               "--status-json", str(status), "--log-file", str(tmp_path / "master.log")])[1:],
                     tmp_path, "master")
    try:
        for i in (1, 2, 3):
            (tmp_path / f"s{i}").mkdir()
            programs.append(Program(Path("ip"), lan4.argv(i, [
                str(agent_exe), "--port", str(PORT), "--broadcast", bcast, "--heartbeat-ms", str(HB),
                "--master-timeout-ms", str(LOSS), "--paused-timeout-ms", str(2 * LOSS), "--election",
                "--score", str(10 * i), "--state-dir", str(tmp_path / f"s{i}"), "--sysfs-root", str(tmp_path / "nosys"),
                "--log-file", str(tmp_path / f"agent{i}.log"), "--log-level", "2"])[1:], tmp_path, f"agent{i}"))
        wait_until(lambda: (s := read_status(status)) and len(s["agents"]) == 3 and
                   all(a["state"] == "ACTIVE" for a in s["agents"]), 10, "three ACTIVE agents")
        # The PC publishes the membership one agent per epoch; its LEADER (every second) carries it.
        wait_until(lambda: all((tmp_path / f"s{i}" / "ev3-agent.state").exists() and
                               (tmp_path / f"s{i}" / "ev3-agent.state").read_text().count(",") == 2
                               for i in (1, 2, 3)), 10, "every agent to know the three members")
        master.stop(signal.SIGKILL)  # the PC dies (it is not among `programs`, which must exit 0)
    finally:
        master.close()  # killed above; stopped here if the test failed before
    won = wait_until(lambda: [i for i in (1, 2, 3) if "election: won epoch" in log(tmp_path, f"agent{i}")], 15,
                     "an agent to win an election")
    assert len(won) == 1, won
    # The lowest score stands first when the three noticed the loss within half a heartbeat of each
    # other (the back-off's step less its jitter: docs/election.md "Timers"); one that noticed it a
    # heartbeat later (its last PONG came later) may be beaten to it. The logs' times count from each
    # program's start, and the three started within milliseconds.
    panic = {i: float(re.search(r"\[\s*([\d.]+)\] I agent: state PANIC", log(tmp_path, f"agent{i}")).group(1))
             for i in (1, 2, 3)}
    if max(panic.values()) - min(panic.values()) < HB / 2000:
        assert won == [1], (won, panic)
    w = won[0]
    leader = int(re.search(r"state ACTIVE \(id (\d+)\)", log(tmp_path, f"agent{w}")).group(1))
    for i in {1, 2, 3} - {w}:
        wait_until(lambda: re.search(rf"following master {leader} \(epoch \d+\)", log(tmp_path, f"agent{i}")), 5,
                   f"agent {i} to follow agent {leader}")
    assert all("election: won epoch" not in log(tmp_path, f"agent{i}") for i in {1, 2, 3} - {w})
