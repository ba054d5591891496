"""Fixtures of the black-box tests: the programs under test ($EV3_BIN/ev3-agent, ev3-master;
$EV3_ARM_BIN/ev3-agent for the armel test), started on free loopback ports with short timers and
stopped (SIGTERM, must exit 0) at the end of each test."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from ev3net import HB, LOSS, PAUSED, SYNC, FakeAgent, Program, TestMaster, free_ports, read_status, wait_until

REPO = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(REPO / "tests" / "python" / "sim"))
from ev3sim_proc import Sims, cannot_run  # noqa: E402


def _bin(name: str) -> Path:
    p = Path(os.environ.get("EV3_BIN") or REPO / "build" / "bin") / name
    if not (p.is_file() and os.access(p, os.X_OK)):
        pytest.fail(f"{p} is missing: build it with `make build` (or set EV3_BIN)", pytrace=False)
    return p


@pytest.fixture
def agent_exe() -> Path:
    return _bin("ev3-agent")


@pytest.fixture
def master_exe() -> Path:
    return _bin("ev3-master")


@pytest.fixture
def sim_factory(tmp_path):
    """sim(world, args, robots) -> Sim on a fresh directory (robots: [(name, "x,y,heading")], default
    one robot at the world's start); stopped at the end (SIGTERM, exit 0). ev3-sim needs /dev/fuse:
    without it the test fails (never skips)."""
    why = cannot_run()
    if why:
        pytest.fail(why, pytrace=False)
    sims = Sims(tmp_path)
    yield lambda world, args=None, robots=None: sims.start(world, robots, args)
    bad = sims.stop_all()
    assert not bad, f"ev3-sim did not exit 0: {bad}"


@pytest.fixture
def programs():
    """Collects started programs; at the end each is stopped with SIGTERM and must exit 0."""
    started: list[Program] = []
    yield started
    codes = {}
    try:
        for p in started:
            codes[p.name] = p.stop()
    finally:
        for p in started:
            p.close()
    bad = {n: c for n, c in codes.items() if c != 0}
    assert not bad, f"programs did not exit 0 on SIGTERM: {bad}"


@pytest.fixture
def start_master(master_exe, programs, tmp_path):
    """Starts ev3-master on a free loopback port with --status-json and short timers, for Python
    test agents (FakeAgent): start(*extra, name=...); p.port, p.status; with control=True also
    --control on p.sock (its control socket)."""
    def start(*extra: str, stdin=subprocess.PIPE, name: str = "master", control: bool = False):
        port = free_ports(1)[0]
        status = tmp_path / f"{name}.json"
        sock = tmp_path / f"{name}.sock"
        if control:
            extra = ("--control", str(sock), *extra)
        p = Program(master_exe, ["--port", str(port), "--bind", "127.0.0.1", "--status-json", str(status),
                                 "--agent-timeout-ms", "1000", "--resend-ms", "150", "--log-level", "3",
                                 "--log-file", str(tmp_path / f"{name}.log"), *extra],
                    tmp_path, name, stdin=stdin)
        programs.append(p)
        p.port, p.status, p.sock = port, status, sock
        wait_until(lambda: read_status(status), 3, "the first status JSON")
        return p
    return start


@pytest.fixture
def agents():
    """Python test agents (FakeAgent) of a test, closed at its end."""
    made: list[FakeAgent] = []
    yield made
    for a in made:
        a.close()


@pytest.fixture
def tm():
    """A Python test master on a free port."""
    m = TestMaster()
    yield m
    m.close()


@pytest.fixture
def start_agent(agent_exe, programs, tmp_path, tm):
    """Starts ev3-agent broadcasting to the test master, with short timers."""
    def start(*extra: str, name: str = "agent", exe: Path | None = None, prefix: list[str] | None = None):
        port = free_ports(1)[0]
        args = ["--port", str(port), "--bind", "127.0.0.1", "--broadcast", f"127.0.0.1:{tm.port}",
                "--heartbeat-ms", str(HB), "--master-timeout-ms", str(LOSS),
                "--paused-timeout-ms", str(PAUSED), "--sync-timeout-ms", str(SYNC),
                "--log-level", "4", "--log-file", str(tmp_path / f"{name}.log"), *extra]
        if prefix:
            p = Program(Path(prefix[0]), prefix[1:] + [str(exe or agent_exe)] + args, tmp_path, name)
        else:
            p = Program(exe or agent_exe, args, tmp_path, name)
        programs.append(p)
        tm.agent_port = port
        return p
    return start


# --- trace validation (docs/spec.md "Conformance") --------------------------------------------------
# Every ev3-agent / ev3-master started by a scenario runs with `--trace FILE`; when the test ends the
# trace is checked by TLC against the spec (ev3conformance.tracecheck) in a background pool of 2 TLC
# runs, so the checks overlap the following scenarios: agent traces against AgentLogic (validate),
# master traces against MasterLogic (validate --master, with the run's --agent-timeout-ms,
# --resend-ms and --max-resends). At the end of the session every failed check is reported as an
# error at teardown of its test, with the first record the spec cannot match.
# EV3_TRACE_VALIDATE=0 turns it off; =sync checks at each teardown (slower, fails the test at once).
# Agents started with --election (test_election.py, with their own --trace=FILE) are checked too: their
# traces hold Election.tla actions (HandleHeartbeat, StartElection, Forward, ...), checked by the
# per-agent projection of Election.tla composed with AgentLogic (spec/tla/trace/ElectionTrace.tla; constants:
# the run's timers, its --score, the epoch / voted_for of its --state-dir at start).
# Masters started with --election (test_election.py: 2) are checked by MasterLogic composed with
# Election.tla's rules of the PC (spec/tla/trace/MasterElectionTrace.tla: Heartbeat, StartElection,
# HandleVote, BecomeMaster, HandleStale, ... by Election's own XOk / XNext of node 1; MasterRoute and
# MasterHandover as stated there; constants: the run's master timers, and the epoch / members of its
# --state-file when it restarts from one). The Master core an elected agent runs writes its records to
# the agent's trace as node master:ID:EPOCH: each is checked the same way as node ID
# (tracecheck.agent_master_runs), counted with the master traces. A trace with no record is an error
# (a check of nothing cannot fail), unless the test is marked empty_trace and its trace has no record.

import concurrent.futures as _cf  # noqa: E402
import threading as _threading  # noqa: E402
import time as _time  # noqa: E402

import ev3net as _ev3net  # noqa: E402

_MODE = os.environ.get("EV3_TRACE_VALIDATE", "1")
_POOL: _cf.ThreadPoolExecutor | None = None
# (nodeid, name, master? or "merged" or ("refused", invariant, text named): a planted run, future of Result)
_PENDING: list[tuple[str, str, bool | str | tuple, _cf.Future]] = []
_CURRENT: list = []                                 # the running test's item
_STATS = {"traces": 0, "records": 0, "master_traces": 0, "master_records": 0, "empty": 0,
          "election_masters": 0, "election_agents": 0, "election_agent_masters": 0, "seconds": 0.0,
          "master_seconds": 0.0, "merged_runs": 0, "merged_records": 0, "merged_seconds": 0.0, "planted": 0}
_STATS_LOCK = _threading.Lock()
_orig_init = _ev3net.Program.__init__

def _traced_init(self, exe, args, tmp, name, *a, **kw):
    args = list(args)
    self.trace_path = None
    prog = Path(args[0]).name if Path(exe).name.startswith("qemu") and args else Path(exe).name
    if Path(exe).name == "ip" and args[:2] == ["netns", "exec"] and len(args) > 3:
        prog = Path(args[3]).name  # a program in a network namespace (netns.Lan.argv)
    if (_MODE != "0" and prog in ("ev3-agent", "ev3-master") and args and "--driver" not in args
            and not any(x == "--trace" or x.startswith("--trace=") for x in args)
            and any(x.startswith("--") for x in args)):
        self.trace_path = Path(tmp) / f"{name}.trace.ndjson"
        args += ["--trace", str(self.trace_path)]
    elif "--trace" in args[:-1]:
        self.trace_path = Path(args[args.index("--trace") + 1])
    else:  # the scenario's own --trace=FILE
        self.trace_path = next((Path(x.split("=", 1)[1]) for x in args if x.startswith("--trace=")), None)
    self.trace_args = args
    self.trace_prog = prog
    self.trace_state = _state_file(args) if prog == "ev3-master" else _agent_state(args)
    if self.trace_path is not None and _CURRENT:
        _CURRENT[0].__dict__.setdefault("_ev3_started", []).append(self)
    _orig_init(self, exe, args, tmp, name, *a, **kw)


_ev3net.Program.__init__ = _traced_init


def _consts(args: list[str], state: dict | None = None) -> dict:
    from ev3conformance import tracecheck
    c = tracecheck.agent_timer_consts(args)
    if "--election" in args:
        # Election.tla's side: the agent's score (unknown without --score: both outcomes of a
        # comparison allowed) and the durable epoch / vote it starts from.
        c["Election"] = True
        c["Score"] = int(args[args.index("--score") + 1]) if "--score" in args[:-1] else None
        state = state or {}
        c["Epoch"] = int(state.get("epoch", 1))
        c["VotedFor"] = int(state.get("voted_for", 0))
        c["Members"] = [int(x) for x in state.get("members", "").split(",") if x.strip()]
        c["MEpoch"] = int(state.get("members_epoch", 0) or 0)
        c["Floor"] = int(state.get("floor", 0) or 0)
    return c


def _agent_state(args: list[str]) -> dict:
    """The key=value lines of DIR/ev3-agent.state of the agent's --state-dir at start (epoch, voted_for)."""
    if "--state-dir" not in args[:-1]:
        return {}
    f = Path(args[args.index("--state-dir") + 1]) / "ev3-agent.state"
    try:
        return dict(line.split("=", 1) for line in f.read_text().splitlines() if "=" in line)
    except OSError:
        return {}


_MASTER_FLAGS = {"--agent-timeout-ms": "TDrop", "--resend-ms": "TResend", "--max-resends": "MaxResends"}


def _master_consts(args: list[str], state: dict) -> dict:
    """MasterLogic's constants for a run of ev3-master: its timers (ms) and max resends as given on
    the command line, else the program's defaults (docs/programs.md); its first id and msgid from
    the --state-file it was started with (else 2 and 1)."""
    c = {"TDrop": 10000, "TResend": 500, "MaxResends": 10}
    for i, x in enumerate(args[:-1]):
        if x in _MASTER_FLAGS:
            c[_MASTER_FLAGS[x]] = int(args[i + 1])
    if "next_id" in state and "next_msgid" in state:
        c["NextId"], c["FirstMsgid"] = int(state["next_id"]), int(state["next_msgid"])
    if "--election" in args:
        # Election.tla's PC (node 1): a master restarted from its state file stands as a candidate
        # (Restart(PC)) in the epoch and with the membership the file holds; a fresh one is MASTER of 1.
        restored = "next_id" in state and "next_msgid" in state and "epoch" in state
        c["Election"] = True
        c["Life"] = "CANDIDATE" if restored else "MASTER"
        c["Epoch"] = int(state["epoch"]) if restored else 1
        c["Members"] = [int(x) for x in state.get("members", "").split(",") if x.strip()] if restored else []
        c["MEpoch"] = int(state.get("members_epoch", 0) or 0) if restored else 0
    return c


def _state_file(args: list[str]) -> dict:
    """The key=value lines of the --state-file the master starts from (empty: none yet)."""
    if "--state-file" not in args[:-1]:
        return {}
    f = Path(args[args.index("--state-file") + 1])
    try:
        return dict(line.split("=", 1) for line in f.read_text().splitlines() if "=" in line)
    except OSError:
        return {}


def _validate(path: Path, consts: dict, master: bool, node: str | None = None):
    from ev3conformance import tracecheck
    t0 = _time.monotonic()
    r = tracecheck.validate_master(path, consts, node=node) if master else tracecheck.validate(path, consts)
    with _STATS_LOCK:
        _STATS["master_seconds" if master else "seconds"] += _time.monotonic() - t0
    return r


def _submit(nodeid: str, p, expect_empty: bool = False) -> None:
    global _POOL
    path = getattr(p, "trace_path", None)
    if path is None or _MODE == "0":
        return
    if expect_empty:  # @pytest.mark.empty_trace: a trace with no record is what the scenario expects
        from ev3conformance import tracecheck
        try:
            if not tracecheck.read_trace(path).records:
                _STATS["empty"] += 1
                return
        except tracecheck.TraceError:
            pass  # not readable: the check below says why
    master = p.trace_prog == "ev3-master"
    if master and "--election" in p.trace_args:
        _STATS["election_masters"] += 1
    if not master and "--election" in p.trace_args:
        _STATS["election_agents"] += 1
    if _POOL is None:
        _POOL = _cf.ThreadPoolExecutor(max_workers=2)
    consts = _master_consts(p.trace_args, p.trace_state) if master else _consts(p.trace_args, p.trace_state)
    jobs = [(p.name, master, None, consts)]
    if not master and "--election" in p.trace_args:
        # the Master core the agent ran while elected (node master:ID:EPOCH in its trace)
        from ev3conformance import tracecheck
        for node, mc in tracecheck.agent_master_runs(path):
            _STATS["election_agent_masters"] += 1
            jobs.append((f"{p.name} ({node})", True, node, mc))
    for name, is_master, node, c in jobs:
        fut = _POOL.submit(_validate, path, c, is_master, node)
        if _MODE == "sync":
            r = fut.result()
            _count(r, is_master)
            assert r.ok, f"trace of {name} does not conform to the spec: {r.message}"
            continue
        _PENDING.append((nodeid, name, is_master, fut))


def _refused(r, kind) -> str | None:
    """Why a planted run's Result @p r is not what ("refused", invariant) @p kind expects, or None."""
    if r.ok:
        return f"the run with {kind[1]}'s fault planted conforms: the check did not bite"
    if f"({kind[1]}" not in r.message or kind[2] not in r.message:
        return f"the run with {kind[1]}'s fault planted is not refused naming it and {kind[2]}: {r.message}"
    return None


def _count(r, master) -> None:
    if isinstance(master, tuple):
        _STATS["planted"] += 1
        return
    if master == "merged":
        _STATS["merged_runs"] += 1
        _STATS["merged_records"] += r.records
        _STATS["merged_seconds"] += r.seconds
        return
    k = "master_" if master else ""
    _STATS[k + "traces"] += 1
    _STATS[k + "records"] += r.records


def _epoch_of(p) -> int:
    """The epoch a program started from: its --state-dir's / --state-file's (a fresh one: 1)."""
    st = p.trace_state or {}
    restored = p.trace_prog == "ev3-agent" or {"next_id", "next_msgid"} <= st.keys()
    return int(st.get("epoch", 1)) if restored else 1


def _merged_inputs(started: list):
    """What the whole-run check of the programs @p started takes: (their trace files, each node's
    epoch at start, the agents' master timeout (given, or ev3-agent's rule from its heartbeat): the
    largest, if they differ), or None when there is no run to merge (fewer than two traced programs, none
    with --election)."""
    from ev3conformance import merged
    progs = [p for p in started if getattr(p, "trace_path", None) is not None]
    if len(progs) < 2 or not any("--election" in p.trace_args for p in progs):
        return None
    paths = list(dict.fromkeys(p.trace_path for p in progs))  # a program restarted on the same trace: once
    epochs = {f"{p.trace_path.name}:{'master' if p.trace_prog == 'ev3-master' else 'agent'}": _epoch_of(p)
              for p in progs}
    from ev3conformance import tracecheck
    losses = [tracecheck.agent_timer_consts(p.trace_args)["TLoss"] for p in progs if p.trace_prog == "ev3-agent"]
    return paths, epochs, max(losses, default=merged.TLOSS)


class _WholeRun:
    """The whole run of one test, for a test that checks more of it than the check at teardown."""

    def __init__(self, item) -> None:
        self.item = item

    def inputs(self):
        """(trace files, epochs at start, the agents' timeout) of the programs the test started so far,
        as the check at teardown takes them (_merged_inputs)."""
        got = _merged_inputs(getattr(self.item, "_ev3_started", []))
        assert got, "no run to merge: fewer than two traced programs, or none with --election"
        return got

    def refused(self, planted: Path, epochs: dict, loss: int, invariant: str, naming: str) -> None:
        """The run with a fault planted (merged.plant into directory @p planted) must be refused naming
        @p invariant and @p naming (the record planted): checked by TLC in the background pool as the other checks (at once with sync);
        anything else fails the test at teardown."""
        global _POOL
        from ev3conformance import merged
        if _POOL is None:
            _POOL = _cf.ThreadPoolExecutor(max_workers=2)
        fut = _POOL.submit(merged.validate, [planted], epochs, None, loss)
        kind = ("refused", invariant, naming)
        if _MODE == "sync":
            r = fut.result()
            _count(r, kind)
            bad = _refused(r, kind)
            assert bad is None, bad
            return
        _PENDING.append((self.item.nodeid, f"the whole run planted ({invariant})", kind, fut))


@pytest.fixture
def merged_run(request) -> _WholeRun:
    return _WholeRun(request.node)


def _submit_merged(nodeid: str, started: list) -> None:
    """Whole-run validation (docs/spec.md "Whole-run traces"): when the test ran programs with
    --election, the traces of all the programs it started are merged into one behaviour (each receive
    after its send) and checked by TLC against System's and Election's invariants (ev3conformance.merged)."""
    global _POOL
    run = _merged_inputs(started) if _MODE != "0" else None
    if run is None:
        return
    from ev3conformance import merged
    paths, epochs, loss = run
    if _POOL is None:
        _POOL = _cf.ThreadPoolExecutor(max_workers=2)
    fut = _POOL.submit(merged.validate, paths, epochs, None, loss)
    name = f"the whole run ({len(paths)} traces merged)"
    if _MODE == "sync":
        r = fut.result()
        _count(r, "merged")
        assert r.ok, f"trace of {name} does not conform to the spec: {r.message}"
        return
    _PENDING.append((nodeid, name, "merged", fut))


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    _CURRENT[:] = [item]


@pytest.fixture(autouse=True)
def _trace_check(request):
    """Collects the traces of the programs the test started (see `programs`)."""
    yield
    for p in getattr(request.node, "_ev3_started", []):
        _submit(request.node.nodeid, p, request.node.get_closest_marker("empty_trace") is not None)
    _submit_merged(request.node.nodeid, getattr(request.node, "_ev3_started", []))


def pytest_configure(config):
    config.addinivalue_line("markers", "empty_trace: the programs the scenario starts may write no trace "
                                       "record (an empty trace is then counted apart, not checked: an empty "
                                       "trace check is an error)")


def pytest_sessionfinish(session, exitstatus):
    if not _PENDING and not (_MODE == "sync" and _STATS["traces"] + _STATS["master_traces"]):
        return
    from _pytest.reports import TestReport
    t0 = _time.monotonic()
    bad = 0
    for nodeid, name, master, fut in _PENDING:
        r = fut.result()
        _count(r, master)
        why = _refused(r, master) if isinstance(master, tuple) else (
            None if r.ok else f"trace of {name} does not conform to the spec: {r.message}")
        if why is None:
            continue
        bad += 1
        rep = TestReport(nodeid=nodeid, location=(nodeid.split("::")[0], None, nodeid), keywords={},
                         outcome="failed", longrepr=why, when="teardown")
        session.config.hook.pytest_runtest_logreport(report=rep)
    waited = _time.monotonic() - t0
    tr = session.config.pluginmanager.get_plugin("terminalreporter")
    if tr is not None:
        tr.ensure_newline()
        tr.write_line(f"trace validation: {_STATS['traces']} agent traces ({_STATS['records']} records), "
                      f"{_STATS['master_traces']} master traces "
                      f"({_STATS['master_records']} records), {_STATS['empty']} empty as expected, "
                      f"{bad} not conforming; with --election: {_STATS['election_agents']} agents (AgentLogic + Election), "
                      f"{_STATS['election_masters']} masters (MasterLogic + Election's PC), "
                      f"{_STATS['election_agent_masters']} agent-masters' Master cores; whole runs merged "
                      f"and checked: {_STATS['merged_runs']} ({_STATS['merged_records']} records, "
                      f"{_STATS['merged_seconds']:.0f} s), with a fault planted and refused: {_STATS['planted']}; "
                      f"TLC {_STATS['seconds'] + _STATS['master_seconds']:.0f} s (masters "
                      f"{_STATS['master_seconds']:.0f} s) in 2 parallel runs, {waited:.0f} s waited at the end")
    if bad:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
