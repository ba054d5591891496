"""`validate --master` on a trace of the real `ev3-master` over UDP (real ms clock, a resend deadline
per entry): a scenario on loopback that reaches every MasterLogic handler and every kind of
MasterTick (MASTER resent, a command resent and failed, an agent dropped) conforms, and the same
trace with one record corrupted is rejected, naming that record (docs/spec.md "Master trace
validation")."""
from __future__ import annotations

import json
import os
import socket
import subprocess
import threading
import time
from pathlib import Path

import pytest

from ev3conformance import tracecheck
from ev3conformance.wire import DecodeError, decode

REPO = Path(__file__).resolve().parents[3]
BIN = Path(os.environ.get("EV3_BIN") or REPO / "build" / "bin")
RESEND, DROP, MAX_RESENDS = 60, 1500, 2
CONSTS = {"TDrop": DROP, "TResend": RESEND, "MaxResends": MAX_RESENDS}
COMMAND_TYPES = range(7, 15)  # BEHAVIOUR .. RESTART
AFTER = {8: "WORKING", 9: "ACTIVE", 10: "PAUSED", 11: "WORKING", 12: "ACTIVE"}  # an ACKed command's state


def _free_port() -> int:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


class Agent:
    """A minimal agent on loopback: sends what it is told, ACKs MASTER / commands once per msgid when
    `answer` (taking the state the command leads to), PINGs its `state` every 100 ms when `pinging`."""

    def __init__(self, master_port: int, temp_id: int) -> None:
        self.master_port, self.temp_id = master_port, temp_id
        self.id, self.mid = 0, 0
        self.answer, self.pinging, self.state = True, False, "ACTIVE"
        self.got: list = []
        self.answered: set[int] = set()
        self.lock = threading.Lock()
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.02)
        self.stop = False
        self.threads = [threading.Thread(target=f, daemon=True) for f in (self._recv, self._ping)]
        for t in self.threads:
            t.start()

    def send(self, sender: int, receiver: int, type_: int, *params: str) -> int:
        with self.lock:
            self.mid += 1
            mid = self.mid
        text = ":".join([str(sender), str(receiver), str(mid), str(type_), *params])
        self.sock.sendto(text.encode(), ("127.0.0.1", self.master_port))
        return mid

    def _recv(self) -> None:
        while not self.stop:
            try:
                data, _ = self.sock.recvfrom(65536)
            except (socket.timeout, OSError):
                continue
            try:
                m = decode(data)
            except DecodeError:
                continue
            self.got.append(m)
            if m.type == 2 and not self.id and m.params[0] == str(self.temp_id).encode():
                self.id = m.receiver
            if self.answer and (m.type == 2 or m.type in COMMAND_TYPES) and m.msgid not in self.answered:
                self.answered.add(m.msgid)
                self.state = AFTER.get(m.type, self.state)
                self.send(m.receiver, 1, 3, str(m.msgid))

    def _ping(self) -> None:
        while not self.stop:
            if self.pinging and self.id:
                self.send(self.id, 1, 5, self.state)
            time.sleep(0.1)

    def close(self) -> None:
        self.stop = True
        for t in self.threads:
            t.join(1)
        self.sock.close()


def _records(path: Path) -> list[dict]:
    if not path.exists():
        return []
    out = []
    for line in path.read_text().splitlines():
        try:
            out.append(json.loads(line))
        except ValueError:
            break  # a line still being written
    return out


