"""ev3-master over real UDP on loopback, driven by Python test agents: registration, id
uniqueness, PONG with the PING's msgid, resends, time-outs, agent loss in --status-json, the
console (stdin lines, --script, a pseudo-terminal) and the command line."""

from __future__ import annotations

import os
import pty
import select
import subprocess
import time

import pytest

from ev3net import T, FakeAgent, free_ports, read_status, wait_until
from ev3conformance.wire import Message


def agent(agents, master, temp_id, **kw) -> FakeAgent:
    a = FakeAgent(master.port, temp_id, **kw)
    agents.append(a)
    return a


def status_agents(master) -> dict[int, dict]:
    s = read_status(master.status) or {}
    return {a["id"]: a for a in s.get("agents", [])}


def test_registers_several_agents_with_unique_ids(start_master, agents):
    m = start_master()
    fleet = [agent(agents, m, 50001 + i) for i in range(3)]
    ids = [a.register() for a in fleet]
    assert len(set(ids)) == 3 and all(2 <= i <= 49999 for i in ids)
    for a in fleet:
        a.pinging = True
    st = wait_until(lambda: (lambda s: s if len(s) == 3 and all(x["state"] == "ACTIVE" for x in s.values())
                             else None)(status_agents(m)), 3, "3 ACTIVE agents in the status JSON")
    assert sorted(st) == sorted(ids)
    assert {st[i]["announced"] for i in ids} == {50001, 50002, 50003}
    out = wait_until(lambda: m.stdout() if m.stdout().count("registered") == 3 else None, 2, "3 registered lines")
    assert "announced 50002" in out


def test_repeated_agent_copies_do_not_create_entries_and_ids_are_not_reused(start_master, agents):
    m = start_master()
    a = agent(agents, m, 50010)
    first = a.register()
    for _ in range(5):  # the same announcement again (new msgids): still one entry
        a.send_master("AGENT", "A", sender=50010)
    st = wait_until(lambda: status_agents(m) if first in status_agents(m) else None, 2, "the agent in status")
    assert list(st) == [first]
    # a is silent: lost after the agent timeout; a newcomer gets a new id, never the old one.
    wait_until(lambda: any(x["id"] == first for x in (read_status(m.status) or {}).get("lost", [])), 4,
               "the silent agent in 'lost'")
    b = agent(agents, m, 50011)
    assert b.register() != first


def test_pong_carries_the_ping_msgid(start_master, agents):
    m = start_master()
    a = agent(agents, m, 50020)
    a.register()
    mark = a.mark()
    mid = a.send_master("PING", "WORKING")
    _, pong, _ = a.wait_for(lambda x: x.type == T["PONG"], 2, "PONG", mark)
    assert pong.params == (str(mid).encode(),) and pong.receiver == a.id and pong.sender == 1
    wait_until(lambda: status_agents(m).get(a.id, {}).get("state") == "WORKING", 2, "state WORKING")


def test_unregistered_ping_gets_no_pong(start_master, agents, tmp_path):
    m = start_master("--log-level", "4")
    a = agent(agents, m, 50021)
    a.id = 777
    mark = a.mark()
    a.send_master("PING", "ACTIVE")
    time.sleep(0.3)
    assert not [x for _, x, _ in a.received(mark) if x.type == T["PONG"]]
    wait_until(lambda: (read_status(m.status) or {}).get("drops", {}).get("unknown_sender"), 2,
               "unknown_sender counted")
    # at --log-level 4 (verbose) the drop is logged with its count and the sender's address
    wait_until(lambda: f"drop (unknown_sender, 1 so far) from 127.0.0.1:{a.port}: "
               in (tmp_path / "master.log").read_text(), 2, "the verbose drop line")


def test_unanswered_command_is_resent_with_its_msgid(start_master, agents):
    m = start_master()
    a = agent(agents, m, 50030, answer=False)
    a.register()
    a.pinging = True
    m.write(f"start {a.id}")
    wait_until(lambda: len({x.msgid for x in a.commands}) == 1 and len(a.commands) >= 6, 3,
               "START sent and resent")
    starts = [x for x in a.commands if x.type == T["START"]]
    assert len({x.msgid for x in starts}) == 1, "a resend must keep the msgid"
    a.send(Message(a.id, 1, a.next_msgid(), T["ACK"], (str(starts[0].msgid).encode(),)), m.port)
    wait_until(lambda: "START acknowledged" in m.stdout(), 2, "START acknowledged")


