-------------------------------- MODULE Fleet --------------------------------
(***************************************************************************)
(* One master and the agents in Agents over a network that loses,         *)
(* duplicates and reorders datagrams.  Agents run AgentLogic unchanged,    *)
(* the master runs MasterLogic unchanged.  An operator (environment) gives *)
(* the master commands; the master syncs agents (AGENT/PANIC -> MASTER     *)
(* with an id), answers PINGs of synced agents with PONG, resends each     *)
(* pending command every tick until ACK or NOT, reconciles agents whose    *)
(* reported state differs from what the operator asked, and may crash and  *)
(* restart with an empty registry.  An agent may crash too (its volatile   *)
(* state is lost: OFF while down, then a fresh IDLE agent with a new       *)
(* temporary id and msgid counter, as agent/main.cpp starts one), and may  *)
(* time out although the master is alive (a false suspicion: its PONGs    *)
(* late, its clock fast).                                                  *)
(*                                                                         *)
(* Time is discrete: Tick advances every agent's timers and the master's   *)
(* together.  A datagram is delivered or lost within the tick it was sent  *)
(* in, or late: each datagram still in flight when time passes spends one  *)
(* unit of the late budget (so a datagram may arrive ticks after it was    *)
(* sent, after the timeouts it should have prevented, after a copy, after *)
(* the crash of its sender or of its receiver).  Order is arbitrary.      *)
(* Loss, duplication, lateness, crashes, false suspicions and operator     *)
(* commands each have a budget (set in the cfg): the network eventually    *)
(* stops losing.                                                           *)
(*                                                                         *)
(* Extension point for relay and election (types 21-39): new endpoint      *)
(* roles and master-side state go into MasterLogic / a new variable, new   *)
(* message handlers into MasterRecv / AgentRecv; network and time stay.    *)
(***************************************************************************)
EXTENDS Naturals, Sequences, FiniteSets, TLC, Messages

CONSTANTS Behaviours, UnknownBehaviour, ModelName, TSync, TPing, TLoss,
          TPaused, Window, Steps, BUG,
          Agents,      \* the agents' endpoints (model values: a symmetry set)
          TDrop,       \* master drops an agent not heard for TDrop ticks
          MaxResends,  \* an operator command fails after this many resends
          MaxLoss,     \* datagrams the network may lose, in all
          MaxDup,      \* datagrams the network may duplicate, in all
          MaxCrashes,  \* master crashes, in all
          MaxOps,      \* operator commands, in all
          MaxLate,     \* datagram-ticks of delay: a datagram in flight when time passes costs one
          MaxAgentCrashes, \* agent crashes, in all
          MaxSuspect   \* false suspicions (a timeout while the master is alive), in all

\* Every behaviour the operator runs passes the robots' check on receipt (its refusal is
\* MCAgent's: Agent.tla).
L == INSTANCE AgentLogic WITH Refused <- {}, CheckReason <- "refused by the check"
M == INSTANCE MasterLogic WITH ExactMsgids <- FALSE

MasterEp == 0                      \* endpoint (address) of the master
Endpoints == Agents \cup {MasterEp}
\* Agent a draws temporary id TempOf(a): any injective choice.  Temporary ids
\* are only compared for equality, so the spec is symmetric in Agents.
TempIdx == CHOOSE f \in [Agents -> 1..Cardinality(Agents)] :
               \A x, y \in Agents : x # y => f[x] # f[y]
TempOf(a) == 50000 + TempIdx[a]
\* Temporary ids an agent may draw when it starts again after the c-th agent
\* crash (agent/main.cpp draws one at random): one no agent has drawn before,
\* or the one it drew last time (a is the agent that crashed last) -- the
\* same random draw again, which once left the agent in PANIC for ever
\* (MasterLogic MasterSync, BUG "HeardByTemp").  RestartTempOf(a, 0) = TempOf(a).
RestartTempOf(a, c) == 50000 + c * Cardinality(Agents) + TempIdx[a]
RestartTemps(a, c) == {RestartTempOf(a, c - 1), RestartTempOf(a, c)}
Mission == CHOOSE b \in Behaviours : TRUE   \* what the operator runs

