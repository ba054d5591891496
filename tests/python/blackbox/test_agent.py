"""ev3-agent over real UDP on loopback, driven by a Python test master (ev3conformance.wire):
every row of docs/brief.md section 2's table, and the answers of docs/protocol.md (ACK/NOT with the msgid,
duplicates answered again and acted on once), the `wait` behaviour, LEDs, signals, command line."""

from __future__ import annotations

import json
import signal
import subprocess
import time

import pytest

from ev3net import HB, LOSS, PAUSED, SYNC, T, Message, show, wait_until

ID = 2


@pytest.fixture
def active(start_agent, tm):
    """An agent synced with the test master: ACTIVE with id 2."""
    p = start_agent()
    tm.sync(ID)
    tm.wait_state(ID, "ACTIVE")
    return p


@pytest.fixture
def working(active, tm):
    """ACTIVE -> WORKING with a long wait behaviour."""
    tm.ack(ID, "BEHAVIOUR", "wait", "seconds=60")
    tm.ack(ID, "START")
    tm.wait_state(ID, "WORKING")
    return active


@pytest.fixture
def paused(working, tm):
    tm.ack(ID, "PAUSE")
    tm.wait_state(ID, "PAUSED")
    return working


# --- the lifecycle table, row by row -----------------------------------------------------------

def test_idle_to_active_on_master(start_agent, tm):
    start_agent()
    _, a, _ = tm.wait_for(lambda m: m.type == T["AGENT"], 3, "AGENT")
    assert a.receiver == 0 and a.params == (b"A",) and 50000 <= a.sender <= 65535
    tm.sync(7)
    tm.wait_state(7, "ACTIVE")


def test_idle_to_panic_on_sync_timeout(start_agent, tm):
    start_agent()
    t0, a, _ = tm.wait_for(lambda m: m.type == T["AGENT"], 3, "AGENT")
    t1, p, _ = tm.wait_for(lambda m: m.type == T["PANIC"], SYNC / 1000 + 2, "PANIC after the sync timeout")
    assert p.sender == a.sender and p.receiver == 0
    # The first AGENT goes out one heartbeat after start; PANIC one sync timeout after start.
    assert t1 - t0 >= (SYNC - 2 * HB) / 1000 - 0.05, f"PANIC too early: {t1 - t0:.3f} s"
    assert not any(m.type == T["PING"] for _, m, _ in tm.received())


def test_active_to_working_on_start_after_behaviour_ack(active, tm):
    tm.ack(ID, "BEHAVIOUR", "wait", "seconds=60")
    tm.ack(ID, "START")
    tm.wait_state(ID, "WORKING")


@pytest.mark.parametrize("command", ["STOP", "STANDBY"])
def test_working_to_active_on_stop_and_standby(working, tm, command):
    tm.ack(ID, command)
    tm.wait_state(ID, "ACTIVE")


def test_working_to_paused_on_pause(working, tm):
    tm.ack(ID, "PAUSE")
    tm.wait_state(ID, "PAUSED")


def test_working_to_paused_on_heartbeat_loss(working, tm):
    tm.auto_pong = False
    t0 = time.monotonic()
    t = tm.wait_state(ID, "PAUSED", LOSS / 1000 + 2)
    assert t - t0 >= LOSS / 1000 - 2 * HB / 1000 - 0.05


@pytest.mark.parametrize("command", ["RESUME", "START"])
def test_paused_to_working_on_resume_and_start(paused, tm, command):
    tm.ack(ID, command)
    tm.wait_state(ID, "WORKING")


def test_paused_to_active_on_stop(paused, tm):
    tm.ack(ID, "STOP")
    tm.wait_state(ID, "ACTIVE")


def test_paused_to_panic_on_loss(paused, tm):
    tm.auto_pong = False
    mark = tm.mark()
    t0 = time.monotonic()
    t, p, _ = tm.wait_for(lambda m: m.type == T["PANIC"], PAUSED / 1000 + 2, "PANIC", mark)
    assert p.sender == ID
    assert t - t0 >= PAUSED / 1000 - 2 * HB / 1000 - 0.05


def test_active_to_panic_on_loss(active, tm):
    tm.auto_pong = False
    mark = tm.mark()
    _, p, _ = tm.wait_for(lambda m: m.type == T["PANIC"], LOSS / 1000 + 2, "PANIC", mark)
    assert p.sender == ID and p.receiver == 0


