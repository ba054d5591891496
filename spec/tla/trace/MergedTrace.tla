------------------------------ MODULE MergedTrace ------------------------------
(***************************************************************************)
(* Whole-run trace validation (docs/spec.md "Whole-run traces"): the       *)
(* NDJSON traces of every node of one real run, merged into one behaviour  *)
(* by ev3conformance.merged, walked record by record while the global      *)
(* safety properties of the election are checked over what happened.      *)
(*                                                                         *)
(* The merge is a topological order of the run's happens-before graph:     *)
(* each process's records in the order it wrote them, and the receive of a *)
(* datagram (its sender and msgid) after the record that sent it; no wall  *)
(* clock is read.  Every order of that graph gives the same verdict for    *)
(* the properties below: each is about causally related records (a         *)
(* master's election before the heartbeats and commands it sends).         *)
(*                                                                         *)
(* A node's global variables (id, epoch, leader, following) follow its     *)
(* records' changed fields; the history variables are those of             *)
(* Election.tla, restated over the run (Election.tla's membership rules    *)
(* change; these predicates do not read them):                             *)
(*   elected  every master and its epoch: the PC of epoch 1 from the       *)
(*            start, then each BecomeMaster record, with the node's epoch; *)
(*   applied  every command that took effect at an agent: bare (an         *)
(*            AgentLogic handler of a master's datagram: epoch 1) or       *)
(*            inside an EPOCH_CMD (ApplyCommand: its sender and epoch),     *)
(*            with the agent's epoch after it (the newest it has seen).    *)
(* `at` is the record's place in Trace: the check names the records.       *)
(*                                                                         *)
(* A record: [n |-> its node (a number), a |-> action, ch |-> the global variables it *)
(* changed (a record of some of id, epoch, leader, following), em |->      *)
(* [t, src, e] of an Election datagram (t "NONE": none), m |-> [t, src] of  *)
(* a bare datagram (t "NONE": none), cmd |-> ApplyCommand's inner handler].*)
(***************************************************************************)
EXTENDS Naturals, Sequences, FiniteSets

CONSTANTS
    Trace,    \* the merged records
    Start,    \* node n's [id, epoch, leader, following] before its first record: Start[n]
    Agents,   \* the nodes that are agent cores (numbers)
    PC        \* the PC master's id: master of epoch 1 from the start

ASSUME Len(Trace) > 0 /\ Agents \subseteq DOMAIN Start

VARIABLES loc, elected, applied, cursor

vars == <<loc, elected, applied, cursor>>

\* AgentLogic's receive handlers that act on a master's command (RecvDuplicate only answers again).
Commands == {"RecvMaster", "RecvBehaviour", "RecvStart", "RecvStop", "RecvPause", "RecvResume",
             "RecvStandby", "RecvContinue", "RecvRestart"}

Upd(l, ch) == [f \in DOMAIN l |-> IF f \in DOMAIN ch THEN ch[f] ELSE l[f]]

\* The command record r made take effect: its sender and epoch.
Takes(r) == r.n \in Agents /\ (r.a \in Commands \/ (r.a = "ApplyCommand" /\ r.cmd \in Commands))
CmdSrc(r) == IF r.a = "ApplyCommand" THEN r.em.src ELSE r.m.src
CmdEpoch(r) == IF r.a = "ApplyCommand" THEN r.em.e ELSE 1

Init ==
    /\ loc = Start
    /\ elected = {[e |-> 1, id |-> PC, at |-> 0]}
    /\ applied = {}
    /\ cursor = 1

Walk ==
    /\ cursor <= Len(Trace)
    /\ LET r == Trace[cursor]
           l2 == Upd(loc[r.n], r.ch)
       IN /\ loc' = [loc EXCEPT ![r.n] = l2]
          /\ elected' = IF r.a = "BecomeMaster"
                        THEN elected \cup {[e |-> l2.epoch, id |-> l2.id, at |-> cursor]}
                        ELSE elected
          /\ applied' = IF Takes(r)
                        THEN applied \cup {[a |-> r.n, src |-> CmdSrc(r), e |-> CmdEpoch(r),
                                            seen |-> l2.epoch, at |-> cursor]}
                        ELSE applied
    /\ cursor' = cursor + 1

Next == Walk

-----------------------------------------------------------------------------
(* The properties (Election.tla's, over the run).                          *)

IsMaster(e, id) == \E x \in elected : x.e = e /\ x.id = id

\* At most one node became master in each epoch.
AtMostOneMasterPerEpoch == \A x, y \in elected : x.e = y.e => x.id = y.id

\* A command took effect at an agent only in the newest epoch the agent had seen, and only from the
\* master elected in that epoch (before: the merge orders its election before its commands).
StaleMasterFenced == \A c \in applied : c.e = c.seen /\ IsMaster(c.e, c.src)

\* An agent follows only its newest epoch, and only the master elected in it.
FollowersAgree ==
    \A n \in Agents : loc[n].following # 0 =>
        /\ loc[n].following = loc[n].epoch
        /\ IsMaster(loc[n].following, loc[n].leader)

\* Violated on purpose once every record was walked: the run conforms.
Walked == cursor <= Len(Trace)
================================================================================
