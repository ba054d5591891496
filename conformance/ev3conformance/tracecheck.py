"""Implementation -> spec: an NDJSON trace of the agent core (docs/core.md "Trace") becomes a TLA+
module whose behaviour walks the trace with AgentLogic's handlers; TLC checks it.

The module has a variable `cursor` (next record) and `failed` (the record that could not be
matched). Invariant `Matched == cursor <= Len(Trace)` is violated exactly when the whole trace was
matched (TLC exit 12 with that invariant = success); `NotStuck == failed = 0` is violated when a
record cannot be matched (its number is reported). Tick records of n ticks are n spec Ticks, taken in one step (closed form, see Adv).
Variables absent from a record's "changed" must be unchanged.
"""

from __future__ import annotations

import json
import os
import re
import tempfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from ev3conformance import graph as gr
from ev3conformance import tla, wire

AGENT_VARS = ["state", "led", "id", "beh", "step", "wait", "motors", "devOk", "silence", "clk", "win"]
RECV = ["RecvMaster", "RecvPong", "RecvBehaviour", "RecvStart", "RecvStop", "RecvPause", "RecvResume",
        "RecvStandby", "RecvContinue", "RecvRestart", "RecvDuplicate", "Ignore"]
REF_TYPES = {"MASTER", "ACK", "NOT", "PONG", "ACTION_OK", "ACTION_INTERR", "ACTION_ERR"}

# The programs' defaults (docs/programs.md, timers.hpp); a trace of a run with other timers needs
# them passed (validate --timers).
DEFAULTS = {"TSync": 10000, "TPing": 1000, "TLoss": 3000, "TPaused": 6000, "Window": 50,
            "Behaviours": ["wait"], "ModelName": "A", "Steps": 1000000000}


@dataclass
class Result:
    path: str
    ok: bool
    records: int
    message: str
    skipped: bool = False



# AgentLogic's internal actions a trace record may name, and their arguments in the check.
_INTERNAL = [("SyncTimeout", "a"), ("HeartbeatLost", "a"), ("ActionOk", "a"),
             ("ActionInterrupted", "a, r.e"), ("ActionFailed", "a"), ("SensorReport", "a"),
             ("DeviceUnplugged", "a"), ("DevicePlugged", "a"), ("BatteryLow", "a")]


def _internal_case(suffix: str) -> str:
    """A CASE over _INTERNAL calling L!<action><suffix> (suffix "Ok": the enabling conditions)."""
    return "\n      [] ".join(f'r.a = "{n}" -> L!{n}{suffix}({args})' for n, args in _INTERNAL)


def _agent_steps(t_ping: int, apply: str) -> str:
    """The TLA+ operators both agent trace checks share: Adv (n ticks at once), Recv (the receive
    handler named by the record, @p apply its CASE arms), IntOk / Internal (AgentLogic's internal
    actions)."""
    return f'''Adv(a, k) == IF k = 0 THEN a
             ELSE [a EXCEPT !.clk = (a.clk + k) % {t_ping},
                            !.silence = IF a.state = "PANIC" THEN 0 ELSE a.silence + k]
Recv(h, a, m) ==
    CASE {apply}
IntOk(r, a) ==
    CASE {_internal_case("Ok")}
      [] OTHER -> FALSE
Internal(r, a) ==
    CASE {_internal_case("")}
'''

def _msg(text: str) -> dict:
    m = wire.decode(text.encode("latin-1"))
    name = m.type_name
    ps = [p.decode("latin-1") for p in m.params]
    if name in REF_TYPES and ps:
        ref, args = int(ps[0]), ps[1:]
    else:
        ref, args = 0, ps
    return {"src": m.sender, "dst": m.receiver, "msgid": m.msgid, "type": name, "ref": ref,
            "args": tuple(args)}


def _win(w: list) -> tuple:
    out = []
    for e in w:
        a = e["ans"]
        out.append({"src": e["src"], "msgid": e["msgid"],
                    "ans": {"src": a["src"], "dst": 1, "type": a["type"], "ref": a["ref"],
                            "args": (a["reason"],) if "reason" in a else ()}})
    return tuple(out)


def load(path: Path, node: str | None = None) -> list[dict]:
    """The trace's records (of @p node, if given). A last line without its newline that is not JSON
    was cut by a kill (a master killed with SIGKILL: the program writes through stdio) and is left out."""
    recs = []
    with open(path) as f:
        text = f.read()
    lines = text.split("\n")
    for i, line in enumerate(lines):
        line = line.strip()
        if not line:
            continue
        try:
            r = json.loads(line)
        except json.JSONDecodeError:
            if i == len(lines) - 1:  # unterminated last line: cut by a kill
                break
            raise
        if node is None or r.get("node") == node:
            recs.append(r)
    return recs


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
        if r["action"] not in ("Ignore",) and m["dst"] >= 50000:
            return m["dst"]
    return 50000


def agent_module(name: str, recs: list[dict], consts: dict, temp_id: int) -> str:
    items = []
    for r in recs:
        ch = dict(r.get("changed", {}))
        ch.pop("dupActed", None)
        if "win" in ch:
            ch["win"] = _win(ch["win"])
        a = r["action"]
        m = r.get("args", {}).get("msg")
        mrec = _msg(m) if m else {"src": 0, "dst": 0, "msgid": 0, "type": "NONE", "ref": 0, "args": ()}
        chs = tla.to_tla(ch) if ch else "[x \\in {} |-> 0]"
        items.append(f'[a |-> "{a}", m |-> {tla.to_tla(mrec)}, e |-> {tla.to_tla(r.get("args", {}).get("e", ""))},'
                     f' n |-> {int(r.get("args", {}).get("ticks", 1))}, ch |-> {chs}]')
    c = consts
    behs = "{" + ", ".join(tla.to_tla(b) for b in c["Behaviours"]) + "}"
    apply = "\n      [] ".join(f'h = "{h}" -> L!{h}(a, m)' for h in RECV)
    return f"""---- MODULE {name} ----
EXTENDS Naturals, Sequences, TLC
VARIABLES ag, out, cursor, sub, snap, failed
L == INSTANCE AgentLogic WITH Behaviours <- {behs}, UnknownBehaviour <- "?unknown",
       ModelName <- {tla.to_tla(c["ModelName"])}, TSync <- {c["TSync"]}, TPing <- {c["TPing"]},
       TLoss <- {c["TLoss"]}, TPaused <- {c["TPaused"]}, Window <- {c["Window"]},
       Steps <- {c["Steps"]}, BUG <- "none"
Trace == <<
  {(","+chr(10)+"  ").join(items)}
>>
Vars == {tla.to_tla(set(AGENT_VARS))}
Fits(r, before, after) ==
    \\A v \\in Vars : IF v \\in DOMAIN r.ch THEN after[v] = r.ch[v] ELSE after[v] = before[v]
{_agent_steps(c["TPing"], apply)}Init == /\\ ag = L!InitAgent({temp_id}) /\\ out = <<>> /\\ cursor = 1 /\\ sub = 0 /\\ snap = ag /\\ failed = 0
Match ==
    /\\ failed = 0 /\\ cursor <= Len(Trace)
    /\\ LET r == Trace[cursor] IN
       IF r.a = "Tick" THEN
          \\* n Ticks in one step: Adv(ag, n - 1) is the state before the last one. Tick changes
          \\* only clk and silence, and TimeoutDue is monotone in silence, so the n Ticks are all
          \\* enabled iff the first and the last are (closed form; the last is the spec's Tick).
          /\\ L!TickOk(ag) /\\ L!TickOk(Adv(ag, r.n - 1))
          /\\ LET res == L!Tick(Adv(ag, r.n - 1)) IN
               /\\ ag' = res.ag /\\ out' = res.out
               /\\ Fits(r, ag, res.ag) /\\ cursor' = cursor + 1 /\\ sub' = 0 /\\ snap' = res.ag
       ELSE IF r.m.type # "NONE" THEN
          /\\ ag.state # "OFF" /\\ L!Handler(ag, r.m) = r.a
          /\\ LET res == Recv(r.a, ag, r.m) IN
               /\\ ag' = res.ag /\\ out' = res.out /\\ Fits(r, ag, res.ag)
               /\\ cursor' = cursor + 1 /\\ sub' = 0 /\\ snap' = res.ag
       ELSE
          /\\ IntOk(r, ag)
          /\\ LET res == Internal(r, ag) IN
             /\\ ag' = res.ag /\\ out' = res.out /\\ Fits(r, ag, res.ag)
             /\\ cursor' = cursor + 1 /\\ sub' = 0 /\\ snap' = res.ag
    /\\ UNCHANGED failed
Stuck == failed = 0 /\\ cursor <= Len(Trace) /\\ ~ENABLED Match
         /\\ failed' = cursor /\\ UNCHANGED <<ag, out, cursor, sub, snap>>
Next == Match \\/ Stuck
Matched == cursor <= Len(Trace)
NotStuck == failed = 0
====
"""


