"""Implementation -> spec: NDJSON traces of the programs (docs/core.md "Trace") checked by TLC against
the trace modules of spec/tla/trace/ (docs/spec.md "Implementation -> spec (validate)").

The TLA+ lives in .tla files, parsed by SANY in `make spec`: AgentTrace, ElectionTrace, MasterTrace
and MasterElectionTrace give a node's initial local state and its step relation (the set of local
states a record leads to), TraceWalk walks one node's records with it, and MC<kind>Trace.tla/.cfg
put the two together. TLC 2.18 cannot read a file from TLA+ (no Json/IOUtils module; a Java module
override would mean a second JSON parser and a second wire decoder), so this module only converts
data: it decodes each record's datagram with the reference codec (ev3conformance.wire), keeps the
fields the check reads, and writes them with the run's constants as a module TraceData.tla of
definitions (values only: no operator, no TLA+ logic). It then runs TLC on MC<kind>Trace in a
directory holding the spec's modules, the trace modules and that TraceData, and reads the verdict:
invariant Matched violated = every record matched; NotStuck violated = the record TraceWalk names
could not be matched.

A trace that cannot show anything is an error, never a pass: an empty trace, one with no record of
the node asked for (another node's trace), a line that is not JSON, a record without an action, a
datagram that does not decode. A last line cut by a kill (SIGKILL: the programs write through stdio)
is left out, and the result says so.

A record of an action the spec abstracts as a step of no node (BEYOND_SPEC: an agent's EVENT LEAVING
as its program exits, Agent::leaving) is checked here and left out of what TLC walks: it must be
that node's last record and change nothing but its msgid. The datagram it sent is then one no
record of the walk sent (merged counts it as such).

Records of Reports.tla's actions (REPORTS_ACTIONS: an agent's TakeAck, a master's PCTake) change
none of the variables the walks read, and are left out of them too; they are checked here against
Reports.tla's rules instead (check_reports_record): a TakeAck changes nothing but the msgid, and a
PCTake records the number offered exactly when it is the next of the sender's record (a report) or
the marker covers the next (a drop), after the numbers below the offer's `first` it lacked.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

from ev3conformance import driver as drv
from ev3conformance import graph as gr
from ev3conformance import tla, wire

TRACE_SPEC = gr.SPEC / "trace"

AGENT_VARS = ["state", "led", "id", "beh", "step", "wait", "motors", "devOk", "silence", "clk", "win"]
REF_TYPES = {"MASTER", "ACK", "NOT", "PONG", "ACTION_OK", "ACTION_INTERR", "ACTION_ERR"}
# Actions of the cores no spec step stands for (docs/core.md "Trace"): left out of the walk.
BEYOND_SPEC = {"Leave"}
# Reports.tla's actions: checked by check_reports_record, left out of the walks.
REPORTS_ACTIONS = {"TakeAck", "PCTake"}



def model_a_behaviours() -> list[str]:
    """The behaviours ev3-agent's model A accepts, as the built agent's driver reports them
    (docs/driver.md "facts"). Raises TraceError when it cannot be asked."""
    try:
        return [b["name"] for b in drv.agent_facts()["behaviours"]]
    except (OSError, drv.DriverError, KeyError, TypeError) as e:
        raise TraceError(f"model A's behaviours come from ev3-agent --driver (input facts), which could "
                         f"not tell them ({e}); build it (make build) or give the run's Behaviours") from e


# The programs' defaults (docs/programs.md, timers.hpp); a trace of a run with other timers needs
# them passed (validate --timers). Behaviours, when not given: model_a_behaviours().
DEFAULTS = {"TSync": 10000, "TPing": 100, "TLoss": 800, "TPaused": 1000, "Window": 50,
            "ModelName": "A", "Steps": 1000000000}

# ev3-agent's timer flags and the spec constants they set.
AGENT_TIMER_FLAGS = {"--heartbeat-ms": "TPing", "--master-timeout-ms": "TLoss", "--paused-timeout-ms": "TPaused",
                     "--sync-timeout-ms": "TSync"}


def agent_timer_consts(args: list[str]) -> dict:
    """TPing, TLoss, TPaused and TSync of an ev3-agent started with @p args, by its own rule
    (agent_options.cpp, timers.hpp Timers::for_heartbeat): the master timeout is 8 heartbeats, the
    paused timeout 10 heartbeats, or twice the master timeout when that is given; each flag given
    wins."""
    given = {}
    for i, x in enumerate(args):
        flag, eq, value = x.partition("=")
        if flag in AGENT_TIMER_FLAGS and (eq or i + 1 < len(args)):
            given[AGENT_TIMER_FLAGS[flag]] = int(value if eq else args[i + 1])
    c = {"TPing": given.get("TPing", DEFAULTS["TPing"]), "TSync": given.get("TSync", DEFAULTS["TSync"])}
    c["TLoss"] = given.get("TLoss", 8 * c["TPing"])
    c["TPaused"] = given.get("TPaused", 2 * c["TLoss"] if "TLoss" in given else 10 * c["TPing"])
    return c


@dataclass
class Result:
    path: str
    ok: bool
    records: int
    message: str
    skipped: bool = False     # kept for callers: a check with nothing to check is an error, never skipped
    no_records: bool = False  # failed because the trace holds no record of the node asked for


class TraceError(ValueError):
    """A trace that cannot be checked: the message names the line or record and what is wrong."""


@dataclass
class TraceFile:
    records: list[dict]
    cut: int = 0                      # bytes of a last line cut by a kill (left out), or 0
    nodes: Counter = field(default_factory=Counter)   # records per node
    beyond: Counter = field(default_factory=Counter)  # BEYOND_SPEC records left out, per node
    reports: Counter = field(default_factory=Counter)  # REPORTS_ACTIONS records checked and left out, per node
    # The msgids REPORTS_ACTIONS records left out sent (a TakeAck's window sends REPORTs): index in
    # `records` of the node's last record kept before it -> the node's next msgid after it. A
    # merge of traces attributes those sends to that record (the earliest place they may be).
    sent_after: dict[int, int] = field(default_factory=dict)


def read_trace(path: Path) -> TraceFile:
    """Every record of the trace at @p path. A line that is not a JSON object with an "action" is an
    error, except a last line without its newline that is the start of a record: cut by a kill (the
    master killed with SIGKILL: the program writes through stdio), left out and counted in `cut`."""
    try:
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except OSError as e:
        raise TraceError(f"cannot read the trace: {e.strerror or e}") from e
    lines = text.split("\n")
    out = TraceFile([])
    last_kept: dict[str, int] = {}  # node -> index in out.records of its last record kept
    for i, raw in enumerate(lines):
        line = raw.strip()
        if not line:
            continue
        last = i == len(lines) - 1  # no newline after it
        try:
            r = json.loads(line)
        except json.JSONDecodeError as e:
            if last and line.startswith("{"):
                out.cut = len(raw)
                break
            raise TraceError(f"line {i + 1} is not JSON ({e.msg}): {line[:120]!r}") from e
        if not isinstance(r, dict) or not isinstance(r.get("action"), str) or not r["action"]:
            raise TraceError(f"line {i + 1} is not a trace record (a JSON object with an \"action\"): "
                             f"{line[:120]!r}")
        for k in ("args", "changed"):
            if not isinstance(r.get(k, {}), dict):
                raise TraceError(f"line {i + 1}: \"{k}\" is not an object: {line[:120]!r}")
        node = str(r.get("node", ""))
        if out.beyond[node]:
            raise TraceError(f"line {i + 1}: a record of node {node} after its {'/'.join(sorted(BEYOND_SPEC))} "
                             f"record (that one is a node's last)")
        if r["action"] in REPORTS_ACTIONS:
            why = check_reports_record(r)
            if why:
                raise TraceError(f"line {i + 1}: {why}: {line[:160]!r}")
            out.reports[node] += 1
            m = r.get("changed", {}).get("msgid")
            if isinstance(m, int) and node in last_kept:
                out.sent_after[last_kept[node]] = m
            continue
        if r["action"] in BEYOND_SPEC:
            if set(r.get("changed", {})) - {"msgid"}:
                raise TraceError(f"line {i + 1}: a {r['action']} record changes more than the msgid: {line[:120]!r}")
            out.beyond[node] += 1
            continue
        last_kept[node] = len(out.records)
        out.records.append(r)
        out.nodes[node] += 1
    return out


def check_reports_record(r: dict) -> str | None:
    """Why record @p r of a Reports.tla action breaks its rules (None: it keeps them). TakeAck: it
    changes nothing but the msgid (the window's sendings) and lo (what the PC's acknowledgement freed). PCTake: args.stored is the sender's last
    number recorded before; changed.rec.stored after (absent: unchanged). From base = the larger of
    stored and first - 1 (the numbers below `first` the agent no longer holds are recorded as
    skipped), a report seq is recorded iff seq = base + 1, a marker first..last iff it covers base + 1;
    otherwise nothing is."""
    ch = r.get("changed", {})
    if r["action"] == "TakeAck":
        return "a TakeAck record changes more than the msgid and lo" if set(ch) - {"msgid", "lo"} else None
    if set(ch) - {"rec"}:
        return "a PCTake record changes more than the record of reports"
    args = r.get("args", {})
    try:
        m = wire.decode(args["msg"].encode("latin-1"))
        before = int(args["stored"])
        p = [int(x) for x in m.params[:2]]
    except (KeyError, ValueError, TypeError, wire.DecodeError) as e:
        return f"a PCTake record without a REPORT / REPORT_DROPPED and its stored number ({e})"
    after = int(ch["rec"]["stored"]) if "rec" in ch else before
    if m.type_name == "REPORT":
        seq, first, last = p[0], p[1], p[0]
    elif m.type_name == "REPORT_DROPPED":
        seq, first, last = p[0], p[0], p[1]
    else:
        return f"a PCTake record of a {m.type_name}"
    base = max(before, first - 1)
    want = last if seq <= base + 1 <= last else base
    if after != want:
        return (f"PCTake of {m.type_name} {seq}..{last} (first held {first}) with {before} recorded: "
                f"{after} recorded after, Reports.tla records {want}")
    return None


def load(path: Path, node: str | None = None) -> list[dict]:
    """The trace's records (of @p node, if given); see read_trace."""
    recs = read_trace(path).records
    return [r for r in recs if node is None or r.get("node") == node]


