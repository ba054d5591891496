"""Helpers of the black-box tests: real UDP on loopback, the reference codec (ev3conformance.wire),
the programs under test as subprocesses.

- `Node`: a UDP socket on 127.0.0.1 with a receive thread that decodes and records every datagram.
- `TestMaster`: a Python master (id 1) that drives `ev3-agent`: sync, commands, auto-PONG.
- `FakeAgent`: a Python agent that drives `ev3-master`: AGENT, ACK, PING, answers to commands.
- `Program`: `ev3-agent` / `ev3-master` started with a log file, stopped with SIGTERM.
- `Links`: one program's links to its peers through the test, which can lose datagrams of chosen types.
- `wait_until`: a bounded wait for a condition (no sleeps as assertions).
- `assert_static_armel`: the EV3 build is a static ARM executable.
"""

from __future__ import annotations

import json
import re
import selectors
import shutil
import signal
import socket
import subprocess
import threading
import time
from pathlib import Path

from ev3conformance.signing import unseal
from ev3conformance.wire import DecodeError, Message, decode, encode

T = dict(AGENT=1, MASTER=2, ACK=3, NOT=4, PING=5, PONG=6, BEHAVIOUR=7, START=8, STOP=9, PAUSE=10,
         RESUME=11, STANDBY=12, CONTINUE=13, RESTART=14, ACTION_OK=15, ACTION_INTERR=16,
         ACTION_ERR=17, SENSOR_VALUE=18, PANIC=19, EVENT=20, REPORT=40, REPORT_DROPPED=41, REPORT_ACK=42)
NAME = {v: k for k, v in T.items()}

# Short timers for the tests (ms).
HB, LOSS, PAUSED, SYNC = 50, 400, 800, 700


def free_ports(n: int) -> list[int]:
    """n distinct free UDP ports on 127.0.0.1 (held open together while picking)."""
    socks = []
    try:
        for _ in range(n):
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            s.bind(("127.0.0.1", 0))
            socks.append(s)
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()


def wait_until(pred, timeout: float, what: str, interval: float = 0.01):
    """Polls pred() until it returns something truthy (returned) or fails after timeout seconds."""
    end = time.monotonic() + timeout
    while True:
        v = pred()
        if v:
            return v
        if time.monotonic() > end:
            raise AssertionError(f"timed out after {timeout:g} s waiting for {what}")
        time.sleep(interval)


def unsigned(data: bytes) -> bytes:
    """@p data without its signature trailer, when it has one (docs/protocol.md "Signed datagrams")."""
    try:
        return unseal(data)[0]
    except ValueError:
        return data


def show(m: Message) -> str:
    return ":".join([str(m.sender), str(m.receiver), str(m.msgid), NAME.get(m.type, str(m.type))]
                    + [p.decode("latin-1") for p in m.params])


class Node:
    """A UDP endpoint on loopback that records what it receives: (time, Message, from_port)."""

    def __init__(self, port: int = 0) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", port))
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        self.port = self.sock.getsockname()[1]
        self.got: list[tuple[float, Message, int]] = []
        self.undecodable = 0
        self.lock = threading.Lock()
        self._stop = False
        self.sock.settimeout(0.05)
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self._stop:
            try:
                data, addr = self.sock.recvfrom(65536)
            except socket.timeout:
                continue
            except OSError:
                return
            try:
                m = decode(data)
            except DecodeError:
                self.undecodable += 1
                continue
            with self.lock:
                self.got.append((time.monotonic(), m, addr[1]))
            self.on_message(m, addr[1])

    def on_message(self, m: Message, port: int) -> None:  # hook
        pass

    def send(self, m: Message, port: int, copies: int = 3) -> None:
        data = encode(m)
        for _ in range(copies):
            self.sock.sendto(data, ("127.0.0.1", port))

    def send_raw(self, data: bytes, port: int) -> None:
        self.sock.sendto(data, ("127.0.0.1", port))

    def mark(self) -> int:
        with self.lock:
            return len(self.got)

    def received(self, since: int = 0) -> list[tuple[float, Message, int]]:
        with self.lock:
            return list(self.got[since:])

    def wait_for(self, pred, timeout: float, what: str, since: int = 0):
        """The first (time, Message, port) from index `since` on with pred(Message) true."""
        def find():
            for item in self.received(since):
                if pred(item[1]):
                    return item
            return None
        return wait_until(find, timeout, what)

    def close(self) -> None:
        self._stop = True
        self.thread.join(timeout=1)
        self.sock.close()