def _describe_record(recs, k):
    lo = max(0, k - 3)
    rows = []
    for i in range(lo, min(len(recs), k + 1)):
        mark = ">>" if i == k else "  "
        rows.append(f"  {mark} record {i + 1}: {json.dumps(recs[i])[:400]}")
    return "\n".join(rows)


def validate(path: Path, consts: dict | None = None, node: str = "agent", temp_id: int | None = None,
             workdir: Path | None = None) -> Result:
    path = Path(path)
    c = dict(DEFAULTS)
    c.update(consts or {})
    recs = load(path, None)
    nodes = {r.get("node") for r in recs}
    mine = [r for r in recs if r.get("node", "").startswith(node)]
    if not mine:
        other = ", ".join(sorted(n for n in nodes if n)) or "none"
        return Result(str(path), True, 0, f"no {node} records (nodes: {other}); nothing to check", skipped=True)
    tid = temp_id if temp_id is not None else temp_id_of(mine)
    wd = Path(workdir or (gr.BUILD / "traces"))
    wd.mkdir(parents=True, exist_ok=True)
    d = Path(tempfile.mkdtemp(prefix="trace-", dir=wd))
    election = c.get("Election")
    if election is None:
        election = is_election_trace(mine)
    if election:
        name, specs, what = "ElectionTraceCheck", ("AgentLogic.tla", "Messages.tla", "Election.tla"), \
            "AgentLogic + Election (per-agent projection)"
        (d / f"{name}.tla").write_text(election_module(name, mine, c, tid))
    else:
        name, specs, what = "TraceCheck", ("AgentLogic.tla", "Messages.tla"), "the spec"
        (d / f"{name}.tla").write_text(agent_module(name, mine, c, tid))
    (d / f"{name}.cfg").write_text("INIT Init\nNEXT Next\nINVARIANTS Matched NotStuck\nCHECK_DEADLOCK FALSE\n")
    for f in specs:
        (d / f).write_text((gr.SPEC / f).read_text())
    rc, out = gr.tlc(f"{name}.tla", f"{name}.cfg", [], cwd=d)
    tag = ", election" if election else ""
    if rc == 12 and "Invariant Matched is violated" in out:
        return Result(str(path), True, len(mine), f"{len(mine)} records matched (temporary id {tid}{tag})")
    if rc == 12 and "Invariant NotStuck is violated" in out:
        fails = re.findall(r"failed = (\d+)", out)
        k = int(fails[-1]) - 1 if fails else -1
        return Result(str(path), False, len(mine),
                      f"record {k + 1} of {len(mine)} could not be matched by {what} "
                      f"(temporary id {tid}; module kept in {d}):\n{_describe_record(mine, k)}")
    if rc == 0:
        return Result(str(path), False, len(mine), f"TLC ended without matching the trace (module in {d})")
    return Result(str(path), False, len(mine), f"TLC failed (exit {rc}); module in {d}:\n{out[-2500:]}")


def validate_many(paths: list[Path], consts: dict | None = None, jobs: int = 2) -> list[Result]:
    with ThreadPoolExecutor(max_workers=max(1, jobs)) as ex:
        return list(ex.map(lambda p: validate(p, consts), paths))


def jobs_default() -> int:
    return max(1, min(2, os.cpu_count() or 1))


# --- the master (MasterLogic, ExactMsgids = TRUE) ------------------------------------------------
#
# Time. MasterLogic's MasterTick is one abstract resend period for every entry at once: each entry's
# quiet grows by one, an entry quiet for TDrop ticks is dropped, every pending datagram is resent
# (or its command fails). The C++ core counts milliseconds and keeps a resend deadline per entry
# (sent_at + resend) and a drop deadline per entry (heard + drop); `advance` runs one MasterTick at
# each deadline, acting on the entries due then. The check maps this as follows (the same map for
# `ev3-master --driver` traces, resend 1 ms, and for the real program over UDP):
#   - 1 tick = 1 ms for quiet and drops: quiet is ms since heard (the trace's quiet), TDrop the drop
#     timeout in ms; an entry is dropped at the tick where quiet reaches TDrop, as in TickEntries.
#   - the resend period is per entry: an entry's pending datagram is due TResend ms after it was
#     sent (when its msgid was drawn, or last resent by a tick; a re-announcement's resend
#     does not move it, as in the core). The check keeps this time itself (variable `sent`),
#     it is not read from the trace.
#   - a MasterTick record at time t is MasterLogic's TickEntries over exactly the entries due at t
#     (quiet reaching TDrop, or the resend period over): they are dropped / resent / failed by the
#     spec's own per-entry rule, in id order; every other entry only ages by the tick. The record
#     must come at the first ms anything is due (nothing due at t - 1) and something must be due.
#   - between records time passes with nothing due (else the core would have ticked first): every
#     entry ages by the elapsed ms (closed form, one TLC step per record).
# With TResend = 1 every pending datagram is due every ms: the spec's MasterTick exactly (driver).
# Times are rebased to the first record (real traces carry the monotonic clock).

MASTER_RECV = ["MasterSync", "MasterAnswer", "MasterPing", "MasterReport"]
COMMANDS = ["BEHAVIOUR", "START", "STOP", "PAUSE", "RESUME", "STANDBY", "CONTINUE", "RESTART"]
ELECTION_MASTER_ACTIONS = {"Heartbeat", "StartElection", "HandleVote", "BecomeMaster", "HandleElect",
                           "HandleHeartbeat", "HandleStale", "MasterRoute", "MasterHandover"}
# TDrop has no default (the driver's and the program's differ); TResend 1 is the driver's.
MASTER_DEFAULTS = {"TResend": 1, "MaxResends": 10, "Behaviours": ["wait"], "NextId": 2, "FirstMsgid": 1}


def _reg_tla(reg: list) -> str:
    keys = ("ann", "id", "ep", "synced", "pending", "mid", "resends", "desired", "beh", "quiet", "hi")
    out = []
    for x in reg:
        e = {k: x[k] for k in keys}
        e["queue"] = tuple({"type": q["type"], "name": q["name"]} for q in x["queue"])
        out.append(tla.to_tla(e))
    return "{" + ", ".join(out) + "}"


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


def _master_consts(consts: dict, recs: list[dict]) -> tuple[dict, int]:
    """The check's constants (MASTER_DEFAULTS overridden by @p consts) and the trace's first time."""
    c = dict(MASTER_DEFAULTS)
    c.update(consts)
    return c, (int(recs[0].get("now", 0)) if recs else 0)


def _master_changed_parts(ch: dict) -> list[str]:
    """The MasterLogic variables a master record changed, as TLA+ record fields (reg, nextId, msgid)."""
    parts = []
    if "reg" in ch:
        parts.append(f"reg |-> {_reg_tla(ch['reg'])}")
    for k in ("nextId", "msgid"):
        if k in ch:
            parts.append(f"{k} |-> {int(ch[k])}")
    return parts