def test_working_loses_master_paused_then_panic(working, tm):
    """WORKING -> PAUSED (behaviour stopped) -> PANIC, the whole fall-back of a lost master."""
    tm.auto_pong = False
    mark = tm.mark()
    tm.wait_state(ID, "PAUSED", LOSS / 1000 + 2, since=mark)
    tm.wait_for(lambda m: m.type == T["PANIC"], PAUSED / 1000 + 2, "PANIC", mark)


def test_panic_to_active_on_master(active, tm):
    tm.auto_pong = False
    mark = tm.mark()
    tm.wait_for(lambda m: m.type == T["PANIC"], LOSS / 1000 + 2, "PANIC", mark)
    tm.auto_pong = True
    # In PANIC the agent announces its old id; a MASTER naming it gives it a new id.
    mark = tm.mark()
    mid = tm.command(3, "MASTER", str(ID))
    assert tm.answer(3, mid, mark).type == T["ACK"]
    tm.wait_state(3, "ACTIVE")


def test_panic_ignores_other_agents(active, tm):
    tm.auto_pong = False
    mark = tm.mark()
    _, panic, _ = tm.wait_for(lambda m: m.type == T["PANIC"], LOSS / 1000 + 2, "PANIC", mark)
    # Another agent's messages (AGENT, PANIC, even a PING) change nothing: still PANIC, no answer.
    from ev3conformance.wire import Message
    for i, (t, params) in enumerate([("AGENT", (b"A",)), ("PANIC", ()), ("PING", (b"ACTIVE",))]):
        tm.send(Message(9, 0, 500 + i, T[t], params), tm.agent_port)
    mark = tm.mark()
    tm.wait_for(lambda m: m.type == T["PANIC"], 2, "PANIC still", mark)
    # (late copies of the last PING, sent before the PANIC, have smaller msgids)
    assert not [m for _, m, _ in tm.received(mark)
                if m.type in (T["ACK"], T["NOT"], T["PING"]) and m.msgid > panic.msgid]


# --- docs/protocol.md answers -------------------------------------------------------------------

def test_refusals_carry_msgid_and_reason(active, tm):
    assert tm.refused(ID, "START") == b"no behaviour"
    assert tm.refused(ID, "PAUSE") == b"wrong state"
    assert tm.refused(ID, "RESUME") == b"wrong state"
    assert tm.refused(ID, "BEHAVIOUR", "fly", "x=1") == b"unknown behaviour"
    tm.ack(ID, "BEHAVIOUR", "wait", "seconds=5")


def test_duplicates_answered_again_acted_on_once(working, tm):
    mark = tm.mark()
    pause_id = tm.command(ID, "PAUSE")
    first = tm.answer(ID, pause_id, mark)
    assert first.type == T["ACK"]
    tm.wait_state(ID, "PAUSED")
    tm.ack(ID, "RESUME")
    tm.wait_state(ID, "WORKING")
    # The same PAUSE again (a resend with its msgid): answered again with ACK, not acted on.
    mark = tm.mark()
    tm.command(ID, "PAUSE", msgid=pause_id)
    again = tm.answer(ID, pause_id, mark)
    assert again.type == T["ACK"] and again.msgid != first.msgid
    since = tm.mark()
    time.sleep(4 * HB / 1000)  # several heartbeats: all of them must still say WORKING
    pings = [m.params[0] for _, m, _ in tm.received(since) if m.type == T["PING"]]
    assert pings and set(pings) == {b"WORKING"}, pings


def test_commands_answered_three_copies_each(active, tm):
    """Each of the 3 copies of a command is answered (the first acted on, the others repeated)."""
    mark = tm.mark()
    mid = tm.command(ID, "BEHAVIOUR", "wait", "seconds=1")
    wait_until(lambda: len([m for _, m, _ in tm.received(mark)
                            if m.type == T["ACK"] and m.params[0] == str(mid).encode()]) >= 3, 2,
               "3 ACKs of the 3 copies")


# --- the wait behaviour ----------------------------------------------------------------------------

def test_wait_reports_action_ok_when_time_is_up(active, tm):
    tm.ack(ID, "BEHAVIOUR", "wait", "seconds=0.5")
    mark = tm.mark()
    t0 = time.monotonic()
    tm.ack(ID, "START")
    t, ok, _ = tm.wait_for(lambda m: m.type == T["ACTION_OK"], 3, "ACTION_OK", mark)
    assert ok.params == (b"0",)
    assert 0.4 <= t - t0 <= 1.0, f"ACTION_OK after {t - t0:.3f} s"


