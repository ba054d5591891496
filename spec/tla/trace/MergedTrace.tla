------------------------------ MODULE MergedTrace ------------------------------
(***************************************************************************)
(* Whole-run trace validation (docs/spec.md "Whole-run traces"): the       *)
(* NDJSON traces of every node of one real run, merged into one behaviour  *)
(* by ev3conformance.merged, walked record by record while the invariants  *)
(* of the composed spec -- System.tla's and Election.tla's own             *)
(* definitions, INSTANCEd with the run's state mapped onto their variables *)
(* (Sys below) -- are checked over what happened.  No property is restated *)
(* here: this module only says how the records make the state.            *)
(*                                                                         *)
(* The merge is a topological order of the run's happens-before graph:     *)
(* each process's records in the order it wrote them, and the receive of a *)
(* datagram (its sender and msgid) after the record that sent it; no wall  *)
(* clock is read.                                                          *)
(*                                                                         *)
(* The walk keeps, per traced node (a number: an agent core, a PC run, an  *)
(* elected agent's Master core), the fields its records change (loc), and  *)
(* the histories of System.tla over the run:                               *)
(*   elected  every master and its epoch: the PC of epoch 1 from the       *)
(*            start, then each BecomeMaster record, with the node's epoch; *)
(*   applied  every command that took effect at an agent: bare (an         *)
(*            AgentLogic handler of a master's datagram: epoch 1) or       *)
(*            inside an EPOCH_CMD (ApplyCommand: its sender and epoch),     *)
(*            with the agent's epoch after it (Election's seen);            *)
(*   heard    per agent, the ticks (its Tick records) since a genuine      *)
(*            datagram of the master it follows, in the epoch it follows,  *)
(*            reached it: whatever the agent did with it, and only if the  *)
(*            merge paired the receive with the master's own send, or its  *)
(*            msgid is past the master's last recorded one (records lost   *)
(*            with a kill) (g): a datagram only claiming the id does not;  *)
(*   told     per agent, the highest epoch a datagram of System's Telling  *)
(*            actions (and HandleHeartbeat) carried to it;                 *)
(*   obeyed   each command that took effect, with told before it;          *)
(*   handed   each HANDOVER a Master core sent: its HandleHeartbeat of a   *)
(*            newer epoch's LEADER that sent a datagram.                   *)
(* `at` is the record's place in Trace: the check names the records.       *)
(*                                                                         *)
(* Election's node n is the traced node with id n: an agent core (its id   *)
(* changes once, temp id -> assigned), the PC run that acted last, and an  *)
(* elected agent is MASTER while its Master core (node master:ID:EPOCH)    *)
(* runs as master (its records since its start, until STEPPED_DOWN).       *)
(*                                                                         *)
(* A record: [n |-> its node, a |-> action, ch |-> the fields it changed   *)
(* (some of id, epoch, leader, following, life, via, relays, votedFor),    *)
(* em |-> [t, src, e, x] of an Election datagram (t "NONE": none; x: a     *)
(* LEADER's leader, 0 in a copy of a membership), m |->                    *)
(* [t, src] of a bare datagram (t "NONE": none), cmd |-> ApplyCommand's    *)
(* inner handler, g |-> the receive was paired with its send, sent |-> the *)
(* record sent a datagram, ticks |-> time a Tick record let pass].         *)
(***************************************************************************)
EXTENDS Naturals, Sequences, FiniteSets

CONSTANTS
    Trace,    \* the merged records
    Start,    \* node n's fields before its first record: Start[n]
    Agents,   \* the nodes that are agent cores (numbers)
    PCs,      \* the nodes that are runs of the PC master, in the order they ran
    Cores,    \* the Master core nodes: [n, id, e] of node n, master:ID:EPOCH
    AgentIds, \* every id an agent core had (temp ids and assigned ones)
    PC,       \* the PC master's id: master of epoch 1 from the start
    TLoss     \* the agents' heartbeat timeout (ticks): System's T

ASSUME Len(Trace) > 0 /\ Agents \subseteq DOMAIN Start /\ TLoss \in Nat \ {0}

VARIABLES loc, pcrun, elected, applied, heard, told, obeyed, handed, cursor

vars == <<loc, pcrun, elected, applied, heard, told, obeyed, handed, cursor>>

\* AgentLogic's receive handlers that act on a master's command (RecvDuplicate only answers again).
Commands == {"RecvMaster", "RecvBehaviour", "RecvStart", "RecvStop", "RecvPause", "RecvResume",
             "RecvStandby", "RecvContinue", "RecvRestart"}

CoreNodes == {c.n : c \in Cores}
Max2(x, y) == IF x > y THEN x ELSE y
Min2(x, y) == IF x < y THEN x ELSE y

\* A Master core runs as master from its first record on, until its records say STEPPED_DOWN.
Upd(n, l, ch) ==
    [f \in DOMAIN l |-> IF f \in DOMAIN ch THEN ch[f]
                        ELSE IF f = "life" /\ n \in CoreNodes /\ l.life = "NONE" THEN "MASTER"
                        ELSE l[f]]

\* The command record r made take effect: its sender and epoch.
Takes(r) == r.n \in Agents /\ (r.a \in Commands \/ (r.a = "ApplyCommand" /\ r.cmd \in Commands))
CmdSrc(r) == IF r.a = "ApplyCommand" THEN r.em.src ELSE r.m.src
CmdEpoch(r) == IF r.a = "ApplyCommand" THEN r.em.e ELSE 1
Src(r) == IF r.em.t # "NONE" THEN r.em.src ELSE r.m.src

\* Record r brought agent r.n (fields l2 after it) a genuine datagram of the master it follows,
\* in the epoch it follows (a bare datagram carries none).  A copy of a membership (LEADER with
\* leader 0: the PC's as it stands) is not one: System's heard restarts on a master's LEADER
\* (HandleHeartbeat, Refresh) or command, and Election's copies go to one agent each.
FromMaster(r, l2) ==
    /\ r.g /\ l2.leader # 0 /\ Src(r) = l2.leader
    /\ r.em.t = "NONE" \/ r.em.e = l2.following
    /\ ~(r.em.t = "HB" /\ r.em.x = 0)

-----------------------------------------------------------------------------
(* The run as System's state.                                              *)

Ids == {PC} \cup AgentIds
\* The agent core whose id is a now (0: none: a temp id replaced, or never seen).
AgentOf(a) == IF \E n \in Agents : loc[n].id = a THEN CHOOSE n \in Agents : loc[n].id = a ELSE 0
\* Agent a's Master cores: running as master, and stepped down in the epoch the agent acts in.
CoreUp(a) == \E c \in Cores : c.id = a /\ loc[c.n].life = "MASTER"
CoreDown(a, e) == \E c \in Cores : c.id = a /\ c.e = e /\ loc[c.n].life = "STEPPED_DOWN"
\* The fields of Election's node n.
Node(n) ==
    IF n = PC THEN IF pcrun = 0 THEN [life |-> "MASTER", epoch |-> 1] ELSE loc[pcrun]
    ELSE IF AgentOf(n) = 0
         THEN [life |-> "DOWN", epoch |-> 0, leader |-> 0, following |-> 0, via |-> 0,
               relays |-> {}, votedFor |-> 0]
         ELSE loc[AgentOf(n)]
Life(n) ==
    IF n # PC /\ CoreUp(n) THEN "MASTER"
    ELSE IF n # PC /\ Node(n).life = "MASTER" /\ CoreDown(n, Node(n).epoch) THEN "PANIC"
    ELSE Node(n).life
OfAgent(f, a, none) == IF AgentOf(a) = 0 THEN none ELSE f[AgentOf(a)]

Sys == INSTANCE System WITH
    Agents <- AgentIds, T <- TLoss,
    Score <- [n \in {} |-> 0], MaxEpoch <- 2147483647, MaxFaults <- 0, Crashes <- TRUE,
    PCCrash <- TRUE, PCReturns <- TRUE, Partitions <- TRUE, MaxLoss <- 0, SpuriousTimeout <- TRUE,
    CmdAgents <- AgentIds, PreVote <- TRUE, Joiners <- {}, MaxChanges <- 0, BUG <- "None",
    life <- [n \in Ids |-> Life(n)],
    epoch <- [n \in Ids |-> Node(n).epoch],
    votedFor <- [a \in AgentIds |-> Node(a).votedFor],
    leader <- [a \in AgentIds |-> Node(a).leader],
    following <- [a \in AgentIds |-> Node(a).following],
    via <- [a \in AgentIds |-> Node(a).via],
    relays <- [a \in AgentIds |-> Node(a).relays],
    elected <- {<<x.e, x.id>> : x \in elected},
    applied <- {[a |-> loc[c.a].id, src |-> c.src, e |-> c.e, seen |-> c.seen] : c \in applied},
    heard <- [a \in AgentIds |-> OfAgent(heard, a, 0)],
    told <- [a \in AgentIds |-> OfAgent(told, a, 1)],
    obeyed <- {[a |-> loc[c.a].id, src |-> c.src, e |-> c.e, told |-> c.told] : c \in obeyed},
    handed <- {[src |-> h.src, e |-> h.e] : h \in handed},
    \* not traced, read by no invariant checked here (docs/spec.md "Whole-run traces")
    votes <- [n \in Ids |-> {}], offered <- [a \in AgentIds |-> {}], prevotes <- [a \in AgentIds |-> {}],
    net <- {}, down <- {}, faults <- 0, lost <- 0, members <- [n \in Ids |-> {}],
    mepoch <- [n \in Ids |-> 0], floor <- [a \in AgentIds |-> 0], want <- {}, changes <- 0,
    lastAction <- <<>>, silence <- [a \in AgentIds |-> 0], hnet <- {}

Init ==
    /\ loc = Start
    /\ pcrun = IF PCs = <<>> THEN 0 ELSE PCs[1]
    /\ elected = {[e |-> 1, id |-> PC, at |-> 0]}
    /\ applied = {}
    /\ heard = [n \in DOMAIN Start |-> 0]
    /\ told = [n \in DOMAIN Start |-> 1]
    /\ obeyed = {}
    /\ handed = {}
    /\ cursor = 1

Walk ==
    /\ cursor <= Len(Trace)
    /\ LET r == Trace[cursor]
           l == loc[r.n]
           l2 == Upd(r.n, l, r.ch)
           ag == r.n \in Agents
       IN /\ loc' = [loc EXCEPT ![r.n] = l2]
          /\ pcrun' = IF \E i \in DOMAIN PCs : PCs[i] = r.n THEN r.n ELSE pcrun
          /\ elected' = IF r.a = "BecomeMaster"
                        THEN elected \cup {[e |-> l2.epoch, id |-> l2.id, at |-> cursor]}
                        ELSE elected
          /\ applied' = IF Takes(r)
                        THEN applied \cup {[a |-> r.n, src |-> CmdSrc(r), e |-> CmdEpoch(r),
                                            seen |-> l2.epoch, at |-> cursor]}
                        ELSE applied
          /\ heard' = IF ~ag THEN heard
                      ELSE IF FromMaster(r, l2) THEN [heard EXCEPT ![r.n] = 0]
                      ELSE [heard EXCEPT ![r.n] = Min2(@ + r.ticks, TLoss + 1)]
          /\ told' = IF ag /\ r.em.t # "NONE" /\ r.a \in Sys!Telling \cup {"HandleHeartbeat"}
                     THEN [told EXCEPT ![r.n] = Max2(@, r.em.e)] ELSE told
          /\ obeyed' = IF Takes(r)
                       THEN obeyed \cup {[a |-> r.n, src |-> CmdSrc(r), e |-> CmdEpoch(r),
                                          told |-> told[r.n], at |-> cursor]}
                       ELSE obeyed
          /\ handed' = IF r.n \in CoreNodes /\ r.a = "HandleHeartbeat" /\ r.em.t = "HB"
                          /\ r.em.e > l.epoch /\ r.sent
                       THEN handed \cup {[src |-> l.id, e |-> r.em.e, at |-> cursor]}
                       ELSE handed
    /\ cursor' = cursor + 1

Next == Walk

-----------------------------------------------------------------------------
(* The invariants checked: Election's and System's, by name.               *)

AtMostOneMasterPerEpochInv == Sys!AtMostOneMasterPerEpochInv
FollowersAgreeInv == Sys!FollowersAgreeInv
RelayOneHopInv == Sys!RelayOneHopInv
NoRelayCycleInv == Sys!NoRelayCycleInv
StaleMasterFencedInv == Sys!StaleMasterFencedInv
LifecycleInv == Sys!LifecycleInv
NoUnsupervisedMotionInv == Sys!NoUnsupervisedMotionInv
ObeyedNewestEpochInv == Sys!ObeyedNewestEpochInv
HandoverStepsDownInv == Sys!HandoverStepsDownInv

\* Violated on purpose once every record was walked: the run conforms.
Walked == cursor <= Len(Trace)
================================================================================