def master_module(name: str, recs: list[dict], consts: dict) -> str:
    """MasterTraceCheck: one TLC step per record, with the time map above. consts: TDrop and TResend
    (ms), MaxResends, Behaviours, NextId / FirstMsgid (the master's first id and msgid: 2 and 1 unless
    it was restarted from a state file)."""
    c, base = _master_consts(consts, recs)
    items = []
    for r in recs:
        ch = r.get("changed", {})
        parts = _master_changed_parts(ch)
        m = r.get("args", {}).get("msg")
        mrec = _msg(m) if m else {"src": 0, "dst": 0, "msgid": 0, "type": "NONE", "ref": 0, "args": ()}
        chs = "[" + ", ".join(parts) + "]" if parts else "[x \\in {} |-> 0]"
        now = int(r.get("now", 0)) - base
        items.append(f'[a |-> "{r["action"]}", m |-> {tla.to_tla(mrec)}, now |-> {now}, ch |-> {chs}]')
    behs = "{" + ", ".join(tla.to_tla(b) for b in _behaviour_names(recs, c.get("Behaviours"))) + "}"
    return f"""---- MODULE {name} ----
EXTENDS Naturals, Sequences, FiniteSets, TLC
VARIABLES ms, cursor, clock, sent, failed
TDrop == {int(c["TDrop"])}
M == INSTANCE MasterLogic WITH TDrop <- TDrop, MaxResends <- {int(c["MaxResends"])},
       ExactMsgids <- TRUE, BUG <- "none"
TResend == {int(c["TResend"])}
Behs == {behs}
Trace == <<
  {(","+chr(10)+"  ").join(items)}
>>
Vars == {{"reg", "nextId", "msgid"}}
Val(v, s) == IF v = "msgid" THEN s.msgid[0] ELSE s[v]
\\* The record's changed variables have its values; the others are as before the action.
Fits(r, before, after) ==
    \\A v \\in Vars : IF v \\in DOMAIN r.ch THEN Val(v, after) = r.ch[v] ELSE after[v] = before[v]
Eps(r) == {{x.ep : x \\in ms.reg}} \\cup (IF "reg" \\in DOMAIN r.ch THEN {{x.ep : x \\in r.ch.reg}} ELSE {{}})
Cmds == {{M!Cmd(t, M!NoBehaviour) : t \\in {tla.to_tla(set(COMMANDS) - {"BEHAVIOUR"})}}}
        \\cup {{M!Cmd("BEHAVIOUR", b) : b \\in Behs}}
Ids(s) == {{x.id : x \\in s.reg}}
EntryOf(s, i) == CHOOSE x \\in s.reg : x.id = i
\\* Time passes k ms with nothing due: every entry's quiet grows by k.
Age(s, k) == [s EXCEPT !.reg = {{[x EXCEPT !.quiet = x.quiet + k] : x \\in s.reg}}]
\\* The entries due at time t >= clock: quiet reaches TDrop, or the pending datagram was sent
\\* TResend ms ago (sent: the check's own record of when, see NewSent).
DueAt(y, t) == y.quiet + (t - clock) >= TDrop \\/ (y.pending /\\ t - sent[y.id] >= TResend)
Due(t) == {{y.id : y \\in {{x \\in ms.reg : DueAt(x, t)}}}}
\\* When each entry's pending datagram was last sent, after a step at time t that produced s2:
\\* now if its msgid was drawn in the step (new entry, next command, resync) or a tick resent it
\\* (ids D), else as before (a re-announcement resends it without moving its deadline).
NewSent(s2, D, t) ==
    [i \\in Ids(s2) |-> IF i \\in D \\/ ~\\E y \\in ms.reg : y.id = i /\\ y.pending /\\ y.mid = EntryOf(s2, i).mid
                       THEN t ELSE sent[i]]
\\* The operator's command: MasterCommand for one id (or an unknown one: 1), or for every
\\* registered id in id order (the console's `all`: one core call, one record).
RECURSIVE ForAll(_, _, _)
ForAll(s, ids, c) ==
    IF ids = {{}} THEN s
    ELSE LET i == CHOOSE i \\in ids : \\A j \\in ids : i <= j
         IN ForAll(M!MasterCommand(s, i, c).ms, ids \\ {{i}}, c)
CmdResults(s) == {{M!MasterCommand(s, id, c).ms : id \\in Ids(s) \\cup {{1}}, c \\in Cmds}}
                 \\cup {{ForAll(s, Ids(s), c) : c \\in Cmds}}
Init == /\\ ms = [reg |-> {{}}, nextId |-> {int(c["NextId"])}, msgid |-> [k \\in {{0}} |-> {int(c["FirstMsgid"])}]]
        /\\ cursor = 1 /\\ clock = 0 /\\ sent = [i \\in {{}} |-> 0] /\\ failed = 0
Match ==
    /\\ failed = 0 /\\ cursor <= Len(Trace)
    /\\ LET r == Trace[cursor]
           t == r.now
       IN /\\ IF r.a = "MasterTick" THEN
                \\* the first ms anything is due: the spec's per-entry tick for the due entries
                /\\ t > clock /\\ Due(t - 1) = {{}} /\\ Due(t) # {{}}
                /\\ LET D == Due(t)
                       s1 == Age(ms, t - 1 - clock)
                       tk == M!TickEntries(s1, D, {{}})
                       s2 == [tk.ms EXCEPT !.reg = {{IF x.id \\in D THEN x ELSE [x EXCEPT !.quiet = x.quiet + 1]
                                                     : x \\in tk.ms.reg}}]
                   IN /\\ Fits(r, s1, s2) /\\ ms' = s2 /\\ sent' = NewSent(s2, D, t)
             ELSE
                /\\ t >= clock /\\ Due(t) = {{}}
                /\\ LET s1 == Age(ms, t - clock) IN
                   IF r.a = "MasterCommand" THEN
                      \\E s2 \\in CmdResults(s1) :
                         /\\ Fits(r, s1, s2) /\\ ms' = s2 /\\ sent' = NewSent(s2, {{}}, t)
                   ELSE
                      /\\ r.a \\in {tla.to_tla(set(MASTER_RECV))} /\\ M!Handler(r.m) = r.a
                      /\\ \\E from \\in Eps(r) \\cup {{0}} :
                            LET s2 == M!Receive(s1, r.m, from).ms IN
                            /\\ Fits(r, s1, s2) /\\ ms' = s2 /\\ sent' = NewSent(s2, {{}}, t)
          /\\ clock' = t
    /\\ cursor' = cursor + 1
    /\\ UNCHANGED failed
Stuck == failed = 0 /\\ cursor <= Len(Trace) /\\ ~ENABLED Match
         /\\ failed' = cursor /\\ UNCHANGED <<ms, cursor, clock, sent>>
Next == Match \\/ Stuck
Matched == cursor <= Len(Trace)
NotStuck == failed = 0
====
"""


def validate_master(path: Path, consts: dict, workdir: Path | None = None, node: str | None = None) -> Result:
    """A master trace against MasterLogic (exact msgids): `ev3-master --driver --trace` (TResend 1,
    the default) or the real program's `--trace` over UDP (TResend = its --resend-ms). consts: TDrop
    (--agent-timeout-ms / the driver's drop), TResend, MaxResends, Behaviours, NextId, FirstMsgid.
    A trace of `ev3-master --election` (Election.tla records, or consts Election = True) is checked by
    MasterLogic + Election.tla's PC rules (master_election_module; consts Epoch, Members, Life: the
    state the master starts from); Election = False forces MasterLogic alone."""
    path = Path(path)
    if node is None:  # the master program's records (an agent-master's are named master:ID:EPOCH)
        recs = [r for r in load(path, None) if r.get("node", "").startswith("master") and ":" not in r.get("node", "")]
    else:
        recs = [r for r in load(path, None) if r.get("node", "") == node]
    if not recs:
        return Result(str(path), True, 0, "no master records; nothing to check", skipped=True)
    wd = Path(workdir or (gr.BUILD / "traces"))
    wd.mkdir(parents=True, exist_ok=True)
    d = Path(tempfile.mkdtemp(prefix="mtrace-", dir=wd))
    election = consts.get("Election")
    if election is None:
        election = is_master_election_trace(recs)
    if election:
        name, what, tag = "MasterElectionTraceCheck", "MasterLogic + Election (the PC's rules)", ", election"
        (d / f"{name}.tla").write_text(master_election_module(name, recs, consts))
        specs = ("MasterLogic.tla", "Messages.tla", "Election.tla")
    else:
        name, what, tag = "MasterTraceCheck", "MasterLogic", ""
        (d / f"{name}.tla").write_text(master_module(name, recs, consts))
        specs = ("MasterLogic.tla", "Messages.tla")
    (d / f"{name}.cfg").write_text("INIT Init\nNEXT Next\nINVARIANTS Matched NotStuck\nCHECK_DEADLOCK FALSE\n")
    for f in specs:
        (d / f).write_text((gr.SPEC / f).read_text())
    rc, out = gr.tlc(f"{name}.tla", f"{name}.cfg", [], cwd=d)
    if rc == 12 and "Invariant Matched is violated" in out:
        return Result(str(path), True, len(recs), f"{len(recs)} master records matched{tag}")
    if rc == 12 and "Invariant NotStuck is violated" in out:
        fails = re.findall(r"failed = (\d+)", out)
        k = int(fails[-1]) - 1 if fails else -1
        why = ""
        if not election and 0 <= k < len(recs) and recs[k].get("action") in ELECTION_MASTER_ACTIONS:
            why = " (an Election.tla action: run without --no-election)"
        return Result(str(path), False, len(recs),
                      f"record {k + 1} of {len(recs)} could not be matched by {what}{why} "
                      f"(module kept in {d}):\n{_describe_record(recs, k)}")
    return Result(str(path), False, len(recs), f"TLC failed (exit {rc}); module in {d}:\n{out[-2500:]}")