def test_wait_pause_keeps_time_left_resume_continues(active, tm):
    tm.ack(ID, "BEHAVIOUR", "wait", "seconds=1")
    mark = tm.mark()
    tm.ack(ID, "START")
    time.sleep(0.4)
    tm.ack(ID, "PAUSE")
    time.sleep(0.8)  # paused: the time left (about 0.6 s) must not run out
    assert not [m for _, m, _ in tm.received(mark) if m.type == T["ACTION_OK"]]
    t0 = time.monotonic()
    tm.ack(ID, "RESUME")
    t, _, _ = tm.wait_for(lambda m: m.type == T["ACTION_OK"], 3, "ACTION_OK", mark)
    assert 0.4 <= t - t0 <= 0.95, f"resumed wait ended {t - t0:.3f} s after RESUME (expected ~0.6)"


def test_wait_stop_discards_and_start_starts_over(active, tm):
    tm.ack(ID, "BEHAVIOUR", "wait", "seconds=0.6")
    mark = tm.mark()
    tm.ack(ID, "START")
    time.sleep(0.3)
    tm.ack(ID, "STOP")
    time.sleep(0.5)
    assert not [m for _, m, _ in tm.received(mark) if m.type == T["ACTION_OK"]]
    t0 = time.monotonic()
    tm.ack(ID, "START")
    t, _, _ = tm.wait_for(lambda m: m.type == T["ACTION_OK"], 3, "ACTION_OK", mark)
    assert 0.5 <= t - t0 <= 1.0


def test_wait_with_bad_seconds_is_refused_on_receipt_with_the_reason(active, tm):
    # The robot checks a BEHAVIOUR before it answers: a bad argument is refused there, in its words,
    # and nothing is loaded (it used to be ACKed and fail at START with ACTION_ERR).
    assert tm.refused(ID, "BEHAVIOUR", "wait", "seconds=soon") == b"argument 'seconds=soon': 'soon' is not a value"
    assert tm.refused(ID, "START") == b"no behaviour"


# --- signals, LEDs, trace, command line ------------------------------------------------------------

def test_sigterm_tells_the_master_and_exits_0(working, tm):
    mark = tm.mark()
    assert working.stop(signal.SIGTERM) == 0
    _, e, _ = tm.wait_for(lambda m: m.type == T["EVENT"], 2, "EVENT LEAVING", mark)
    assert e.params == (b"LEAVING",) and e.sender == ID
    log = (working.err_path.parent / "agent.log").read_text()
    assert "stopping (signal 15)" in log and "behaviour stopped" in log


def test_a_failed_state_write_stops_the_agent_sending_nothing_more(start_agent, programs, tm, tmp_path):
    # DIR/ev3-agent.state.tmp a directory: the write of the election state fails (temp file first)
    (tmp_path / "s" / "ev3-agent.state.tmp").mkdir(parents=True)
    p = start_agent("--election", "--state-dir", str(tmp_path / "s"))
    tm.sync(ID)
    tm.wait_state(ID, "ACTIVE")
    mark = tm.mark()
    # the PC's LEADER lists the agent: the membership it learns is durable, and cannot be written
    tm.send(Message(1, 0, tm.next_msgid(), 29, (b"1", b"1", str(ID).encode())), tm.agent_port)  # LEADER
    assert p.proc.wait(3) == 1
    programs.remove(p)  # it exited by itself, with status 1
    p.close()
    assert "the election state is not on disk: sending nothing more, exiting" in p.stderr()
    log = (tmp_path / "agent.log").read_text()
    assert "stopping: the state file could not be written" in log
    assert not [m for _, m, _ in tm.received(mark) if m.type == T["EVENT"]], "no EVENT LEAVING after the failure"
    assert not (tmp_path / "s" / "ev3-agent.state").exists()


def test_sigint_exits_0(start_agent):
    p = start_agent()
    time.sleep(0.2)
    assert p.stop(signal.SIGINT) == 0