class TestMaster(Node):
    """A master (id 1) driving one ev3-agent at agent_port."""

    __test__ = False  # not a pytest class

    def __init__(self, port: int = 0) -> None:
        self.msgid = 1000
        self.auto_pong = True
        self.auto_report_ack = True  # record REPORTs and acknowledge them, as the PC does
        self.records: dict[int, int] = {}  # agent -> its last report number recorded
        self.agent_port = 0
        super().__init__(port)

    def next_msgid(self) -> int:
        self.msgid += 1
        return self.msgid

    def on_message(self, m: Message, port: int) -> None:
        if m.type == T["PING"] and self.auto_pong:
            self.send(Message(1, m.sender, self.next_msgid(), T["PONG"], (str(m.msgid).encode(),)), port)
        if m.type == T["REPORT"] and self.auto_report_ack:
            self.take_report(m, port)

    def take_report(self, m: Message, port: int) -> None:
        """Reports.tla's PCTake and PCAck: a REPORT whose number is the next of the agent's record is
        recorded (its report joins what was received, as the master shows it), then REPORT_ACK."""
        seq, first = int(m.params[0]), int(m.params[1])
        last = self.records.get(m.sender, first - 1)
        if seq == max(last, first - 1) + 1:
            self.records[m.sender] = last = seq
            with self.lock:
                self.got.append((time.monotonic(), decode(m.params[2]), port))
        self.send(Message(1, m.sender, 0, T["REPORT_ACK"], (str(last).encode(),)), port, copies=1)

    def command(self, agent_id: int, type_name: str, *params: str, msgid: int | None = None) -> int:
        mid = self.next_msgid() if msgid is None else msgid
        self.send(Message(1, agent_id, mid, T[type_name], tuple(p.encode() for p in params)), self.agent_port)
        return mid

    def answer(self, agent_id: int, msgid: int, since: int = 0, timeout: float = 2.0) -> Message:
        """The agent's ACK or NOT of msgid."""
        _, m, _ = self.wait_for(lambda m: m.sender == agent_id and m.type in (T["ACK"], T["NOT"])
                                and m.params and m.params[0] == str(msgid).encode(),
                                timeout, f"ACK/NOT of msgid {msgid} from agent {agent_id}", since)
        return m

    def ack(self, agent_id: int, type_name: str, *params: str, timeout: float = 2.0) -> int:
        mark = self.mark()
        mid = self.command(agent_id, type_name, *params)
        m = self.answer(agent_id, mid, mark, timeout)
        assert m.type == T["ACK"], f"{type_name} refused: {show(m)}"
        return mid

    def refused(self, agent_id: int, type_name: str, *params: str) -> bytes:
        mark = self.mark()
        mid = self.command(agent_id, type_name, *params)
        m = self.answer(agent_id, mid, mark)
        assert m.type == T["NOT"], f"{type_name} was not refused: {show(m)}"
        return m.params[1]

    def wait_state(self, agent_id: int, state: str, timeout: float = 2.0, since: int | None = None) -> float:
        """Time of the first PING from agent_id reporting state (after `since`, default now)."""
        s = self.mark() if since is None else since
        t, _, _ = self.wait_for(lambda m: m.sender == agent_id and m.type == T["PING"]
                                and m.params == (state.encode(),), timeout,
                                f"PING {state} from agent {agent_id}", s)
        return t

    def sync(self, new_id: int = 2, timeout: float = 3.0) -> int:
        """Answers the agent's AGENT with MASTER(new_id); returns the temporary id."""
        _, a, port = self.wait_for(lambda m: m.type == T["AGENT"], timeout, "AGENT broadcast")
        self.agent_port = port
        mark = self.mark()
        mid = self.command(new_id, "MASTER", str(a.sender))
        m = self.answer(new_id, mid, mark)
        assert m.type == T["ACK"]
        return a.sender