# --- agents with --election (Election.tla + AgentLogic) ------------------------------------------
#
# A per-agent projection (docs/spec.md "Election traces"). The agent's own Election variables (life,
# epoch, votedFor, votes, leader, following, via, relays, offered, prevotes) are checked with
# Election.tla's own per-node operators (XOk: the enabling condition on the node's own state, XNext:
# its new local state); the environment (links, the network, the other nodes) is not observed, so
# its guards are taken as satisfiable and a received datagram is the record's. The lifecycle
# variables are checked with AgentLogic as for any agent; the two compose as docs/election.md
# section 5 maps them (life CANDIDATE / MASTER = state PANIC; the followed master is AgentLogic's
# MasterId).

ELECTION_ACTIONS = {"RequestRelay", "OfferRelay", "HandleAccept", "AcceptRelay", "RelayDropped",
                    "GrantPreVote", "HandlePreVote", "StartElection", "HandleElect", "HandleVote",
                    "BecomeMaster", "HandleHeartbeat", "HandleStale", "Forward", "ApplyCommand"}
ELECTION_VARS = ["life", "epoch", "votedFor", "votes", "leader", "following", "via", "relays", "offered",
                 "prevotes"]
_EL_TYPES = {"RELAY_REQ": "RREQ", "RELAY_OFFER": "ROFFER", "RELAY_ACCEPT": "RACCEPT", "RELAY_ROUTE": "ROUTE",
             "RELAY": "RELAY", "RELAY_DROP": "RDROP", "ELECT": "ELECT", "VOTE": "VOTE", "LEADER": "HB",
             "EPOCH_STALE": "STALE", "EPOCH_CMD": "CMD", "HANDOVER": "HANDOVER", "PREVOTE_OK": "PREOK"}
_NONE_MSG = {"src": 0, "dst": 0, "msgid": 0, "type": "NONE", "ref": 0, "args": ()}
_NONE_EL = {"t": "NONE", "src": 0, "dst": 0, "e": 0, "x": 0, "sc": 0, "tgt": 0}
# The largest number TLC's integers hold: the epoch bound of the check (MaxEpoch).
_TLC_MAXINT = 2147483647


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
    d = {"t": t, "src": m.sender, "dst": m.receiver, "e": 0, "x": 0, "sc": 0, "tgt": 0}
    inner, members = None, []
    if t == "RELAY":
        d["tgt"] = _num(ps, 0)
    else:
        d["e"] = _num(ps, 0)
    if t in ("RREQ", "ELECT"):
        d["sc"] = _num(ps, 1)
    if t in ("ROFFER", "RACCEPT"):
        d["x"] = _num(ps, 1)
    if t == "HB":
        members = [_num(ps, i) for i in range(2, len(ps))]
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


