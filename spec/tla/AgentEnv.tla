------------------------------- MODULE AgentEnv -------------------------------
(***************************************************************************)
(* One agent (Agent.tla, unchanged) and what its environment really did:  *)
(* properties stated over what happened, not over the agent's             *)
(* own bookkeeping.                                                        *)
(*                                                                         *)
(*  - heard: history of the environment, ticks since a genuine datagram of *)
(*    the master (sender MasterId, addressed to the agent) last reached    *)
(*    the agent, saturated at Cap (> TPaused: every threshold is below it). *)
(*    The agent's own silence is not read by any property here.            *)
(*  - gone: the master is gone for good (MasterGone); from then on the     *)
(*    environment delivers no datagram of the master.                      *)
(*  - Peers and spoofed ids: besides Agent's EnvMsgs, the environment      *)
(*    delivers MASTER, commands and PONG from ids that are not the         *)
(*    master's (PeerSrcs: a peer's id, an unsynced agent's temporary id).  *)
(*  - The agent crashes and restarts (Reboot): it comes back as at Init,   *)
(*    with a new temporary id drawn (here the same TempId), nothing kept.  *)
(*  - first: history, for every (sender, msgid) the agent answered afresh *)
(*    (acted on, or refused) in this life, the answer it gave then (ACK,   *)
(*    or NOT and its reason); kept by the environment, not read from the   *)
(*    agent's window, and not bounded by it: a window that forgets too     *)
(*    early, is keyed wrongly, or lets a copy delayed past Window newer    *)
(*    commands through is invisible to ActedOnceInv, which reads the       *)
(*    window itself (spec mutations A05, A10, docs/spec.md).  A reboot     *)
(*    empties it (the agent's window is lost with it).  again: the last    *)
(*    step answered afresh a datagram already in it.                       *)
(*                                                                         *)
(* Older epochs (a fenced master) are Election.tla's (StaleMasterFenced-   *)
(* Inv): the one-agent model has one master.                               *)
(***************************************************************************)
EXTENDS Agent

CONSTANT PeerSrcs   \* sender ids that are not the master's

ASSUME MasterId \notin PeerSrcs

VARIABLES heard, gone, first, again

envVars == <<ag, out, lastAction, heard, gone, first, again>>

Cap == TPaused + 1

\* Datagrams from anyone but the master: the commands the agent acts on, MASTER naming its
\* id (to an id a master may assign), PONG.
PeerMsgs ==
       {Msg(s, ag.id, i, c, 0, <<>>) : s \in PeerSrcs, i \in MsgIds,
                                        c \in {"START", "STOP", "PAUSE", "RESUME"}}
  \cup {Msg(s, ag.id, 1, "BEHAVIOUR", 0, <<b>>) : s \in PeerSrcs, b \in Behaviours}
  \cup {Msg(s, d, 1, "MASTER", ag.id, <<>>) : s \in PeerSrcs, d \in AssignIds}
  \cup {Msg(s, ag.id, 0, "PONG", 0, <<>>) : s \in PeerSrcs}

\* A datagram of the master that reaches the agent (whatever the agent does with it).
Genuine(m) == m.src = MasterId /\ L!AddressedTo(ag, m)

EnvInit == Init /\ heard = 0 /\ gone = FALSE /\ first = {} /\ again = FALSE

\* The handlers that answer a datagram afresh: act on it (or refuse it) and ACK (NOT) it.
FreshAnswers == L!RecvNames \ {"RecvPong", "RecvDuplicate", "Ignore"}

\* What the agent answered in a step that emitted o: each ACK or NOT, its sender field cleared (a
\* MASTER's ACK carries the id it was given; the master reads the type, ref and reason).
Replies(o) == {[o[j] EXCEPT !.src = 0] : j \in {k \in 1..Len(o) : o[k].type \in {"ACK", "NOT"}}}
\* m's (sender, msgid) was answered afresh before, in this life.
Known(m) == \E f \in first : f.src = m.src /\ f.msgid = m.msgid

Deliver(m) ==
    /\ m.src = MasterId => ~gone
    /\ Receive(m)
    /\ heard' = IF Genuine(m) THEN 0 ELSE heard
    /\ first' = IF lastAction'.name \in FreshAnswers /\ ~Known(m)
                THEN first \cup {[src |-> m.src, msgid |-> m.msgid, ans |-> Replies(out')]}
                ELSE first
    /\ again' = (lastAction'.name \in FreshAnswers /\ Known(m))
    /\ UNCHANGED gone

TickE == Tick /\ heard' = (IF heard < Cap THEN heard + 1 ELSE Cap) /\ again' = FALSE
         /\ UNCHANGED <<gone, first>>
HeartbeatLostE == HeartbeatLost /\ again' = FALSE /\ UNCHANGED <<heard, gone, first>>
SyncTimeoutE == SyncTimeout /\ again' = FALSE /\ UNCHANGED <<heard, gone, first>>

Internal ==
    /\ \/ ActionOk \/ \E e \in L!Warnings : ActionInterrupted(e)
       \/ (\E f \in L!Failures : ActionFailed(f)) \/ SensorReport
       \/ \E p \in EventPorts : DeviceUnplugged(p) \/ DevicePlugged(p)
       \/ BatteryLow
       \/ \E e \in L!RobotEvents, p \in EventPorts : RobotEvent(e, p)
    /\ again' = FALSE
    /\ UNCHANGED <<heard, gone, first>>

\* The master is gone for good.
MasterGone == ~gone /\ gone' = TRUE /\ again' = FALSE
              /\ UNCHANGED <<ag, out, lastAction, heard, first>>

\* The agent crashes (power, firmware) and starts again from scratch.
Reboot ==
    /\ ag.state # "OFF"
    /\ ag' = L!InitAgent(TempId)
    /\ out' = <<>>
    /\ lastAction' = [name |-> "Init", args |-> <<>>]
    /\ first' = {}
    /\ again' = FALSE
    /\ UNCHANGED <<heard, gone>>

EnvNext ==
    \/ \E m \in EnvMsgs \cup PeerMsgs : Deliver(m)
    \/ TickE \/ SyncTimeoutE \/ HeartbeatLostE
    \/ Internal
    \/ MasterGone \/ Reboot

\* Time passes and due timeouts fire.
EnvFairness == WF_envVars(TickE) /\ WF_envVars(HeartbeatLostE) /\ WF_envVars(SyncTimeoutE)

EnvSpec == EnvInit /\ [][EnvNext]_envVars /\ EnvFairness

-----------------------------------------------------------------------------
(* Properties.                                                              *)

\* No motion without a master: WORKING (motors may run) only while a genuine datagram of
\* the master reached the agent within the last TLoss ticks.
MotionHeardInv == ag.state = "WORKING" => heard <= TLoss

\* Every timeout fires on time, by the environment's clock: ACTIVE only while the master was
\* heard within TLoss ticks, PAUSED within TPaused (the agent's timeouts may not be late).
SyncedHeardInv ==
    /\ ag.state = "ACTIVE" => heard <= TLoss
    /\ ag.state = "PAUSED" => heard <= TPaused

\* No datagram is answered afresh (acted on) twice in a life: a copy gets the stored answer
\* (RecvDuplicate) while the window remembers it, and is ignored as stale after, however many
\* newer commands came between.
AnsweredOnceInv == ~again

\* A copy gets the answer the original got: whatever the agent answers to a datagram whose
\* (sender, msgid) it answered afresh before in this life is that first answer (a copy of a
\* refused command is refused again, not ACKed).
StoredAnswerProp ==
    [][lastAction'.name \in L!RecvNames =>
         \A f \in first : f.src = lastAction'.args[1].src /\ f.msgid = lastAction'.args[1].msgid
                          /\ Replies(out') # {} => Replies(out') = f.ans]_envVars

\* Datagrams not from the master change nothing the agent does: no state change, nothing
\* emitted.
NotFromMasterInertProp ==
    [][lastAction'.name \in L!RecvNames /\ lastAction'.args[1].src # MasterId
         => ag' = ag /\ out' = <<>>]_envVars

\* A WORKING agent whose master is gone leaves WORKING.
MasterGoneLeavesWorking == (gone /\ ag.state = "WORKING") ~> ag.state # "WORKING"

\* Every state change is one of brief sec. 2's table, or a reboot (lastAction Init).
TransitionsProp ==
    [][lastAction'.name = "Init" \/ L!TransitionOk(ag, ag', lastAction'.name)]_envVars

\* The views: out and lastAction name the last step (for traces); no successor depends on them.
\* EnvView (MCAgentEnv.cfg) also leaves out the history of first answers, which only
\* AnsweredOnceInv and StoredAnswerProp read: they are checked with CopiesView
\* (MCAgentEnvCopies.cfg), where two states that differ in it stay apart.
EnvView == <<ag, heard, gone>>
CopiesView == <<ag, heard, gone, first, again>>
=============================================================================