VARIABLES
    ag,          \* ag[a]: agent a's local state (AgentLogic)
    net,         \* datagrams in flight: [from, to : Endpoints, m : message]
    up,          \* the master is running
    ms,          \* the master's local state (MasterLogic)
    sess,        \* sess[a]: answers (ACK/NOT) agent a has sent (its msgid stamp, below)
    budget,      \* [loss, dup, crash, ops]: what the environment may still do
    lost,        \* lost[a]: history, agent a was synced when the master crashed
    life,        \* life[a]: history, agent a's restarts so far (its life: 0 until the first)
    acted        \* history: a record [agent, life, src, mid, n] each time an agent acted on
                 \*   a command or MASTER (CommandOnceInv)

vars == <<ag, net, up, ms, sess, budget, lost, life, acted>>

TypeOK ==
    /\ \A a \in Agents : ag[a] \in L!AgentType
    /\ \A e \in net : e.from \in Endpoints /\ e.to \in Endpoints
    /\ up \in BOOLEAN
    /\ M!MasterType(ms, Agents, Behaviours)
    /\ sess \in [Agents -> Nat]
    /\ budget \in [loss : Nat, dup : Nat, crash : Nat, ops : Nat, late : Nat, acrash : Nat,
                  suspect : Nat]
    /\ lost \in [Agents -> BOOLEAN]
    /\ life \in [Agents -> Nat]
    /\ \A h \in acted : h.agent \in Agents /\ h.life \in Nat /\ h.mid \in Nat /\ h.n \in Nat

Init ==
    /\ ag = [a \in Agents |-> L!InitAgent(TempOf(a))]
    /\ net = {}
    /\ up = TRUE
    /\ ms = M!InitMaster(Agents)
    /\ sess = [a \in Agents |-> 0]
    /\ budget = [loss |-> MaxLoss, dup |-> MaxDup, crash |-> MaxCrashes, ops |-> MaxOps,
                  late |-> MaxLate, acrash |-> MaxAgentCrashes, suspect |-> MaxSuspect]
    /\ lost = [a \in Agents |-> FALSE]
    /\ life = [a \in Agents |-> 0]
    /\ acted = {}

\* The msgid an agent's datagram carries.  Real msgids grow by one per
\* datagram (unbounded); the master only compares them ("above every msgid
\* heard from that agent": the PANIC resync guard, and reconcile, which only
\* a PING newer than the agent's last answer may trigger).  The fleet stamps
\* the coarse, order-preserving image 4*s + slot, s the answers the agent has
\* sent (sess; the ACK of MASTER is one), slot 0 for an answer, 1 for a PING
\* or report, 2 in PANIC: every answer compares above what the agent sent
\* before it, a PING after an answer above that answer, the first PANIC
\* above the PINGs and answers before it, copies of one PANIC equal.  Only
\* PINGs between the same two answers compare equal (MasterPing: >=)
\* (docs/spec.md).
Answer(o) == o.type \in {"ACK", "NOT"}
Stamp(o, s, st) == [src |-> o.src, dst |-> o.dst,
                    msgid |-> 4 * s + (CASE Answer(o) -> 0 [] st = "PANIC" -> 2 [] OTHER -> 1),
                    type |-> o.type, ref |-> o.ref, args |-> o.args]
\* Datagrams for what agent a emits (in its state b, session s).  Agents
\* emit to the master or broadcast (AGENT, PANIC); a broadcast reaches the
\* other agents too, but an agent ignores other agents' broadcasts (checked
\* in Agent.tla), so the fleet routes them to the master only.
Emit(a, outs, s, b) ==
    {[from |-> a, to |-> MasterEp, m |-> Stamp(outs[i], s, b.state)] : i \in 1..Len(outs)}
\* Datagrams for what the master emits.
MEmit(outs) == {[from |-> MasterEp, to |-> o.to, m |-> o.m] : o \in outs}

-----------------------------------------------------------------------------
(* The network.                                                             *)