def election_module(name: str, recs: list[dict], consts: dict, temp_id: int) -> str:
    """ElectionTraceCheck: one TLC step per record; variables ag (AgentLogic's local state) and el (the
    agent's Election variables, Election.tla's Loc record). consts: the timers as for agent_module, and
    Score (the agent's --score; None: unknown, both outcomes of a score comparison are allowed), Epoch and
    VotedFor (what the agent started with from its --state-dir; 1 and 0)."""
    items = []
    fleet: set[int] = set()
    for r in recs:
        ch = dict(r.get("changed", {}))
        ch.pop("dupActed", None)
        lch = {k: v for k, v in ch.items() if k in AGENT_VARS}
        if "win" in lch:
            lch["win"] = _win(lch["win"])
        ech = _el_changed(ch)
        a = r["action"]
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
        chs = tla.to_tla(lch) if lch else "[x \\in {} |-> 0]"
        echs = tla.to_tla(ech) if ech else "[x \\in {} |-> 0]"
        items.append(f'[a |-> "{a}", m |-> {tla.to_tla(m)}, em |-> {tla.to_tla(em)}, im |-> {tla.to_tla(im)},'
                     f' cmd |-> {tla.to_tla(args.get("cmd", "Ignore"))}, e |-> {tla.to_tla(args.get("e", ""))},'
                     f' n |-> {int(args.get("ticks", 1))}, ch |-> {chs}, ech |-> {echs}]')
    c = consts
    behs = "{" + ", ".join(tla.to_tla(b) for b in c["Behaviours"]) + "}"
    score = c.get("Score")
    scores = "{%d}" % int(score) if score is not None else "{0, %d}" % _TLC_MAXINT
    apply = "\n      [] ".join(f'h = "{h}" -> L!{h}(a, m)' for h in RECV)
    epoch0, voted0 = int(c.get("Epoch", 1) or 1), int(c.get("VotedFor", 0) or 0)
    return f"""---- MODULE {name} ----
EXTENDS Naturals, Sequences, FiniteSets, TLC
VARIABLES ag, el, cursor, failed
L == INSTANCE AgentLogic WITH Behaviours <- {behs}, UnknownBehaviour <- "?unknown",
       ModelName <- {tla.to_tla(c["ModelName"])}, TSync <- {c["TSync"]}, TPing <- {c["TPing"]},
       TLoss <- {c["TLoss"]}, TPaused <- {c["TPaused"]}, Window <- {c["Window"]},
       Steps <- {c["Steps"]}, BUG <- "none"
\\* The fleet: the members the LEADERs in the trace list (quorums count against it).
Fleet == {tla.to_tla(set(fleet)) if fleet else "{}"}
\\* Only Election's per-node operators are used: its variables are never read.
E == INSTANCE Election WITH Agents <- Fleet, Score <- [n \\in {{}} |-> 0], MaxEpoch <- {_TLC_MAXINT},
       MaxFaults <- 0, Crashes <- FALSE, PCCrash <- FALSE, PCReturns <- FALSE, Partitions <- FALSE,
       MaxLoss <- 0, SpuriousTimeout <- FALSE, CmdAgents <- {{}}, PreVote <- TRUE, BUG <- "None",
       life <- {{}}, epoch <- {{}}, votedFor <- {{}}, votes <- {{}}, leader <- {{}}, following <- {{}},
       via <- {{}}, relays <- {{}}, offered <- {{}}, prevotes <- {{}}, net <- {{}}, down <- {{}}, faults <- 0,
       lost <- 0, elected <- {{}}, applied <- {{}}, lastAction <- <<>>
\\* The agent's own score (its --score), or both outcomes of every comparison when unknown.
MyScores == {scores}
Trace == <<
  {(","+chr(10)+"  ").join(items)}
>>
Vars == {tla.to_tla(set(AGENT_VARS))}
ElVars == {tla.to_tla(set(ELECTION_VARS))}
Fits(r, before, after) ==
    \\A v \\in Vars : IF v \\in DOMAIN r.ch THEN after[v] = r.ch[v] ELSE after[v] = before[v]
\\* votes is compared while the agent is a candidate: the core clears it when the candidacy ends
\\* (BecomeMaster, a LEADER heard), Election.tla keeps the last set, read only by a CANDIDATE.
FitsEl(r, before, after) ==
    \\A v \\in ElVars :
        IF v = "votes" /\\ after.life # "CANDIDATE" THEN TRUE
        ELSE IF v \\in DOMAIN r.ech THEN after[v] = r.ech[v] ELSE after[v] = before[v]
{_agent_steps(c["TPing"], apply)}
\\* --- composition (docs/spec.md "Election traces") ---
\\* life CANDIDATE / MASTER are the lifecycle's PANIC; otherwise life is the lifecycle state.
StateOf(life) == IF life \\in {{"CANDIDATE", "MASTER"}} THEN "PANIC" ELSE life
LifeOf(st, old) == IF old \\in {{"CANDIDATE", "MASTER"}} /\\ st = "PANIC" THEN old ELSE st
\\* AgentLogic's master is MasterId; the agent follows master c (el.leader, else the PC; the sender of an
\\* EPOCH_CMD): the lifecycle sees c as MasterId and MasterId as c (a swap: dedupe keys stay distinct).
Cur(s) == IF s.leader # 0 THEN s.leader ELSE L!MasterId
Swap(x, c) == IF x = c THEN L!MasterId ELSE IF x = L!MasterId THEN c ELSE x
SwapMsg(m, c) == [m EXCEPT !.src = Swap(@, c)]
SwapAg(a, c) == [a EXCEPT !.win = [i \\in 1..Len(a.win) |-> [a.win[i] EXCEPT !.src = Swap(@, c)]]]
Handled(a, m, c) == L!Handler(SwapAg(a, c), SwapMsg(m, c))
Received(h, a, m, c) == SwapAg(Recv(h, SwapAg(a, c), SwapMsg(m, c)).ag, c)
\\* A bare command or MASTER counts as epoch 1: past epoch 1 it is fenced (ignored, EPOCH_STALE).
BareFenced(s, a, m) == s.epoch > 1 /\\ L!Answered(m) /\\ L!AddressedTo(a, m)
\\* The lifecycle after Election step s -> s2 of agent a: the state follows life; a WORKING agent paused
\\* (master changed, newer epoch) stops its motors; PANIC -> ACTIVE (a LEADER, a relay taken) restarts the
\\* periodic phase; -> PANIC (RELAY_DROP) is HeartbeatLost's; hearing a master resets the silence.
Follow(a, s2, heard) ==
    LET st == StateOf(s2.life)
        b == CASE st = a.state -> a
               [] st = "PAUSED" /\\ a.state = "WORKING" -> [L!Goto(a, "PAUSED") EXCEPT !.motors = "OFF"]
               [] st = "ACTIVE" /\\ a.state = "PANIC" -> [L!Goto(a, "ACTIVE") EXCEPT !.clk = 0]
               [] st = "PANIC" -> [L!Goto(L!Stopped(a), "PANIC") EXCEPT !.silence = 0, !.clk = 0]
               [] OTHER -> [a EXCEPT !.state = "none"]
    IN IF heard THEN [b EXCEPT !.silence = 0] ELSE b
\\* RELAY's x: the relayed agent (the target, or the sender when it goes to the master).
FwdMsg(m, s) == IF m.tgt = s.leader THEN [m EXCEPT !.x = m.src] ELSE [m EXCEPT !.x = m.tgt]
\\* The agent's Election step for record r from s (its id me, its score sv): the set of new local
\\* states, empty when the action is not enabled on the agent's own state.
IfOk(ok, s2) == IF ok THEN {{s2}} ELSE {{}}
ElSteps(r, s, me, sv) ==
    LET m == r.em IN
    CASE r.a = "RequestRelay" -> IfOk(E!RequestRelayOk(s), s)
      [] r.a = "StartElection" -> IfOk(E!StartElectionOk(me, s), E!StartElectionNext(me, s))
      [] r.a = "BecomeMaster" -> IfOk(E!BecomeMasterOk(s), E!BecomeMasterNext(s))
      [] r.a = "GrantPreVote" -> IfOk(E!GrantPreVoteOk(me, s, m, m.sc, sv), s)
      [] r.a = "Forward" -> IfOk(E!ForwardOk(me, s, FwdMsg(m, s)), s)
      [] r.a = "OfferRelay" -> {{IF E!OfferRelayOk(me, s, m) THEN E!OfferRelayNext(s, m) ELSE s}}
      [] r.a = "HandleAccept" -> {{IF E!HandleAcceptOk(me, s, m) THEN E!HandleAcceptNext(s, m) ELSE s}}
      [] r.a = "AcceptRelay" -> {{IF E!AcceptRelayOk(me, s, m) THEN E!AcceptRelayNext(s, m) ELSE s}}
      [] r.a = "RelayDropped" -> {{IF E!RelayDroppedOk(me, s, m) THEN E!RelayDroppedNext(s) ELSE s}}
      [] r.a = "HandlePreVote" -> {{IF E!HandlePreVoteOk(me, s, m) THEN E!HandlePreVoteNext(s, m) ELSE s}}
      [] r.a = "HandleElect" ->
           {{IF E!HandleElectOk(me, s, m, m.sc, sv) THEN E!HandleElectNext(me, s, m, m.sc, sv) ELSE s}}
      [] r.a = "HandleVote" -> {{IF E!HandleVoteOk(me, s, m) THEN E!HandleVoteNext(s, m) ELSE s}}
      [] r.a = "HandleHeartbeat" ->
           {{IF E!HandleHeartbeatOk(me, s, m) THEN E!HandleHeartbeatNext(s, m) ELSE s}}
      [] r.a = "HandleStale" -> {{IF E!HandleStaleOk(me, s, m) THEN E!HandleStaleNext(me, s, m) ELSE s}}
      [] OTHER -> {{}}
\\* Following master c in epoch e after a MASTER (bare: the PC, epoch 1; inside EPOCH_CMD: its sender
\\* and epoch): Election's rule for hearing c's heartbeat; the lifecycle gives the state.
Synced(s, c, e, st) == [E!HandleHeartbeatNext(s, E!M("HB", c, 0, e, 0)) EXCEPT !.life = LifeOf(st, s.life)]
InitEl == [life |-> "IDLE", epoch |-> {epoch0}, votedFor |-> {voted0}, votes |-> {{}}, leader |-> 0,
           following |-> 0, via |-> 0, relays |-> {{}}, offered |-> {{}}, prevotes |-> {{}}]
Init == /\\ ag = L!InitAgent({temp_id}) /\\ el = InitEl /\\ cursor = 1 /\\ failed = 0
Step(r, a2, s2) == /\\ Fits(r, ag, a2) /\\ FitsEl(r, el, s2) /\\ ag' = a2 /\\ el' = s2
Match ==
    /\\ failed = 0 /\\ cursor <= Len(Trace)
    /\\ LET r == Trace[cursor] IN
       IF r.a = "Tick" THEN
          /\\ L!TickOk(ag) /\\ L!TickOk(Adv(ag, r.n - 1))
          /\\ Step(r, L!Tick(Adv(ag, r.n - 1)).ag, el)
       ELSE IF r.a = "ApplyCommand" THEN
          \\* EPOCH_CMD of master c in epoch e: the inner datagram goes to AgentLogic's handler r.cmd
          \\* (c seen as the master); a MASTER syncs a masterless agent in e, anything else passes the
          \\* fence (Election's Obeys: c is the master it follows in e, its highest epoch).
          LET c == r.em.src
              a2 == Received(r.cmd, ag, r.im, c)
          IN /\\ ag.state # "OFF" /\\ r.em.t = "CMD" /\\ r.im.type # "NONE" /\\ r.im.src = c
             /\\ Handled(ag, r.im, c) = r.cmd
             /\\ IF r.im.type = "MASTER"
                THEN /\\ r.em.e >= el.epoch
                     /\\ Step(r, a2, IF r.cmd = "RecvMaster" THEN Synced(el, c, r.em.e, a2.state) ELSE el)
                ELSE /\\ E!Obeys(el, r.em)
                     /\\ Step(r, a2, [el EXCEPT !.life = LifeOf(a2.state, el.life)])
       ELSE IF r.a \\in {tla.to_tla(ELECTION_ACTIONS)} THEN
          \\* An Election action: its rule on the agent's own state (environment guards satisfiable). A
          \\* receive handler not enabled on the agent's own state must be a stutter (the core answering
          \\* a copy again: a VOTE re-sent, a LEADER of the master it follows).
          \\E sv \\in MyScores : \\E s2 \\in ElSteps(r, el, ag.id, sv) :
             Step(r, Follow(ag, s2, r.a \\in {{"HandleHeartbeat", "AcceptRelay"}} /\\ r.em.e >= el.epoch), s2)
       ELSE IF r.em.t # "NONE" THEN
          \\* an Election datagram no Election handler took: the environment's guards may all fail
          /\\ r.a = "Ignore" /\\ Step(r, ag, el)
       ELSE IF r.m.type # "NONE" THEN
          /\\ ag.state # "OFF"
          /\\ IF BareFenced(el, ag, r.m)
             THEN r.a = "Ignore" /\\ Step(r, ag, el)
             ELSE /\\ Handled(ag, r.m, Cur(el)) = r.a
                  /\\ LET a2 == Received(r.a, ag, r.m, Cur(el)) IN
                     Step(r, a2, IF r.a = "RecvMaster" THEN Synced(el, Cur(el), 1, a2.state)
                                 ELSE [el EXCEPT !.life = LifeOf(a2.state, el.life)])
       ELSE
          /\\ IntOk(r, ag)
          /\\ LET a2 == Internal(r, ag).ag IN
             IF r.a = "HeartbeatLost"
             THEN E!TimeoutOk(el) /\\ Step(r, a2, E!TimeoutNext(el))
             ELSE Step(r, a2, [el EXCEPT !.life = LifeOf(a2.state, el.life)])
    /\\ cursor' = cursor + 1
    /\\ UNCHANGED failed
Stuck == failed = 0 /\\ cursor <= Len(Trace) /\\ ~ENABLED Match
         /\\ failed' = cursor /\\ UNCHANGED <<ag, el, cursor>>
Next == Match \\/ Stuck
Matched == cursor <= Len(Trace)
NotStuck == failed = 0
====
"""


