-------------------------------- MODULE Fleet --------------------------------
(***************************************************************************)
(* One master and N agents over a network that loses, duplicates and       *)
(* reorders datagrams.  Agents run AgentLogic unchanged.  The master syncs *)
(* agents (AGENT/PANIC -> MASTER with an id), answers PINGs of registered  *)
(* agents with PONG, drives each agent through BEHAVIOUR then START (every *)
(* command resent each tick until ACK or NOT), collects reports, and may   *)
(* crash and restart with an empty registry.                               *)
(*                                                                         *)
(* Time is discrete: Tick advances every agent's timers together and is    *)
(* taken only when the network has drained (bounded delay: a datagram is   *)
(* delivered or lost within the tick it was sent in; order within a tick  *)
(* is arbitrary).  Loss, duplication and crashes each have a budget (set   *)
(* in the MC module): the network eventually stops losing.                 *)
(*                                                                         *)
(* Extension point for relay and election (types 21-39): new endpoint      *)
(* roles and master-side state go into `master', new message handlers into *)
(* MasterRecv / AgentRecv; the network and time model stay as they are.    *)
(***************************************************************************)
EXTENDS Naturals, Sequences, FiniteSets, Messages

CONSTANTS Behaviours, UnknownBehaviour, ModelName, TSync, TPing, TLoss,
          TPaused, Window, Steps, BUG,
          N,           \* number of agents
          TDrop,       \* master drops an agent not heard for TDrop ticks
          MaxLoss,     \* datagrams the network may lose, in all
          MaxDup,      \* datagrams the network may duplicate, in all
          MaxCrashes   \* master crashes, in all

L == INSTANCE AgentLogic

Agents == 1..N
MasterEp == 0                      \* endpoint (address) of the master
Endpoints == Agents \cup {MasterEp}
TempOf(a) == 50000 + a             \* temporary id agent a draws
Job == {"MASTER", "BEHAVIOUR", "START", "RESUME", "DONE"}  \* command pending per agent

VARIABLES
    ag,          \* ag[a]: agent a's local state (AgentLogic)
    net,         \* datagrams in flight: [from, to : Endpoints, m : message]
    master,      \* [up, reg, nextId, msgid]; msgid[a]: next msgid towards agent a
    budget,      \* [loss, dup, crash]: what the environment may still do
    lost         \* lost[a]: history, agent a was synced when the master crashed

vars == <<ag, net, master, budget, lost>>

\* A registry entry: announced id, assigned id, endpoint, pending command,
\* its msgid, ticks since the agent was last heard.
RegEntry == [ann : Nat, id : Nat, ep : Agents, job : Job, mid : Nat, quiet : Nat]

TypeOK ==
    /\ \A a \in Agents : ag[a] \in L!AgentType
    /\ \A e \in net : e.from \in Endpoints /\ e.to \in Endpoints
    /\ master.up \in BOOLEAN
    /\ master.reg \subseteq RegEntry
    /\ master.nextId \in L!AssignedIds
    /\ master.msgid \in [Agents -> Nat \ {0}]
    /\ budget \in [loss : Nat, dup : Nat, crash : Nat]
    /\ lost \in [Agents -> BOOLEAN]

Init ==
    /\ ag = [a \in Agents |-> L!InitAgent(TempOf(a))]
    /\ net = {}
    /\ master = [up |-> TRUE, reg |-> {}, nextId |-> 2, msgid |-> [a \in Agents |-> 1]]
    /\ budget = [loss |-> MaxLoss, dup |-> MaxDup, crash |-> MaxCrashes]
    /\ lost = [a \in Agents |-> FALSE]

\* Datagrams for what agent `from' emits.  Agents emit to the master or
\* broadcast (AGENT, PANIC); a broadcast reaches the other agents too, but
\* an agent ignores other agents' broadcasts (checked in Agent.tla), so the
\* fleet routes them to the master only (abstraction, keeps TLC fast).
Route(from, o, toEp) == {[from |-> from, to |-> toEp, m |-> o]}
Emit(a, outs) == UNION {Route(a, outs[i], MasterEp) : i \in 1..Len(outs)}
\* Agent messages are stamped msgid 0: the master's handlers are idempotent
\* and need no msgid (abstraction, docs/spec.md).
Stamp(o) == [src |-> o.src, dst |-> o.dst, msgid |-> 0, type |-> o.type,
             ref |-> o.ref, args |-> o.args]

-----------------------------------------------------------------------------
(* The network.                                                             *)

\* The network loses a datagram (while the loss budget lasts).
Lose(e) == /\ budget.loss > 0
           /\ net' = net \ {e}
           /\ budget' = [budget EXCEPT !.loss = @ - 1]
           /\ UNCHANGED <<ag, master, lost>>

-----------------------------------------------------------------------------
(* Agents.                                                                  *)

\* Agent a receives datagram e (the copy stays in flight if duplicated).
AgentRecv(a, e, dup) ==
    LET r == L!Receive(ag[a], e.m) IN
    /\ e.to = a
    /\ ag' = [ag EXCEPT ![a] = r.ag]
    /\ net' = ((IF dup THEN net ELSE net \ {e}) \cup Emit(a, [i \in 1..Len(r.out) |-> Stamp(r.out[i])]))
    /\ lost' = [lost EXCEPT ![a] = lost[a] /\ r.ag.state # "PANIC"]
    /\ UNCHANGED master

\* Agent a's timeout fires (SyncTimeout or HeartbeatLost).
AgentTimeout(a) ==
    LET r == IF L!SyncTimeoutOk(ag[a]) THEN L!SyncTimeout(ag[a]) ELSE L!HeartbeatLost(ag[a]) IN
    /\ L!SyncTimeoutOk(ag[a]) \/ L!HeartbeatLostOk(ag[a])
    /\ ag' = [ag EXCEPT ![a] = r.ag]
    /\ net' = net \cup Emit(a, [i \in 1..Len(r.out) |-> Stamp(r.out[i])])
    /\ lost' = [lost EXCEPT ![a] = lost[a] /\ r.ag.state # "PANIC"]
    /\ UNCHANGED <<master, budget>>

-----------------------------------------------------------------------------
(* The master.                                                              *)

MsgTo(r, type, ref, args) ==
    [from |-> MasterEp, to |-> r.ep,
     m |-> Msg(MasterId, r.id, r.mid, type, ref, args)]
\* The datagram of the command pending for entry r.
Pending(r) ==
    CASE r.job = "MASTER"    -> {MsgTo(r, "MASTER", r.ann, <<>>)}
      [] r.job = "BEHAVIOUR" -> {MsgTo(r, "BEHAVIOUR", 0, <<CHOOSE b \in Behaviours : TRUE>>)}
      [] r.job = "START"     -> {MsgTo(r, "START", 0, <<>>)}
      [] r.job = "RESUME"    -> {MsgTo(r, "RESUME", 0, <<>>)}
      [] OTHER               -> {}
Next_(j) == CASE j = "MASTER" -> "BEHAVIOUR" [] j = "BEHAVIOUR" -> "START" [] OTHER -> "DONE"

Known(reg, s) == {r \in reg : r.ann = s \/ r.id = s}

\* The master receives AGENT or PANIC from announced id s: a new agent gets
\* an id (its old one if it announces an assigned id, else the next free)
\* and MASTER; an agent already registered gets the pending MASTER again.
MasterSync(e) ==
    LET s == e.m.src
        k == Known(master.reg, s)
        nid == IF s \in L!AssignedIds THEN s ELSE master.nextId
        r == [ann |-> s, id |-> nid, ep |-> e.from, job |-> "MASTER",
              mid |-> master.msgid[e.from], quiet |-> 0]
    IN IF k # {}
       THEN /\ net' = (net \ {e}) \cup UNION {Pending(x) : x \in k}
            /\ master' = [master EXCEPT !.reg = (@ \ k) \cup {[x EXCEPT !.quiet = 0] : x \in k}]
       ELSE /\ master' = [master EXCEPT
                  !.reg = {x \in @ : x.ep # e.from} \cup {r},
                  !.nextId = IF s \in L!AssignedIds THEN @ ELSE @ + 1,
                  !.msgid[e.from] = @ + 1]
            /\ net' = (net \ {e}) \cup Pending(r)

\* ACK or NOT of the pending command: ACK moves to the next command, NOT
\* gives up on this agent's job.
MasterAnswer(e) ==
    LET s == e.m.src
        k == {x \in master.reg : x.id = s /\ x.mid = e.m.ref /\ x.job # "DONE"}
        x == CHOOSE x \in k : TRUE
        y == [x EXCEPT !.job = IF e.m.type = "ACK" THEN Next_(x.job) ELSE "DONE",
                       !.mid = master.msgid[x.ep], !.quiet = 0]
    IN IF k = {}
       THEN net' = net \ {e} /\ UNCHANGED master
       ELSE /\ master' = [master EXCEPT !.reg = (@ \ {x}) \cup {y}, !.msgid[x.ep] = @ + 1]
            /\ net' = (net \ {e}) \cup Pending(y)

\* PING from a registered agent: PONG at once (and the agent is heard).
\* The master reconciles on the state the PING reports: an agent it has
\* done with that reports PAUSED (heartbeat was lost) gets RESUME, one that
\* reports ACTIVE gets its BEHAVIOUR and START again.
\* A PING from an id the master does not know gets no answer, so an agent
\* of a crashed master's session loses its heartbeat and resyncs via PANIC.
MasterPing(e) ==
    LET k == {x \in master.reg : x.id = e.m.src} IN
    IF k = {} THEN net' = net \ {e} /\ UNCHANGED master
    ELSE LET x == CHOOSE x \in k : TRUE IN
         /\ LET j == IF x.job # "DONE" THEN x.job
                     ELSE CASE e.m.args[1] = "PAUSED" -> "RESUME"
                            [] e.m.args[1] = "ACTIVE" -> "BEHAVIOUR"
                            [] OTHER                  -> "DONE"
                y == [x EXCEPT !.quiet = 0, !.job = j,
                               !.mid = IF j # x.job THEN master.msgid[x.ep] ELSE @]
            IN master' = [master EXCEPT !.reg = (@ \ {x}) \cup {y},
                                        !.msgid[x.ep] = IF j # x.job THEN @ + 1 ELSE @]
         /\ net' = (net \ {e}) \cup
                   {[from |-> MasterEp, to |-> e.from,
                     m |-> Msg(MasterId, e.m.src, 0, "PONG", 0, <<>>)]}

\* The master (when up) receives datagram e; a crashed master drops it.
MasterRecv(e, dup) ==
    /\ e.to = MasterEp
    /\ IF ~master.up THEN net' = net \ {e} /\ UNCHANGED master
       ELSE CASE e.m.type \in {"AGENT", "PANIC"} -> MasterSync(e)
              [] e.m.type \in {"ACK", "NOT"}     -> MasterAnswer(e)
              [] e.m.type = "PING"               -> MasterPing(e)
              [] OTHER -> net' = net \ {e} /\ UNCHANGED master  \* reports: consumed
    /\ UNCHANGED <<ag, lost>>

\* The master crashes: registry gone.  Its id and msgid counters survive
\* (stable storage, or derived from a clock), so ids and msgids are never
\* reused.
MasterCrash ==
    /\ master.up /\ budget.crash > 0
    /\ master' = [master EXCEPT !.up = FALSE, !.reg = {},
                     !.nextId = IF BUG = "ReuseIds" THEN 2 ELSE @]
    /\ budget' = [budget EXCEPT !.crash = @ - 1]
    /\ lost' = [a \in Agents |-> ag[a].state \in L!Synced]
    /\ UNCHANGED <<ag, net>>

\* The master restarts with an empty registry.
MasterRestart ==
    /\ ~master.up
    /\ master' = [master EXCEPT !.up = TRUE]
    /\ UNCHANGED <<ag, net, budget, lost>>

-----------------------------------------------------------------------------
(* Delivery and time.                                                       *)

\* The network delivers e to its endpoint; with dup, a copy stays in flight.
Deliver(e, dup) ==
    /\ dup => budget.dup > 0
    /\ IF dup THEN budget' = [budget EXCEPT !.dup = @ - 1] ELSE UNCHANGED budget
    /\ IF e.to = MasterEp THEN MasterRecv(e, dup) ELSE AgentRecv(e.to, e, dup)

DeliverAny == \E e \in net : Deliver(e, FALSE)

\* One tick of time, once the network has drained and no timeout is due:
\* every agent's timers advance (periodic AGENT/PING/PANIC go out, a running
\* behaviour reports ACTION_OK), the
\* master resends every pending command, counts ticks since it last heard
\* each agent and drops those quiet for TDrop ticks.
Tick ==
    LET t == [a \in Agents |-> L!Tick(ag[a])]
        \* a running behaviour finishes one action per tick: ACTION_OK
        r == [a \in Agents |->
                IF L!ActionOkOk(t[a].ag)
                THEN [ag |-> L!ActionOk(t[a].ag).ag,
                      out |-> t[a].out \o L!ActionOk(t[a].ag).out]
                ELSE t[a]]
        live == {a \in Agents : ag[a].state # "OFF"}
    IN
    /\ net = {}
    /\ \A a \in live : L!TickOk(ag[a])
    /\ ag' = [a \in Agents |-> IF a \in live THEN r[a].ag ELSE ag[a]]
    /\ LET reg2 == {[x EXCEPT !.quiet = @ + 1] : x \in master.reg}
           reg3 == {x \in reg2 : x.quiet < TDrop}
       IN /\ master' = IF master.up THEN [master EXCEPT !.reg = reg3] ELSE master
          /\ net' = UNION {Emit(a, [i \in 1..Len(r[a].out) |-> Stamp(r[a].out[i])]) : a \in live}
                    \cup (IF master.up THEN UNION {Pending(x) : x \in reg3} ELSE {})
    /\ UNCHANGED <<budget, lost>>

Next ==
    \/ \E e \in net : Deliver(e, FALSE) \/ Deliver(e, TRUE) \/ Lose(e)
    \/ \E a \in Agents : AgentTimeout(a)
    \/ MasterCrash \/ MasterRestart
    \/ Tick

Fairness ==
    /\ WF_vars(DeliverAny)
    /\ \A a \in Agents : WF_vars(AgentTimeout(a))
    /\ WF_vars(MasterRestart)
    /\ WF_vars(Tick)

Spec == Init /\ [][Next]_vars
FairSpec == Spec /\ Fairness

-----------------------------------------------------------------------------
(* Safety.                                                                  *)

LedInv == \A a \in Agents : L!LedMatches(ag[a])
BehaviourOnlyInWorkingInv == \A a \in Agents : L!MotionOnlyWorking(ag[a])
NoUnsupervisedMotionInv == \A a \in Agents : L!Supervised(ag[a])
\* However many copies arrive, no agent acts on a command twice.
ActedOnceInv == \A a \in Agents : ~ag[a].dupActed
\* Two synced agents never hold the same id.
UniqueIdsInv ==
    \A a, b \in Agents : a # b /\ ag[a].state \in L!Synced /\ ag[b].state \in L!Synced
                         => ag[a].id # ag[b].id
AllowedTransitionsProp ==
    [][\A a \in Agents : \/ ag[a].state = ag'[a].state
                         \/ \E t \in L!AllowedTransitions :
                               t[1] = ag[a].state /\ t[2] = ag'[a].state]_vars

(* Liveness, under Fairness, once the budgets are spent.                    *)

\* Every agent eventually is, and stays, ACTIVE-or-later with an id.
EventuallySynced == \A a \in Agents : <>[](ag[a].state \in L!Synced)
\* The master keeps sending BEHAVIOUR then START: they take effect.
CommandsTakeEffect == \A a \in Agents : <>[](ag[a].state = "WORKING")
\* After a master crash every agent synced then leaves WORKING and panics.
CrashLeadsToPanic == \A a \in Agents : lost[a] ~> ag[a].state = "PANIC"
\* An agent in PANIC resyncs once the master is back.
Resync == \A a \in Agents : ag[a].state = "PANIC" ~> ag[a].state \in L!Synced
=============================================================================
