----------------------------- MODULE AgentLogic -----------------------------
(***************************************************************************)
(* The agent's logic as pure operators on one agent's local state (a       *)
(* record), shared by Agent.tla (one agent, any environment) and Fleet.tla *)
(* (N agents and a master).  Every step of the agent is one of the         *)
(* handlers below; a handler X has an enabling condition XOk(a, ...) and   *)
(* an effect X(a, ...) that returns [ag |-> new local state, out |-> the   *)
(* sequence of messages the agent emits in that step].  The C++ core has   *)
(* one handler per action, with the same name (docs/spec.md).              *)
(***************************************************************************)
EXTENDS Naturals, Sequences, Messages

CONSTANTS
    Behaviours,        \* behaviours this robot knows by name
    UnknownBehaviour,  \* a behaviour name it cannot run (stands for all others)
    Refused,           \* requests of Behaviours the robot's check on receipt refuses: a custom
                       \*   definition that does not parse or does not check, or needs a device
                       \*   or an action the robot lacks (docs/behaviours.md)
    CheckReason,       \* the reason that check gives (stands for "line 4 col 12: unknown action
                       \*   'trun' (...)", "the robot has no gyro (...)": the robot's own words)
    ModelName,         \* robot model announced in AGENT (e.g. "A")
    TSync,             \* sync timeout: ticks in IDLE without a MASTER before PANIC
    TPing,             \* heartbeat: ticks between periodic AGENT / PING / PANIC sends
    TLoss,             \* master-loss timeout: ticks without hearing the master
                       \*   before ACTIVE->PANIC and WORKING->PAUSED
    TPaused,           \* ticks without hearing the master before PAUSED->PANIC
    Window,            \* size of the dedupe window (entries, FIFO)
    Steps,             \* actions in a behaviour's cycle (action ids 0..Steps-1)
    BUG                \* "none" in every real model; names one broken rule otherwise

ASSUME /\ UnknownBehaviour \notin Behaviours
       /\ Refused \subseteq Behaviours
       /\ CheckReason \notin {"unknown behaviour", "missing device", "no behaviour", "wrong state"}
       /\ TSync \in Nat \ {0}
       /\ TPing \in Nat \ {0}
       /\ TLoss \in Nat \ {0}
       /\ TPaused \in Nat /\ TPaused > TLoss
       /\ Window \in Nat \ {0}
       /\ Steps \in Nat \ {0}

-----------------------------------------------------------------------------
States   == {"IDLE", "ACTIVE", "WORKING", "PAUSED", "PANIC", "OFF"}
Synced   == {"ACTIVE", "WORKING", "PAUSED"}     \* states that have a master
Masterless == {"IDLE", "PANIC"}

\* LED pattern of each state (OFF: the agent shut down, LEDs dark).
LedOf == [ IDLE |-> "YELLOW_BLINK", ACTIVE |-> "GREEN_BLINK",
           WORKING |-> "GREEN", PAUSED |-> "ORANGE", PANIC |-> "RED_BLINK",
           OFF |-> "DARK" ]
Leds == {LedOf[s] : s \in States}

NoBehaviour == "NONE"
Waits  == {"NONE", "CONTINUE", "RESTART"}   \* WORKING sub-state (brief sec. 3)
Warnings == {"OBSTACLE_DETECTED", "PROXIMITY_ALERT"}
\* Why an action failed, as the robot says it in ACTION_ERR ("outB stalled at -913 of -2046
\* counts"): any text; the protocol does nothing with it, so one stands for all.
Failures == {"stalled"}
\* "missing device" stands for the robot's words naming the device ("missing device: the robot
\* has no colour sensor (explore needs it)"): which device is missing changes nothing here.
Reasons  == {"unknown behaviour", "missing device", "no behaviour", "wrong state", CheckReason}

\* Names of all handlers; lastAction.name is one of these.
RecvNames == {"RecvMaster", "RecvPong", "RecvBehaviour", "RecvStart", "RecvStop",
              "RecvPause", "RecvResume", "RecvStandby", "RecvContinue",
              "RecvRestart", "RecvDuplicate", "Ignore"}
InternalNames == {"Tick", "SyncTimeout", "HeartbeatLost", "ActionOk",
                  "ActionInterrupted", "ActionFailed", "SensorReport",
                  "DeviceUnplugged", "DevicePlugged", "BatteryLow", "RobotEvent"}
ActionNames == RecvNames \cup InternalNames

Answers == [src : Nat, dst : {MasterId}, type : {"ACK"}, ref : Nat, args : {<<>>}]
           \cup [src : Nat, dst : {MasterId}, type : {"NOT"}, ref : Nat,
                  args : {<<r>> : r \in Reasons}]
\* The EV3's ports (docs/devices.md): the second param of EVENT for a device's event.
Ports == {"in1", "in2", "in3", "in4", "outA", "outB", "outC", "outD"}
\* Events a synced agent reports with RobotEvent (docs/devices.md "Events"): the thesis' normal
\* events outside a running action (the warnings, a device connected) and a device unplugged that
\* changes nothing the protocol sees (a device the model does not use, or one more while another
\* is missing already: devOk is FALSE).
RobotEvents == Warnings \cup {"DEVICE_CONNECTED", "DEVICE_DISCONNECTED"}
\* EVENT's params: the name, then the port of the device it is about (not for BATTERY_LOW).
EventArgs == {<<"BATTERY_LOW">>} \cup {<<e, p>> : e \in RobotEvents, p \in Ports}
\* Everything an agent can emit.
OutMsgs ==
         [src : Nat, dst : {Broadcast}, type : {"AGENT"}, ref : {0}, args : {<<ModelName>>}]
    \cup [src : Nat, dst : {Broadcast}, type : {"PANIC"}, ref : {0}, args : {<<>>}]
    \cup [src : Nat, dst : {MasterId}, type : {"PING"}, ref : {0}, args : {<<s>> : s \in States}]
    \cup Answers
    \cup [src : Nat, dst : {MasterId}, type : {"ACTION_OK"}, ref : Nat, args : {<<>>}]
    \cup [src : Nat, dst : {MasterId}, type : {"ACTION_INTERR"}, ref : Nat,
           args : {<<e>> : e \in Warnings}]
    \cup [src : Nat, dst : {MasterId}, type : {"ACTION_ERR"}, ref : Nat, args : {<<f>> : f \in Failures}]
    \cup [src : Nat, dst : {MasterId}, type : {"SENSOR_VALUE"}, ref : {0},
           args : {<<"port", "mode", "value">>}]
    \cup [src : Nat, dst : {MasterId}, type : {"EVENT"}, ref : {0},
           args : EventArgs]
WinEntry == [src : Nat, msgid : Nat, ans : Answers]

\* Local state of one agent.
AgentType ==
    [ state : States, led : Leds, id : Nat, beh : Behaviours \cup {NoBehaviour},
      step : 0..(Steps - 1), wait : Waits, motors : {"ON", "OFF"},
      devOk : BOOLEAN, silence : Nat, clk : 0..(TPing - 1),
      win : Seq(WinEntry), dupActed : BOOLEAN ]

InitAgent(tmp) ==
    [ state |-> "IDLE", led |-> LedOf["IDLE"], id |-> tmp, beh |-> NoBehaviour,
      step |-> 0, wait |-> "NONE", motors |-> "OFF", devOk |-> TRUE,
      silence |-> 0, clk |-> 0, win |-> <<>>, dupActed |-> FALSE ]

-----------------------------------------------------------------------------
(* Helpers                                                                  *)

\* Enter state s: the LED follows the state.
LedFor(s) == IF BUG = "WrongLed" /\ s = "PAUSED" THEN LedOf["WORKING"] ELSE LedOf[s]
Goto(a, s) == [a EXCEPT !.state = s, !.led = LedFor(s)]

\* The addressing rule of docs/protocol.md "Ids" (the reference, bug-free).
AddressedTo(a, m) ==
    \/ m.dst = a.id
    \/ m.dst = Broadcast
    \/ /\ a.state \in Masterless /\ m.type = "MASTER"
       /\ m.ref = a.id /\ m.dst \in AssignedIds
\* The filter the agent applies.
Accepts(a, m) == IF BUG = "NoAddressFilter" THEN TRUE ELSE AddressedTo(a, m)

\* A message the agent acts on: from the master, addressed to it, alive.
FromMaster(a, m) == a.state # "OFF" /\ (m.src = MasterId \/ BUG = "NoSenderCheck") /\ Accepts(a, m)

Answered(m) == m.type \in Commands \cup {"MASTER"}
Seen(a, m) == \E i \in 1..Len(a.win) : a.win[i].src = m.src /\ a.win[i].msgid = m.msgid
Stored(a, m) == LET i == CHOOSE i \in 1..Len(a.win) :
                             a.win[i].src = m.src /\ a.win[i].msgid = m.msgid
                IN a.win[i].ans
\* A command or MASTER older than one the window remembers from the same
\* sender: a copy (or a resend given up) that outlived its own entry in the
\* FIFO window.  The master draws its msgids in increasing order and never
\* reuses them (they survive its crashes: docs/core.md), and sends an agent
\* the next command (or a resync's MASTER) only once the last one is answered
\* or given up; so a datagram below a remembered one was acted on already, or
\* given up by the master, and must not take effect now (TLC, fleet_window:
\* BUG "NoStaleCheck" acts on such a copy twice: a BEHAVIOUR copy after the
\* resync's MASTER evicted it, a resync's MASTER copy in the next PANIC).
Stale(a, m) == /\ Answered(m) /\ BUG # "NoStaleCheck"
               /\ \E i \in 1..Len(a.win) : a.win[i].src = m.src /\ a.win[i].msgid > m.msgid
Fresh(a, m) == IF BUG = "NoDedupe" THEN TRUE ELSE ~Seen(a, m) /\ ~Stale(a, m)

Ack(a, m)    == Out(a.id, MasterId, "ACK", m.msgid, <<>>)
Nak(a, m, r) == Out(a.id, MasterId, "NOT", m.msgid, <<r>>)

\* Act on a fresh command: new local state b (window not yet updated),
\* answer ans; remember (src, msgid) -> ans, FIFO eviction; hearing the master
\* resets the silence counter.  (BUG "ForgetAnswers": the window remembers
\* nothing, so every copy is fresh; dupActed, which asks the window, never
\* notices: Fleet's CommandOnceInv does, in fleet_small.)
Answer(a, m, b, ans) ==
    LET w == Append(a.win, [src |-> m.src, msgid |-> m.msgid, ans |-> ans])
    IN [ ag  |-> [b EXCEPT !.win = IF Len(w) > Window THEN Tail(w) ELSE w,
                           !.silence = 0,
                           !.dupActed = a.dupActed \/ Seen(a, m),
                           !.win = IF BUG = "ForgetAnswers" THEN a.win ELSE @],
         out |-> <<ans>> ]
Refuse(a, m, r) == Answer(a, m, a, Nak(a, m, r))

Stopped(a) == [a EXCEPT !.motors = "OFF", !.wait = "NONE"]
RunFrom0(a) == [Goto(a, "WORKING") EXCEPT !.step = 0, !.wait = "NONE", !.motors = "ON"]

-----------------------------------------------------------------------------
(* Receive handlers.  Each takes the decoded datagram m.                    *)

\* Agent without master (IDLE or PANIC) gets MASTER(param = its id): ACK from
\* the new id, ACTIVE with the id from the receiver field, fresh session.
RecvMasterOk(a, m) ==
    /\ FromMaster(a, m) /\ m.type = "MASTER" /\ Fresh(a, m)
    /\ a.state \in Masterless /\ m.ref = a.id /\ m.dst \in AssignedIds
RecvMaster(a, m) ==
    LET b == [Goto(a, "ACTIVE") EXCEPT !.id = m.dst, !.beh = NoBehaviour,
                 !.step = 0, !.wait = "NONE", !.motors = "OFF", !.clk = 0]
    IN Answer(a, m, b, Ack(b, m))

\* PONG from the master while synced: heartbeat heard.
RecvPongOk(a, m) == FromMaster(a, m) /\ m.type = "PONG" /\ a.state \in Synced
RecvPong(a, m) == [ag |-> [a EXCEPT !.silence = 0], out |-> <<>>]

\* BEHAVIOUR(name, ...): ACK and load it if it can be run, else NOT.
\* In WORKING the new behaviour replaces the running one and starts from its
\* first action; in PAUSED it replaces it (RESUME/START then runs it).
\* The robot's check (parse, arguments, the checker, on the robot's model and
\* devices) runs on receipt, before the answer: a request it refuses gets NOT
\* with the check's own reason and changes nothing else (the loaded behaviour,
\* if any, stays loaded and running).
RecvBehaviourOk(a, m) == FromMaster(a, m) /\ m.type = "BEHAVIOUR" /\ Fresh(a, m)
RecvBehaviour(a, m) ==
    LET bh == m.args[1] IN
    IF a.state \notin Synced THEN Refuse(a, m, "wrong state")
    ELSE IF bh \notin Behaviours /\ BUG # "AcceptUnknown"
         THEN Refuse(a, m, "unknown behaviour")
    ELSE IF ~a.devOk THEN Refuse(a, m, "missing device")
    ELSE IF bh \in Refused /\ BUG # "NoCheckOnReceipt" THEN Refuse(a, m, CheckReason)
    ELSE LET b0 == [a EXCEPT !.beh = bh, !.step = 0, !.wait = "NONE"]
             b  == IF a.state = "WORKING" THEN [b0 EXCEPT !.motors = "ON"] ELSE b0
         IN Answer(a, m, b, Ack(a, m))

\* START: run the loaded behaviour from its start (ACTIVE, PAUSED, WORKING).
RecvStartOk(a, m) == FromMaster(a, m) /\ m.type = "START" /\ Fresh(a, m)
RecvStart(a, m) ==
    IF a.state \notin Synced THEN Refuse(a, m, "wrong state")
    ELSE IF a.beh = NoBehaviour /\ BUG # "StartWithout" THEN Refuse(a, m, "no behaviour")
    ELSE Answer(a, m, RunFrom0(a), Ack(a, m))

\* STOP: stop the behaviour (kept loaded) and go to ACTIVE.
RecvStopOk(a, m) == FromMaster(a, m) /\ m.type = "STOP" /\ Fresh(a, m)
RecvStop(a, m) ==
    IF a.state \in {"WORKING", "PAUSED"}
    THEN Answer(a, m, Goto(Stopped(a), "ACTIVE"), Ack(a, m))
    ELSE Refuse(a, m, "wrong state")

\* PAUSE: WORKING -> PAUSED, motors stopped, progress kept.
RecvPauseOk(a, m) == FromMaster(a, m) /\ m.type = "PAUSE" /\ Fresh(a, m)
RecvPause(a, m) ==
    IF a.state = "WORKING" \/ (BUG = "PauseFromActive" /\ a.state = "ACTIVE")
    THEN Answer(a, m, [Goto(a, "PAUSED") EXCEPT
                         !.motors = IF BUG = "PauseKeepsMotors" THEN a.motors ELSE "OFF"],
                Ack(a, m))
    ELSE Refuse(a, m, "wrong state")

\* RESUME: PAUSED -> WORKING where it was (still waiting if it was waiting:
\* the motors stay off until CONTINUE or RESTART).  The broken variant
\* ResumeWhileWaiting turns them on whatever the action waits for.
RecvResumeOk(a, m) == FromMaster(a, m) /\ m.type = "RESUME" /\ Fresh(a, m)
RecvResume(a, m) ==
    IF a.state = "PAUSED"
    THEN Answer(a, m, [Goto(a, "WORKING") EXCEPT
                         !.motors = IF a.wait = "NONE" \/ BUG = "ResumeWhileWaiting" THEN "ON" ELSE "OFF"],
                Ack(a, m))
    ELSE Refuse(a, m, "wrong state")

\* STANDBY: WORKING -> ACTIVE (behaviour stopped, kept loaded).
RecvStandbyOk(a, m) == FromMaster(a, m) /\ m.type = "STANDBY" /\ Fresh(a, m)
RecvStandby(a, m) ==
    IF a.state = "WORKING"
    THEN Answer(a, m, Goto(Stopped(a), "ACTIVE"), Ack(a, m))
    ELSE Refuse(a, m, "wrong state")

\* CONTINUE: after ACTION_INTERR, go on with the behaviour.
RecvContinueOk(a, m) == FromMaster(a, m) /\ m.type = "CONTINUE" /\ Fresh(a, m)
RecvContinue(a, m) ==
    IF a.state = "WORKING" /\ a.wait = "CONTINUE"
    THEN Answer(a, m, [a EXCEPT !.wait = "NONE", !.motors = "ON"], Ack(a, m))
    ELSE Refuse(a, m, "wrong state")

\* RESTART: after ACTION_ERR, run the same behaviour again from its start.
RecvRestartOk(a, m) == FromMaster(a, m) /\ m.type = "RESTART" /\ Fresh(a, m)
RecvRestart(a, m) ==
    IF a.state = "WORKING" /\ a.wait = "RESTART"
    THEN Answer(a, m, RunFrom0(a), Ack(a, m))
    ELSE Refuse(a, m, "wrong state")

\* A copy (or resend) of a command or MASTER already answered: the same
\* answer again, nothing else.  (BUG "AckCopies": a copy is ACKed whatever the
\* original got, so the master takes a refused command for done.)
RecvDuplicateOk(a, m) == FromMaster(a, m) /\ Answered(m) /\ Seen(a, m)
                         /\ BUG # "NoDedupe"
RecvDuplicate(a, m) == [ag |-> a, out |-> <<IF BUG = "AckCopies" THEN Ack(a, m) ELSE Stored(a, m)>>]

\* Which receive handler takes m (at most one does).
Handler(a, m) ==
    CASE RecvMasterOk(a, m)    -> "RecvMaster"
      [] RecvPongOk(a, m)      -> "RecvPong"
      [] RecvBehaviourOk(a, m) -> "RecvBehaviour"
      [] RecvStartOk(a, m)     -> "RecvStart"
      [] RecvStopOk(a, m)      -> "RecvStop"
      [] RecvPauseOk(a, m)     -> "RecvPause"
      [] RecvResumeOk(a, m)    -> "RecvResume"
      [] RecvStandbyOk(a, m)   -> "RecvStandby"
      [] RecvContinueOk(a, m)  -> "RecvContinue"
      [] RecvRestartOk(a, m)   -> "RecvRestart"
      [] RecvDuplicateOk(a, m) -> "RecvDuplicate"
      [] OTHER                 -> "Ignore"

\* Everything else is dropped silently: not addressed to it, from another
\* agent, a MASTER it does not take, PONG/ACK without a master, reports.
\* (BUG "SilenceOnIgnored": a datagram with the master's id that the agent ignores, e.g. one
\* for another agent, still counts as hearing the master.)
Ignore(a, m) == [ag |-> IF BUG = "SilenceOnIgnored" /\ m.src = MasterId THEN [a EXCEPT !.silence = 0] ELSE a, out |-> <<>>]

\* Dispatch: the effect of receiving m.
Receive(a, m) ==
    CASE Handler(a, m) = "RecvMaster"    -> RecvMaster(a, m)
      [] Handler(a, m) = "RecvPong"      -> RecvPong(a, m)
      [] Handler(a, m) = "RecvBehaviour" -> RecvBehaviour(a, m)
      [] Handler(a, m) = "RecvStart"     -> RecvStart(a, m)
      [] Handler(a, m) = "RecvStop"      -> RecvStop(a, m)
      [] Handler(a, m) = "RecvPause"     -> RecvPause(a, m)
      [] Handler(a, m) = "RecvResume"    -> RecvResume(a, m)
      [] Handler(a, m) = "RecvStandby"   -> RecvStandby(a, m)
      [] Handler(a, m) = "RecvContinue"  -> RecvContinue(a, m)
      [] Handler(a, m) = "RecvRestart"   -> RecvRestart(a, m)
      [] Handler(a, m) = "RecvDuplicate" -> RecvDuplicate(a, m)
      [] OTHER                           -> Ignore(a, m)

-----------------------------------------------------------------------------
(* Time.  A timeout is urgent: time does not advance past it.               *)

SyncDue(a) == a.state = "IDLE" /\ a.silence >= TSync
LossDue(a) == \/ a.state = "ACTIVE" /\ a.silence >= TLoss
              \/ a.state = "WORKING"
                 /\ IF BUG = "LateTimeout" THEN a.silence > TLoss ELSE a.silence >= TLoss
              \/ a.state = "PAUSED" /\ a.silence >= TPaused
TimeoutDue(a) == SyncDue(a) \/ LossDue(a)

PanicMsg(a) == Out(a.id, Broadcast, "PANIC", 0, <<>>)
\* AGENT carries the model; on the wire the names of the model's devices follow
\* it, fixed for a robot whether plugged or not, so they change nothing here
\* (which are missing the master learns from EVENT DEVICE_DISCONNECTED).
Periodic(a) ==
    CASE a.state = "IDLE"  -> Out(a.id, Broadcast, "AGENT", 0, <<ModelName>>)
      [] a.state = "PANIC" -> PanicMsg(a)
      [] OTHER             -> Out(a.id, MasterId, "PING", 0, <<a.state>>)

\* One tick of the agent's clock: silence grows (not in PANIC), every
\* TPing ticks the periodic message goes out (AGENT/PING/PANIC).
TickOk(a) == a.state # "OFF" /\ ~TimeoutDue(a)
Tick(a) ==
    LET c == (a.clk + 1) % TPing
        b == [a EXCEPT !.clk = c,
                       !.silence = IF a.state = "PANIC" THEN 0 ELSE a.silence + 1]
    IN [ag |-> b, out |-> IF c = 0 THEN <<Periodic(a)>> ELSE <<>>]

\* IDLE and no MASTER within TSync ticks: PANIC.
SyncTimeoutOk(a) == SyncDue(a)
SyncTimeout(a) ==
    LET b == [Goto(a, "PANIC") EXCEPT !.silence = 0, !.clk = 0]
    IN [ag |-> b, out |-> <<PanicMsg(b)>>]

\* Master not heard for too long: ACTIVE -> PANIC, WORKING -> PAUSED
\* (behaviour stopped, progress kept), PAUSED -> PANIC.
HeartbeatLostOk(a) == LossDue(a) /\ (BUG = "FreezeOnLoss" => a.state # "WORKING")
HeartbeatLost(a) ==
    IF a.state = "WORKING"
    THEN [ag |-> [Goto(a, "PAUSED") EXCEPT !.motors = "OFF"], out |-> <<>>]
    ELSE LET b == [Goto(Stopped(a), "PANIC") EXCEPT !.silence = 0, !.clk = 0]
         IN [ag |-> b, out |-> <<PanicMsg(b)>>]

-----------------------------------------------------------------------------
(* The running behaviour and the devices.                                   *)

Running(a) == a.state = "WORKING" /\ a.wait = "NONE"

\* The current action finished: ACTION_OK(action id), next action.
ActionOkOk(a) == Running(a)
ActionOk(a) == [ ag  |-> [a EXCEPT !.step = IF BUG = "StepOverflow" THEN a.step + 1
                                                          ELSE (a.step + 1) % Steps],
                 out |-> <<Out(a.id, MasterId, "ACTION_OK", a.step, <<>>)>> ]

\* A warning event (obstacle, proximity) the behaviour cannot resolve itself:
\* motors stop, ACTION_INTERR(action id, event), wait for CONTINUE.  Warnings
\* the behaviour handles itself, and warnings outside WORKING, change nothing
\* the protocol can see and are not modelled.
ActionInterruptedOk(a, e) == Running(a) /\ e \in Warnings
ActionInterrupted(a, e) ==
    [ ag  |-> [a EXCEPT !.wait = "CONTINUE", !.motors = "OFF"],
      out |-> <<Out(a.id, MasterId, "ACTION_INTERR", a.step, <<e>>)>> ]

\* The current action failed for reason f: motors stop, ACTION_ERR(action id, f), wait for
\* RESTART (or a new BEHAVIOUR).
ActionFailedOk(a) == Running(a)
ActionFailed(a, f) ==
    [ ag  |-> [a EXCEPT !.wait = "RESTART", !.motors = "OFF"],
      out |-> <<Out(a.id, MasterId, "ACTION_ERR", a.step, <<f>>)>> ]

\* A reading of the sensors the behaviour asked for.
SensorReportOk(a) == Running(a)
SensorReport(a) ==
    [ ag  |-> a,
      out |-> <<Out(a.id, MasterId, "SENSOR_VALUE", 0, <<"port", "mode", "value">>)>> ]

\* A device of the model is unplugged on port p (critical): the behaviour
\* stops and is unloaded, WORKING/PAUSED -> ACTIVE, BEHAVIOUR is refused
\* ("missing device") until it is back; a synced agent tells the master
\* EVENT(DEVICE_DISCONNECTED, p).
DeviceUnpluggedOk(a, p) == a.state # "OFF" /\ a.devOk /\ p \in Ports
DeviceUnplugged(a, p) ==
    LET b0 == [Stopped(a) EXCEPT !.devOk = FALSE, !.beh = NoBehaviour, !.step = 0]
        b  == IF a.state \in {"WORKING", "PAUSED"} THEN Goto(b0, "ACTIVE") ELSE b0
    IN [ ag  |-> b,
         out |-> IF a.state \in Synced
                 THEN <<Out(a.id, MasterId, "EVENT", 0, <<"DEVICE_DISCONNECTED", p>>)>>
                 ELSE <<>> ]

\* The last missing device of the model is plugged back in, on port p:
\* EVENT(DEVICE_CONNECTED, p) when synced.
DevicePluggedOk(a, p) == a.state # "OFF" /\ ~a.devOk /\ p \in Ports
DevicePlugged(a, p) ==
    [ ag  |-> [a EXCEPT !.devOk = TRUE],
      out |-> IF a.state \in Synced
              THEN <<Out(a.id, MasterId, "EVENT", 0, <<"DEVICE_CONNECTED", p>>)>>
              ELSE <<>> ]

\* Battery low (critical): tell the master (if synced), stop, shut down.
BatteryLowOk(a) == a.state # "OFF"
BatteryLow(a) ==
    [ ag  |-> Goto(Stopped(a), "OFF"),
      out |-> IF a.state \in Synced
              THEN <<Out(a.id, MasterId, "EVENT", 0, <<"BATTERY_LOW">>)>>
              ELSE <<>> ]

\* A robot event e on port p that changes nothing of the agent's protocol
\* state (RobotEvents: the bumper pressed, the ultrasonic's alert, a device
\* connected or unplugged that DevicePlugged / DeviceUnplugged do not take):
\* a synced agent tells the master EVENT(e, p).  Unsynced, there is no master
\* to tell (the agent logs it).  An event that interrupts the running action
\* is reported as ACTION_INTERR by ActionInterrupted instead: the robot side
\* chooses (docs/devices.md "Events"); both are allowed here.
RobotEventOk(a, e, p) == a.state \in Synced /\ e \in RobotEvents /\ p \in Ports
RobotEvent(a, e, p) ==
    [ ag  |-> a,
      out |-> <<Out(a.id, MasterId, "EVENT", 0, <<e, p>>)>> ]

-----------------------------------------------------------------------------
(* Allowed state changes: brief sec. 2, with the action that may cause each.*)
AllowedTransitions ==
    { <<"IDLE", "ACTIVE", "RecvMaster">>, <<"IDLE", "PANIC", "SyncTimeout">>,
      <<"ACTIVE", "WORKING", "RecvStart">>, <<"ACTIVE", "PANIC", "HeartbeatLost">>,
      <<"WORKING", "ACTIVE", "RecvStop">>, <<"WORKING", "ACTIVE", "RecvStandby">>,
      <<"WORKING", "PAUSED", "RecvPause">>, <<"WORKING", "PAUSED", "HeartbeatLost">>,
      <<"PAUSED", "WORKING", "RecvResume">>, <<"PAUSED", "WORKING", "RecvStart">>,
      <<"PAUSED", "ACTIVE", "RecvStop">>, <<"PAUSED", "PANIC", "HeartbeatLost">>,
      <<"PANIC", "ACTIVE", "RecvMaster">>,
      \* decided here (docs/spec.md): unplugged device, battery low
      <<"WORKING", "ACTIVE", "DeviceUnplugged">>, <<"PAUSED", "ACTIVE", "DeviceUnplugged">>,
      <<"IDLE", "OFF", "BatteryLow">>, <<"ACTIVE", "OFF", "BatteryLow">>,
      <<"WORKING", "OFF", "BatteryLow">>, <<"PAUSED", "OFF", "BatteryLow">>,
      <<"PANIC", "OFF", "BatteryLow">> }

\* A step of one agent from a to b by action name n respects the table.
TransitionOk(a, b, n) == a.state = b.state \/ <<a.state, b.state, n>> \in AllowedTransitions

\* Local invariants of one agent.
LedMatches(a)          == a.led = LedOf[a.state]
MotionOnlyWorking(a)   == a.motors = "ON" => a.state = "WORKING"
MotionOnlyRunning(a)   == a.motors = "ON" => a.wait = "NONE"
Supervised(a)          == a.state = "WORKING" => a.silence <= TLoss
=============================================================================