# --- the master with --election (MasterLogic + Election.tla's PC rules) ------------------------
#
# `ev3-master --election` writes, besides MasterLogic's records, Election.tla records of the PC (node
# 1 in Election.tla; its own variables life, epoch, votes) and two master-side extensions. The check
# (module MasterElectionTraceCheck, docs/spec.md "Election master traces") keeps MasterLogic's state
# `ms` with the time map above, the PC's Election record `el` (Election.tla's Loc: life, epoch, votes;
# the agent-only fields NoNode / {}) and the membership `mem` quorums count against; one TLC step per
# record:
#   - MasterLogic's records (MasterSync, MasterAnswer, MasterPing, MasterReport) only while MASTER (the
#     core ignores the fleet's datagrams otherwise), after the master's route bookkeeping (the core's
#     note_route, not in MasterLogic: the sender's entry moves to the endpoint it was heard from; a
#     member that PINGs unregistered is adopted as synced with desired UNKNOWN; a member syncing
#     that PINGs is synced): a datagram inside RELAY(1, inner) is the inner one (the relay is
#     transparent). MasterCommand and MasterTick as MasterLogic; the registry ticks only while MASTER.
#   - Election.tla's PC rules by its own operators: StartElection (XOk / XNext of node 1), HandleVote
#     (from a member), BecomeMaster (Quorum over `mem`), HandleStale; Heartbeat's guard (life MASTER:
#     Election has no HeartbeatOk operator). HandleHeartbeat of the PC (docs/core.md deviation 4): an
#     older LEADER is answered EPOCH_STALE (state unchanged, Election's Stale branch), a newer one is
#     HandleStale's rule with the LEADER's epoch. HandleElect: the PC ignores ELECT (Election has no
#     HandleElect of the PC): rejected. Every datagram the core sends draws a msgid (LEADER, ELECT,
#     EPOCH_STALE): `msgid` grows by one on Heartbeat, StartElection, BecomeMaster and an answered
#     older LEADER. (Self: node 1; the Master core of an elected agent is checked as its node, see
#     agent_master_runs at the end: HandleElect / HandleHeartbeat / HandleStale are then Election's
#     rules of that agent node, the trace's STEPPED_DOWN any life but MASTER, HANDOVER sent once.)
#   - The core's time: Heartbeat and StartElection come from its deadlines like MasterTick (nothing of
#     the registry due before their ms; at the same ms the heartbeat goes first). Operator arguments
#     are bound once (\E x \in {e}): TLC passes them by name and re-evaluates them at every use.
#   - Extensions Election abstracts (docs/election.md section 5): MasterRoute (RELAY_ROUTE(epoch, a):
#     only as MASTER of that epoch, for an entry or a member; the entry moves to the relay's endpoint
#     or a member is adopted), MasterHandover (HANDOVER(epoch, ids): only as MASTER, epoch not above
#     ours; its assigned ids join `mem`, nothing else changes).
#   - Not observed: what the master sends (as for MasterLogic): EPOCH_CMD and RELAY wrapping of its
#     commands (checked at the agents: ApplyCommand's fence), LEADER's membership; the election's
#     timers (leader heartbeat, candidate timeout: Election.tla has no time); the `via` of an entry.

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