def _no_records(tf: TraceFile, what: str, hint: str) -> str:
    """Why there is nothing to check: an empty trace, or one of other nodes only."""
    if not tf.records:
        cut = f" (its only line was cut: {tf.cut} bytes)" if tf.cut else ""
        return f"no records: the trace is empty{cut}; nothing was checked"
    held = ", ".join(f"{n or '(no node)'} ({k})" for n, k in sorted(tf.nodes.items()))
    return f"no {what} records: the trace holds {held}; nothing was checked{hint}"


def _also(tf: TraceFile, checked: int) -> str:
    """What the result leaves out: a cut last line, records of other nodes."""
    parts = []
    if tf.cut:
        parts.append(f"its last line was cut ({tf.cut} bytes, left out)")
    if len(tf.records) > checked:
        others = ", ".join(f"{n or '(no node)'} ({k})" for n, k in sorted(tf.nodes.items()))
        parts.append(f"{len(tf.records) - checked} records of other nodes not checked here (nodes: {others})")
    return "; " + "; ".join(parts) if parts else ""


# --- the data: records as the trace modules read them (spec/tla/trace/*.tla, "A record ...") -------

_NONE_MSG = {"src": 0, "dst": 0, "msgid": 0, "type": "NONE", "ref": 0, "args": ()}