\* The network loses a datagram (while the loss budget lasts).
Lose(e) == /\ budget.loss > 0
           /\ net' = net \ {e}
           /\ budget' = [budget EXCEPT !.loss = @ - 1]
           /\ UNCHANGED <<ag, up, ms, sess, lost, life, acted>>

-----------------------------------------------------------------------------
(* Agents.                                                                  *)

\* What the history records when agent a takes m: m is a command or MASTER
\* (answered with ACK or NOT) and a acts on it -- runs its handler, not
\* RecvDuplicate's stored answer nor Ignore.  The command is the datagram
\* the master sent: its sender and msgid, at the agent that took it, in that
\* agent's life.  The master's msgids are never reused (they survive its
\* crashes: MasterLogic CrashMaster; master/main.cpp --state-file reserves
\* them in blocks), and a resend carries the msgid of the first send, so
\* equal (src, mid) at one agent means copies of one command, in any master
\* session.  An agent that restarted is a new life: a copy reaching it again
\* is not the same agent acting twice.  n counts the times: 1 the first.
ActHandlers == {"RecvMaster", "RecvBehaviour", "RecvStart", "RecvStop", "RecvPause",
                "RecvResume", "RecvStandby", "RecvContinue", "RecvRestart"}
Acts(a, m) ==
    LET n == Cardinality({h \in acted : h.agent = a /\ h.life = life[a]
                                        /\ h.src = m.src /\ h.mid = m.msgid})
    IN IF L!Handler(ag[a], m) \in ActHandlers /\ L!Answered(m)
       THEN {[agent |-> a, life |-> life[a], src |-> m.src, mid |-> m.msgid, n |-> n + 1]}
       ELSE {}

\* Agent a receives datagram e (the copy stays in flight if duplicated).
\* Timeouts are urgent (as in Agent.tla): while one of a's timeouts is due,
\* nothing is delivered to a -- the timeout fires first (AgentTimeout); the
\* network may still lose the datagram or deliver others.
AgentRecv(a, e, dup) ==
    LET r == L!Receive(ag[a], e.m)
        s == IF \E i \in 1..Len(r.out) : Answer(r.out[i]) THEN sess[a] + 1 ELSE sess[a]
    IN
    /\ e.to = a
    /\ ~L!TimeoutDue(ag[a])
    /\ ag' = [ag EXCEPT ![a] = r.ag]
    /\ sess' = [sess EXCEPT ![a] = s]
    /\ net' = (IF dup THEN net ELSE net \ {e}) \cup Emit(a, r.out, s, r.ag)
    /\ lost' = [lost EXCEPT ![a] = lost[a] /\ r.ag.state # "PANIC"]
    /\ acted' = acted \cup Acts(a, e.m)
    /\ UNCHANGED <<up, ms, life>>

\* Agent a's timeout fires (SyncTimeout or HeartbeatLost).
AgentTimeout(a) ==
    LET r == IF L!SyncTimeoutOk(ag[a]) THEN L!SyncTimeout(ag[a]) ELSE L!HeartbeatLost(ag[a]) IN
    /\ L!SyncTimeoutOk(ag[a]) \/ L!HeartbeatLostOk(ag[a])
    /\ ag' = [ag EXCEPT ![a] = r.ag]
    /\ net' = net \cup Emit(a, r.out, sess[a], r.ag)
    /\ lost' = [lost EXCEPT ![a] = lost[a] /\ r.ag.state # "PANIC"]
    /\ UNCHANGED <<up, ms, sess, budget, life, acted>>

\* False suspicion: synced agent a's heartbeat timeout fires before it is due,
\* whether or not the master is alive (HeartbeatLost's effect: WORKING ->
\* PAUSED, ACTIVE or PAUSED -> PANIC).  The master must take it back.
AgentSuspect(a) ==
    LET r == L!HeartbeatLost(ag[a]) IN
    /\ budget.suspect > 0
    /\ ag[a].state \in L!Synced /\ ~L!TimeoutDue(ag[a])
    /\ ag' = [ag EXCEPT ![a] = r.ag]
    /\ net' = net \cup Emit(a, r.out, sess[a], r.ag)
    /\ budget' = [budget EXCEPT !.suspect = @ - 1]
    /\ lost' = [lost EXCEPT ![a] = lost[a] /\ r.ag.state # "PANIC"]
    /\ UNCHANGED <<up, ms, sess, life, acted>>