def master_election_module(name: str, recs: list[dict], consts: dict) -> str:
    """MasterElectionTraceCheck (see above). consts: as master_module, and Epoch, Members (the epoch
    and membership the master starts from: its --state-file, else 1 and none) and Life ("CANDIDATE"
    when restarted from a state file: Election's Restart(PC); else "MASTER")."""
    c, base = _master_consts(consts, recs)
    items = []
    for r in recs:
        ch = r.get("changed", {})
        parts, eparts = _master_changed_parts(ch), []
        if "life" in ch:
            eparts.append(f"life |-> {tla.to_tla(ch['life'])}")
        if "epoch" in ch:
            eparts.append(f"epoch |-> {int(ch['epoch'])}")
        if "votes" in ch:
            eparts.append(f"votes |-> {tla.to_tla(frozenset(int(v) for v in ch['votes']))}")
        text = r.get("args", {}).get("msg")
        m, em, ids = dict(_NONE_MSG), dict(_NONE_EL), []
        if text:
            m, em, ids, _relayed = _master_el_msg(text)
            if m["dst"] == int(c.get("Self", 1) or 1):
                m["dst"] = 1  # an agent-master: MasterLogic's master is MasterId
        chs = "[" + ", ".join(parts) + "]" if parts else "[x \\in {} |-> 0]"
        echs = "[" + ", ".join(eparts) + "]" if eparts else "[x \\in {} |-> 0]"
        now = int(r.get("now", 0)) - base
        items.append(f'[a |-> "{r["action"]}", m |-> {tla.to_tla(m)}, em |-> {tla.to_tla(em)}, '
                     f'ids |-> {tla.to_tla(frozenset(ids))}, now |-> {now}, ch |-> {chs}, ech |-> {echs}]')
    behs = "{" + ", ".join(tla.to_tla(b) for b in _behaviour_names(recs, c.get("Behaviours"))) + "}"
    members = frozenset(int(x) for x in (c.get("Members") or []))
    # Election's Agents is a constant: one instance per membership the trace can reach (the start's,
    # grown by each HANDOVER's assigned ids); BecomeMasterOk picks the one equal to `mem`.
    fleets, cur = [members], set(members)
    for r in recs:
        if r.get("action") == "MasterHandover" and r.get("args", {}).get("msg"):
            try:
                _m, _em, ids, _rl = _master_el_msg(r["args"]["msg"])
            except wire.DecodeError:
                continue
            cur |= {i for i in ids if 2 <= i <= 49999}
            if frozenset(cur) not in fleets:
                fleets.append(frozenset(cur))
    quorum = "\n      [] ".join(f"mem = {tla.to_tla(f) if f else '{}'} -> E({tla.to_tla(f) if f else '{}'})!BecomeMasterOk(s)"
                                 for f in fleets)
    life0 = str(c.get("Life") or "MASTER")
    self_id = int(c.get("Self", 1) or 1)
    epoch0 = int(c.get("Epoch", 1) or 1)
    return f"""---- MODULE {name} ----
EXTENDS Integers, Sequences, FiniteSets, TLC
VARIABLES ms, el, mem, handed, cursor, clock, sent, failed
TDrop == {int(c["TDrop"])}
M == INSTANCE MasterLogic WITH TDrop <- TDrop, MaxResends <- {int(c["MaxResends"])},
       ExactMsgids <- TRUE, BUG <- "none"
\\* Election.tla's per-node operators for a fleet F (the membership: quorums count against it); its
\\* variables are never read.
\\* (Election's Agents is a constant: one instance per membership, see QuorumOk.)
E(F) == INSTANCE Election WITH Agents <- F, Score <- [n \\in {{}} |-> 0], MaxEpoch <- {_TLC_MAXINT},
       MaxFaults <- 0, Crashes <- FALSE, PCCrash <- FALSE, PCReturns <- FALSE, Partitions <- FALSE,
       MaxLoss <- 0, SpuriousTimeout <- FALSE, CmdAgents <- {{}}, PreVote <- TRUE, BUG <- "None",
       life <- {{}}, epoch <- {{}}, votedFor <- {{}}, votes <- {{}}, leader <- {{}}, following <- {{}},
       via <- {{}}, relays <- {{}}, offered <- {{}}, prevotes <- {{}}, net <- {{}}, down <- {{}}, faults <- 0,
       lost <- 0, elected <- {{}}, applied <- {{}}, lastAction <- <<>>
PC == 1
\\* The master's node: the PC, or the elected agent whose Master core wrote the trace.
Self == {self_id}
\\* The trace's life: the PC's Election life; an agent-master's Master core knows MASTER and STEPPED_DOWN
\\* (any other Election life of the node: its agent core carries the node's lifecycle).
View(l) == IF Self = PC \\/ l \\in {{"MASTER", "CANDIDATE"}} THEN l ELSE "STEPPED_DOWN"
TResend == {int(c["TResend"])}
Behs == {behs}
Trace == <<
  {(","+chr(10)+"  ").join(items)}
>>
Vars == {{"reg", "nextId", "msgid"}}
ElVars == {{"life", "epoch", "votes"}}
Val(v, s) == IF v = "msgid" THEN s.msgid[0] ELSE s[v]
Fits(r, before, after) ==
    \\A v \\in Vars : IF v \\in DOMAIN r.ch THEN Val(v, after) = r.ch[v] ELSE after[v] = before[v]
FitsEl(r, before, after) ==
    \\A v \\in ElVars :
        IF v = "life" THEN View(after.life) = IF v \\in DOMAIN r.ech THEN r.ech.life ELSE View(before.life)
        ELSE IF v \\in DOMAIN r.ech THEN after[v] = r.ech[v] ELSE after[v] = before[v]
Eps(r) == {{x.ep : x \\in ms.reg}} \\cup (IF "reg" \\in DOMAIN r.ch THEN {{x.ep : x \\in r.ch.reg}} ELSE {{}})
Cmds == {{M!Cmd(t, M!NoBehaviour) : t \\in {tla.to_tla(set(COMMANDS) - {"BEHAVIOUR"})}}}
        \\cup {{M!Cmd("BEHAVIOUR", b) : b \\in Behs}}
Ids(s) == {{x.id : x \\in s.reg}}
EntryOf(s, i) == CHOOSE x \\in s.reg : x.id = i
Age(s, k) == [s EXCEPT !.reg = {{[x EXCEPT !.quiet = x.quiet + k] : x \\in s.reg}}]
\\* The registry's deadlines (MasterLogic's tick, time map above) run only while the PC is MASTER.
DueAt(y, t) == y.quiet + (t - clock) >= TDrop \\/ (y.pending /\\ t - sent[y.id] >= TResend)
Due(t) == IF el.life = "MASTER" THEN {{y.id : y \\in {{x \\in ms.reg : DueAt(x, t)}}}} ELSE {{}}
NewSent(s2, D, t) ==
    [i \\in Ids(s2) |-> IF i \\in D \\/ ~\\E y \\in ms.reg : y.id = i /\\ y.pending /\\ y.mid = EntryOf(s2, i).mid
                       THEN t ELSE sent[i]]
\\* The console's `all` (one core call, one record): MasterCommand for every registered id in id order
\\* leads from s to s2. (A predicate with each intermediate state bound by \\E: TLC passes operator
\\* arguments by name, and a recursive operator returning the state re-evaluates them exponentially.)
RECURSIVE ForAllLeads(_, _, _, _)
ForAllLeads(s, ids, c, s2) ==
    IF ids = {{}} THEN s = s2
    ELSE \\E i \\in {{CHOOSE i \\in ids : \\A j \\in ids : i <= j}} :
         \\E s1 \\in {{M!MasterCommand(s, i, c).ms}} : ForAllLeads(s1, ids \\ {{i}}, c, s2)
CmdResults(s) == {{M!MasterCommand(s, id, c).ms : id \\in Ids(s) \\cup {{1}}, c \\in Cmds}}
\\* The state a MasterCommand record claims (its changed variables over s).
Claimed(r, s) == [reg |-> IF "reg" \\in DOMAIN r.ch THEN r.ch.reg ELSE s.reg,
                  nextId |-> IF "nextId" \\in DOMAIN r.ch THEN r.ch.nextId ELSE s.nextId,
                  msgid |-> [k \\in {{0}} |-> IF "msgid" \\in DOMAIN r.ch THEN r.ch.msgid ELSE s.msgid[0]]]
\\* A datagram the election side sends (LEADER, ELECT, EPOCH_STALE) draws a msgid.
Drawn(s) == [s EXCEPT !.msgid[0] = @ + 1]
\\* --- master-side extensions (not in MasterLogic; Election abstracts them) ---
\\* A member registered without MASTER (it follows our LEADER): synced, desired unknown.
Adopted(i, from) == [ann |-> i, id |-> i, ep |-> from, synced |-> TRUE, pending |-> FALSE, mid |-> 0,
                     resends |-> 0, queue |-> <<>>, desired |-> M!UnknownDesired, beh |-> M!NoBehaviour,
                     quiet |-> 0, hi |-> 0]
\\* Where a fleet datagram came from (the core's note_route, before MasterLogic's handler).
Route(s, m, from) ==
    IF m.src \\in Ids(s) THEN
       LET x == EntryOf(s, m.src)
           y == [x EXCEPT !.ep = from]
       IN IF m.type = "PING" /\\ ~x.synced /\\ m.src \\in mem
          THEN LET r == M!StartNext(s, [y EXCEPT !.synced = TRUE, !.pending = FALSE])
               IN M!Replace(r.ms, x, r.x)
          ELSE M!Replace(s, x, y)
    ELSE IF m.type = "PING" /\\ m.src \\in mem THEN [s EXCEPT !.reg = @ \\cup {{Adopted(m.src, from)}}]
    ELSE s
\\* RELAY_ROUTE(e, a) from a relay heard at endpoint from: a is reached there.
RouteTo(s, a, from) ==
    IF a \\in Ids(s) THEN M!Replace(s, EntryOf(s, a), [EntryOf(s, a) EXCEPT !.ep = from])
    ELSE [s EXCEPT !.reg = @ \\cup {{Adopted(a, from)}}]
AssignedIds == 2..49999
\\* Election's BecomeMasterOk (a majority of the membership voted) over the membership mem.
QuorumOk(s) ==
    CASE {quorum}
      [] OTHER -> FALSE
\\* The rules that do not read the membership.
EP == INSTANCE Election WITH Agents <- {tla.to_tla(members) if members else "{}"}, Score <- [n \\in {{}} |-> 0],
       MaxEpoch <- {_TLC_MAXINT}, MaxFaults <- 0, Crashes <- FALSE, PCCrash <- FALSE, PCReturns <- FALSE,
       Partitions <- FALSE, MaxLoss <- 0, SpuriousTimeout <- FALSE, CmdAgents <- {{}}, PreVote <- TRUE,
       BUG <- "None", life <- {{}}, epoch <- {{}}, votedFor <- {{}}, votes <- {{}}, leader <- {{}},
       following <- {{}}, via <- {{}}, relays <- {{}}, offered <- {{}}, prevotes <- {{}}, net <- {{}}, down <- {{}},
       faults <- 0, lost <- 0, elected <- {{}}, applied <- {{}}, lastAction <- <<>>
InitEl == [life |-> {tla.to_tla(life0)}, epoch |-> {epoch0}, votes |-> {{}}, votedFor |-> 0, leader |-> 0,
           following |-> 0, via |-> 0, relays |-> {{}}, offered |-> {{}}, prevotes |-> {{}}]
Init == /\\ ms = [reg |-> {{}}, nextId |-> {int(c["NextId"])}, msgid |-> [k \\in {{0}} |-> {int(c["FirstMsgid"])}]]
        /\\ el = InitEl /\\ mem = {tla.to_tla(members) if members else "{}"}
        /\\ handed = FALSE /\\ cursor = 1 /\\ clock = 0 /\\ sent = [i \\in {{}} |-> 0] /\\ failed = 0
\\* One step of the master: registry s2 (before: s0), election state el2, membership mem2. (TLC passes
\\* operator arguments by name: \\E x \\in {{e}} evaluates each once.)
Step(r, s0, s2x, el2x, mem2, D, t) ==
    \\E s2 \\in {{s2x}} : \\E el2 \\in {{el2x}} :
       /\\ Fits(r, s0, s2) /\\ FitsEl(r, el, el2)
       /\\ ms' = s2 /\\ el' = el2 /\\ mem' = mem2 /\\ sent' = NewSent(s2, D, t)
Match ==
    /\\ failed = 0 /\\ cursor <= Len(Trace)
    /\\ \\E r \\in {{Trace[cursor]}} : \\E s0 \\in {{Age(ms, Trace[cursor].now - clock)}} :
       LET t == r.now
           k == t - clock
           em == r.em
       IN /\\ t >= clock
          \\* Heartbeat, StartElection, MasterTick come from the core's deadlines: at the first ms
          \\* anything of the registry is due (Heartbeat first when both are); the rest find nothing due.
          /\\ IF r.a \\in {{"Heartbeat", "StartElection", "MasterTick"}} THEN k > 0 => Due(t - 1) = {{}}
             ELSE Due(t) = {{}}
          /\\ IF r.a = "MasterTick" THEN
                  /\\ Due(t) # {{}}
                  /\\ \\E D \\in {{Due(t)}} :
                     \\E pre \\in {{[s0 EXCEPT !.reg = {{IF x.id \\in D THEN [x EXCEPT !.quiet = @ - 1] ELSE x : x \\in @}}]}} :
                        Step(r, s0, M!TickEntries(pre, D, {{}}).ms, el, mem, D, t)
             ELSE IF r.a = "MasterCommand" THEN
                  \\E s2 \\in CmdResults(s0) \\cup {{Claimed(r, s0)}} :
                     /\\ s2 \\in CmdResults(s0) \\/ \\E c \\in Cmds : ForAllLeads(s0, Ids(s0), c, s2)
                     /\\ Step(r, s0, s2, el, mem, {{}}, t)
             ELSE IF r.a \\in {tla.to_tla(set(MASTER_RECV))} THEN
                  /\\ el.life = "MASTER" /\\ r.m.type # "NONE" /\\ M!Handler(r.m) = r.a
                  /\\ \\E from \\in Eps(r) \\cup {{0}} :
                        \\E s1 \\in {{Route(s0, r.m, from)}} :
                           \\* ids exhausted (an agent-master assigns none): an unknown temporary id is ignored
                           IF r.a = "MasterSync" /\\ M!Known(s1, r.m.src) = {{}} /\\ r.m.src \\notin AssignedIds
                              /\\ s1.nextId > 49999
                           THEN Step(r, s0, s1, el, mem, {{}}, t)
                           ELSE Step(r, s0, M!Receive(s1, r.m, from).ms, el, mem, {{}}, t)
             ELSE IF r.a = "Heartbeat" THEN
                  /\\ el.life = "MASTER"   \\* Election's Heartbeat(n): life[n] = "MASTER"
                  /\\ Step(r, s0, Drawn(s0), el, mem, {{}}, t)
             ELSE IF r.a = "StartElection" THEN
                  /\\ EP!StartElectionOk(Self, el)
                  /\\ Step(r, s0, Drawn(s0), EP!StartElectionNext(Self, el), mem, {{}}, t)
             ELSE IF r.a = "HandleVote" THEN
                  /\\ em.src \\in mem /\\ EP!HandleVoteOk(Self, el, em)
                  /\\ Step(r, s0, s0, EP!HandleVoteNext(el, em), mem, {{}}, t)
             ELSE IF r.a = "BecomeMaster" THEN
                  /\\ QuorumOk(el)
                  /\\ Step(r, s0, Drawn(s0), EP!BecomeMasterNext(el), mem, {{}}, t)
             ELSE IF r.a = "HandleStale" THEN
                  /\\ EP!HandleStaleOk(Self, el, em)
                  /\\ Step(r, s0, s0, EP!HandleStaleNext(Self, el, em), mem, {{}}, t)
             ELSE IF r.a = "HandleHeartbeat" THEN
                  LET st == [em EXCEPT !.t = "STALE", !.dst = PC] IN
                  /\\ em.t = "HB" /\\ em.src # Self
                  /\\ IF em.e < el.epoch
                     THEN /\\ View(el.life) # "STEPPED_DOWN"
                          /\\ Step(r, s0, Drawn(s0), el, mem, {{}}, t)
                     ELSE IF Self = PC
                     THEN /\\ EP!HandleStaleOk(PC, el, st)
                          /\\ Step(r, s0, s0, EP!HandleStaleNext(PC, el, st), mem, {{}}, t)
                     \\* an agent-master: Election's HandleHeartbeat of node Self (it follows the newer
                     \\* master); its Master core hands the registry over once (HANDOVER: a msgid)
                     ELSE /\\ EP!HandleHeartbeatOk(Self, el, em)
                          /\\ Step(r, s0, IF handed THEN s0 ELSE Drawn(s0), EP!HandleHeartbeatNext(el, em), mem, {{}}, t)
             ELSE IF r.a = "HandleElect" THEN
                  \\* an agent-master steps down on a newer ELECT (Election's HandleElect of node Self; the
                  \\* vote is its agent core's); the PC ignores ELECT (Election has no HandleElect of the PC)
                  /\\ Self # PC /\\ em.t = "ELECT" /\\ em.e > el.epoch /\\ View(el.life) # "STEPPED_DOWN"
                  /\\ EP!HandleElectOk(Self, el, em, 0, 0)
                  /\\ Step(r, s0, s0, EP!HandleElectNext(Self, el, em, 0, 0), mem, {{}}, t)
             ELSE IF r.a = "MasterRoute" THEN
                  /\\ em.t = "ROUTE" /\\ em.dst = Self /\\ el.life = "MASTER" /\\ em.e = el.epoch
                  /\\ em.x \\in Ids(s0) \\cup mem
                  /\\ \\E from \\in Eps(r) \\cup {{0}} : Step(r, s0, RouteTo(s0, em.x, from), el, mem, {{}}, t)
             ELSE IF r.a = "MasterHandover" THEN
                  /\\ em.t = "HANDOVER" /\\ em.dst = Self /\\ el.life = "MASTER" /\\ em.e <= el.epoch
                  /\\ Step(r, s0, s0, el, mem \\cup (r.ids \\cap (AssignedIds \\ {{Self}})), {{}}, t)
             ELSE FALSE
          /\\ clock' = t
          /\\ handed' = (handed \\/ (r.a = "HandleHeartbeat" /\\ Self # PC /\\ em.e >= el.epoch))
    /\\ cursor' = cursor + 1
    /\\ UNCHANGED failed
Stuck == failed = 0 /\\ cursor <= Len(Trace) /\\ ~ENABLED Match
         /\\ failed' = cursor /\\ UNCHANGED <<ms, el, mem, handed, cursor, clock, sent>>
Next == Match \\/ Stuck
Matched == cursor <= Len(Trace)
NotStuck == failed = 0
====
"""