class FakeAgent(Node):
    """An agent driving ev3-master: announces itself, ACKs MASTER, pings, answers commands."""

    def __init__(self, master_port: int, temp_id: int, answer: bool = True, devices: tuple[str, ...] = ()) -> None:
        self.master_port = master_port
        self.temp_id = temp_id
        self.devices = devices        # announced in AGENT after the model
        self.id = 0
        self.msgid = 0
        self.answer = answer          # answer commands automatically with ACK
        self.pinging = False
        self.commands: list[Message] = []
        super().__init__()
        self._pinger = threading.Thread(target=self._ping_loop, daemon=True)
        self._pinger.start()

    def next_msgid(self) -> int:
        self.msgid += 1
        return self.msgid

    def command_types(self) -> list[int]:
        """The types of the commands received, one per msgid (copies counted once), in order."""
        return list({x.msgid: x.type for x in self.commands}.values())

    def send_master(self, type_name: str, *params: str, sender: int | None = None, copies: int = 3) -> int:
        mid = self.next_msgid()
        self.send(Message(self.id if sender is None else sender, 1 if type_name not in ("AGENT", "PANIC") else 0,
                          mid, T[type_name], tuple(p.encode() for p in params)), self.master_port, copies)
        return mid

    def on_message(self, m: Message, port: int) -> None:
        if m.type == T["MASTER"] and m.params[0] == str(self.temp_id).encode() and self.id == 0:
            self.id = m.receiver
            self.send(Message(self.id, 1, self.next_msgid(), T["ACK"], (str(m.msgid).encode(),)), port)
        elif T["BEHAVIOUR"] <= m.type <= T["RESTART"]:
            self.commands.append(m)
            if self.answer:
                self.send(Message(self.id, 1, self.next_msgid(), T["ACK"], (str(m.msgid).encode(),)), port)

    def register(self, timeout: float = 3.0) -> int:
        end = time.monotonic() + timeout
        while self.id == 0:
            assert time.monotonic() < end, f"agent {self.temp_id} got no MASTER"
            self.send_master("AGENT", "A", *self.devices, sender=self.temp_id)
            time.sleep(0.05)
        return self.id

    def _ping_loop(self) -> None:
        while not self._stop:
            if self.pinging and self.id:
                try:
                    self.send_master("PING", "ACTIVE")
                except OSError:
                    return
            time.sleep(HB / 1000)


class Links:
    """Program X's links to @p n peers through the test, on loopback: peer k sends to X at
    to_x(k's port) and X sends to k at to_peer(k's port); each datagram is passed on unchanged from
    the link's other face, so either end answers through the link. While `drop` names message types
    (wire names), datagrams of those types on their way to X are lost, counted by type in `dropped`
    and kept in `withheld` (signed ones too: their type is read under the trailer).
    Every datagram passed on is kept in `passed` (towards X?, bytes): what a man in the middle captures.
    The faces are bound at once (before the programs' ports are picked); connect() starts the links."""

    def __init__(self, n: int) -> None:
        self.faces = []  # per peer: (the face the peer sends to, the face X sends to)
        for _ in range(n):
            pair = tuple(socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(2))
            for s in pair:
                s.bind(("127.0.0.1", 0))
            self.faces.append(pair)
        self.drop: set[str] = set()
        self.dropped: dict[str, int] = {}
        self.passed: list[tuple[bool, bytes]] = []
        self.withheld: list[bytes] = []
        self._stop = False
        self._thread: threading.Thread | None = None

    def connect(self, x: int, peers: list[int]) -> None:
        assert len(peers) == len(self.faces), (peers, len(self.faces))
        self.x, self.peers = x, list(peers)
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def to_x(self, peer: int) -> int:
        return self.faces[self.peers.index(peer)][0].getsockname()[1]

    def to_peer(self, peer: int) -> int:
        return self.faces[self.peers.index(peer)][1].getsockname()[1]

    def port(self, sender: int, receiver: int) -> int:
        """The port @p sender sends to to reach @p receiver (ports of the programs)."""
        if receiver == self.x and sender in self.peers:
            return self.to_x(sender)
        if sender == self.x and receiver in self.peers:
            return self.to_peer(receiver)
        return receiver

    def _run(self) -> None:
        sel = selectors.DefaultSelector()
        for k, (from_peer, from_x) in enumerate(self.faces):
            sel.register(from_peer, selectors.EVENT_READ, (k, True))
            sel.register(from_x, selectors.EVENT_READ, (k, False))
        while not self._stop:
            for key, _ in sel.select(0.05):
                k, towards_x = key.data
                try:
                    data = key.fileobj.recv(65536)
                except OSError:
                    continue
                if towards_x:
                    try:
                        t = decode(unsigned(data)).type_name or "?"
                    except DecodeError:
                        t = "?"
                    if t in self.drop:
                        self.dropped[t] = self.dropped.get(t, 0) + 1
                        self.withheld.append(data)
                        continue
                    out, to = self.faces[k][1], self.x
                else:
                    out, to = self.faces[k][0], self.peers[k]
                self.passed.append((towards_x, data))
                try:
                    out.sendto(data, ("127.0.0.1", to))
                except OSError:
                    pass  # the program is down (the PC killed): lost, as on a network
        sel.close()

    def close(self) -> None:
        self._stop = True
        if self._thread is not None:
            self._thread.join(timeout=1)
        for pair in self.faces:
            for s in pair:
                s.close()


