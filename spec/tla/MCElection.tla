---------------------------- MODULE MCElection ------------------------------
(***************************************************************************)
(* Model-checking bounds for Election.  The cfgs pick the agents, the     *)
(* faults and BUG (figures: docs/election.md, spec/tla/manifest.json):     *)
(*   MCElectionSmall.cfg  3 agents, master crash, relay, one election      *)
(*                        round, loss and duplication, commands (make spec)*)
(*   MCElectionFull.cfg   3 agents, cuts, the PC master returning          *)
(*                        (make spec-full)                                 *)
(*   MCElectionSim.cfg    5 agents, everything, for -simulate              *)
(*   MCElectionBug*.cfg   the broken variants, each refuted by TLC         *)
(*   MCElectionLive*.cfg  liveness under stabilisation (MCElectionLive)    *)
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

\* State constraint for the broken election variants (DoubleVote,
\* MinorityQuorum, ForgetVote): no relay traffic (RELAY_REQ stays: it is
\* also the pre-vote).  It only prunes behaviours,
\* so a violation found under it is a violation of the unconstrained spec.
NoRelayBound ==
    /\ NetBound
    /\ \A m \in net : m.t \notin {"ROFFER", "RACCEPT", "RDROP", "RELAY", "CMD"}
=============================================================================