def _msg(text: str) -> dict:
    """A datagram as AgentLogic's / MasterLogic's message record (Messages.tla's Msg)."""
    m = wire.decode(text.encode("latin-1"))
    name = m.type_name
    ps = [p.decode("latin-1") for p in m.params]
    if name in REF_TYPES and ps:
        ref, args = int(ps[0]), ps[1:]
    else:
        ref, args = 0, ps
    return {"src": m.sender, "dst": m.receiver, "msgid": m.msgid, "type": name, "ref": ref,
            "args": tuple(args)}


def _reason(text: str) -> str:
    """A NOT reason as AgentLogic's Reasons: "missing device: the robot has no colour sensor (...)"
    is the spec's "missing device" (the device's name stands for any)."""
    return "missing device" if text.startswith("missing device: ") else text


def _win(w: list) -> tuple:
    """The dedupe window as AgentLogic's WinEntry sequence."""
    out = []
    for e in w:
        a = e["ans"]
        out.append({"src": e["src"], "msgid": e["msgid"],
                    "ans": {"src": a["src"], "dst": 1, "type": a["type"], "ref": a["ref"],
                            "args": (_reason(a["reason"]),) if "reason" in a else ()}})
    return tuple(out)


def _agent_changed(ch: dict) -> dict:
    """AgentLogic's variables of a record's changed (dupActed is never written)."""
    out = {k: v for k, v in ch.items() if k in AGENT_VARS}
    if "win" in out:
        out["win"] = _win(out["win"])
    return out


def _record(recs: list[dict], k: int, convert) -> dict:
    """convert(record k), with an error naming the record when its data is not what the trace format says."""
    try:
        return convert(recs[k])
    except wire.DecodeError as e:
        raise TraceError(f"record {k + 1} of {len(recs)}: its datagram does not decode ({e}): "
                         f"{json.dumps(recs[k])[:300]}") from e
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise TraceError(f"record {k + 1} of {len(recs)} is malformed ({type(e).__name__}: {e}): "
                         f"{json.dumps(recs[k])[:300]}") from e


def _agent_record(r: dict) -> dict:
    """AgentTrace's record: [a, m, e, p, n, ch]."""
    args = r.get("args", {})
    m = args.get("msg")
    return {"a": r["action"], "m": _msg(m) if m else dict(_NONE_MSG), "e": str(args.get("e", "")),
            "p": str(args.get("p", "")), "n": int(args.get("ticks", 1)), "v": str(args.get("check", "")),
            "ch": _agent_changed(r.get("changed", {}))}


def temp_id_of(recs: list[dict]) -> int:
    """The agent's temporary id: named by the first MASTER it took (or addressed by a command)."""
    for r in recs:
        msg = r.get("args", {}).get("msg")
        if not msg:
            continue
        try:
            m = _msg(msg)
        except wire.DecodeError:
            continue
        if r["action"] == "RecvMaster":
            return m["ref"]
        if r["action"] == "ApplyCommand" and r.get("args", {}).get("cmd") == "RecvMaster":
            # the MASTER inside EPOCH_CMD (a PC past epoch 1: it syncs agents in its epoch)
            try:
                return _msg(wire.decode(msg.encode("latin-1")).params[1].decode("latin-1"))["ref"]
            except (wire.DecodeError, IndexError):
                pass
        if r["action"] not in ("Ignore",) and m["dst"] >= 50000:
            return m["dst"]
    return 50000


