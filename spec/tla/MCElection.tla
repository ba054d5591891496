---------------------------- MODULE MCElection ------------------------------
(***************************************************************************)
(* Model-checking bounds for Election.  The cfgs pick the agents, the     *)
(* faults and BUG (figures: docs/election.md, spec/tla/manifest.json):     *)
(*   MCElectionSmall.cfg  3 agents, master crash, relay, one election      *)
(*                        round, duplication, commands (make spec)         *)
(*   MCElectionVote.cfg   3 agents, a master or an agent crash, spurious  *)
(*                        timeouts, no pre-vote: double votes (make spec)  *)
(*   MCElectionMember.cfg 2 agents, one joining late, the PC changing the *)
(*                        membership, then crashing (make spec)            *)
(*   MCElectionFresh.cfg  2 agents, a fresh fleet: the PC's first two      *)
(*                        steps, heard or not (make spec)                  *)
(*   MCElectionFull.cfg   3 agents, cuts, the PC master returning          *)
(*                        (make spec-full)                                 *)
(*   MCElectionRelay.cfg  2 agents, PC up, cuts PC-2 and PC-3, MaxMsgs 7:  *)
(*                        relay cycles reachable (make spec)               *)
(*   MCElectionSim.cfg    5 agents, everything, for -simulate              *)
(*   MCElectionLive*.cfg  liveness under stabilisation (MCElectionLive)    *)
(* The broken variants (BUG) have no cfg of their own: tools/spec.py runs  *)
(* each with the constants of a make-spec model (manifest.json "refute").  *)
(* Delivery keeps a datagram in net (duplication), so MaxMsgs bounds the   *)
(* datagrams sent in a behaviour (plus those lost), not only those in     *)
(* flight.                                                                 *)
(***************************************************************************)
EXTENDS Election, TLC

\* Lower id = weaker agent; the PC has score 0 (it always may take over).
MCScore == [n \in {1} \cup Agents |-> IF n = 1 THEN 0 ELSE n]

CONSTANT MaxMsgs
\* State constraint: at most MaxMsgs datagrams in flight.
NetBound == Cardinality(net) <= MaxMsgs

\* State constraint of the full model: only the links of agent 2 (the weakest,
\* so the one that wins elections) are ever cut: it can be cut from the PC (and
\* relay through a peer) or from one peer; with the PC it makes every
\* minority/majority split of the fleet that two faults can make, up to
\* the agents' roles.
CONSTANT CutLinks
CutBound == NetBound /\ down \subseteq CutLinks

\* State constraint of the vote model (MCElectionVote.cfg): no relay traffic and no
\* commands (RELAY_REQ stays: it is also the pre-vote); the relay and the fence are the
\* small model's.  Without the pre-vote (PreVote = FALSE: an agent may stand whenever it
\* has no master, a superset of the behaviours with it) two candidacies in one epoch and a
\* voter answering both take four datagrams, so five reach double votes and a vote moved
\* across a crash.  It only prunes behaviours, so a violation found under it is a
\* violation of the unconstrained spec.
VoteBound ==
    /\ NetBound
    /\ \A m \in net : m.t \notin {"ROFFER", "RACCEPT", "RDROP", "RELAY", "CMD"}

\* State constraint of the fresh-fleet model (MCElectionFresh.cfg): only the election's own
\* datagrams (ELECT, VOTE, LEADER and its copies, EPOCH_STALE): no RELAY_REQ, so no agent gets a
\* pre-vote (PreVote = TRUE: nobody stands but the PC) and no peer shares its list.  What is left
\* is the PC's reconfigurations and what each agent hears of them, in any order.  It only prunes
\* behaviours, so a violation found under it is a violation of the unconstrained spec.
FreshBound ==
    /\ NetBound
    /\ \A m \in net : m.t \in {"ELECT", "VOTE", "HB", "STALE"}

\* The view of every model: the state without lastAction (the name of the step that
\* led to it, kept for traces and the conformance replay).  No invariant reads it, so
\* two states that differ only in it have the same successors and the same verdicts.
StateView == <<life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
               members, mepoch, floor, want, changes,
               net, down, faults, lost, elected, applied>>
=============================================================================