def test_command_times_out_and_refusal_is_shown(start_master, agents):
    m = start_master("--max-resends", "2")
    a = agent(agents, m, 50031, answer=False)
    a.register()
    a.pinging = True
    m.write(f"pause {a.id}")
    wait_until(lambda: "PAUSE timed out" in m.stdout(), 3, "PAUSE timed out")
    m.write(f"start {a.id}")
    _, s = wait_until(lambda: next(((0, x) for x in a.commands if x.type == T["START"]), None), 2, "START")
    a.send(Message(a.id, 1, a.next_msgid(), T["NOT"], (str(s.msgid).encode(), b"no behaviour")), m.port)
    wait_until(lambda: "START refused (NOT): no behaviour" in m.stdout(), 2, "the refusal and its reason")


def test_agent_lost_shows_in_status_json(start_master, agents):
    m = start_master()
    a = agent(agents, m, 50040)
    a.register()
    a.pinging = True
    wait_until(lambda: a.id in status_agents(m), 2, "agent in status")
    a.pinging = False
    t0 = time.monotonic()
    st = wait_until(lambda: (lambda s: s if s and any(x["id"] == a.id for x in s["lost"]) else None)(
        read_status(m.status)), 4, "agent in lost")
    assert a.id not in {x["id"] for x in st["agents"]}
    assert time.monotonic() - t0 >= 0.9 - 0.3
    assert f"agent {a.id} lost" in m.stdout()


def test_console_errors_name_what_is_wrong(start_master):
    m = start_master()
    for line in ["fly 2", "start 999", "start two", "behaviour 2 wait 3", "start"]:
        m.write(line)
    out = wait_until(lambda: m.stdout() if m.stdout().count("error:") >= 5 else None, 2, "5 errors")
    assert "unknown command 'fly'" in out
    assert "unknown agent id 999" in out
    assert "bad agent id 'two'" in out
    assert "bad argument '3' (expected key=value)" in out
    m.write("list")
    wait_until(lambda: "ID    ADDRESS" in m.stdout(), 2, "the table")
    m.write("quit")
    m.proc.wait(3)
    assert m.proc.returncode == 0


def scripted_master(start_master, agents, tmp_path, temp_id: int, script: str):
    """A master running `script` (--script) and a fake agent registered with it (id 2)."""
    a = FakeAgent(free_ports(1)[0], temp_id)
    agents.append(a)
    path = tmp_path / "s.txt"
    path.write_text(script)
    m = start_master("--script", str(path), stdin=subprocess.DEVNULL)
    # start_master picked its own port; point the agent at it.
    a.master_port = m.port
    a.register()
    a.pinging = True
    return m, a


def test_script_runs_commands_with_waits(start_master, agents, tmp_path):
    m, a = scripted_master(start_master, agents, tmp_path, 50050,
                           "# demo\nwait 0.8\nbehaviour 2 wait seconds=2\nwait 0.5\nstart 2\n")
    _, s = wait_until(lambda: next(((0, x) for x in a.commands if x.type == T["START"]), None), 4, "START")
    b = next(x for x in a.commands if x.type == T["BEHAVIOUR"])
    assert b.params == (b"wait", b"seconds=2")
    tb = next(t for t, x, _ in a.received() if x.type == T["BEHAVIOUR"])
    ts = next(t for t, x, _ in a.received() if x.type == T["START"])
    assert ts - tb >= 0.45
    wait_until(lambda: "START acknowledged" in m.stdout(), 2, "START acknowledged")
    assert m.proc.poll() is None, "the master keeps running after the script"


def test_live_table_on_a_terminal(master_exe, tmp_path, agents):
    port = free_ports(1)[0]
    pid, fd = pty.fork()
    if pid == 0:
        os.execv(str(master_exe), [str(master_exe), "--port", str(port), "--bind", "127.0.0.1"])
    out = b""
    try:
        a = FakeAgent(port, 50060)
        agents.append(a)
        a.register()
        a.pinging = True

        def read_some():
            nonlocal out
            while select.select([fd], [], [], 0.05)[0]:
                try:
                    out += os.read(fd, 65536)
                except OSError:
                    break
            return out
        wait_until(lambda: b"127.0.0.1" in read_some() and b"ACTIVE" in out, 4, "the agent ACTIVE in the table")
        assert b"\x1b[" in out and b"ID    ADDRESS" in out and b"ev3>" in out
        os.write(fd, b"start 77\n")
        wait_until(lambda: b"unknown agent id 77" in read_some(), 2, "the answer on the terminal")
        os.write(fd, b"quit\n")
        _, status = os.waitpid(pid, 0)
        pid = 0
        assert os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0
    finally:
        if pid:
            os.kill(pid, 9)
            os.waitpid(pid, 0)
        os.close(fd)