def data_module(records: list[dict], consts: dict, about: str) -> str:
    """The module TraceData: the records as the sequence Trace and each constant as a definition
    (values only). @p about: a line saying where the data comes from (a comment)."""
    about = " ".join(about.split())
    body = ",\n".join("  " + tla.to_tla(r) for r in records)
    lines = ["---- MODULE TraceData ----",
             "\\* Data only, written by ev3conformance.tracecheck (no TLA+ logic: see spec/tla/trace/).",
             f"\\* {about}",
             f"Trace == <<\n{body}\n>>"]
    lines += [f"{k} == {tla.to_tla(v)}" for k, v in consts.items()]
    return "\n".join(lines) + "\n====\n"


def _describe_record(recs, k):
    lo = max(0, k - 3)
    rows = []
    for i in range(lo, min(len(recs), k + 1)):
        mark = ">>" if i == k else "  "
        rows.append(f"  {mark} record {i + 1}: {json.dumps(recs[i])[:400]}")
    return "\n".join(rows)


@dataclass
class _Verdict:
    kind: str          # "matched", "stuck" or "error"
    record: int = -1   # stuck: the index of the record that could not be matched
    detail: str = ""   # error: what TLC said
    dir: Path | None = None


def check(module: str, data: str, n: int, workdir: Path | None, prefix: str) -> _Verdict:
    """TLC on spec/tla/trace/@p module (MCAgentTrace, ...) with @p data as TraceData, in a new
    directory under @p workdir holding the spec's modules; @p n records. The directory is removed when
    the trace conforms, kept otherwise (rerun TLC there: java -cp tla2tools.jar tlc2.TLC -config
    MODULE.cfg MODULE.tla)."""
    wd = Path(workdir or (gr.BUILD / "traces"))
    wd.mkdir(parents=True, exist_ok=True)
    d = Path(tempfile.mkdtemp(prefix=prefix, dir=wd))
    for f in sorted(gr.SPEC.glob("*.tla")) + sorted(TRACE_SPEC.glob("*.tla")) + sorted(TRACE_SPEC.glob("*.cfg")):
        shutil.copy(f, d / f.name)
    (d / "TraceData.tla").write_text(data)
    rc, out = gr.tlc(f"{module}.tla", f"{module}.cfg", [], cwd=d)
    if rc == 12 and "Invariant Matched is violated" in out:
        # TraceWalk's cursor past the last record: cross-checks that TLC walked every record read here
        cur = re.findall(r"^/\\ cursor = (\d+)", out, re.M)
        if cur and int(cur[-1]) == n + 1:
            shutil.rmtree(d, ignore_errors=True)
            return _Verdict("matched")
        return _Verdict("error", detail=f"TLC's walk ended at record {cur[-1] if cur else '?'}, the trace has "
                                        f"{n} (check kept in {d})", dir=d)
    if rc == 12 and "Invariant NotStuck is violated" in out:
        fails = re.findall(r"^/\\ failed = (\d+)", out, re.M)
        return _Verdict("stuck", record=int(fails[-1]) - 1 if fails else -1, dir=d)
    if rc == 0:
        return _Verdict("error", detail=f"TLC ended without matching the trace (check in {d})", dir=d)
    return _Verdict("error", detail=f"TLC failed (exit {rc}); check in {d}:\n{out[-2500:]}", dir=d)


# --- one node's data, and its check --------------------------------------------------------------

class NoRecords(TraceError):
    """The trace holds no record of the node asked for."""


@dataclass
class NodeData:
    """One node's records converted for its trace module (data only): what TraceData holds."""
    node: str            # the node's name in the trace
    module: str          # the check: MCAgentTrace, MCElectionTrace, MCMasterTrace, MCMasterElectionTrace
    what: str            # what it checks against (for messages)
    records: list[dict]  # the node's records as read
    items: list[dict]    # the same as the module reads them
    consts: dict         # the module's constants
    file: TraceFile
    tag: str = ""        # ", election" when checked with Election.tla

    def data(self, path: Path) -> str:
        return data_module(self.items, self.consts, f"{len(self.records)} records of node {self.node} in {path}")


def agent_data(path: Path, consts: dict | None = None, node: str = "agent", temp_id: int | None = None) -> NodeData:
    """An agent's records (of node @p node) for AgentTrace, or ElectionTrace when the agent ran with
    --election (Election records in the trace, or consts Election = True). Raises TraceError."""
    c = dict(DEFAULTS)
    c.update(consts or {})
    tf = read_trace(path)
    mine = [r for r in tf.records if str(r.get("node", "")).startswith(node)]
    if not mine:
        raise NoRecords(_no_records(tf, node, " (a master's trace: validate --master)"))
    if c.get("Behaviours") is None:
        c["Behaviours"] = model_a_behaviours()
    tid = temp_id if temp_id is not None else temp_id_of(mine)
    election = c.get("Election")
    if election is None:
        election = is_election_trace(mine)
    k = {"Behaviours": frozenset(c["Behaviours"]), "ModelName": str(c["ModelName"]), "TSync": int(c["TSync"]),
         "TPing": int(c["TPing"]), "TLoss": int(c["TLoss"]), "TPaused": int(c["TPaused"]),
         "Window": int(c["Window"]), "Steps": int(c["Steps"]), "TempId": int(tid)}
    if not election:
        return NodeData(node, "MCAgentTrace", "the spec", mine,
                        [_record(mine, i, _agent_record) for i in range(len(mine))], k, tf)
    items, fleet = _election_records(mine)
    score = c.get("Score")
    k.update({"Fleet": frozenset(fleet), "Score": int(score) if score is not None else 0,
              "ScoreKnown": score is not None, "InitEpoch": int(c.get("Epoch", 1) or 1),
              "InitVotedFor": int(c.get("VotedFor", 0) or 0),
              "InitMembers": frozenset(int(x) for x in (c.get("Members") or [])),
              "InitMEpoch": int(c.get("MEpoch", 0) or 0), "InitFloor": int(c.get("Floor", 0) or 0),
              # the core records the membership only when it changes (a restored agent that
              # hears the list it kept records none); a trace without it checks no membership
              "WithMembers": bool(c.get("Members") or c.get("MEpoch") or c.get("Floor")) or any(
                  {"members", "mepoch", "floor"} & r.get("changed", {}).keys() for r in mine)})
    return NodeData(node, "MCElectionTrace", "AgentLogic + Election (per-agent projection)", mine, items, k, tf,
                    ", election")


