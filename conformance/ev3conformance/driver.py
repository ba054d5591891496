"""A driver process (`ev3-agent --driver`, `ev3-master --driver`, or any program speaking
docs/driver.md): NDJSON in, one NDJSON line out per input line."""

from __future__ import annotations

import functools
import json
import os
import signal
import subprocess
import tempfile
import threading
from pathlib import Path

from ev3conformance import wire

ROOT = Path(__file__).resolve().parents[2]


def default_bin() -> Path:
    return Path(os.environ.get("EV3_BIN") or ROOT / "build" / "bin")


class DriverError(RuntimeError):
    pass


class DriverKilled(DriverError):
    """The driver was killed (its CPU limit: SIGXCPU, then SIGKILL) instead of answering: no verdict
    on what it computes, only that it did not finish. A crash (SIGSEGV, SIGABRT) is a DriverError."""


# The signals of a CPU limit (prlimit --cpu: SIGXCPU at the soft limit, SIGKILL at the hard one).
KILLED = {-signal.SIGXCPU, -signal.SIGKILL}


class Driver:
    """One driver process. `ask(obj)` sends one input and returns its output; `stream(lines)`
    pipelines many inputs (a writer thread) and yields the outputs in order."""

    def __init__(self, argv: list[str], trace: Path | None = None) -> None:
        self.argv = list(argv) + (["--trace", str(trace)] if trace else [])
        self._err = tempfile.TemporaryFile()
        try:
            self.proc = subprocess.Popen(self.argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                         stderr=self._err, bufsize=1 << 16)
        except OSError:
            self._err.close()
            raise
        self.lines = 0

    def stderr(self) -> str:
        self._err.seek(0)
        return self._err.read().decode("utf-8", "replace")[-3000:]

    def _read(self, sent: str) -> dict:
        line = self.proc.stdout.readline()
        if not line:
            try:
                status = self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                status = None
            kind = DriverKilled if status in KILLED else DriverError
            raise kind(f"{' '.join(self.argv)} exited (status {status}) without "
                       f"answering {sent!r}; stderr:\n{self.stderr()}")
        self.lines += 1
        try:
            return json.loads(line)
        except ValueError as exc:
            raise DriverError(f"driver output is not JSON ({exc}): {line[:300]!r}") from None

    def ask(self, obj: dict) -> dict:
        s = json.dumps(obj, separators=(",", ":"))
        try:
            self.proc.stdin.write(s.encode() + b"\n")
            self.proc.stdin.flush()
        except BrokenPipeError:
            raise DriverError(f"driver exited; stderr:\n{self.stderr()}") from None
        return self._read(s)

    def stream(self, objs):
        """Pipelined: yields (input, output) for each input of the iterable `objs`."""
        fifo: list[str] = []
        lock = threading.Condition()
        done = [False]

        def writer():
            try:
                for o in objs:
                    s = json.dumps(o, separators=(",", ":"))
                    with lock:
                        fifo.append(s)
                        lock.notify()
                    self.proc.stdin.write(s.encode() + b"\n")
                self.proc.stdin.flush()
            except (BrokenPipeError, ValueError):
                pass
            finally:
                with lock:
                    done[0] = True
                    lock.notify()

        t = threading.Thread(target=writer, daemon=True)
        t.start()
        i = 0
        while True:
            with lock:
                while i >= len(fifo) and not done[0]:
                    lock.wait()
                if i >= len(fifo):
                    break
                s = fifo[i]
            i += 1
            yield s, self._read(s)

    def close(self) -> None:
        if self.proc.poll() is None:
            try:
                self.proc.stdin.close()
            except OSError:
                pass
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        for f in (self.proc.stdin, self.proc.stdout):
            try:
                f.close()
            except OSError:
                pass
        self._err.close()

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


def agent_facts(argv: list[str] | None = None) -> dict:
    """What an agent's driver reports of its program (input "facts", docs/driver.md): "model" and
    "behaviours" [{"name", "devices"}], the behaviours the program's model accepts. argv: default
    `$EV3_BIN/ev3-agent --driver`. Asked once per argv. Raises DriverError (OSError when the
    program cannot be started)."""
    return _facts(tuple(argv or [str(default_bin() / "ev3-agent"), "--driver"]))


@functools.lru_cache(maxsize=None)
def _facts(argv: tuple) -> dict:
    d = Driver(list(argv))
    try:
        out = d.ask({"type": "facts"})
    finally:
        d.close()
    if not isinstance(out.get("facts"), dict):
        raise DriverError(f"{' '.join(argv)} reports no facts: {json.dumps(out)[:300]}")
    return out["facts"]


# --- spec messages <-> wire ----------------------------------------------------------------------

TYPE_NUM = {t.name: n for n, t in wire.MESSAGE_TYPES.items()}
REF_TYPES = {"MASTER", "ACK", "NOT", "PONG", "ACTION_OK", "ACTION_INTERR", "ACTION_ERR"}


def spec_to_wire(m: dict, msgid: int | None = None) -> bytes:
    """A spec message record (Messages.tla Msg) -> its datagram (reference codec)."""
    args = [a.encode() for a in m.get("args", ())]
    params = ([str(m["ref"]).encode()] + args) if m["type"] in REF_TYPES else args
    mid = m["msgid"] if msgid is None else msgid
    return wire.encode(wire.Message(m["src"], m["dst"], mid, TYPE_NUM[m["type"]], tuple(params)))


def wire_to_spec(data: bytes) -> tuple:
    """A datagram -> the spec's Out record as a tuple (src, dst, type, ref, args); msgid dropped.
    AGENT's args are its model alone: the devices after it are fixed per robot (AgentLogic.tla)."""
    msg = wire.decode(data)
    name = msg.type_name
    ps = [p.decode("latin-1") for p in msg.params]
    if name == "AGENT":
        ps = ps[:1]
    if name in REF_TYPES and ps:
        return (msg.sender, msg.receiver, name, int(ps[0]), tuple(ps[1:]))
    return (msg.sender, msg.receiver, name, 0, tuple(ps))


def msgid_of(data: bytes) -> int:
    return wire.decode(data).msgid


def beyond_reports(data: bytes) -> bytes | None:
    """A datagram as the specs without Reports.tla see it (AgentLogic, Fleet, Election: a report is
    sent once, and never acknowledged). A REPORT's first sending (its msgid that of the report
    inside: Agent::Make) is the report inside; a later sending, REPORT_DROPPED and REPORT_ACK are
    Reports.tla's alone (None); every other datagram is itself. Reports.tla's own models check those."""
    try:
        msg = wire.decode(data)
    except wire.DecodeError:
        return data
    if msg.type_name in ("REPORT_DROPPED", "REPORT_ACK"):
        return None
    if msg.type_name != "REPORT":
        return data
    try:
        inner = wire.decode(msg.params[2])
    except wire.DecodeError:
        return data
    return msg.params[2] if inner.msgid == msg.msgid else None


def sent_beyond_reports(sent: list[dict]) -> list[dict]:
    """The driver's `sent` records as beyond_reports() sees them (hex replaced or left out)."""
    out = []
    for s in sent:
        d = beyond_reports(bytes.fromhex(s["hex"]))
        if d is not None:
            out.append({**s, "hex": d.hex()})
    return out


def spec_out(m: dict) -> tuple:
    return (m["src"], m["dst"], m["type"], m["ref"], tuple(m["args"]))
