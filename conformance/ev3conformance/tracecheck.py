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

MASTER_RECV = ["MasterSync", "MasterAnswer", "MasterPing", "MasterReport"]
COMMANDS = ["BEHAVIOUR", "START", "STOP", "PAUSE", "RESUME", "STANDBY", "CONTINUE", "RESTART"]


def _reg_tla(reg: list) -> str:
    keys = ("ann", "id", "ep", "synced", "pending", "mid", "resends", "desired", "beh", "quiet", "hi")
    out = []
    for x in reg:
        e = {k: x[k] for k in keys}
        e["queue"] = tuple({"type": q["type"], "name": q["name"]} for q in x["queue"])
        out.append(tla.to_tla(e))
    return "{" + ", ".join(out) + "}"


def master_module(name: str, recs: list[dict], consts: dict) -> str:
    """MasterTraceCheck: one step per record; between records, the spec MasterTicks the core did not
    record (nothing due: no datagram, nobody dropped) are silent steps. 1 tick = 1 ms (the driver's
    resend period must be 1 ms); quiet is in ticks = ms."""
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
        items.append(f'[a |-> "{r["action"]}", m |-> {tla.to_tla(mrec)}, now |-> {int(r.get("now", 0))}, ch |-> {chs}]')
    behs = "{" + ", ".join(tla.to_tla(b) for b in consts.get("Behaviours", ["wait"])) + "}"
    return f"""---- MODULE {name} ----
EXTENDS Naturals, Sequences, FiniteSets, TLC
VARIABLES ms, cursor, clock, failed
M == INSTANCE MasterLogic WITH TDrop <- {consts["TDrop"]}, MaxResends <- {consts["MaxResends"]},
       ExactMsgids <- TRUE, BUG <- "none"
Behs == {behs}
Trace == <<
  {(","+chr(10)+"  ").join(items)}
>>
Vars == {{"reg", "nextId", "msgid"}}
Val(v, s) == IF v = "msgid" THEN s.msgid[0] ELSE s[v]
Fits(r, after) == \\A v \\in Vars : IF v \\in DOMAIN r.ch THEN Val(v, after) = r.ch[v] ELSE after[v] = ms[v]
Eps(r) == {{x.ep : x \\in ms.reg}} \\cup (IF "reg" \\in DOMAIN r.ch THEN {{x.ep : x \\in r.ch.reg}} ELSE {{}})
Cmds == {{M!Cmd(t, M!NoBehaviour) : t \\in {tla.to_tla(set(COMMANDS) - {"BEHAVIOUR"})}}}
        \\cup {{M!Cmd("BEHAVIOUR", b) : b \\in Behs}}
Init == ms = M!InitMaster({{1}}) /\\ cursor = 1 /\\ clock = 0 /\\ failed = 0
Silent ==
    /\\ cursor <= Len(Trace)
    /\\ clock + (IF Trace[cursor].a = "MasterTick" THEN 1 ELSE 0) < Trace[cursor].now
    /\\ LET t == M!MasterTick(ms) IN
         /\\ t.out = {{}} /\\ {{x.id : x \\in t.ms.reg}} = {{x.id : x \\in ms.reg}}
         /\\ ms' = t.ms
    /\\ clock' = clock + 1 /\\ UNCHANGED cursor
Match ==
    /\\ cursor <= Len(Trace)
    /\\ LET r == Trace[cursor] IN
       IF r.a = "MasterTick" THEN
          /\\ clock + 1 = r.now
          /\\ LET t == M!MasterTick(ms) IN Fits(r, t.ms) /\\ ms' = t.ms
          /\\ clock' = r.now
       ELSE IF r.a = "MasterCommand" THEN
          /\\ clock = r.now
          /\\ \\E id \\in {{x.id : x \\in ms.reg}} \\cup {{1}}, c \\in Cmds :  \\* 1: an unknown id
                LET t == M!MasterCommand(ms, id, c) IN Fits(r, t.ms) /\\ ms' = t.ms
          /\\ UNCHANGED clock
       ELSE
          /\\ clock = r.now
          /\\ M!Handler(r.m) = r.a
          /\\ \\E from \\in Eps(r) \\cup {{0}} :
                LET t == M!Receive(ms, r.m, from) IN Fits(r, t.ms) /\\ ms' = t.ms
          /\\ UNCHANGED clock
    /\\ cursor' = cursor + 1
Step == failed = 0 /\\ (Silent \\/ Match) /\\ UNCHANGED failed
Stuck == failed = 0 /\\ cursor <= Len(Trace) /\\ ~ENABLED (Silent \\/ Match)
         /\\ failed' = cursor /\\ UNCHANGED <<ms, cursor, clock>>
Next == Step \\/ Stuck
Matched == cursor <= Len(Trace)
NotStuck == failed = 0
====
"""


def validate_master(path: Path, consts: dict, workdir: Path | None = None) -> Result:
    """A master trace (`ev3-master --driver --trace`, resend 1 ms) against MasterLogic (exact
    msgids): consts TDrop (= the driver's drop ms), MaxResends, Behaviours."""
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
        return Result(str(path), False, len(recs),
                      f"record {k + 1} of {len(recs)} could not be matched by MasterLogic "
                      f"(module kept in {d}):\n{_describe_record(recs, k)}")
    return Result(str(path), False, len(recs), f"TLC failed (exit {rc}); module in {d}:\n{out[-2500:]}")