def validate(path: Path, consts: dict | None = None, node: str = "agent", temp_id: int | None = None,
             workdir: Path | None = None) -> Result:
    """An agent's trace (records of node @p node) against AgentLogic, or AgentLogic + Election when the
    agent ran with --election (Election records in the trace, or consts Election = True). consts: the
    run's timers TSync, TPing, TLoss, TPaused (ms), Window, Behaviours; election: Score (None:
    unknown), Epoch, VotedFor (its --state-dir at start)."""
    path = Path(path)
    try:
        nd = agent_data(path, consts, node, temp_id)
    except TraceError as e:
        return Result(str(path), False, 0, str(e), no_records=isinstance(e, NoRecords))
    n, tid = len(nd.records), nd.consts["TempId"]
    v = check(nd.module, nd.data(path), n, workdir, "trace-")
    if v.kind == "matched":
        return Result(str(path), True, n, f"{n} records matched (temporary id {tid}{nd.tag}){_also(nd.file, n)}")
    if v.kind == "stuck":
        return Result(str(path), False, n,
                      f"record {v.record + 1} of {n} could not be matched by {nd.what} "
                      f"(temporary id {tid}; check kept in {v.dir}):\n{_describe_record(nd.records, v.record)}")
    return Result(str(path), False, n, v.detail)


def validate_many(paths: list[Path], consts: dict | None = None, jobs: int = 2) -> list[Result]:
    with ThreadPoolExecutor(max_workers=max(1, jobs)) as ex:
        return list(ex.map(lambda p: validate(p, consts), paths))


def jobs_default() -> int:
    return max(1, min(2, os.cpu_count() or 1))


# --- the master (MasterTrace: MasterLogic, ExactMsgids = TRUE; time map in MasterTrace.tla) --------

MASTER_RECV = ["MasterSync", "MasterAnswer", "MasterPing", "MasterReport"]
ELECTION_MASTER_ACTIONS = {"Heartbeat", "StartElection", "HandleVote", "BecomeMaster", "HandleElect",
                           "HandleHeartbeat", "HandleStale", "MasterRoute", "MasterHandover", "Reconfigure",
                           "LearnMembers"}
# TDrop has no default (the driver's and the program's differ); TResend 1 is the driver's.
MASTER_DEFAULTS = {"TResend": 1, "MaxResends": 10, "Behaviours": ["wait"], "NextId": 2}


def first_msgid(recs: list[dict]) -> int:
    """The master's first msgid as its trace says: `msgid_from` of the first record that sent (a
    master starts from its state file's or the wall clock's msgid, ev3proto/msgids.hpp); 1 when no
    record sent anything (or an older trace without msgid_from)."""
    for r in recs:
        if "msgid_from" in r:
            return int(r["msgid_from"])
    return 1
_REG_KEYS = ("ann", "id", "ep", "synced", "pending", "mid", "resends", "desired", "beh", "quiet", "hi")


def _reg(reg: list) -> frozenset:
    """A registry as MasterLogic's set of entries."""
    out = []
    for x in reg:
        e = tla.Rec((k, x[k]) for k in _REG_KEYS)
        e["queue"] = tuple(tla.Rec(type=q["type"], name=q["name"]) for q in x["queue"])
        out.append(e)
    return frozenset(out)


def _behaviour_names(recs: list[dict], given) -> list[str]:
    """The behaviour names the operator may have used: the given ones and every one a trace record's
    registry shows (queued BEHAVIOUR, or ACKed)."""
    names = list(given or ["wait"])
    for r in recs:
        for x in r.get("changed", {}).get("reg", []):
            for n in [x.get("beh")] + [q.get("name") for q in x.get("queue", []) if q.get("type") == "BEHAVIOUR"]:
                if n and n != "NONE" and n not in names:
                    names.append(n)
    return names


def _master_changed(ch: dict) -> dict:
    """The MasterLogic variables a master record changed (reg, nextId, msgid)."""
    out = {}
    if "reg" in ch:
        out["reg"] = _reg(ch["reg"])
    for k in ("nextId", "msgid"):
        if k in ch:
            out[k] = int(ch[k])
    return out