@pytest.mark.empty_trace  # no agent: the master hears nothing, its trace has no record
def test_sigint_exits_0_and_writes_status(start_master):
    m = start_master(stdin=subprocess.DEVNULL)
    assert m.stop(2) == 0
    assert read_status(m.status) is not None


def test_a_failed_state_write_stops_the_master_sending_nothing_more(start_master, agents, programs, tmp_path):
    state = tmp_path / "master.state"
    m = start_master("--state-file", str(state))
    agent(agents, m, 50001).register()  # its id handed out: next_id written first
    written = state.read_text()
    # DIR/master.state.tmp a directory: the next write fails (temp file first)
    (tmp_path / "master.state.tmp").mkdir()
    second = agent(agents, m, 50002)
    for _ in range(20):
        if m.proc.poll() is not None:
            break
        second.send_master("AGENT", "A", sender=50002)
        time.sleep(0.05)
    assert m.proc.wait(3) == 1
    programs.remove(m)  # it exited by itself, with status 1
    m.close()
    assert second.id == 0, "an id handed out that is not on disk"
    assert "the master's state is not on disk: sending nothing more, exiting" in m.stderr()
    assert "stopping: the state file could not be written" in (tmp_path / "master.log").read_text()
    assert state.read_text() == written


@pytest.mark.parametrize("args,named", [
    (["--agent-timeout-ms", "x"], "--agent-timeout-ms"), (["--bind", "nowhere"], "--bind"),
    (["--script", "/nonexistent/x"], "--script"), (["--fault-dup", "-1"], "--fault-dup"),
])
def test_bad_flag_exits_2_naming_it(master_exe, args, named):
    r = subprocess.run([str(master_exe), *args], capture_output=True, text=True, timeout=5,
                       stdin=subprocess.DEVNULL)
    assert r.returncode == 2
    assert named in r.stderr


def test_help(master_exe):
    r = subprocess.run([str(master_exe), "--help"], capture_output=True, text=True, timeout=5)
    assert r.returncode == 0 and "--status-json" in r.stdout and "--script" in r.stdout


def test_custom_behaviour_from_a_file_checked_then_sent_compact(start_master, agents, tmp_path):
    """`behaviour ID custom @FILE`: a definition that does not check is refused at the console with
    the file and the place, and nothing is sent; a good one goes out compact in one param."""
    bad = tmp_path / "bad.bhv"
    bad.write_text("behaviour spin\nstate turning = trun 90 speed=200 -> turning\n")
    good = tmp_path / "spin.bhv"
    good.write_text("# spin on the spot\nbehaviour spin\nparam angle = 90\n"
                    "state turning = turn $angle speed=200 -> turning\n"
                    "on OBSTACLE_DETECTED, PROXIMITY_ALERT -> end\n")
    m, a = scripted_master(start_master, agents, tmp_path, 50051,
                           f"wait 0.8\nbehaviour 2 custom @{bad}\nbehaviour 2 custom @{good} angle=45\n")
    b = wait_until(lambda: next((x for x in a.commands if x.type == T["BEHAVIOUR"]), None), 4, "BEHAVIOUR")
    out = m.stdout()
    assert f"error: refused before sending: {bad}: line 2 col 17: unknown action 'trun'" in out
    assert b.params[0] == b"custom" and b.params[2] == b"angle=45"
    assert b"behaviour spin" in b.params[1] and b"#" not in b.params[1] and b"\n" not in b.params[1]
    sent = [x for x in a.commands if x.type == T["BEHAVIOUR"]]  # copies and resends: one msgid
    assert not any(b"trun" in x.params[1] for x in sent), "the bad one was not sent"
    assert len({x.msgid for x in sent}) == 1, [x.msgid for x in sent]


def test_rule_explore_exploit_switches_a_robot_that_sees_the_colour(start_master, agents, tmp_path):
    m, a = scripted_master(start_master, agents, tmp_path, 50052,
                           "wait 0.8\nrule explore-exploit red speed=200\nbehaviour 2 explore\nstart 2\n")
    wait_until(lambda: "START acknowledged" in m.stdout(), 4, "START acknowledged")
    a.send_master("SENSOR_VALUE", "in3", "COL-COLOR", "3")  # green: not the colour
    a.send_master("SENSOR_VALUE", "in3", "COL-COLOR", "5")  # red
    b = wait_until(lambda: next((x for x in a.commands if x.type == T["BEHAVIOUR"] and x.params[0] == b"exploit"),
                                None), 3, "BEHAVIOUR exploit")
    assert b.params == (b"exploit", b"colour=red", b"speed=200")
    assert "rule explore-exploit: agent 2 is on red" in m.stdout()
