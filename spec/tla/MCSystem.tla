----------------------------- MODULE MCSystem -------------------------------
(***************************************************************************)
(* Model-checking bounds for System (the whole fleet; docs/spec.md "The   *)
(* whole system").  The cfgs pick the agents, the faults and BUG:          *)
(*   MCSystem.cfg      2 agents, the PC crashes and comes back: an agent   *)
(*                     elected, the PC taking the fleet back (HANDOVER),   *)
(*                     commands, time (make spec)                          *)
(*   MCSystemStale.cfg 2 agents, the PC lives, 8 datagrams: its LEADER    *)
(*                     late at an agent working for an elected agent       *)
(*   MCSystemHandover.cfg  3 agents, the handover itself (make spec)       *)
(*   MCSystemFull.cfg  3 agents, the same with loss (make spec-full)       *)
(* The broken variants have no cfg of their own (tools/spec.py refute,     *)
(* manifest.json "refute").  The bounds and views are MCElection's.        *)
(***************************************************************************)
EXTENDS System, MCElection

\* The view: the state without lastAction (no property reads it; the step
\* that led to a state does not change its successors).
SysView == <<StateView, silence, heard, told, obeyed, hnet, handed>>

\* The view of a model without commands (CmdAgents = {}): no agent is ever WORKING and nothing
\* is obeyed, so heard and told, histories no action reads, decide no property there: two states
\* that differ only in them have the same successors and the same verdicts.
SysViewNoCmd == <<StateView, silence, hnet, handed>>

\* State constraint: at most MaxMsgs datagrams sent (delivery keeps them: duplication), and so
\* at most as many HANDOVERs (one per elected agent that hears a newer LEADER).  The copies of a
\* list (a LEADER to one agent: the PC's with its ELECT, Election.tla Teach, a peer's on a
\* RELAY_REQ) do not count: the PC's is one broadcast in the code, one datagram per agent here,
\* and there are at most as many as agents per list (here one list: MaxChanges 0, every agent
\* knows it), so the budget stays the one of the protocol's other datagrams.
Copies == {m \in net : m.t = "HB" /\ m.dst # NoNode}
SysBound == Cardinality(net \ Copies) <= MaxMsgs

\* State constraint of the handover model: no relay traffic and no commands (RELAY_REQ stays:
\* it is also the pre-vote), as MCElection's VoteBound.  It only prunes behaviours.
SysVoteBound ==
    /\ SysBound
    /\ \A m \in net : m.t \notin {"ROFFER", "RACCEPT", "RDROP", "RELAY", "CMD"}

\* State constraint of the handover model: the PC takes the fleet back from an elected agent.
\* It comes back only once an agent is master of epoch 2 (it crashed in epoch 1), and the
\* agents stand only in epoch 2 (the PC in 3); no RELAY_REQ (PreVote = FALSE: a candidate needs
\* no pre-vote, and nobody has a newer membership to share); before the PC crashes every agent
\* follows it (false suspicion is in MCSystem.cfg).  It only prunes behaviours.
HandoverBound ==
    /\ SysVoteBound
    /\ \A m \in net : m.t \notin {"RREQ", "PREOK"}
    /\ faults = 0 => \A a \in Agents : life[a] \in Followers
    /\ life[PC] # "DOWN" /\ faults > 0 => \E a \in Agents : <<2, a>> \in elected
    /\ \A a \in Agents : life[a] = "CANDIDATE" => epoch[a] <= 2
\* Action constraint of the handover model: the PC takes no LEADER (Election's HandleHeartbeat of
\* the PC, which lets it stand again on an elected agent's LEADER instead of learning the epoch from
\* an EPOCH_STALE).  With it the model has 140,297 distinct states and takes 197 s (1 worker), four
\* times its budget; its scenario (the agent-master hears the PC's LEADER first and hands over) is
\* the same either way, and MCSystem.cfg (system) checks the PC's rule.  It only prunes behaviours.
NoPCHeartbeat == ~(lastAction'[1] = "HandleHeartbeat" /\ lastAction'[2] = PC)

=============================================================================