def _master_records(recs: list[dict]) -> list[dict]:
    """MasterTrace's records [a, m, now, ch]; times from the first record (real traces carry the
    monotonic clock)."""
    base = int(recs[0].get("now", 0))

    def one(r):
        m = r.get("args", {}).get("msg")
        return {"a": r["action"], "m": _msg(m) if m else dict(_NONE_MSG), "now": int(r.get("now", 0)) - base,
                "ch": _master_changed(r.get("changed", {}))}
    return [_record(recs, k, one) for k in range(len(recs))]


def _master_consts(c: dict, recs: list[dict]) -> dict:
    """MasterTrace's constants."""
    return {"TDrop": int(c["TDrop"]), "MaxResends": int(c["MaxResends"]), "TResend": int(c["TResend"]),
            "Behaviours": frozenset(_behaviour_names(recs, c.get("Behaviours"))),
            "NextId": int(c["NextId"]), "FirstMsgid": int(c["FirstMsgid"])}


def master_data(path: Path, consts: dict, node: str | None = None) -> NodeData:
    """A master's records for MasterTrace, or MasterElectionTrace when it ran with --election (see
    validate_master). Raises TraceError."""
    c = dict(MASTER_DEFAULTS)
    c.update({k: v for k, v in consts.items() if v is not None})
    tf = read_trace(path)
    if node is None:  # the master program's records (an agent-master's are named master:ID:EPOCH)
        recs = [r for r in tf.records if str(r.get("node", "")).startswith("master") and ":" not in str(r.get("node", ""))]
    else:
        recs = [r for r in tf.records if r.get("node", "") == node]
    if not recs:
        hint = " (an agent's trace: validate without --master)" if node is None else ""
        raise NoRecords(_no_records(tf, node or "master", hint))
    election = c.get("Election")
    if election is None:
        election = is_master_election_trace(recs)
    if "FirstMsgid" not in c:
        c["FirstMsgid"] = first_msgid(recs)
    k = _master_consts(c, recs)
    if not election:
        return NodeData(node or "master", "MCMasterTrace", "MasterLogic", recs, _master_records(recs), k, tf)
    k.update({"Self": int(c.get("Self", 1) or 1), "InitLife": str(c.get("Life") or "MASTER"),
              "InitEpoch": int(c.get("Epoch", 1) or 1),
              "InitMembers": frozenset(int(x) for x in (c.get("Members") or [])),
              "InitMEpoch": int(c.get("MEpoch") or c.get("Epoch", 1) or 1),
              # the core records the membership of its epoch when it changes
              "WithMembers": any({"members", "mepoch"} & r.get("changed", {}).keys() for r in recs)})
    return NodeData(node or "master", "MCMasterElectionTrace", "MasterLogic + Election (the PC's rules)", recs,
                    _master_election_records(recs), k, tf, ", election")


def validate_master(path: Path, consts: dict, workdir: Path | None = None, node: str | None = None) -> Result:
    """A master trace against MasterLogic (exact msgids): `ev3-master --driver --trace` (TResend 1,
    the default) or the real program's `--trace` over UDP (TResend = its --resend-ms). consts: TDrop
    (--agent-timeout-ms / the driver's drop), TResend, MaxResends, Behaviours, NextId, FirstMsgid
    (default: the trace's own, first_msgid).
    A trace of `ev3-master --election` (Election.tla records, or consts Election = True) is checked by
    MasterLogic + Election.tla's PC rules (MasterElectionTrace; consts Epoch, Members, Life: the
    state the master starts from); Election = False forces MasterLogic alone. @p node: the records of
    that node (an agent-master's, master:ID:EPOCH); default: the master program's (node master)."""
    path = Path(path)
    try:
        nd = master_data(path, consts, node)
    except TraceError as e:
        return Result(str(path), False, 0, str(e), no_records=isinstance(e, NoRecords))
    n = len(nd.records)
    v = check(nd.module, nd.data(path), n, workdir, "mtrace-")
    if v.kind == "matched":
        return Result(str(path), True, n, f"{n} master records matched{nd.tag}{_also(nd.file, n)}")
    if v.kind == "stuck":
        k = v.record
        why = ""
        if not nd.tag and 0 <= k < n and nd.records[k].get("action") in ELECTION_MASTER_ACTIONS:
            why = " (an Election.tla action: run without --no-election)"
        return Result(str(path), False, n,
                      f"record {k + 1} of {n} could not be matched by {nd.what}{why} "
                      f"(check kept in {v.dir}):\n{_describe_record(nd.records, k)}")
    return Result(str(path), False, n, v.detail)


# --- agents with --election (ElectionTrace: AgentLogic + Election.tla per agent) -------------------

ELECTION_ACTIONS = {"RequestRelay", "OfferRelay", "HandleAccept", "AcceptRelay", "RelayDropped",
                    "GrantPreVote", "HandlePreVote", "StartElection", "HandleElect", "HandleVote",
                    "BecomeMaster", "HandleHeartbeat", "HandleStale", "Forward", "ApplyCommand",
                    "ShareMembers", "LearnMembers"}