# --- the Master core an elected agent runs (ev3-agent --election --trace) --------------------------
#
# While an agent is the elected master, its program runs a Master core (docs/core.md "An agent becomes
# master") whose records go to the agent's --trace as node "master:ID:EPOCH" (one core per epoch won).
# Each is checked by master_election_module with Self = ID: MASTER of EPOCH from its first record, no
# ids to assign (next id 50000: an unknown temporary id is ignored), the membership its agent core
# knew (the members of the last LEADER it took before), the first msgid read from its first record
# (a Heartbeat: the core draws msgids above the agent core's); its step-down by Election's
# HandleElect / HandleHeartbeat / HandleStale of node ID (the trace's STEPPED_DOWN: any life but
# MASTER), HANDOVER sent once.


def agent_master_runs(path: Path, consts: dict | None = None) -> list[tuple[str, dict]]:
    """(node, validate_master constants) of each Master core in an agent's trace. consts: the master
    timers TDrop, TResend, MaxResends (default: ev3-agent's, the defaults of timers.hpp: 10000, 500, 10)."""
    recs = load(Path(path), None)
    out = []
    for name in dict.fromkeys(r.get("node", "") for r in recs):
        parts = name.split(":")
        if len(parts) != 3 or parts[0] != "master":
            continue
        mine = [r for r in recs if r.get("node") == name]
        start = mine[0].get("now", 0)
        members: list[int] = []
        best = 0
        for r in recs:  # the last LEADER the agent core took (not an older epoch's) before this core started
            if r.get("node") == "agent" and r.get("now", 0) <= start and r.get("action") == "HandleHeartbeat":
                try:
                    m = wire.decode(r["args"]["msg"].encode("latin-1"))
                except (KeyError, wire.DecodeError):
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