class Program:
    """An ev3-agent / ev3-master process with its output in files under tmp."""

    def __init__(self, exe: Path, args: list[str], tmp: Path, name: str, stdin=subprocess.DEVNULL) -> None:
        self.name = name
        self.out_path = tmp / f"{name}.out"
        self.err_path = tmp / f"{name}.err"
        self._out = open(self.out_path, "wb")
        self._err = open(self.err_path, "wb")
        self.proc = subprocess.Popen([str(exe), *args], stdin=stdin, stdout=self._out, stderr=self._err)

    @property
    def stdin(self):
        return self.proc.stdin

    def stdout(self) -> str:
        return self.out_path.read_text(errors="replace")

    def stderr(self) -> str:
        return self.err_path.read_text(errors="replace")

    def write(self, line: str) -> None:
        self.proc.stdin.write((line + "\n").encode())
        self.proc.stdin.flush()

    def stop(self, sig: int = signal.SIGTERM, timeout: float = 5.0) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
                raise AssertionError(f"{self.name} did not stop within {timeout} s of signal {sig}")
        return self.proc.returncode

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        if self.proc.stdin:
            self.proc.stdin.close()
        self._out.close()
        self._err.close()


def drop_counters(log: str) -> dict[str, int]:
    """The drop counters of a program's last stop line in @p log ("...; drops: a=1 b=2")."""
    lines = [l for l in log.splitlines() if "; drops: " in l]
    assert lines, "no stop line with drop counters in the log"
    return {k: int(v) for k, v in (x.split("=") for x in lines[-1].split("; drops: ", 1)[1].split() if "=" in x)}


def assert_static_armel(exe: Path) -> None:
    """@p exe is a static ARM executable (the EV3 build), when `file` is there to say."""
    if shutil.which("file"):
        info = subprocess.run(["file", str(exe)], capture_output=True, text=True).stdout
        assert "ARM" in info and "statically linked" in info, info


def trace_records(path: Path) -> list[dict]:
    """The records of a running program's --trace file so far (a last line still being written is
    left out)."""
    if not path.exists():
        return []
    text = path.read_text()
    lines = text.splitlines() if text.endswith("\n") else text.splitlines()[:-1]
    return [json.loads(x) for x in lines if x.strip()]


# ---- a fleet's failover, as the agents' traces tell it (bench/failover.py, test_fault_scenarios.py)

def knows_members(recs: list[dict]) -> bool:
    """The agent's trace holds a LEADER that listed three members."""
    return any(r["action"] == "HandleHeartbeat" and len(r.get("changed", {}).get("members", [])) == 3 for r in recs)


