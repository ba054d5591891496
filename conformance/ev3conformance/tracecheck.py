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
    recs = []
    with open(path) as f:
        for line in f:
            line = line.strip()
            if not line:
                continue
            r = json.loads(line)
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
Adv(a, k) == IF k = 0 THEN a
             ELSE [a EXCEPT !.clk = (a.clk + k) % {c["TPing"]},
                            !.silence = IF a.state = "PANIC" THEN 0 ELSE a.silence + k]
Recv(h, a, m) ==
    CASE {apply}
IntOk(r, a) ==
    CASE r.a = "SyncTimeout" -> L!SyncTimeoutOk(a)
      [] r.a = "HeartbeatLost" -> L!HeartbeatLostOk(a)
      [] r.a = "ActionOk" -> L!ActionOkOk(a)
      [] r.a = "ActionInterrupted" -> L!ActionInterruptedOk(a, r.e)
      [] r.a = "ActionFailed" -> L!ActionFailedOk(a)
      [] r.a = "SensorReport" -> L!SensorReportOk(a)
      [] r.a = "DeviceUnplugged" -> L!DeviceUnpluggedOk(a)
      [] r.a = "DevicePlugged" -> L!DevicePluggedOk(a)
      [] r.a = "BatteryLow" -> L!BatteryLowOk(a)
      [] OTHER -> FALSE
Internal(r, a) ==
    CASE r.a = "SyncTimeout" -> L!SyncTimeout(a)
      [] r.a = "HeartbeatLost" -> L!HeartbeatLost(a)
      [] r.a = "ActionOk" -> L!ActionOk(a)
      [] r.a = "ActionInterrupted" -> L!ActionInterrupted(a, r.e)
      [] r.a = "ActionFailed" -> L!ActionFailed(a)
      [] r.a = "SensorReport" -> L!SensorReport(a)
      [] r.a = "DeviceUnplugged" -> L!DeviceUnplugged(a)
      [] r.a = "DevicePlugged" -> L!DevicePlugged(a)
      [] r.a = "BatteryLow" -> L!BatteryLow(a)
Init == /\\ ag = L!InitAgent({temp_id}) /\\ out = <<>> /\\ cursor = 1 /\\ sub = 0 /\\ snap = ag /\\ failed = 0
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
    name = "TraceCheck"
    (d / f"{name}.tla").write_text(agent_module(name, mine, c, tid))
    (d / f"{name}.cfg").write_text("INIT Init\nNEXT Next\nINVARIANTS Matched NotStuck\nCHECK_DEADLOCK FALSE\n")
    for f in ("AgentLogic.tla", "Messages.tla"):
        (d / f).write_text((gr.SPEC / f).read_text())
    rc, out = gr.tlc(f"{name}.tla", f"{name}.cfg", [], cwd=d)
    if rc == 12 and "Invariant Matched is violated" in out:
        return Result(str(path), True, len(mine), f"{len(mine)} records matched (temporary id {tid})")
    if rc == 12 and "Invariant NotStuck is violated" in out:
        fails = re.findall(r"failed = (\d+)", out)
        k = int(fails[-1]) - 1 if fails else -1
        return Result(str(path), False, len(mine),
                      f"record {k + 1} of {len(mine)} could not be matched by the spec "
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


def master_module(name: str, recs: list[dict], consts: dict) -> str:
    """MasterTraceCheck: one TLC step per record, with the time map above. consts: TDrop and TResend
    (ms), MaxResends, Behaviours, NextId / FirstMsgid (the master's first id and msgid: 2 and 1 unless
    it was restarted from a state file)."""
    c = dict(MASTER_DEFAULTS)
    c.update(consts)
    base = int(recs[0].get("now", 0)) if recs else 0
    items = []
    for r in recs:
        ch = r.get("changed", {})
        parts = []
        if "reg" in ch:
            parts.append(f"reg |-> {_reg_tla(ch['reg'])}")
        for k in ("nextId", "msgid"):
            if k in ch:
                parts.append(f"{k} |-> {int(ch[k])}")
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


def validate_master(path: Path, consts: dict, workdir: Path | None = None) -> Result:
    """A master trace against MasterLogic (exact msgids): `ev3-master --driver --trace` (TResend 1,
    the default) or the real program's `--trace` over UDP (TResend = its --resend-ms). consts: TDrop
    (--agent-timeout-ms / the driver's drop), TResend, MaxResends, Behaviours, NextId, FirstMsgid.
    A trace with Election.tla actions (ev3-master --election) fails at the first one: only
    MasterLogic is checked."""
    path = Path(path)
    recs = [r for r in load(path, None) if r.get("node", "").startswith("master")]
    if not recs:
        return Result(str(path), True, 0, "no master records; nothing to check", skipped=True)
    wd = Path(workdir or (gr.BUILD / "traces"))
    wd.mkdir(parents=True, exist_ok=True)
    d = Path(tempfile.mkdtemp(prefix="mtrace-", dir=wd))
    name = "MasterTraceCheck"
    (d / f"{name}.tla").write_text(master_module(name, recs, consts))
    (d / f"{name}.cfg").write_text("INIT Init\nNEXT Next\nINVARIANTS Matched NotStuck\nCHECK_DEADLOCK FALSE\n")
    for f in ("MasterLogic.tla", "Messages.tla"):
        (d / f).write_text((gr.SPEC / f).read_text())
    rc, out = gr.tlc(f"{name}.tla", f"{name}.cfg", [], cwd=d)
    if rc == 12 and "Invariant Matched is violated" in out:
        return Result(str(path), True, len(recs), f"{len(recs)} master records matched")
    if rc == 12 and "Invariant NotStuck is violated" in out:
        fails = re.findall(r"failed = (\d+)", out)
        k = int(fails[-1]) - 1 if fails else -1
        why = ""
        if 0 <= k < len(recs) and recs[k].get("action") in ELECTION_MASTER_ACTIONS:
            why = " (an Election.tla action: validate --master checks MasterLogic only)"
        return Result(str(path), False, len(recs),
                      f"record {k + 1} of {len(recs)} could not be matched by MasterLogic{why} "
                      f"(module kept in {d}):\n{_describe_record(recs, k)}")
    return Result(str(path), False, len(recs), f"TLC failed (exit {rc}); module in {d}:\n{out[-2500:]}")