def _wait(path: Path, pred, what: str, since: int = 0, timeout: float = 4.0) -> int:
    """The index of the first trace record from `since` on that satisfies pred."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        for i, r in enumerate(_records(path)[since:], since):
            if pred(r):
                return i
        time.sleep(0.03)
    raise AssertionError(f"timed out waiting for {what} in the master's trace")


def _entry(r: dict, i: int) -> dict | None:
    return next((x for x in r.get("changed", {}).get("reg", []) if x["id"] == i), None)


@pytest.fixture(scope="module")
def udp_trace(tmp_path_factory) -> Path:
    """The trace of one ev3-master run over loopback UDP (about 3 s)."""
    exe = BIN / "ev3-master"
    if not exe.is_file():
        pytest.fail(f"{exe} is missing: build it with `make build` (or set EV3_BIN)", pytrace=False)
    tmp = tmp_path_factory.mktemp("udp")
    trace = tmp / "master.ndjson"
    port = _free_port()
    m = subprocess.Popen([str(exe), "--port", str(port), "--bind", "127.0.0.1", "--resend-ms", str(RESEND),
                          "--agent-timeout-ms", str(DROP), "--max-resends", str(MAX_RESENDS),
                          "--trace", str(trace), "--log-level", "1"],
                         stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    a, b = Agent(port, 50001), Agent(port, 50002)

    def say(line: str) -> None:
        m.stdin.write((line + "\n").encode())
        m.stdin.flush()
    try:
        time.sleep(0.2)
        # A: MASTER unanswered (resent on its timer, not counted); A announces itself again (MASTER
        # resent at once, its resend deadline kept: the next tick resends it on the old period), then
        # ACKs.
        a.answer = False
        a.send(50001, 0, 1, "A")
        k = _wait(trace, lambda r: r["action"] == "MasterTick" and not (_entry(r, 2) or {"synced": 1})["synced"],
                  "MASTER resent by a tick")
        a.send(50001, 0, 1, "A")
        k = _wait(trace, lambda r: r["action"] == "MasterSync", "the second announcement", k + 1)
        k = _wait(trace, lambda r: r["action"] == "MasterTick", "MASTER resent after it", k)
        a.answer = True
        k = _wait(trace, lambda r: (_entry(r, 2) or {}).get("synced"), "agent 2 synced", k)
        a.pinging = True
        b.send(50002, 0, 1, "A")
        k = _wait(trace, lambda r: (_entry(r, 3) or {}).get("synced"), "agent 3 synced", k)
        b.answer = False  # B goes silent: its PAUSE is resent, fails, then B is dropped
        say("pause 3")
        say("behaviour 2 wait seconds=5")
        say("start 2")
        k1 = _wait(trace, lambda r: r["action"] == "MasterAnswer" and (_entry(r, 2) or {}).get("beh") == "wait"
                   and not _entry(r, 2)["queue"], "START acknowledged", k)
        k2 = _wait(trace, lambda r: r["action"] == "MasterTick" and (_entry(r, 3) or {}).get("desired") == "PAUSED"
                   and not _entry(r, 3)["queue"], "PAUSE failed after its resends", k)
        k = max(k1, k2)
        a.send(2, 1, 15, "0")  # ACTION_OK: a report
        a.state = "PAUSED"  # as if its heartbeat was lost: the master reconciles with RESUME
        k1 = _wait(trace, lambda r: r["action"] == "MasterPing" and any(
            q["type"] == "RESUME" for q in (_entry(r, 2) or {}).get("queue", [])), "RESUME queued by reconcile", k)
        k2 = _wait(trace, lambda r: r["action"] == "MasterTick" and "reg" in r["changed"] and _entry(r, 3) is None,
                   "agent 3 dropped", k, timeout=3.0)
        k = max(k1, k2)
        # A panics (its PONGs lost): the master syncs it again, then reconciles it to WORKING.
        a.pinging = False
        time.sleep(0.15)
        a.state = "ACTIVE"
        a.send(2, 0, 19)
        k = _wait(trace, lambda r: r["action"] == "MasterSync" and r["args"]["msg"].startswith("2:0:"),
                  "PANIC resync", k)
        a.pinging = True
        k = _wait(trace, lambda r: r["action"] == "MasterPing" and any(
            q["type"] == "BEHAVIOUR" for q in (_entry(r, 2) or {}).get("queue", [])), "BEHAVIOUR + START queued", k)
        _wait(trace, lambda r: r["action"] == "MasterPing" and "WORKING" in r["args"]["msg"], "WORKING again", k)
        say("quit")
        assert m.wait(5) == 0
    finally:
        if m.poll() is None:
            m.kill()
            m.wait()
        m.stdin.close()
        a.close()
        b.close()
    return trace


def test_real_master_trace_conforms(udp_trace, tmp_path):
    recs = _records(udp_trace)
    acts = {r["action"] for r in recs}
    assert {"MasterSync", "MasterAnswer", "MasterPing", "MasterReport", "MasterCommand", "MasterTick"} <= acts
    r = tracecheck.validate_master(udp_trace, CONSTS, workdir=tmp_path)
    assert r.ok, r.message
    assert r.records == len(recs)


def _corrupt(src: Path, dst: Path, k: int, change) -> None:
    recs = _records(src)
    change(recs[k])
    dst.write_text("".join(json.dumps(r) + "\n" for r in recs))


@pytest.mark.parametrize("what", ["tick one ms late", "resend count", "command msgid"])
def test_real_master_trace_corrupted_is_rejected(udp_trace, tmp_path, what):
    recs = _records(udp_trace)
    if what == "tick one ms late":  # the first resend comes 1 ms after its deadline
        k = next(i for i, r in enumerate(recs) if r["action"] == "MasterTick")
        change = lambda r: r.__setitem__("now", r["now"] + 1)  # noqa: E731
    elif what == "resend count":  # a command's resend not counted
        k = next(i for i, r in enumerate(recs) if r["action"] == "MasterTick"
                 and any(x["synced"] and x["resends"] for x in r["changed"].get("reg", [])))
        change = lambda r: [x.__setitem__("resends", x["resends"] - 1) for x in r["changed"]["reg"]  # noqa: E731
                            if x["synced"] and x["resends"]]
    else:  # the command claims another msgid
        k = next(i for i, r in enumerate(recs) if r["action"] == "MasterCommand" and "msgid" in r["changed"])
        change = lambda r: [x.__setitem__("mid", x["mid"] + 1) for x in r["changed"]["reg"] if x["id"] == 2]  # noqa: E731
    bad = tmp_path / "bad.ndjson"
    _corrupt(udp_trace, bad, k, change)
    r = tracecheck.validate_master(bad, CONSTS, workdir=tmp_path)
    assert not r.ok
    assert f"record {k + 1} of {len(recs)} could not be matched" in r.message, r.message