\* Agent a crashes (power cut, reset): the motors stop, it is down (OFF: it
\* neither sends nor takes anything) until AgentRestart.
AgentCrash(a) ==
    /\ budget.acrash > 0
    /\ ag[a].state # "OFF"
    /\ ag' = [ag EXCEPT ![a] = L!Goto(L!Stopped(ag[a]), "OFF")]
    /\ budget' = [budget EXCEPT !.acrash = @ - 1]
    /\ UNCHANGED <<net, up, ms, sess, lost, life, acted>>

\* Agent a starts again as agent/main.cpp starts it: nothing of the lifecycle
\* survives (the election's epoch and vote, on its SD card, are not in this
\* spec): IDLE with a temporary id and a new msgid counter, drawn at random --
\* the temporary id fresh or its last one again (RestartTemps), the msgids
\* above or below every msgid of its previous life (sess kept or reset).  It
\* no longer was synced when the master crashed (lost).
AgentRestart(a) ==
    /\ ag[a].state = "OFF"
    /\ \E t \in RestartTemps(a, MaxAgentCrashes - budget.acrash) :
          ag' = [ag EXCEPT ![a] = L!InitAgent(t)]
    /\ \E s \in {0, sess[a]} : sess' = [sess EXCEPT ![a] = s]
    /\ lost' = [lost EXCEPT ![a] = FALSE]
    /\ life' = [life EXCEPT ![a] = @ + 1]
    /\ UNCHANGED <<net, up, ms, budget, acted>>

-----------------------------------------------------------------------------
(* The master and its operator.                                             *)

\* The master (when up) receives datagram e; a crashed master drops it.  With
\* dup a copy stays in flight, as for an agent (AgentRecv).
MasterRecv(e, dup) ==
    /\ e.to = MasterEp
    /\ LET rest == IF dup THEN net ELSE net \ {e}
       IN IF ~up THEN net' = rest /\ UNCHANGED ms
          ELSE LET r == M!Receive(ms, e.m, e.from)
               IN /\ ms' = r.ms
                  /\ net' = rest \cup MEmit(r.out)
    /\ UNCHANGED <<ag, up, sess, lost, life, acted>>

