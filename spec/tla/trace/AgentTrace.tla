------------------------------ MODULE AgentTrace ------------------------------
(***************************************************************************)
(* One agent's NDJSON trace records (docs/core.md "Trace") against         *)
(* AgentLogic: AgentStep(r, s) is the set of local states record r leads   *)
(* to from s (docs/spec.md "Implementation -> spec (validate)").           *)
(*                                                                         *)
(* A record, as ev3conformance.tracecheck converts it (data only):         *)
(*   [a  |-> the action (a handler of AgentLogic),                         *)
(*    m  |-> the datagram received, decoded as AgentLogic's messages       *)
(*           (type "NONE" for an internal action),                         *)
(*    e  |-> ActionInterrupted's warning, RobotEvent's event ("" otherwise),*)
(*    p  |-> DeviceUnplugged's, DevicePlugged's, RobotEvent's port ("" else), *)
(*    n  |-> Tick: the number of consecutive spec Ticks it stands for,     *)
(*    v  |-> RecvBehaviour: the reason the robot's check on receipt        *)
(*           refused the request with ("" if it accepted or was not asked),*)
(*    ch |-> the variables the action changed, with their new values]      *)
(* The record names the handler; the handler must be the one AgentLogic    *)
(* dispatches to, every variable in ch must have that value after it and   *)
(* every other one must be unchanged.                                      *)
(***************************************************************************)
EXTENDS Naturals, Sequences

CONSTANTS
    Behaviours, ModelName, TSync, TPing, TLoss, TPaused, Window, Steps,  \* AgentLogic's
    TempId       \* the agent's temporary id (before a master assigns one)

L == INSTANCE AgentLogic WITH UnknownBehaviour <- "?unknown", BUG <- "none", Refused <- {},
                              CheckReason <- "?check"
\* AgentLogic as the robot's check on receipt answered one BEHAVIOUR: v is the reason it refused the
\* request with (the record's v), "" when it accepted it or was not asked.
LV(v) == INSTANCE AgentLogic WITH UnknownBehaviour <- "?unknown", BUG <- "none",
                                 Refused <- IF v = "" THEN {} ELSE Behaviours,
                                 CheckReason <- IF v = "" THEN "?check" ELSE v

\* AgentLogic's variables a record may list in ch (dupActed is never written).
AgentVars == {"state", "led", "id", "beh", "step", "wait", "motors", "devOk", "silence", "clk", "win"}

\* The record's changed variables have its values; every other one is as before the action.
Fits(r, before, after) ==
    \A v \in AgentVars : IF v \in DOMAIN r.ch THEN after[v] = r.ch[v] ELSE after[v] = before[v]

\* k Ticks at once, without the last one's periodic send (see AgentStep).
Adv(a, k) == IF k = 0 THEN a
             ELSE [a EXCEPT !.clk = (a.clk + k) % TPing,
                            !.silence = IF a.state = "PANIC" THEN 0 ELSE a.silence + k]

\* The receive handler named h (v: the verdict of the robot's check, for RecvBehaviour).
Recv(h, a, m, v) ==
    CASE h = "RecvMaster"    -> L!RecvMaster(a, m)
      [] h = "RecvPong"      -> L!RecvPong(a, m)
      [] h = "RecvBehaviour" -> LV(v)!RecvBehaviour(a, m)
      [] h = "RecvStart"     -> L!RecvStart(a, m)
      [] h = "RecvStop"      -> L!RecvStop(a, m)
      [] h = "RecvPause"     -> L!RecvPause(a, m)
      [] h = "RecvResume"    -> L!RecvResume(a, m)
      [] h = "RecvStandby"   -> L!RecvStandby(a, m)
      [] h = "RecvContinue"  -> L!RecvContinue(a, m)
      [] h = "RecvRestart"   -> L!RecvRestart(a, m)
      [] h = "RecvDuplicate" -> L!RecvDuplicate(a, m)
      [] h = "Ignore"        -> L!Ignore(a, m)

\* AgentLogic's internal action named by record r: its enabling condition (FALSE for any other
\* name) and its effect.
IntOk(r, a) ==
    CASE r.a = "SyncTimeout"       -> L!SyncTimeoutOk(a)
      [] r.a = "HeartbeatLost"     -> L!HeartbeatLostOk(a)
      [] r.a = "ActionOk"          -> L!ActionOkOk(a)
      [] r.a = "ActionInterrupted" -> L!ActionInterruptedOk(a, r.e)
      [] r.a = "ActionFailed"      -> L!ActionFailedOk(a)
      [] r.a = "SensorReport"      -> L!SensorReportOk(a)
      [] r.a = "DeviceUnplugged"   -> L!DeviceUnpluggedOk(a, r.p)
      [] r.a = "DevicePlugged"     -> L!DevicePluggedOk(a, r.p)
      [] r.a = "BatteryLow"        -> L!BatteryLowOk(a)
      [] r.a = "RobotEvent"        -> L!RobotEventOk(a, r.e, r.p)
      [] OTHER                     -> FALSE
Internal(r, a) ==
    CASE r.a = "SyncTimeout"       -> L!SyncTimeout(a)
      [] r.a = "HeartbeatLost"     -> L!HeartbeatLost(a)
      [] r.a = "ActionOk"          -> L!ActionOk(a)
      [] r.a = "ActionInterrupted" -> L!ActionInterrupted(a, r.e)
      [] r.a = "ActionFailed"      -> L!ActionFailed(a, r.e)
      [] r.a = "SensorReport"      -> L!SensorReport(a)
      [] r.a = "DeviceUnplugged"   -> L!DeviceUnplugged(a, r.p)
      [] r.a = "DevicePlugged"     -> L!DevicePlugged(a, r.p)
      [] r.a = "BatteryLow"        -> L!BatteryLow(a)
      [] r.a = "RobotEvent"        -> L!RobotEvent(a, r.e, r.p)

\* AgentLogic's effect res ([ag, out]) of record r from a, if r's changes fit it.  (res is bound
\* once by \in: TLC passes operator arguments by name and would evaluate it at each use.)
IfFits(r, a, res) == {x \in {res} : Fits(r, a, x.ag)}

-----------------------------------------------------------------------------
(* The agent's local state in a check: AgentLogic's state ag and out, the  *)
(* datagrams its last step sent (as AgentLogic computes them; the trace    *)
(* does not hold them).                                                    *)

AgentStart == [ag |-> L!InitAgent(TempId), out |-> <<>>]

AgentStep(r, s) ==
    LET a == s.ag IN
    IF r.a = "Tick" THEN
       \* n Ticks in one step: Adv(a, n - 1) is the state before the last one.  Tick changes only
       \* clk and silence, and TimeoutDue is monotone in silence, so the n Ticks are all enabled
       \* iff the first and the last are (closed form; the last is the spec's Tick).
       IF L!TickOk(a) /\ L!TickOk(Adv(a, r.n - 1)) THEN IfFits(r, a, L!Tick(Adv(a, r.n - 1))) ELSE {}
    ELSE IF r.m.type # "NONE" THEN
       \* a datagram: the handler AgentLogic dispatches it to must be the record's
       IF a.state # "OFF" /\ L!Handler(a, r.m) = r.a THEN IfFits(r, a, Recv(r.a, a, r.m, r.v)) ELSE {}
    ELSE IF IntOk(r, a) THEN IfFits(r, a, Internal(r, a))
    ELSE {}
===============================================================================