def test_leds_written_to_sysfs(start_agent, tm, tmp_path):
    root = tmp_path / "sys"
    names = ["led0:red:brick-status", "led0:green:brick-status", "led1:red:brick-status",
             "led1:green:brick-status"]
    for n in names:
        (root / "class" / "leds" / n).mkdir(parents=True)
        (root / "class" / "leds" / n / "max_brightness").write_text("255\n")
    start_agent("--sysfs-root", str(root))
    led = root / "class" / "leds"

    def value(name, attr):
        """The LED file's text, or None while the agent has not written it yet."""
        try:
            return (led / name / attr).read_text()
        except FileNotFoundError:
            return None

    # IDLE: yellow blinking = red and green on, timer trigger. The agent writes the files one after
    # another, so wait for the whole pattern rather than for the first file.
    wait_until(lambda: value(names[0], "trigger") == "timer" and value(names[1], "brightness") == "255",
               2, "IDLE pattern (red timer trigger, green at 255)")
    tm.sync(ID)
    # ACTIVE: green blinking, red off.
    wait_until(lambda: value(names[0], "brightness") == "0", 2, "red LED off")
    assert (led / names[1] / "trigger").read_text() == "timer"
    tm.ack(ID, "BEHAVIOUR", "wait", "seconds=30")
    tm.ack(ID, "START")
    # WORKING: solid green.
    wait_until(lambda: value(names[1], "trigger") == "none", 2, "solid green")
    tm.ack(ID, "PAUSE")
    # PAUSED: orange = red full, green half.
    wait_until(lambda: value(names[3], "brightness") == "128", 2, "orange")


def test_missing_sysfs_is_logged_not_fatal(start_agent, tm, tmp_path):
    p = start_agent("--sysfs-root", str(tmp_path / "nowhere"))
    tm.sync(ID)
    tm.wait_state(ID, "ACTIVE")
    p.stop()
    assert "no ev3dev devices under" in (tmp_path / "agent.log").read_text()


def test_trace_is_ndjson_of_spec_actions(start_agent, tm, tmp_path):
    p = start_agent("--trace", str(tmp_path / "t.ndjson"))
    tm.sync(ID)
    tm.ack(ID, "BEHAVIOUR", "wait", "seconds=5")
    tm.ack(ID, "START")
    tm.wait_state(ID, "WORKING")
    assert p.stop() == 0
    recs = [json.loads(l) for l in (tmp_path / "t.ndjson").read_text().splitlines()]
    actions = [r["action"] for r in recs]
    assert {"Tick", "RecvMaster", "RecvBehaviour", "RecvStart"} <= set(actions)
    start = next(r for r in recs if r["action"] == "RecvStart")
    assert start["changed"]["state"] == "WORKING"


def test_thesis_form_of_the_command_line(agent_exe, programs, tmp_path, tm):
    from ev3net import Program, free_ports
    port = free_ports(1)[0]
    p = Program(agent_exe, ["agent", f"port={port}", "model=B", "loglevel=2", f"broadcast=127.0.0.1:{tm.port}",
                            "heartbeat_ms=50", "bind=127.0.0.1"], tmp_path, "thesis")
    programs.append(p)
    _, a, _ = tm.wait_for(lambda m: m.type == T["AGENT"], 3, "AGENT")
    assert a.params == (b"B",)
    assert f"listening on 127.0.0.1:{port}" in wait_until(lambda: p.stderr() or None, 2, "log")


@pytest.mark.parametrize("args,named", [
    (["--port", "99999"], "--port"), (["--log-level", "9"], "--log-level"), (["--nope"], "--nope"),
    (["--broadcast", "x"], "--broadcast"), (["colour=red"], "colour"), (["--heartbeat-ms", "0"], "--heartbeat-ms"),
])
def test_bad_flag_exits_2_naming_it(agent_exe, args, named):
    r = subprocess.run([str(agent_exe), *args], capture_output=True, text=True, timeout=5)
    assert r.returncode == 2
    assert named in r.stderr


def test_help(agent_exe):
    r = subprocess.run([str(agent_exe), "--help"], capture_output=True, text=True, timeout=5)
    assert r.returncode == 0 and "--sysfs-root" in r.stdout and "--broadcast" in r.stdout
    # the prose names what the program has: model A's behaviours (as its driver reports them), the
    # driver mode, the exit statuses
    facts = subprocess.run([str(agent_exe), "--driver"], input='{"type":"facts"}\n', capture_output=True,
                           text=True, timeout=5)
    names = [b["name"] for b in json.loads(facts.stdout.splitlines()[0])["facts"]["behaviours"]]
    assert names and all(n in r.stdout for n in names), (names, r.stdout)
    assert "--driver" in r.stdout and "Exit status" in r.stdout