ELECTION_VARS = ["life", "epoch", "votedFor", "votes", "leader", "following", "via", "relays", "offered",
                 "prevotes", "members", "mepoch", "floor"]
# Wire type names -> Election.tla's message types.
_EL_TYPES = {"RELAY_REQ": "RREQ", "RELAY_OFFER": "ROFFER", "RELAY_ACCEPT": "RACCEPT", "RELAY_ROUTE": "ROUTE",
             "RELAY": "RELAY", "RELAY_DROP": "RDROP", "ELECT": "ELECT", "VOTE": "VOTE", "LEADER": "HB",
             "EPOCH_STALE": "STALE", "EPOCH_CMD": "CMD", "HANDOVER": "HANDOVER", "PREVOTE_OK": "PREOK"}
_NONE_EL = {"t": "NONE", "src": 0, "dst": 0, "e": 0, "x": 0, "sc": 0, "tgt": 0, "k": 0, "mem": frozenset()}


def is_election_trace(recs: list[dict]) -> bool:
    """True when the agent ran with --election: Election actions or Election variables in the trace."""
    return any(r.get("action") in ELECTION_ACTIONS or "life" in r.get("changed", {}) for r in recs)


def _num(ps: list[bytes], i: int) -> int:
    try:
        return int(ps[i])
    except (IndexError, ValueError):
        return 0


def _el_msg(text: str) -> tuple[dict, dict | None, list[int]]:
    """An Election datagram as Election.tla's [t, src, dst, e, x] (+ sc: the score it carries, tgt: RELAY's
    target), the inner datagram of EPOCH_CMD (AgentLogic's record, or None) and LEADER's members."""
    m = wire.decode(text.encode("latin-1"))
    t = _EL_TYPES.get(m.type_name or "")
    if t is None:
        return dict(_NONE_EL), None, []
    ps = list(m.params)
    d = {"t": t, "src": m.sender, "dst": m.receiver, "e": 0, "x": 0, "sc": 0, "tgt": 0, "k": 0, "mem": frozenset()}
    inner, members = None, []
    if t == "RELAY":
        d["tgt"] = _num(ps, 0)
    else:
        d["e"] = _num(ps, 0)
    if t in ("RREQ", "ELECT"):
        d["sc"] = _num(ps, 1)
        d["k"] = _num(ps, 2)  # members_epoch (0 when the sender left it out)
    if t in ("ROFFER", "RACCEPT"):
        d["x"] = _num(ps, 1)
    if t == "HB":
        # the leader: a master's LEADER names its sender, a copy of a membership 0 (Election.tla
        # reads no x of a LEADER: its copies are told apart by their receiver)
        d["x"] = _num(ps, 1)
        members = [_num(ps, i) for i in range(2, len(ps))]
        d["mem"] = frozenset(x for x in members if 2 <= x <= 49999)
    if t == "CMD" and len(ps) > 1:
        try:
            inner = _msg(ps[1].decode("latin-1"))
        except wire.DecodeError:
            inner = None
    return d, inner, members


def _el_changed(ch: dict) -> dict:
    out = {}
    for k in ELECTION_VARS:
        if k in ch:
            v = ch[k]
            out[k] = frozenset(v) if isinstance(v, list) else v
    return out


def _election_records(recs: list[dict]) -> tuple[list[dict], set[int]]:
    """ElectionTrace's records [a, m, em, im, cmd, e, p, n, ch, ech] and the fleet: the members the
    LEADERs in the trace list."""
    fleet: set[int] = set()

    def one(r):
        args = r.get("args", {})
        text = args.get("msg")
        m, em, im = dict(_NONE_MSG), dict(_NONE_EL), dict(_NONE_MSG)
        if text:
            dm = wire.decode(text.encode("latin-1"))
            if (dm.type_name or "") in _EL_TYPES:
                em, inner, members = _el_msg(text)
                fleet.update(x for x in members if x)
                if inner is not None:
                    im = inner
            else:
                m = _msg(text)
        return {"a": r["action"], "m": m, "em": em, "im": im, "cmd": str(args.get("cmd", "Ignore")),
                "e": str(args.get("e", "")), "p": str(args.get("p", "")), "n": int(args.get("ticks", 1)),
                "v": str(args.get("check", "")), "ch": _agent_changed(r.get("changed", {})), "ech": _el_changed(r.get("changed", {}))}
    return [_record(recs, k, one) for k in range(len(recs))], fleet


# --- the master with --election (MasterElectionTrace: MasterLogic + Election.tla's rules of the node) -

_MASTER_EL_TYPES = {"VOTE", "LEADER", "EPOCH_STALE", "RELAY_ROUTE", "HANDOVER", "ELECT"}


def is_master_election_trace(recs: list[dict]) -> bool:
    """True when the master ran with --election: Election actions or variables in its records."""
    return any(r.get("action") in ELECTION_MASTER_ACTIONS or
               any(k in r.get("changed", {}) for k in ("life", "epoch", "votes")) for r in recs)


