--------------------------- MODULE MCElectionLive ---------------------------
(***************************************************************************)
(* Liveness of Election under stabilisation (docs/election.md, section 4). *)
(*                                                                         *)
(* Faults stop after a budget: MaxFaults crashes and cuts, MaxLoss lost    *)
(* datagrams; a cut link may stay cut for ever (Heal has no fairness).     *)
(* Every protocol action is weakly fair: a node that can act eventually   *)
(* does, and a datagram in flight to a node that is up and linked is       *)
(* eventually handled.  An agent in PANIC may stand as soon as the        *)
(* protocol lets it (a majority granted it a pre-vote), before or after   *)
(* any relay offer: no "relay first" timing is assumed (it was, before    *)
(* the pre-vote; the variant NoPreVote (PreVote = FALSE on the relay    *)
(* model, tools/spec.py refute) shows                                    *)
(* what goes wrong without it).  Timers are modelled by one enabling      *)
(* condition (with Backoff = FALSE it is dropped: the broken variant):     *)
(*   - back-off: an agent stands only if no weaker agent it is linked to is *)
(*     itself without a master it hears (the weaker one's back-off is     *)
(*     shorter, so its ELECT arrives first); a candidate stands again only *)
(*     when its election is stalled: nobody can still vote for it.         *)
(* Duplication is a fault too: a late copy of a datagram whose sender has *)
(* moved on (a LEADER of a master that is gone, an offer its relay can no  *)
(* longer honour, a RELAY_DROP older than the relay's current table, a     *)
(* PREVOTE_OK of a peer that has found a master since) is                  *)
(* not delivered in these models (Current); without that, an endless      *)
(* stream of duplicates of a dead master's heartbeat keeps agents from     *)
(* standing, which TLC shows at once.  Safety with unbounded duplication   *)
(* is checked by the other models.                                         *)
(* No state constraint: TLC would take a pruned state for a final one.     *)
(***************************************************************************)
EXTENDS MCElection

CONSTANT Backoff

Weaker(n) == {a \in Agents : Score[a] < Score[n]}

\* Nothing can still bring candidate n a vote or make it master.
Stalled(n) ==
    /\ ~ENABLED BecomeMaster(n)
    /\ ~ENABLED (\E m \in net : HandleVote(n, m))
    /\ ~\E m \in net : m.t = "ELECT" /\ m.src = n /\ m.e = epoch[n]
                       /\ \E v \in Agents : ENABLED HandleElect(v, m)

StandOK(n) ==
    \/ ~Backoff
    \/ n = PC
    \/ /\ \A a \in Weaker(n) :
            Linked(a, n) => life[a] = "DOWN" \/ (life[a] \in Followers /\ HeartbeatOK(a))
       /\ life[n] = "CANDIDATE" => Stalled(n)

Stand(n) == StartElection(n) /\ StandOK(n)

\* Timeout as Election has it; the broken variant FreezeOnLoss (the name of the
\* same broken rule in AgentLogic) never times out in WORKING: it must fail
\* MasterGoneLeavesWorkingProp (tools/spec.py refute, election_live_work).
LiveTimeout(a) == Timeout(a) /\ (BUG = "FreezeOnLoss" => life[a] # "WORKING")

\* The datagram is not a late copy of something its sender no longer means.
\* A LEADER copy (ShareMembers) is always current: it only teaches a membership.
Current(m) ==
    CASE m.t = "HB" -> m.dst # NoNode \/ (life[m.src] = "MASTER" /\ epoch[m.src] = m.e)
      [] m.t = "ROFFER" -> /\ life[m.src] \in Followers /\ via[m.src] = NoNode
                           /\ leader[m.src] = m.x /\ following[m.src] = m.e
      [] m.t = "RDROP" -> m.dst \notin relays[m.src]
      [] m.t = "PREOK" -> life[m.src] \in {"PANIC", "CANDIDATE"} /\ epoch[m.src] <= m.e
      [] OTHER -> TRUE

\* A command takes effect at an agent at most once per master and epoch: a copy
\* of one already applied is what the agent's dedupe window drops (Election's
\* commands carry no msgid).  Without it an endless stream of copies of a dead
\* master's command keeps an agent that has lost it going WORKING -> PAUSED ->
\* WORKING, never reaching PANIC (TLC, election_live_work).  Commands are an
\* option of the masters (no fairness), so this only drops behaviours.
LiveApply(a, m) ==
    /\ ApplyCommand(a, m)
    /\ \A r \in applied : ~(r.a = a /\ r.src = m.src /\ r.e = m.e)

\* A LEADER of a master that has died since is delivered to an agent that
\* does not know the membership it lists yet (it was in flight when the
\* master died; the agent follows it, times out, and knows the membership):
\* once per agent, so no endless stream of a dead master's heartbeats.
Teaches(a, m) == m.t = "HB" /\ m.dst = NoNode /\ m.e > mepoch[a]
CurrentFor(a, m) == Current(m) \/ Teaches(a, m)

Deliver(a, m) ==
    /\ CurrentFor(a, m)
    /\ \/ OfferRelay(a, m) \/ AcceptRelay(a, m) \/ HandleAccept(a, m)
       \/ RelayDropped(a, m) \/ GrantPreVote(a, m) \/ HandlePreVote(a, m)
       \/ HandleElect(a, m) \/ HandleHeartbeat(a, m)
       \/ Forward(a, m) \/ LiveApply(a, m)
       \/ ShareMembers(a, m) \/ LearnMembers(a, m)

LiveNext ==
    \/ \E a \in Agents : LiveTimeout(a) \/ RequestRelay(a) \/ AddMember(a) \/ DropMember(a)
    \/ Reconfigure
    \/ \E n \in Nodes : Stand(n) \/ BecomeMaster(n) \/ Heartbeat(n) \/ Crash(n) \/ Restart(n)
    \/ \E s \in Nodes, a \in CmdAgents : SendCommand(s, a)
    \/ \E x, y \in Nodes : ({x, y} \in CutLinks /\ Cut(x, y)) \/ Heal(x, y)
    \/ \E m \in net :
         \/ Lose(m)
         \/ HandleVote(m.dst, m) \/ HandleStale(m.dst, m)
         \/ \E a \in Agents : Deliver(a, m)

\* Weak fairness per node and kind of step (grouping all agents under one WF
\* is too weak: one agent's steps would starve another's, and TLC finds such
\* spurious loops at once).  Commands (SendCommand, ApplyCommand) are not fair: a
\* model may send them (election_live_work), none has to.
Fairness ==
    /\ \A a \in Agents :
         /\ WF_vars(LiveTimeout(a)) /\ WF_vars(RequestRelay(a))
         /\ WF_vars(\E m \in net : Current(m) /\ OfferRelay(a, m))
         /\ WF_vars(\E m \in net : Current(m) /\ AcceptRelay(a, m))
         /\ WF_vars(\E m \in net : Current(m) /\ HandleAccept(a, m))
         /\ WF_vars(\E m \in net : Current(m) /\ RelayDropped(a, m))
         /\ WF_vars(\E m \in net : Current(m) /\ GrantPreVote(a, m))
         /\ WF_vars(\E m \in net : Current(m) /\ HandlePreVote(a, m))
         /\ WF_vars(\E m \in net : Current(m) /\ HandleElect(a, m))
         /\ WF_vars(\E m \in net : CurrentFor(a, m) /\ HandleHeartbeat(a, m))
         /\ WF_vars(\E m \in net : Current(m) /\ ShareMembers(a, m))
         /\ WF_vars(\E m \in net : Current(m) /\ LearnMembers(a, m))
    /\ \A n \in Nodes :
         /\ WF_vars(Stand(n)) /\ WF_vars(BecomeMaster(n)) /\ WF_vars(Heartbeat(n))
         /\ WF_vars(\E m \in net : HandleVote(n, m))
         /\ WF_vars(\E m \in net : HandleStale(n, m))
    /\ WF_vars(Reconfigure)

LiveSpec == Init /\ [][LiveNext]_vars /\ Fairness

\* A master exists and every agent that is up follows it, for ever after
\* (in these models every agent that is up is linked to a majority).
Leader(n) ==
    /\ life[n] = "MASTER"
    /\ \A a \in Agents \ {n} :
         life[a] # "DOWN" => life[a] \in Followers /\ leader[a] = n /\ following[a] = epoch[n]
MasterEventuallyProp == <>[](\E n \in Nodes : Leader(n))

\* An agent in PANIC eventually follows a master again (directly or through
\* a relay that keeps its own link), or is the master.
LeavesPanicProp == \A a \in Agents : life[a] = "PANIC" ~> life[a] \in Followers \cup {"MASTER"}
=============================================================================
