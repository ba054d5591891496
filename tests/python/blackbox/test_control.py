"""ev3-master's control socket (`--control PATH`, docs/programs.md "The control socket"): the console
language over a Unix socket, one command per line, one answer per line, text or JSON; a command to
robots answered once they have answered it; the socket's mode, group, and what is refused."""

from __future__ import annotations

import grp
import json
import os
import socket
import stat
import subprocess
import time

import pytest

from ev3net import T, FakeAgent, free_ports, read_status, wait_until
from ev3conformance.wire import Message


_OPEN: list[socket.socket] = []


@pytest.fixture(autouse=True)
def _close_clients():
    yield
    while _OPEN:
        _OPEN.pop().close()


class Client:
    """One connection to the control socket (closed at the end of the test)."""

    def __init__(self, path, timeout: float = 5.0) -> None:
        self.s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        _OPEN.append(self.s)
        self.s.settimeout(timeout)
        self.s.connect(str(path))
        self.buf = b""

    def send(self, line: str) -> None:
        self.s.sendall(line.encode() + b"\n")

    def line(self) -> str:
        while b"\n" not in self.buf:
            got = self.s.recv(65536)
            assert got, "the control socket closed"
            self.buf += got
        line, self.buf = self.buf.split(b"\n", 1)
        return line.decode()

    def ask(self, line: str) -> str:
        self.send(line)
        return self.line()

    def ask_json(self, line: str) -> dict:
        return json.loads(self.ask("--json " + line))

    def close(self) -> None:
        self.s.close()


def fleet(agents, m, n: int, **kw) -> list[FakeAgent]:
    out = []
    for i in range(n):
        a = FakeAgent(m.port, 50100 + len(agents), **kw)
        agents.append(a)
        a.register()
        a.pinging = True
        out.append(a)
    wait_until(lambda: len((read_status(m.status) or {}).get("agents", [])) == len(agents), 3, "the agents registered")
    return out


def test_the_control_socket_drives_a_fleet(start_master, agents):
    m = start_master(control=True)
    a, b = fleet(agents, m, 2)
    c = Client(m.sock)
    st = c.ask_json("list")
    assert st["ok"] and sorted(x["id"] for x in st["status"]["agents"]) == sorted([a.id, b.id])
    assert c.ask(f"pause {a.id}") == f"ok: {a.id} PAUSE acked"
    # (a fake robot stays ACTIVE: the core sends PAUSE again itself, reconcile, answered to nobody)
    assert {x.type for x in a.commands} == {T["PAUSE"]} and not b.commands
    r = c.ask_json("behaviour all wait seconds=3")
    assert r == {"ok": True, "command": "BEHAVIOUR", "agent": "all",
                 "answers": [{"agent": min(a.id, b.id), "answer": "acked"},
                             {"agent": max(a.id, b.id), "answer": "acked"}]}
    assert c.ask("start all").startswith("ok: all START: ")
    # each command once per msgid (a copy may leave before the robot's ACK reaches the master)
    assert b.command_types()[:2] == [T["BEHAVIOUR"], T["START"]]
    text = c.ask("list")
    assert "\n" not in text and str(a.id) in text and "drops:" in text
    assert "(control socket)" in m.stdout()  # the operator sees what the socket did
    c.close()


def test_answers_wait_for_the_robot_and_say_what_it_answered(start_master, agents):
    m = start_master("--max-resends", "2", control=True)
    quiet, = fleet(agents, m, 1, answer=False)
    c = Client(m.sock)
    t0 = time.monotonic()
    r = c.ask_json(f"pause {quiet.id}")  # resent twice, 150 ms apart, then timed out
    assert r == {"ok": False, "command": "PAUSE", "agent": quiet.id,
                 "answers": [{"agent": quiet.id, "answer": "timed_out"}]}
    assert time.monotonic() - t0 >= 0.3
    c.send(f"start {quiet.id}")
    _, s = wait_until(lambda: next(((0, x) for x in quiet.commands if x.type == T["START"]), None), 2, "START")
    quiet.send(Message(quiet.id, 1, quiet.next_msgid(), T["NOT"], (str(s.msgid).encode(), b"no behaviour")),
               m.port)
    assert c.line() == f"error: {quiet.id} START refused (no behaviour)"
    assert c.ask_json("stop 4711") == {"ok": False, "command": "STOP", "agent": 4711,
                                      "answers": [{"agent": 4711, "answer": "unknown_agent"}]}
    assert c.ask("pause all").startswith("error: all PAUSE: ")  # the quiet robot times out again
    c.close()


def test_each_client_gets_its_own_answers(start_master, agents):
    m = start_master(control=True)
    a, = fleet(agents, m, 1)
    c1, c2 = Client(m.sock), Client(m.sock)
    c1.send(f"pause {a.id}")
    c2.send(f"--json resume {a.id}")
    assert c1.line() == f"ok: {a.id} PAUSE acked"
    assert c2.line() == json.dumps({"ok": True, "command": "RESUME", "agent": a.id,
                                    "answers": [{"agent": a.id, "answer": "acked"}]}, separators=(",", ":"))
    # A client that leaves before its answer does not disturb the others.
    c3 = Client(m.sock)
    c3.send(f"stop {a.id}")
    c3.close()
    assert c1.ask(f"start {a.id}") == f"ok: {a.id} START acked"
    # The console's command of the same type, queued ahead: its answer is not taken for c1's.
    quiet, = fleet(agents, m, 1, answer=False)
    m.write(f"stop {quiet.id}")
    c1.send(f"stop {quiet.id}")
    wait_until(lambda: len({x.msgid for x in quiet.commands if x.type == T["STOP"]}) == 1, 2, "the console's STOP")
    first = next(x for x in quiet.commands if x.type == T["STOP"])
    quiet.send(Message(quiet.id, 1, quiet.next_msgid(), T["ACK"], (str(first.msgid).encode(),)), m.port)
    wait_until(lambda: len({x.msgid for x in quiet.commands if x.type == T["STOP"]}) == 2, 2, "c1's STOP")
    second = [x for x in quiet.commands if x.type == T["STOP"] and x.msgid != first.msgid][0]
    quiet.send(Message(quiet.id, 1, quiet.next_msgid(), T["NOT"], (str(second.msgid).encode(), b"busy")), m.port)
    assert c1.line() == f"error: {quiet.id} STOP refused (busy)"