\* The operator's mission: every registered agent runs Mission.  It gives
\* agent a's entry the next command when nothing is queued or pending:
\* BEHAVIOUR until one is ACKed, then START until asked.  After a crash or
\* a drop the entry is new and the operator starts again.  The operator acts
\* between deliveries, when the network has drained (as Tick): its timing
\* relative to one tick's datagrams does not matter, and it keeps TLC fast.
OpNext(x) == IF x.beh = M!NoBehaviour THEN M!Cmd("BEHAVIOUR", Mission) ELSE M!Cmd0("START")
OpWanted(x) == x.synced /\ ~x.pending /\ x.queue = <<>>
               /\ (x.beh = M!NoBehaviour \/ x.desired # "WORKING")
Operate(a) ==
    /\ up /\ budget.ops > 0 /\ net = {}
    /\ \E x \in ms.reg :
          /\ x.ep = a /\ OpWanted(x)
          /\ LET r == M!MasterCommand(ms, x.id, OpNext(x)) IN
             /\ ms' = r.ms
             /\ net' = net \cup MEmit(r.out)
    /\ budget' = [budget EXCEPT !.ops = @ - 1]
    /\ UNCHANGED <<ag, up, sess, lost, life, acted>>

\* The master crashes: registry gone; nextId and msgid survive.
MasterCrash ==
    /\ up /\ budget.crash > 0
    /\ up' = FALSE
    /\ ms' = M!CrashMaster(ms)
    /\ budget' = [budget EXCEPT !.crash = @ - 1]
    /\ lost' = [a \in Agents |-> ag[a].state \in L!Synced]
    /\ UNCHANGED <<ag, net, sess, life, acted>>

\* The master restarts with an empty registry.
MasterRestart ==
    /\ ~up
    /\ up' = TRUE
    /\ UNCHANGED <<ag, net, ms, sess, budget, lost, life, acted>>

-----------------------------------------------------------------------------
(* Delivery and time.                                                       *)

\* The network delivers e to its endpoint; with dup, a copy stays in flight.
Deliver(e, dup) ==
    /\ dup => budget.dup > 0
    /\ IF dup THEN budget' = [budget EXCEPT !.dup = @ - 1] ELSE UNCHANGED budget
    /\ IF e.to = MasterEp THEN MasterRecv(e, dup) ELSE AgentRecv(e.to, e, dup)

DeliverAny == \E e \in net : Deliver(e, FALSE)

\* One tick of time, once no timeout is due: every agent's timers advance
\* (periodic AGENT/PING/PANIC go out, a running behaviour reports ACTION_OK),
\* and the master's MasterTick (resends, failures, drops).  The datagrams
\* still in flight stay, each one tick late (the late budget pays for it).
Tick ==
    LET t == [a \in Agents |-> L!Tick(ag[a])]
        \* a running behaviour finishes one action per tick: ACTION_OK, unless
        \* the tick made a timeout due (it fires first: AgentTimeout)
        r == [a \in Agents |->
                IF L!ActionOkOk(t[a].ag) /\ ~L!TimeoutDue(t[a].ag)
                THEN [ag |-> L!ActionOk(t[a].ag).ag,
                      out |-> t[a].out \o L!ActionOk(t[a].ag).out]
                ELSE t[a]]
        live == {a \in Agents : ag[a].state # "OFF"}
        mt == M!MasterTick(ms)
    IN
    /\ Cardinality(net) <= budget.late
    /\ \A a \in live : L!TickOk(ag[a])
    /\ ag' = [a \in Agents |-> IF a \in live THEN r[a].ag ELSE ag[a]]
    /\ ms' = IF up THEN mt.ms ELSE ms
    /\ net' = net \cup UNION {Emit(a, r[a].out, sess[a], r[a].ag) : a \in live}
              \cup (IF up THEN MEmit(mt.out) ELSE {})
    /\ budget' = [budget EXCEPT !.late = @ - Cardinality(net)]
    /\ UNCHANGED <<up, sess, lost, life, acted>>

Next ==
    \/ \E e \in net : Deliver(e, FALSE) \/ Deliver(e, TRUE) \/ Lose(e)
    \/ \E a \in Agents : AgentTimeout(a) \/ Operate(a)
    \/ \E a \in Agents : AgentSuspect(a) \/ AgentCrash(a) \/ AgentRestart(a)
    \/ MasterCrash \/ MasterRestart
    \/ Tick

Fairness ==
    /\ WF_vars(DeliverAny)
    /\ \A a \in Agents : WF_vars(AgentTimeout(a)) /\ SF_vars(Operate(a)) /\ WF_vars(AgentRestart(a))
    /\ WF_vars(MasterRestart)
    /\ WF_vars(Tick)

Spec == Init /\ [][Next]_vars
FairSpec == Spec /\ Fairness

-----------------------------------------------------------------------------
(* Safety.                                                                  *)

LedInv == \A a \in Agents : L!LedMatches(ag[a])
BehaviourOnlyInWorkingInv == \A a \in Agents : L!MotionOnlyWorking(ag[a])
NoUnsupervisedMotionInv == \A a \in Agents : L!Supervised(ag[a])
\* However many copies arrive, no agent acts on a command twice -- as the agent
\* itself sees it: never while its window remembers the command (dupActed).
ActedOnceInv == \A a \in Agents : ~ag[a].dupActed
\* What happened (the history acted, not the agent's window): no command or
\* MASTER datagram the master sent -- one (src, msgid), with all its copies
\* and resends -- is acted on twice by one agent in one life, however late
\* or often it arrives (after its entry left the FIFO window, after a
\* resync, after a crash of the master).
CommandOnceInv == \A h \in acted : h.n = 1
\* Two synced agents never hold the same id.
UniqueIdsInv ==
    \A a, b \in Agents : a # b /\ ag[a].state \in L!Synced /\ ag[b].state \in L!Synced
                         => ag[a].id # ag[b].id
\* The master's registry never holds one id twice.
RegistryInv == \A x, y \in ms.reg : x.id = y.id => x = y
\* A correct run draws a bounded number of msgids: the protocol converges, so what makes the
\* master draw again is paid for by the budgets.  Per agent endpoint: the first sync, one msgid
\* per operator command, and per fault (a loss, a duplicate, a crash, a late datagram, an agent's
\* crash, a false suspicion) at most Redraws: the resync's MASTER and the commands reconcile
\* restores the agent with (BEHAVIOUR, START).  With 2, fleet_suspect exceeds it.  A run that
\* refuses and resends a command, or resyncs an agent, for ever exceeds it: a violation with a
\* trace (within a minute on fleet_late, spec mutation M14), not a state space that never ends.
\* Checked by the make-spec fleet models (the spec-full ones rely on the run limit).
Redraws == 3
Faults == MaxLoss + MaxDup + MaxCrashes + MaxLate + MaxAgentCrashes + MaxSuspect
CounterBoundInv ==
    \A k \in DOMAIN ms.msgid : ms.msgid[k] <= 1 + Redraws * (1 + Faults) + MaxOps
\* (A crash -- any state to OFF, the acrash budget spent -- and a restart --
\* OFF to IDLE -- are not the agent's transitions.)
AllowedTransitionsProp ==
    [][\A a \in Agents : \/ ag[a].state = ag'[a].state
                         \/ \E t \in L!AllowedTransitions :
                               t[1] = ag[a].state /\ t[2] = ag'[a].state
                         \/ ag'[a].state = "OFF" /\ budget'.acrash < budget.acrash
                         \/ ag[a].state = "OFF" /\ ag'[a].state = "IDLE"]_vars

(* Liveness, under Fairness, once the budgets are spent.                    *)

\* Every agent eventually is, and stays, ACTIVE-or-later with an id.
EventuallySynced == \A a \in Agents : <>[](ag[a].state \in L!Synced)
\* The operator's BEHAVIOUR and START, resent until answered, take effect
\* and are kept in effect (reconcile): every agent ends up WORKING for good.
CommandsTakeEffect == \A a \in Agents : <>[](ag[a].state = "WORKING")
\* After a master crash every agent synced then leaves WORKING and panics.
CrashLeadsToPanic == \A a \in Agents : lost[a] ~> ag[a].state = "PANIC"
\* An agent in PANIC resyncs (once the master is back).
Resync == \A a \in Agents : ag[a].state = "PANIC" ~> ag[a].state \in L!Synced
\* Resync and restore: while the master wants an agent WORKING (the entry of its endpoint has
\* desired WORKING), the agent gets there -- through a false suspicion, a resync, reconcile's
\* BEHAVIOUR and START -- unless the master stops wanting it (a new command, a refusal, a drop).
\* Checked on fleet_suspect: CommandsTakeEffect implies it, and without operator commands it is
\* vacuous (no entry wants WORKING).
Wanted(a) == \E x \in ms.reg : x.ep = a /\ x.desired = "WORKING"
Restored == \A a \in Agents : Wanted(a) ~> (ag[a].state = "WORKING" \/ ~Wanted(a))
\* The master and every agent agree in the end: the agent is synced and the
\* master holds it, synced, under the same id, for good (an agent synced to
\* nobody -- PONGed by a master whose MASTER it ignores -- fails it).
EventuallyRegistered ==
    \A a \in Agents : <>[](/\ ag[a].state \in L!Synced
                          /\ \E x \in ms.reg : x.ep = a /\ x.id = ag[a].id /\ x.synced)

\* Symmetry of the full model (safety only: TLC forbids it with liveness).
Symmetry == Permutations(Agents)
=============================================================================
