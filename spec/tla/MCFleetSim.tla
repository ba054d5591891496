------------------------------ MODULE MCFleetSim ------------------------------
(***************************************************************************)
(* Simulation-only wrapper of the fleet for the conformance replay         *)
(* (`ev3-conformance replay --model fleet`, docs/spec.md "Conformance").   *)
(* TLC's -simulate traces carry no action names, so SimNext is Fleet's     *)
(* Next with every disjunct also setting the auxiliary variable act: which *)
(* action, its arguments (the datagram, the node, the operator's command), *)
(* the handler the receiver dispatches to, and the datagrams the step      *)
(* emits (exact for deliveries: net is a set, so a datagram equal to one   *)
(* still in flight would not show in net' \ net).                          *)
(*                                                                         *)
(* act, ticks, lastFault and gap are history variables: with gap = 0,    *)
(* SimNext is Fleet's Next on Fleet's variables.  The conformance tests    *)
(* check it (fleet_replay.check_wrapper): TLC on the same small bounds     *)
(* with MCFleet's Next and with SimNext (SimFaultGaps = {0}, VIEW          *)
(* FleetVars) must find the same distinct states and depth.  With a gap    *)
(* > 0 faults are spread over the run (FaultOk): a subset of Fleet's       *)
(* behaviours.  The models of manifest.json do not use this module.        *)
(***************************************************************************)
EXTENDS MCFleet

CONSTANT SimFaultGaps  \* the gaps a behaviour may draw (ticks between two faults)

VARIABLES
    act,         \* the step: action, arguments, handler, emitted datagrams (history)
    ticks,       \* Ticks so far (history)
    lastFault,   \* the value of ticks at the last fault (history)
    gap          \* this behaviour's gap between faults, drawn in SimInit (0: none)

FleetVars == <<ag, net, up, ms, sess, budget, lost, life, acted>>
simVars == <<FleetVars, act, ticks, lastFault, gap>>

\* Faults (a loss, a duplicate, a master crash) at least gap ticks apart.  A
\* simulation picks among the enabled steps at random, so with gap 0 the
\* budgets are spent in the first ticks, before any agent works (measured:
\* 96 of 100 crashes with no agent registered); a gap spreads them over the
\* run.  Each simulated behaviour draws its gap (a random initial state).  It
\* only filters Fleet's behaviours: every trace is still a behaviour of Fleet.
FaultOk == ticks >= lastFault + gap
Fault == lastFault' = ticks

\* The datagrams a delivery emits (Fleet's AgentRecv / MasterRecv).
DeliverOut(e) ==
    IF e.to = MasterEp
    THEN IF up THEN MEmit(M!Receive(ms, e.m, e.from).out) ELSE {}
    ELSE Emit(e.to, L!Receive(ag[e.to], e.m).out, sess'[e.to], ag'[e.to])
\* The handler that takes the datagram ("Down": the master is not running).
DeliverHandler(e) ==
    IF e.to = MasterEp THEN IF up THEN M!Handler(e.m) ELSE "Down"
    ELSE L!Handler(ag[e.to], e.m)

SimDeliver(e, dup) ==
    /\ Deliver(e, dup)
    /\ IF dup THEN FaultOk /\ Fault ELSE UNCHANGED lastFault
    /\ act' = [name |-> "Deliver", e |-> e, dup |-> dup, h |-> DeliverHandler(e),
               out |-> DeliverOut(e)]
    /\ UNCHANGED ticks

SimLose(e) ==
    /\ Lose(e) /\ FaultOk /\ Fault
    /\ act' = [name |-> "Lose", e |-> e]
    /\ UNCHANGED ticks

SimAgentTimeout(a) ==
    /\ AgentTimeout(a)
    /\ act' = [name |-> "AgentTimeout", node |-> a,
               h |-> IF L!SyncTimeoutOk(ag[a]) THEN "SyncTimeout" ELSE "HeartbeatLost",
               out |-> net' \ net]
    /\ UNCHANGED <<ticks, lastFault>>

\* Operate acts only when net = {}: net' is what it emits.
SimOperate(a) ==
    /\ Operate(a)
    /\ \E x \in ms.reg :
          /\ x.ep = a /\ OpWanted(x)
          /\ act' = [name |-> "Operate", node |-> a, id |-> x.id, cmd |-> OpNext(x), out |-> net']
    /\ UNCHANGED <<ticks, lastFault>>

SimMasterCrash ==
    /\ MasterCrash /\ FaultOk /\ Fault
    /\ act' = [name |-> "MasterCrash"]
    /\ UNCHANGED ticks

SimMasterRestart ==
    /\ MasterRestart
    /\ act' = [name |-> "MasterRestart"]
    /\ UNCHANGED <<ticks, lastFault>>

\* Tick acts only when net = {}: net' is what it emits.
SimTick ==
    /\ Tick
    /\ act' = [name |-> "Tick", out |-> net']
    /\ ticks' = ticks + 1
    /\ UNCHANGED lastFault

SimInit == Init /\ act = [name |-> "Init"] /\ ticks = 0 /\ lastFault = 0 /\ gap \in SimFaultGaps

SimNext ==
    /\ \/ \E e \in net : SimDeliver(e, FALSE) \/ SimDeliver(e, TRUE) \/ SimLose(e)
       \/ \E a \in Agents : SimAgentTimeout(a) \/ SimOperate(a)
       \/ SimMasterCrash \/ SimMasterRestart
       \/ SimTick
    /\ UNCHANGED gap

SimSpec == SimInit /\ [][SimNext]_simVars
=============================================================================