def test_a_client_that_closes_its_side_still_gets_its_answers(start_master, agents):
    m = start_master(control=True)
    a, b = fleet(agents, m, 2)
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    _OPEN.append(s)
    s.settimeout(5)
    s.connect(str(m.sock))
    s.sendall(b"pause all\nhelp")  # as `printf 'pause all\nhelp' | socat - UNIX-CONNECT:...` does
    s.shutdown(socket.SHUT_WR)
    got = b""
    while True:
        x = s.recv(65536)
        if not x:
            break  # the master closes once the answers are out
        got += x
    lines = got.decode().splitlines()
    assert lines[0].startswith("commands: list") and lines[1].startswith("ok: all PAUSE: ") and len(lines) == 2


@pytest.mark.empty_trace  # no agent: the master's trace has no record
def test_a_ninth_client_is_told_there_are_too_many(start_master):
    m = start_master(control=True)
    clients = [Client(m.sock) for _ in range(8)]
    assert all(c.ask("help").startswith("commands:") for c in clients)
    extra = Client(m.sock)
    assert extra.line() == "error: too many control connections (at most 8)"
    clients[0].close()
    time.sleep(0.2)
    assert Client(m.sock).ask("help").startswith("commands:")


@pytest.mark.empty_trace  # no agent: the master's trace has no record
def test_bad_lines_get_an_error_and_the_connection_goes_on(start_master):
    m = start_master("--json", control=True)  # every answer in JSON
    c = Client(m.sock)
    assert c.ask("bogus 1")[:30] == '{"ok":false,"error":"unknown c'
    r = json.loads(c.ask("pause x"))
    assert r["ok"] is False and "x" in r["error"]
    assert json.loads(c.ask("wait 1"))["error"] == "wait is for scripts (--script)"
    c.send("")  # an empty line and a comment get no answer
    c.send("# a comment")
    assert json.loads(c.ask("x" * 70000))["error"] == "line too long (at most 65536 bytes)"
    assert json.loads(c.ask("help"))["answer"].startswith("commands: list")
    assert json.loads(c.ask("list"))["status"]["agents"] == []
    assert json.loads(c.ask("quit"))["answer"] == "quit"
    assert m.proc.wait(5) == 0
    assert not m.sock.exists()  # removed when the master stops


@pytest.mark.empty_trace  # no agent: the master's trace has no record
def test_the_socket_is_0600_and_0660_for_a_group(start_master, tmp_path):
    m = start_master(control=True)
    assert stat.S_IMODE(os.stat(m.sock).st_mode) == 0o600 and stat.S_ISSOCK(os.stat(m.sock).st_mode)
    group = grp.getgrgid(os.getgid() if os.getgid() != 0 else 0).gr_name
    g = start_master("--control-group", group, name="grouped", control=True)
    st = os.stat(g.sock)
    assert stat.S_IMODE(st.st_mode) == 0o660 and grp.getgrgid(st.st_gid).gr_name == group


@pytest.mark.empty_trace  # no agent: the master's trace has no record
def test_what_the_socket_path_refuses(master_exe, start_master, tmp_path):
    def run(*args):
        return subprocess.run([str(master_exe), "--port", str(free_ports(1)[0]), "--bind", "127.0.0.1", *args],
                              capture_output=True, text=True, timeout=5, stdin=subprocess.DEVNULL)
    m = start_master(control=True)
    r = run("--control", str(m.sock))
    assert r.returncode == 2 and f"--control {m.sock}: another program is listening on it" in r.stderr
    plain = tmp_path / "plain"
    plain.write_text("keep me\n")
    r = run("--control", str(plain))
    assert r.returncode == 2 and "is not a socket" in r.stderr and plain.read_text() == "keep me\n"
    r = run("--control", str(tmp_path / ("x" * 120)))
    assert r.returncode == 2 and "longer than a socket path may be" in r.stderr
    r = run("--control", str(tmp_path / "s"), "--control-group", "no-such-group-here")
    assert r.returncode == 2 and "no group no-such-group-here" in r.stderr
    for args, named in ((["--control-group", "root"], "--control-group needs --control"),
                        (["--json"], "--json needs --control"), (["--control", ""], "--control")):
        r = run(*args)
        assert r.returncode == 2 and named in r.stderr


@pytest.mark.empty_trace  # no agent: the master's trace has no record
def test_a_socket_left_by_a_dead_master_is_replaced(start_master, tmp_path):
    path = tmp_path / "master.sock"
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    _OPEN.append(s)
    s.bind(str(path))  # a socket file nobody listens on: what a killed master leaves
    s.close()
    m = start_master(control=True)
    assert m.sock == path and Client(path).ask("help").startswith("commands:")
