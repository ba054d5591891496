-------------------------------- MODULE Agent --------------------------------
(***************************************************************************)
(* One agent against any environment: any message of wire types 1-20 that *)
(* can reach an agent arrives at any time, as often as the environment     *)
(* likes (so copies, resends and stale messages are all covered); time     *)
(* ticks; devices raise events; the behaviour finishes, fails or is        *)
(* interrupted.  Every action is one handler of the C++ core, same name;   *)
(* lastAction records the handler and its arguments, out what the agent    *)
(* emitted in that step, so every edge of TLC's state graph can be         *)
(* replayed against the implementation.                                    *)
(***************************************************************************)
EXTENDS Naturals, Sequences, Messages

CONSTANTS Behaviours, UnknownBehaviour, Refused, CheckReason, ModelName, TSync, TPing, TLoss,
          TPaused, Window, Steps, BUG,
          TempId,      \* the temporary id the agent draws at start
          AssignIds,   \* ids a master may assign it
          Stranger,    \* another agent's id (never this agent's)
          MsgIds,      \* msgids the master's datagrams carry (see EnvMsgs)
          EventPorts   \* ports the device events name (a subset of AgentLogic's Ports)

L == INSTANCE AgentLogic

ASSUME TempId \in L!TempIds /\ AssignIds \subseteq L!AssignedIds
       /\ Stranger \notin AssignIds \cup {TempId, MasterId, Broadcast}
       /\ EventPorts \subseteq L!Ports

VARIABLES
    ag,          \* the agent's local state (AgentLogic.AgentType)
    out,         \* the messages the agent emitted in the last step
    lastAction   \* [name |-> handler, args |-> its arguments]

vars == <<ag, out, lastAction>>

\* Messages the environment may deliver to the agent: every type that can
\* reach an agent, with representative fields.  All commands to the agent's
\* current id with every msgid; one command to another id and one to
\* broadcast (the address filter does not look at the type); MASTER to an
\* id a master may assign, naming this agent's id or another; PONG; an ACK
\* from the master; AGENT and PANIC broadcasts of another agent.
\* Msgids: any of MsgIds at any time.  A real master sends its msgids in
\* increasing order (with gaps: one counter for the whole fleet) and never
\* reuses one, and copies, resends and late datagrams carry older ones
\* (docs/protocol.md "Duplicates and stale copies"); all of that is among
\* these behaviours.  The agent acts on a command or MASTER only above every
\* msgid its window remembers from the master (AgentLogic Stale), so it acts
\* on at most Cardinality(MsgIds) of them per life: MsgIds is large enough
\* for every state and transition of the lifecycle (MASTER, BEHAVIOUR,
\* START, STOP, then one more command: 1..5 in MCAgent).
EnvMsgs ==
       {Msg(MasterId, d, i, "MASTER", p, <<>>) : d \in AssignIds, i \in MsgIds,
                                                 p \in {ag.id, Stranger}}
  \cup {Msg(MasterId, ag.id, i, "BEHAVIOUR", 0, <<b>>) :
            i \in MsgIds, b \in Behaviours \cup {UnknownBehaviour}}
  \cup {Msg(MasterId, ag.id, i, c, 0, <<>>) : i \in MsgIds, c \in Commands \ {"BEHAVIOUR"}}
  \cup {Msg(MasterId, Stranger, 1, "START", 0, <<>>)}
  \cup {Msg(MasterId, Broadcast, i, "STOP", 0, <<>>) : i \in MsgIds}
  \cup {Msg(MasterId, d, 0, "PONG", 0, <<>>) : d \in {ag.id, Stranger}}
  \cup {Msg(MasterId, ag.id, 0, "ACK", 0, <<>>)}
  \cup {Msg(Stranger, Broadcast, 0, "AGENT", 0, <<ModelName>>),
        Msg(Stranger, Broadcast, 0, "PANIC", 0, <<>>)}

-----------------------------------------------------------------------------
TypeOK ==
    /\ ag \in L!AgentType
    /\ out \in Seq(L!OutMsgs)
    /\ lastAction.name \in L!ActionNames \cup {"Init"}

Init ==
    /\ ag = L!InitAgent(TempId)
    /\ out = <<>>
    /\ lastAction = [name |-> "Init", args |-> <<>>]

Do(name, args, r) ==
    /\ ag' = r.ag
    /\ out' = r.out
    /\ lastAction' = [name |-> name, args |-> args]

-----------------------------------------------------------------------------
(* Timeouts are urgent: while SyncTimeout or HeartbeatLost is due, the     *)
(* agent takes no other step (no receive, no device or behaviour event, no  *)
(* Tick); the C++ core fires due timeouts first.                           *)
NoTimeoutDue == ~L!TimeoutDue(ag)

-----------------------------------------------------------------------------
(* Receive handlers: the environment delivers m; the agent dispatches it.   *)
(* Exactly one of them is enabled for each m while no timeout is due.       *)

\* Agent (IDLE/PANIC) takes MASTER naming its id: ACK, ACTIVE with new id.
RecvMaster(m) == NoTimeoutDue /\ L!RecvMasterOk(ag, m) /\ Do("RecvMaster", <<m>>, L!RecvMaster(ag, m))
\* Synced agent hears PONG: heartbeat.
RecvPong(m) == NoTimeoutDue /\ L!RecvPongOk(ag, m) /\ Do("RecvPong", <<m>>, L!RecvPong(ag, m))
\* Fresh BEHAVIOUR: the robot's check on receipt, then ACK and load, or NOT with a reason.
RecvBehaviour(m) == NoTimeoutDue /\ L!RecvBehaviourOk(ag, m) /\ Do("RecvBehaviour", <<m>>, L!RecvBehaviour(ag, m))
\* Fresh START: run the behaviour from its start, or NOT.
RecvStart(m) == NoTimeoutDue /\ L!RecvStartOk(ag, m) /\ Do("RecvStart", <<m>>, L!RecvStart(ag, m))
\* Fresh STOP: WORKING/PAUSED -> ACTIVE, or NOT.
RecvStop(m) == NoTimeoutDue /\ L!RecvStopOk(ag, m) /\ Do("RecvStop", <<m>>, L!RecvStop(ag, m))
\* Fresh PAUSE: WORKING -> PAUSED, or NOT.
RecvPause(m) == NoTimeoutDue /\ L!RecvPauseOk(ag, m) /\ Do("RecvPause", <<m>>, L!RecvPause(ag, m))
\* Fresh RESUME: PAUSED -> WORKING, or NOT.
RecvResume(m) == NoTimeoutDue /\ L!RecvResumeOk(ag, m) /\ Do("RecvResume", <<m>>, L!RecvResume(ag, m))
\* Fresh STANDBY: WORKING -> ACTIVE, or NOT.
RecvStandby(m) == NoTimeoutDue /\ L!RecvStandbyOk(ag, m) /\ Do("RecvStandby", <<m>>, L!RecvStandby(ag, m))
\* Fresh CONTINUE: end the wait after ACTION_INTERR, or NOT.
RecvContinue(m) == NoTimeoutDue /\ L!RecvContinueOk(ag, m) /\ Do("RecvContinue", <<m>>, L!RecvContinue(ag, m))
\* Fresh RESTART: rerun after ACTION_ERR, or NOT.
RecvRestart(m) == NoTimeoutDue /\ L!RecvRestartOk(ag, m) /\ Do("RecvRestart", <<m>>, L!RecvRestart(ag, m))
\* A copy of an answered command or MASTER: the stored answer again.
RecvDuplicate(m) == NoTimeoutDue /\ L!RecvDuplicateOk(ag, m) /\ Do("RecvDuplicate", <<m>>, L!RecvDuplicate(ag, m))
\* Anything else: dropped, nothing emitted.
Ignore(m) == NoTimeoutDue /\ L!Handler(ag, m) = "Ignore" /\ ag.state # "OFF"
             /\ Do("Ignore", <<m>>, L!Ignore(ag, m))

Receive(m) ==
    \/ RecvMaster(m) \/ RecvPong(m) \/ RecvBehaviour(m) \/ RecvStart(m)
    \/ RecvStop(m) \/ RecvPause(m) \/ RecvResume(m) \/ RecvStandby(m)
    \/ RecvContinue(m) \/ RecvRestart(m) \/ RecvDuplicate(m) \/ Ignore(m)

-----------------------------------------------------------------------------
(* Internal actions of the agent.                                           *)

\* The agent's timer fires (once per tick): maybe AGENT/PING/PANIC goes out.
\* (TickOk includes ~TimeoutDue.)
Tick == L!TickOk(ag) /\ Do("Tick", <<>>, L!Tick(ag))
\* IDLE for TSync ticks without MASTER: PANIC.
SyncTimeout == L!SyncTimeoutOk(ag) /\ Do("SyncTimeout", <<>>, L!SyncTimeout(ag))
\* Master silent for TLoss (TPaused in PAUSED) ticks.
HeartbeatLost == L!HeartbeatLostOk(ag) /\ Do("HeartbeatLost", <<>>, L!HeartbeatLost(ag))
\* The behaviour finished its current action.
ActionOk == NoTimeoutDue /\ L!ActionOkOk(ag) /\ Do("ActionOk", <<>>, L!ActionOk(ag))
\* A warning event the behaviour cannot resolve interrupts it.
ActionInterrupted(e) == NoTimeoutDue /\ L!ActionInterruptedOk(ag, e)
                        /\ Do("ActionInterrupted", <<e>>, L!ActionInterrupted(ag, e))
\* The current action failed, for reason f.
ActionFailed(f) == NoTimeoutDue /\ L!ActionFailedOk(ag) /\ Do("ActionFailed", <<f>>, L!ActionFailed(ag, f))
\* The behaviour reports a sensor reading.
SensorReport == NoTimeoutDue /\ L!SensorReportOk(ag) /\ Do("SensorReport", <<>>, L!SensorReport(ag))
\* The device registry detects an unplugged device of the model on port p.
DeviceUnplugged(p) == NoTimeoutDue /\ L!DeviceUnpluggedOk(ag, p)
                      /\ Do("DeviceUnplugged", <<p>>, L!DeviceUnplugged(ag, p))
\* The last missing device is back, on port p.
DevicePlugged(p) == NoTimeoutDue /\ L!DevicePluggedOk(ag, p)
                    /\ Do("DevicePlugged", <<p>>, L!DevicePlugged(ag, p))
\* A robot event that changes no protocol state (bumper, ultrasonic, a device
\* change the two above do not take): EVENT(e, p) to the master when synced.
RobotEvent(e, p) == NoTimeoutDue /\ L!RobotEventOk(ag, e, p)
                    /\ Do("RobotEvent", <<e, p>>, L!RobotEvent(ag, e, p))
\* The battery watcher reports low battery.
BatteryLow == NoTimeoutDue /\ L!BatteryLowOk(ag) /\ Do("BatteryLow", <<>>, L!BatteryLow(ag))

Next ==
    \/ \E m \in EnvMsgs : Receive(m)
    \/ Tick \/ SyncTimeout \/ HeartbeatLost
    \/ ActionOk \/ \E e \in L!Warnings : ActionInterrupted(e)
    \/ (\E f \in L!Failures : ActionFailed(f)) \/ SensorReport
    \/ \E p \in EventPorts : DeviceUnplugged(p) \/ DevicePlugged(p)
    \/ BatteryLow
    \/ \E e \in L!RobotEvents, p \in EventPorts : RobotEvent(e, p)

Spec == Init /\ [][Next]_vars

\* OFF (shut down after BatteryLow) is the only state without successors.
Halted == ag.state = "OFF"

-----------------------------------------------------------------------------
(* Properties.                                                              *)

\* The LEDs show the state's pattern.
LedInv == L!LedMatches(ag)
\* Motors run (a behaviour runs) only in WORKING.
BehaviourOnlyInWorkingInv == L!MotionOnlyWorking(ag)
\* The motors run only while the action runs: never while it waits for CONTINUE
\* (after ACTION_INTERR) or RESTART (after ACTION_ERR).
MotorsOnlyWhileRunningInv == L!MotionOnlyRunning(ag)
\* Never WORKING more than TLoss ticks after last hearing the master.
NoUnsupervisedMotionInv == L!Supervised(ag)
\* No command is acted on while its (sender, msgid) is in the window.
ActedOnceInv == ~ag.dupActed
\* A WORKING agent runs a behaviour it has loaded (START without one is refused).
WorkingLoadedInv == ag.state = "WORKING" => ag.beh # L!NoBehaviour
\* A loaded behaviour passed the robot's check on receipt: what the check refuses is never
\* ACKed, so it never runs (and a refused request leaves the loaded one as it was).
CheckedLoadedInv == ag.beh \notin Refused
\* Only OFF is terminal: in every other state some step is enabled (an agent that
\* freezes, e.g. never leaves WORKING when its master's heartbeat is lost, has none).
OnlyOffTerminalInv == ag.state # "OFF" => ENABLED Next
\* Every state change is one of brief sec. 2's table (action named).
AllowedTransitionsProp ==
    [][L!TransitionOk(ag, ag', lastAction'.name)]_vars
\* Answers (ACK/NOT) go only to messages addressed to the agent, to 0, or
\* a MASTER naming its id while it has no master.
AnswerAddressedProp ==
    [][\A i \in 1..Len(out') :
          out'[i].type \in {"ACK", "NOT"} =>
             /\ lastAction'.name \in L!RecvNames
             /\ L!AddressedTo(ag, lastAction'.args[1])]_vars
=============================================================================
