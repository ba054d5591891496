---------------------------- MODULE MCElection ------------------------------
(***************************************************************************)
(* Model-checking bounds for Election.  The cfgs pick the agents, the     *)
(* faults and BUG:                                                         *)
(*   MCElectionSmall.cfg  3 agents, master crash, relay, election, loss    *)
(*                        and duplication (make test)                      *)
(*   MCElectionFull.cfg   3 agents, partitions, the PC master returning   *)
(*   MCElectionSim.cfg    5 agents, everything, for -simulate             *)
(*   MCElectionBug*.cfg   the broken variants, each refuted by TLC         *)
(***************************************************************************)
EXTENDS Election, TLC

\* Lower id = weaker agent; the PC has score 0 (it always may take over).
MCScore == [n \in {1} \cup Agents |-> IF n = 1 THEN 0 ELSE n]

CONSTANT MaxMsgs
\* State constraint: at most MaxMsgs datagrams in flight.
NetBound == Cardinality(net) <= MaxMsgs
=============================================================================
