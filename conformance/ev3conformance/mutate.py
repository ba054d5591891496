"""Mutation score of the conformance checks: seeded faults in the core (libev3proto/include), each
a small textual patch (an exact, unique search string and its replacement) applied to a COPY of
the sources in build/mutate/src; ev3-agent / ev3-master are rebuilt there (one ninja tree, -O0, so
each mutant recompiles only what includes the patched header) and checked:

  agent mutants:  agent replay of MCAgent's state graph (stops at the first mismatch), then one
                  driver trace (a fixed scenario, TRACE_SCRIPT) validated by TLC (tracecheck);
  master mutants: master replay of MCMaster's state graph, strict (stops at the first mismatch).

A mutant is caught when a check fails (a mismatch, a driver crash, or the driver killed by its
CPU limit: prlimit), survives otherwise. A patch that does not apply (the line changed under
it) is reported as "stale" and not counted; one that leaves the binary byte-identical is
"equivalent" and not counted.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from ev3conformance import driver as drv
from ev3conformance import graph as gr

INC = "libev3proto/include/ev3proto"


@dataclass(frozen=True)
class Mutant:
    name: str
    file: str      # header under libev3proto/include/ev3proto
    old: str       # exact text, must occur exactly once
    new: str
    kind: str      # "agent" or "master": which checks
    what: str


A, M = "agent.hpp", "master.hpp"
MUTANTS: tuple[Mutant, ...] = (
    # ---- agent core
    Mutant("A01-pause-guard-dropped", A,
           "    if (state_ != State::WORKING) return Refuse(m, Refusal::wrong_state);\n    GotoBy(Action::RecvPause);",
           "    GotoBy(Action::RecvPause);", "agent", "dropped guard: PAUSE accepted in any state"),
    Mutant("A02-stop-wrong-next-state", A, "    Stopped();\n    GotoBy(Action::RecvStop);",
           "    Stopped();\n    GotoBy(Action::RecvPause);", "agent", "wrong next state: STOP -> PAUSED"),
    Mutant("A03-loss-timeout-off-by-one", A,
           "      case State::WORKING: return now_ - heard_ >= cfg_.timers[Timer::loss];",
           "      case State::WORKING: return now_ - heard_ > cfg_.timers[Timer::loss];", "agent",
           "off-by-one: heartbeat loss one tick late"),
    Mutant("A04-sync-timeout-off-by-one", A,
           "return state_ == State::IDLE && now_ - heard_ >= cfg_.timers[Timer::sync];",
           "return state_ == State::IDLE && now_ - heard_ > cfg_.timers[Timer::sync];", "agent",
           "off-by-one: sync timeout one tick late"),
    Mutant("A05-no-dedupe", A,
           "bool Fresh(const Message& m) const noexcept { return !win_.contains(m.sender, m.msgid); }",
           "bool Fresh(const Message& m) const noexcept { (void)m; return true; }", "agent",
           "missing dedupe: every copy is fresh"),
    Mutant("A06-ack-wrong-msgid", A, "    a.ref = m.msgid;", "    a.ref = m.msgid + 1;", "agent",
           "wrong msgid in ACK/NOT (ref + 1)"),
    Mutant("A07-led-paused-green", "core.hpp", "    case State::PAUSED: return Led::ORANGE;",
           "    case State::PAUSED: return Led::GREEN;", "agent", "wrong LED: PAUSED shows GREEN"),
    Mutant("A08-pong-ignored", A, "void RecvPong(const Message&) noexcept { heard_ = now_; }",
           "void RecvPong(const Message&) noexcept {}", "agent", "PONG ignored (silence not reset)"),
    Mutant("A09-refusal-reason", A, "if (beh_len_ == 0) return Refuse(m, Refusal::no_behaviour);",
           "if (beh_len_ == 0) return Refuse(m, Refusal::wrong_state);", "agent",
           "wrong refusal reason: START without behaviour says wrong state"),
    Mutant("A10-unknown-behaviour-accepted", A,
           "if (b == nullptr || !fits(m)) return Refuse(m, Refusal::unknown_behaviour);",
           "if (b == nullptr && !fits(m)) return Refuse(m, Refusal::unknown_behaviour);", "agent",
           "dropped guard: unknown behaviour loaded when its args fit"),
    Mutant("A11-resume-motors-off", A, "    if (wait_ == Wait::NONE) motors_on(false);\n    Answer(m, true);",
           "    Answer(m, true);", "agent", "RESUME leaves the motors off"),
    Mutant("A12-heartbeat-period", A, "      periodic_at_ += cfg_.timers[Timer::heartbeat];",
           "      periodic_at_ += cfg_.timers[Timer::heartbeat] + 1;", "agent",
           "off-by-one: heartbeat period one tick long"),
    Mutant("A13-loss-working-panics", A,
           "    if (state_ == State::WORKING) {\n      GotoBy(Action::HeartbeatLost);",
           "    if (state_ == State::PAUSED) {\n      GotoBy(Action::HeartbeatLost);", "agent",
           "wrong next state: lost master in WORKING -> PANIC (not PAUSED)"),
    Mutant("A14-master-ref-unchecked", A, "           ref_of(m) == id_ && is_assigned_id(m.receiver);",
           "           is_assigned_id(m.receiver);", "agent",
           "dropped guard: MASTER for another temporary id taken"),
    Mutant("A15-duplicate-not-answered", A, "    if (a != nullptr) send_answer(*a);",
           "    (void)a;", "agent", "duplicate command not answered again"),
    Mutant("A16-paused-timeout-is-loss", A,
           "      case State::PAUSED: return now_ - heard_ >= cfg_.timers[Timer::paused];",
           "      case State::PAUSED: return now_ - heard_ >= cfg_.timers[Timer::loss];", "agent",
           "wrong timer: PAUSED uses the loss timeout"),
    Mutant("A17-continue-guard", A,
           "if (state_ != State::WORKING || wait_ != Wait::CONTINUE) return Refuse(m, Refusal::wrong_state);",
           "if (state_ != State::WORKING) return Refuse(m, Refusal::wrong_state);", "agent",
           "dropped guard: CONTINUE without an interrupted action"),
    Mutant("A18-answer-keeps-silence", A, "    ++win_rev_;\n    heard_ = now_;", "    ++win_rev_;", "agent",
           "an answered command does not reset the silence"),
    Mutant("A19-failed-waits-continue", A, "    wait_ = Wait::RESTART;\n    motors_pause();",
           "    wait_ = Wait::CONTINUE;\n    motors_pause();", "agent",
           "wrong wait after ACTION_ERR (CONTINUE, not RESTART)"),
    Mutant("A20-action-ok-no-step", A, "    emit(Dest::master, master_id(), MsgType::ACTION_OK, p, 1);\n    ++step_;",
           "    emit(Dest::master, master_id(), MsgType::ACTION_OK, p, 1);", "agent",
           "ACTION_OK does not advance the step"),
    Mutant("A21-missing-device-ignored", A,
           "if (!dev_ok() || (b->devices & ~plugged_) != 0) return Refuse(m, Refusal::missing_device);",
           "if ((b->devices & ~plugged_) != 0) return Refuse(m, Refusal::missing_device);", "agent",
           "dropped half of a guard: the model's other devices are not required"),
    # ---- master core
    Mutant("M01-no-resend", M, "          e.sent_at = now_;\n          send_pending(e);",
           "          e.sent_at = now_;", "master", "master not resending the pending datagram"),
    Mutant("M02-id-reused", M, "      nid = next_id_++;", "      nid = next_id_;", "master",
           "master reusing agent ids"),
    Mutant("M03-msgid-reused", M, "    if (e.queue.empty()) return;\n    e.pending = true;\n    e.mid = msgid_++;",
           "    if (e.queue.empty()) return;\n    e.pending = true;\n    e.mid = msgid_;", "master",
           "master reusing msgids for commands"),
    Mutant("M04-answer-ref-unchecked", M, "if (!e.pending || !ref || *ref != e.mid) return;",
           "if (!e.pending || !ref) return;", "master", "dropped guard: an ACK of any msgid answers"),
    Mutant("M05-pong-wrong-ref", M, "const std::string_view p[1] = {number(m.msgid, num)};\n    send(from, e.id, MsgType::PONG",
           "const std::string_view p[1] = {number(m.msgid + 1, num)};\n    send(from, e.id, MsgType::PONG",
           "master", "wrong msgid in PONG's ref"),
    Mutant("M06-drop-off-by-one", M, "if (now_ - e.heard >= cfg_.timers[Timer::drop]) {",
           "if (now_ - e.heard > cfg_.timers[Timer::drop]) {", "master", "off-by-one: drop one tick late"),
    Mutant("M07-max-resends-off-by-one", M, "if (e.synced && e.resends >= cfg_.max_resends) {",
           "if (e.synced && e.resends > cfg_.max_resends) {", "master", "off-by-one: one resend too many"),
    Mutant("M08-ping-not-heard", M,
           "    e.heard = now_;\n    const bool fresh = m.msgid > e.last_msgid;",
           "    const bool fresh = m.msgid > e.last_msgid;", "master",
           "PING does not refresh the agent (dropped while pinging)"),
    Mutant("M09-not-answers-master", M, "    if (!e.synced && !ack) return;", "", "master",
           "dropped guard: a NOT answers MASTER"),
    Mutant("M10-panic-resync-unordered", M, "s == e.id && m.msgid > e.last_msgid) {", "s == e.id) {",
           "master", "dropped guard: an old PANIC copy re-syncs a synced agent"),
)


# The fixed scenario of the validated trace (agent mutants): timers and constants for tracecheck.
TRACE_TIMERS = {"sync": 5, "heartbeat": 2, "loss": 3, "paused": 6}
TRACE_CONSTS = {"TSync": 5, "TPing": 2, "TLoss": 3, "TPaused": 6}


def _m(mid: int, type_: str, ref: int = 0, args: tuple = (), dst: int = 7, src: int = 1) -> dict:
    m = {"src": src, "dst": dst, "msgid": mid, "type": type_, "ref": ref, "args": args}
    return {"type": "recv", "from": 100 + src, "text": drv.spec_to_wire(m).decode("latin-1")}


def trace_script() -> list[dict]:
    ev = lambda e, **kw: dict({"type": "event", "event": e}, **kw)  # noqa: E731
    adv = lambda ms: {"type": "advance", "ms": ms}  # noqa: E731
    return [
        # Two devices (mask 3); "wait" needs device 1 only: unplugging device 2 must still refuse
        # BEHAVIOUR (devOk: every device of the model), which MCAgent (one device) cannot show.
        {"type": "config", "timers": TRACE_TIMERS, "behaviours": [{"name": "wait", "devices": 1}],
         "devices": 3, "temp_id": 50001},
        adv(1), _m(1, "MASTER", 50001, dst=7), _m(1, "MASTER", 50001, dst=7), adv(2), _m(2, "PONG", 3),
        _m(3, "START"), _m(4, "BEHAVIOUR", args=("dance",)), _m(5, "BEHAVIOUR", args=("wait",)),
        _m(6, "START"), _m(6, "START"), adv(1), ev("action_ok"), ev("sensor_report", port="1", mode="m", values=["4"]),
        _m(7, "PAUSE"), _m(8, "PAUSE"), _m(9, "RESUME"), ev("action_interrupted", warning="OBSTACLE_DETECTED"),
        _m(10, "CONTINUE"), _m(11, "CONTINUE"), ev("action_failed"), _m(12, "RESTART"), adv(2),
        _m(13, "PONG", 4), _m(14, "STANDBY"), _m(15, "STOP"), _m(16, "START"), _m(17, "STOP"),
        ev("device_unplugged", devices=2), _m(18, "BEHAVIOUR", args=("wait",)), _m(19, "START"),
        ev("device_plugged", devices=2), _m(20, "BEHAVIOUR", args=("wait",)), _m(21, "START"),
        ev("battery_low"), adv(3), adv(2), _m(22, "RESUME"), adv(5), adv(2), adv(3),
        _m(23, "MASTER", 7, dst=8), _m(24, "START", dst=8), _m(25, "BEHAVIOUR", args=("wait",), dst=8),
        _m(26, "START", dst=8), adv(1), _m(27, "PAUSE", dst=8), adv(6), adv(1), adv(10),
    ]


@dataclass
class Outcome:
    mutant: Mutant
    status: str  # caught / survived / stale / equivalent / build-failed
    by: str = ""
    seconds: float = 0.0
    detail: str = ""


class Workspace:
    """A copy of the sources (build/mutate/src) and one ninja tree (build/mutate/build)."""

    DIRS = ("cmake", "libev3proto", "io", "agent", "master", "tools/codec", "tools/loadgen")

    def __init__(self, root: Path, base: Path) -> None:
        self.root, self.base = root, base
        self.src, self.bld = base / "src", base / "build"
        self.bin = self.bld / "bin"

    def prepare(self) -> None:
        for d in (self.src, self.bld):  # a fresh tree: copied mtimes must not fool ninja
            if d.exists():
                shutil.rmtree(d)
        self.src.mkdir(parents=True)
        for d in self.DIRS:
            shutil.copytree(self.root / d, self.src / d)
        (self.src / "fuzz").mkdir()
        for f in ("CMakeLists.txt", "fuzz_decode.cpp", "replay_main.cpp"):
            shutil.copy2(self.root / "fuzz" / f, self.src / "fuzz" / f)
        top = (self.root / "CMakeLists.txt").read_text()
        # A mutant may leave a parameter unused: warnings stay on, but not as errors, in the copy.
        (self.src / "CMakeLists.txt").write_text(top.replace(" -Werror", ""))
        self.pristine = {p.name: p.read_text() for p in (self.src / INC).glob("*.hpp")}
        cmd = ["cmake", "-S", str(self.src), "-B", str(self.bld), "-G", "Ninja", "-DEV3_TESTS=OFF",
               "-DCMAKE_BUILD_TYPE=Debug", "-DCMAKE_CXX_FLAGS_DEBUG=-O0",
               f"-DCMAKE_RUNTIME_OUTPUT_DIRECTORY={self.bin}"]
        p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        if p.returncode:
            raise RuntimeError(f"cmake failed:\n{p.stdout[-3000:]}")

    def restore(self) -> None:
        for name, text in self.pristine.items():
            f = self.src / INC / name
            if f.read_text() != text:
                f.write_text(text)

    def apply(self, m: Mutant) -> bool:
        self.restore()
        text = self.pristine.get(m.file)
        if text is None or text.count(m.old) != 1:
            return False
        (self.src / INC / m.file).write_text(text.replace(m.old, m.new))
        return True

    def build(self, jobs: int) -> tuple[bool, str]:
        p = subprocess.run(["ninja", "-C", str(self.bld), f"-j{jobs}", "ev3-agent", "ev3-master"],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        return p.returncode == 0, p.stdout[-3000:]

    def digest(self) -> dict:
        return {n: hashlib.sha256((self.bin / n).read_bytes()).hexdigest() for n in ("ev3-agent", "ev3-master")}


class Checks:
    """The checks, with the state graphs dumped by TLC once."""

    def __init__(self, bin_dir: Path, limit: float) -> None:
        self.bin, self.limit = bin_dir, limit
        self.ag = self.ms = None
        self.ag_cache: dict = {}
        self.ms_cache: dict = {}

    def load(self, kinds: set[str]) -> dict:
        figs = {}
        if "agent" in kinds:
            self.ag, f = gr.dump_graph("MCAgent.tla", "MCAgent.cfg", "mutate-agent")
            self.agc = gr.cfg_constants("MCAgent.tla", "MCAgent.cfg")
            figs["agent"] = f
        if "master" in kinds:
            self.ms, f = gr.dump_graph("MCMaster.tla", "MCMaster.cfg", "mutate-master")
            self.msc = gr.cfg_constants("MCMaster.tla", "MCMaster.cfg")
            figs["master"] = f
        return figs

    def argv(self, prog: str) -> list[str]:
        # A looping mutant is killed by the CPU limit (prlimit execs the driver: same process, so
        # the replay's kill reaches the driver itself): its EOF fails the check (caught).
        return ["prlimit", f"--cpu={int(self.limit)}", str(self.bin / prog), "--driver"]

    def agent_replay(self) -> tuple[bool, str]:
        from ev3conformance import replay
        try:
            f = replay.AgentReplay(self.ag, self.agc, self.argv("ev3-agent"), cache=self.ag_cache).run()
        except replay.Mismatch as m:
            return False, m.report.splitlines()[0]
        except drv.DriverError as e:
            return False, f"driver failed: {str(e).splitlines()[0]}"
        return True, f"{f.replayed} edges matched"

    def master_replay(self) -> tuple[bool, str]:
        from ev3conformance import master_replay as mr
        try:
            f = mr.MasterReplay(self.ms, self.msc, self.argv("ev3-master"), (),
                                stop_first=True, cache=self.ms_cache).run()
        except (drv.DriverError, RuntimeError) as e:
            return False, f"driver failed: {str(e).splitlines()[0]}"
        if f.classes:
            (act, flds), (n, _) = next(iter(f.classes.items()))
            return False, f"MISMATCH (master): {act} differs in [{', '.join(flds)}]"
        return True, f"{f.matched} edges matched"

    def agent_trace(self, work: Path) -> tuple[bool, str]:
        from ev3conformance import tracecheck
        work.mkdir(parents=True, exist_ok=True)
        trace = work / "agent.ndjson"
        trace.unlink(missing_ok=True)
        inp = "\n".join(json.dumps(i) for i in trace_script()) + "\n"
        try:
            p = subprocess.run(self.argv("ev3-agent") + ["--trace", str(trace)], input=inp, text=True,
                               capture_output=True, timeout=10 * self.limit)
        except subprocess.TimeoutExpired:
            return False, "driver hung on the trace scenario"
        if p.returncode != 0 or not trace.exists():
            return False, f"driver exit {p.returncode} on the trace scenario"
        r = tracecheck.validate(trace, TRACE_CONSTS, workdir=work)
        return r.ok, r.message.splitlines()[0]


def run(root: Path, names: list[str] | None = None, jobs: int = 2, limit: float = 120.0,
        log=print) -> list[Outcome]:
    base = gr.BUILD.parent / "mutate"
    ws = Workspace(root, base)
    chosen = [m for m in MUTANTS if not names or any(m.name.startswith(n) for n in names)]
    t0 = time.monotonic()
    ws.prepare()
    ok, out = ws.build(jobs)
    if not ok:
        raise RuntimeError(f"the unmutated copy does not build (retry when the tree builds):\n{out}")
    base_digest = ws.digest()
    log(f"mutate: workspace {base} built in {time.monotonic() - t0:.0f}s")
    ck = Checks(ws.bin, limit)
    t1 = time.monotonic()
    figs = ck.load({m.kind for m in chosen})
    log(f"mutate: state graphs dumped in {time.monotonic() - t1:.0f}s "
        + " ".join(f"{k}: {v.get('distinct')} states" for k, v in figs.items()))
    # The unmutated build must pass every check it is used for (else a "caught" means nothing).
    kinds = {m.kind for m in chosen}
    t2 = time.monotonic()
    base_checks = []
    if "agent" in kinds:
        base_checks += [("agent replay", ck.agent_replay), ("agent trace", lambda: ck.agent_trace(base / "trace"))]
    if "master" in kinds:
        base_checks.append(("master replay", ck.master_replay))
    for label, fn in base_checks:
        good, msg = fn()
        if not good:
            raise RuntimeError(f"the unmutated build fails the {label}: {msg}")
        log(f"mutate: baseline {label}: {msg}")
    log(f"mutate: baseline checks {time.monotonic() - t2:.0f}s")
    res: list[Outcome] = []
    try:
        for m in chosen:
            s = time.monotonic()
            if not ws.apply(m):
                res.append(Outcome(m, "stale", detail="search text not found exactly once"))
                log(f"  {m.name:32} STALE (the line changed: search text not found exactly once)")
                continue
            ok, out = ws.build(jobs)
            if not ok:
                res.append(Outcome(m, "build-failed", detail=out[-500:], seconds=time.monotonic() - s))
                log(f"  {m.name:32} BUILD FAILED")
                continue
            if ws.digest() == base_digest:
                res.append(Outcome(m, "equivalent", detail="binary unchanged", seconds=time.monotonic() - s))
                log(f"  {m.name:32} EQUIVALENT (binaries unchanged)")
                continue
            tb = time.monotonic() - s
            checks = ([("agent replay", ck.agent_replay), ("agent trace", lambda: ck.agent_trace(base / "trace"))]
                      if m.kind == "agent" else [("master replay", ck.master_replay)])
            o = Outcome(m, "survived")
            for label, fn in checks:
                good, msg = fn()
                if not good:
                    o.status, o.by, o.detail = "caught", label, msg
                    break
                o.detail = (o.detail + "; " if o.detail else "") + f"{label}: {msg}"
            o.seconds = time.monotonic() - s
            res.append(o)
            log(f"  {m.name:32} {o.status.upper():8} {o.seconds:5.0f}s (build {tb:.0f}s)  {o.by}: {o.detail[:160]}")
    finally:
        ws.restore()
    return res


def score(res: list[Outcome]) -> tuple[int, int]:
    counted = [o for o in res if o.status in ("caught", "survived")]
    return sum(o.status == "caught" for o in counted), len(counted)