def timeline(recs: list[dict], kill: int) -> dict:
    """What one agent's trace says after the kill at @p kill (ms, CLOCK_MONOTONIC)."""
    v: dict = {}
    out = {"lost": None, "follows": None, "relays": 0, "relay_drops": 0, "first_relay": None}
    for r in recs:
        if r.get("node", "agent") != "agent":
            continue  # an elected agent's Master core writes its own records into the same file
        v.update(r.get("changed", {}))
        if r["now"] < kill:
            continue
        if out["lost"] is None and r.get("changed", {}).get("state") in ("PANIC", "PAUSED"):
            out["lost"] = r["now"] - kill
        if r["action"] == "AcceptRelay":
            out["relays"] += 1
            if out["first_relay"] is None:
                out["first_relay"] = r["now"] - kill
        if r["action"] == "RelayDropped":
            out["relay_drops"] += 1
        new_master = (v.get("leader", 0) not in (0, 1) and v.get("following", 0) > 0) or v.get("life") == "MASTER"
        if new_master and out["follows"] is None:
            out["follows"] = r["now"] - kill
        elif not new_master:
            out["follows"] = None  # lost again: the failover is when it last found one
    return out


def false_master_lost(recs: list[dict], kill: int) -> int:
    """An agent's "master lost" verdicts before the kill, once it was ACTIVE: its heartbeat timeout
    (HeartbeatLost) or its relay's loss (RelayDropped) taking it to PANIC or PAUSED. A pause by a
    newer epoch of its master (an election, a membership change) is no verdict."""
    n, synced = 0, False
    for r in recs:
        if r.get("node", "agent") != "agent" or r["now"] >= kill:
            continue
        st = r.get("changed", {}).get("state")
        if st == "ACTIVE":
            synced = True
        elif st in ("PANIC", "PAUSED") and synced and r["action"] in ("HeartbeatLost", "RelayDropped"):
            n += 1
    return n


def agent_lost(console: str, ids=None) -> int:
    """The master's "agent lost" verdicts in what it printed (its standard output) for the operator,
    of the agents @p ids only when given."""
    found = re.findall(r"agent (\d+) lost \(not heard", console)
    return sum(1 for i in found if ids is None or int(i) in ids)


def read_status(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def sim_agent(exe: Path, root: Path, tmp: Path, n: int, mport: int, loss_ms: int, paused_ms: int,
              *extra: str) -> Program:
    """ev3-agent number @n on the simulated robot whose tree is @root, broadcasting to the master
    on loopback port @mport; its trace agentN.nd and log agentN.log in @tmp."""
    return Program(exe, ["--port", str(free_ports(1)[0]), "--bind", "127.0.0.1", "--broadcast", f"127.0.0.1:{mport}",
                         "--heartbeat-ms", str(HB), "--master-timeout-ms", str(loss_ms),
                         "--paused-timeout-ms", str(paused_ms), "--sysfs-root", str(root),
                         f"--trace={tmp / f'agent{n}.nd'}", *extra, "--log-file", str(tmp / f"agent{n}.log")],
                   tmp, f"agent{n}")


def start_custom_all(master: Program, status: Path, bhv: Path, n: int) -> None:
    """Waits for @n ACTIVE agents in the master's @status, sends them the behaviour in @bhv
    (`behaviour all custom`) and `start all` on the master's console, and waits for @n WORKING."""
    wait_until(lambda: (s := read_status(status)) and sum(a["state"] == "ACTIVE" for a in s["agents"]) == n, 8,
               f"{n} ACTIVE agents")
    master.write(f"behaviour all custom @{bhv}")
    master.write("start all")
    wait_until(lambda: (s := read_status(status)) and sum(a["state"] == "WORKING" for a in s["agents"]) == n, 5,
               f"{n} WORKING agents")


def made(trace: Path) -> int:
    """The reports an agent made, as its trace says (Reports.tla's `made`, written when it grows; the
    agent core's records only, not those of a Master core it ran)."""
    n = 0
    for r in trace_records(trace):
        if r.get("node", "agent") == "agent":
            n = r.get("changed", {}).get("made", n)
    return n