def _master_el_msg(text: str) -> tuple[dict, dict, list[int], bool]:
    """A master record's datagram: (MasterLogic's record or NONE, Election's [t, src, dst, e, x] or NONE,
    HANDOVER's ids, relayed). RELAY(1, inner) is unwrapped: the master takes the inner datagram."""
    dm = wire.decode(text.encode("latin-1"))
    relayed = False
    if dm.type_name == "RELAY" and len(dm.params) > 1:
        text = dm.params[1].decode("latin-1")
        dm = wire.decode(dm.params[1])
        relayed = True
    name = dm.type_name or ""
    if name not in _MASTER_EL_TYPES:
        return _msg(text), dict(_NONE_EL), [], relayed
    em, _inner, _members = _el_msg(text)
    ps = list(dm.params)
    ids: list[int] = []
    if name == "RELAY_ROUTE":
        em["x"] = _num(ps, 1)
    if name == "HANDOVER":
        ids = [_num(ps, i) for i in range(1, len(ps))]
    return dict(_NONE_MSG), em, ids, relayed


def _master_election_records(recs: list[dict]) -> list[dict]:
    """MasterElectionTrace's records [a, m, em, ids, now, ch, ech]."""
    base = int(recs[0].get("now", 0))

    def one(r):
        ch = r.get("changed", {})
        ech = {}
        if "life" in ch:
            ech["life"] = str(ch["life"])
        if "epoch" in ch:
            ech["epoch"] = int(ch["epoch"])
        if "votes" in ch:
            ech["votes"] = frozenset(int(v) for v in ch["votes"])
        if "members" in ch:  # the membership of the epoch (the core records it)
            ech["members"] = frozenset(int(v) for v in ch["members"])
        if "mepoch" in ch:
            ech["mepoch"] = int(ch["mepoch"])
        text = r.get("args", {}).get("msg")
        m, em, ids = dict(_NONE_MSG), dict(_NONE_EL), []
        if text:
            m, em, ids, _relayed = _master_el_msg(text)
        return {"a": r["action"], "m": m, "em": em, "ids": frozenset(ids), "now": int(r.get("now", 0)) - base,
                "ch": _master_changed(ch), "ech": ech}
    return [_record(recs, k, one) for k in range(len(recs))]


# --- the Master core an elected agent runs (ev3-agent --election --trace) --------------------------
#
# While an agent is the elected master, its program runs a Master core (docs/core.md "An agent becomes
# master") whose records go to the agent's --trace as node "master:ID:EPOCH" (one core per epoch won).
# Each is checked by MasterElectionTrace with Self = ID: MASTER of EPOCH from its first record, no
# ids to assign (next id 50000: an unknown temporary id is ignored), the membership its agent core
# knew (the members of the last LEADER it took before, from a master or a peer's copy: LearnMembers),
# the first msgid read from its first record (a Heartbeat: the core draws msgids above the agent
# core's); its step-down by Election's
# HandleElect / HandleHeartbeat / HandleStale of node ID (the trace's STEPPED_DOWN: any life but
# MASTER), HANDOVER sent once.


def agent_master_runs(path: Path, consts: dict | None = None) -> list[tuple[str, dict]]:
    """(node, validate_master constants) of each Master core in an agent's trace. consts: the master
    timers TDrop, TResend, MaxResends (default: ev3-agent's, the defaults of timers.hpp: 10000, 500, 10).
    A trace that cannot be read has none (validate reports why)."""
    try:
        recs = load(Path(path), None)
    except TraceError:
        return []
    out = []
    for name in dict.fromkeys(str(r.get("node", "")) for r in recs):
        parts = name.split(":")
        if len(parts) != 3 or parts[0] != "master" or not (parts[1].isdigit() and parts[2].isdigit()):
            continue
        mine = [r for r in recs if r.get("node") == name]
        start = mine[0].get("now", 0)
        members: list[int] = []
        best = 0
        for r in recs:  # the last LEADER the agent core took (not an older epoch's) before this core started:
            # from a master (HandleHeartbeat) or a peer's copy of one (LearnMembers, leader 0)
            if (r.get("node") == "agent" and r.get("now", 0) <= start
                    and r.get("action") in ("HandleHeartbeat", "LearnMembers")):
                try:
                    m = wire.decode(r["args"]["msg"].encode("latin-1"))
                except (KeyError, AttributeError, wire.DecodeError):
                    continue
                e = _num(list(m.params), 0)
                if e >= best:
                    best = e
                    members = [_num(list(m.params), i) for i in range(2, len(m.params))]
        first = mine[0]
        msgid = first.get("changed", {}).get("msgid")
        c = {"TDrop": 10000, "TResend": 500, "MaxResends": 10}  # the Master core's defaults (timers.hpp)
        c.update(consts or {})
        c.update({"Election": True, "Self": int(parts[1]), "Epoch": int(parts[2]), "Life": "MASTER",
                  "Members": [x for x in members if 2 <= x <= 49999], "NextId": 50000,
                  "FirstMsgid": int(msgid) - 1 if first.get("action") == "Heartbeat" and msgid else 1})
        out.append((name, c))
    return out


# --- the sample traces of the trace modules (make spec: ev3conformance.tracemodules) -------------

SAMPLES = TRACE_SPEC / "samples"
