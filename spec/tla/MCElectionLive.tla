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
(* Duplication is a fault too, with a budget like loss (MaxDup).  In     *)
(* these models a datagram is consumed by its delivery (Received <-       *)
(* LiveReceived): a unicast one leaves the network, a broadcast one (a     *)
(* LEADER, RELAY_REQ, ELECT: one copy per agent) once every agent but its  *)
(* sender has taken its copy (took); a Duplicate fault (dups < MaxDup)     *)
(* keeps the copy for another delivery.  Late datagrams do arrive: a copy *)
(* that nothing takes now stays in flight and may be taken later, in any  *)
(* order, after its sender crashed or moved on (a LEADER of a dead master, *)
(* an offer of a relay that has since lost its master, an old RELAY_DROP   *)
(* or PREVOTE_OK), and delivery is fair, so such copies drain.  A sender   *)
(* that sends again a broadcast whose copies are partly taken (a master's *)
(* heartbeat, a RELAY_REQ retry) gives every agent a fresh copy (Resend).  *)
(* No filter on what is delivered: liveness rests only on the protocol's  *)
(* rules.  Commands: a copy of an EPOCH_CMD or RELAY is never             *)
(* applied twice (the agent's dedupe window, agent.hpp Fresh, drops it by *)
(* sender and msgid), so Duplicate keeps none; a command a master sends   *)
(* again is a new datagram.  Safety with unbounded duplication is checked *)
(* by the other models (Election's Received keeps every datagram).        *)
(* Every cfg of this module sets Received <- LiveReceived and             *)
(* NotInFlight <- LiveNotInFlight, and VIEW LiveView: the datagrams that  *)
(* can never take effect again are left out of the state TLC tells apart *)
(* ("Dead", below, with the argument why that is sound).                  *)
(* No state constraint: TLC would take a pruned state for a final one.     *)
(***************************************************************************)
EXTENDS MCElection

CONSTANTS
    Backoff,  \* FALSE: no back-off (the broken variant NoBackoff)
    MaxDup    \* bound on duplicated deliveries (model checking)

VARIABLES
    took,   \* <<m, a>>: agent a has taken its copy of broadcast m (m still in flight for others)
    dups    \* Duplicate faults so far

lvars == <<vars, took, dups>>

\* Who gets a copy of datagram m: every agent but its sender (a broadcast), or its addressee.
Receivers(m) == IF m.dst = NoNode THEN Agents \ {m.src} ELSE {m.dst}
\* Types a duplicate never takes effect of: the dedupe window drops a command's copy.
Deduped == {"CMD", "RELAY"}
\* A RELAY_REQ stands: an agent without a master sends it again and again (its retry timer),
\* so one record stands for all its copies, as in Election (taking it changes nothing at the
\* peer: what it does is answer, and each answer is a datagram of its own, consumed).
Standing == {"RREQ"}

\* Agent (or PC) a receives its copy of m: with a Duplicate fault (d = 1) the copy stays for
\* another delivery; otherwise a takes it, and a broadcast whose copies are all taken leaves
\* the network with its record in took.  Before the handler: LiveReceived reads took', dups'.
Take(a, m) ==
    /\ m.dst = NoNode => <<m, a>> \notin took
    /\ \E d \in IF m.t \in Deduped \cup Standing \/ dups = MaxDup THEN {0} ELSE {0, 1} :
         /\ dups' = dups + d
         /\ took' = IF m.dst # NoNode \/ d = 1 \/ m.t \in Standing THEN took
                    ELSE LET t == took \cup {<<m, a>>} IN
                         IF \A r \in Receivers(m) : <<m, r>> \in t
                         THEN t \ {<<m, r>> : r \in Receivers(m)} ELSE t
\* Received's liveness meaning (cfg: Received <- LiveReceived): m leaves the network unless a
\* duplicate was kept or other agents still have their copy of the broadcast coming.
LiveReceived(m, N) ==
    IF dups' # dups \/ m.t \in Standing \/ (m.dst = NoNode /\ \E r \in Receivers(m) : <<m, r>> \in took')
    THEN N ELSE N \ {m}

\* Sending again a broadcast datagram still in flight, some of whose copies were taken
\* (Election's send guards "not in net" merge it with the one in flight): every agent gets
\* a fresh copy: a master's periodic LEADER (a RELAY_REQ stands: never taken).
Resend(m) ==
    /\ m \in net /\ \E r \in Receivers(m) : <<m, r>> \in took
    /\ took' = {x \in took : x[1] # m}
    /\ UNCHANGED <<vars, dups>>
LiveHeartbeat(n) ==
    \/ Heartbeat(n) /\ UNCHANGED <<took, dups>>
    \/ life[n] = "MASTER" /\ Resend(MH(n, NoNode, epoch[n], NoNode, members[n]))
LiveRequestRelay(a) == RequestRelay(a) /\ UNCHANGED <<took, dups>>

\* The network loses m: no copy of it arrives any more.
LiveLose(m) == Lose(m) /\ took' = {x \in took : x[1] # m} /\ UNCHANGED dups

Weaker(n) == {a \in Agents : Score[a] < Score[n]}

\* Nothing can still bring candidate n a vote or make it master.
Stalled(n) ==
    /\ ~ENABLED BecomeMaster(n)
    /\ ~ENABLED (\E m \in net : m.t = "VOTE" /\ m.dst = n /\ Take(n, m) /\ HandleVote(n, m))
    /\ ~\E m \in net : m.t = "ELECT" /\ m.src = n /\ m.e = epoch[n]
                       /\ \E v \in Agents : ENABLED (Take(v, m) /\ HandleElect(v, m))

StandOK(n) ==
    \/ ~Backoff
    \/ n = PC
    \/ /\ \A a \in Weaker(n) :
            Linked(a, n) => life[a] = "DOWN" \/ (life[a] \in Followers /\ HeartbeatOK(a))
       /\ life[n] = "CANDIDATE" => Stalled(n)

\* The last epoch the PC stands in (a bound like MaxEpoch, cfg PCLastEpoch <- ..): a model
\* whose PC competes with the agents for the last epochs bounds the PC's retries below the
\* agents', so that a split of the PC's last election is not a split in the model's last epoch
\* (nobody could stand again: a stop of the model, not of the protocol).
PCLastEpoch == MaxEpoch
Stand(n) == StartElection(n) /\ StandOK(n) /\ (n = PC => epoch[PC] < PCLastEpoch)

\* Timeout as Election has it; the broken variant FreezeOnLoss (the name of the
\* same broken rule in AgentLogic) never times out in WORKING: it must fail
\* MasterGoneLeavesWorkingProp (tools/spec.py refute, election_live_work).
LiveTimeout(a) == Timeout(a) /\ (BUG = "FreezeOnLoss" => life[a] # "WORKING")

\* Agent a receives its copy of m and the handler of its kind takes it.
Deliver(a, m) ==
    /\ m.dst \in {a, NoNode}   \* first: every handler needs it (so Take is not tried in vain)
    /\ Take(a, m)
    /\ \/ OfferRelay(a, m) \/ AcceptRelay(a, m) \/ HandleAccept(a, m)
       \/ RelayDropped(a, m) \/ GrantPreVote(a, m) \/ HandlePreVote(a, m)
       \/ HandleElect(a, m) \/ HandleHeartbeat(a, m)
       \/ Forward(a, m) \/ LearnMembers(a, m)
       \/ ApplyCommand(a, m)
\* A peer that takes a RELAY_REQ also sends the asker a copy of its LEADER when it knows a
\* newer membership: the same receipt (agent.hpp: a second step), so it does not take a copy.
Share(a, m) == ShareMembers(a, m) /\ UNCHANGED <<took, dups>>

\* A step that takes no datagram: no copy taken, no duplicate.
Only(A) == A /\ UNCHANGED <<took, dups>>

\* Not here: the PC's HandleHeartbeat (Election: the PC stands again on a newer master's LEADER).
\* A broadcast's copies are counted per agent (Receivers), so taking it would add a receiver to
\* every LEADER; in the models where the PC lives no agent is master (relay) or the PC crashes
\* for good (crash, member, work).  The safety models (election_*, system) have the rule.
LiveNext ==
    \/ Only(\/ \E a \in Agents : LiveTimeout(a) \/ AddMember(a) \/ DropMember(a)
            \/ Reconfigure
            \/ \E n \in Nodes : Stand(n) \/ BecomeMaster(n) \/ Crash(n) \/ Restart(n)
            \/ \E s \in Nodes, a \in CmdAgents : SendCommand(s, a)
            \/ \E x, y \in Nodes : ({x, y} \in CutLinks /\ Cut(x, y)) \/ Heal(x, y))
    \/ \E a \in Agents : LiveRequestRelay(a)
    \/ \E n \in Nodes : LiveHeartbeat(n)
    \/ \E m \in net :
         \/ LiveLose(m)
         \/ m.t \in {"VOTE", "STALE"} /\ Take(m.dst, m) /\ (HandleVote(m.dst, m) \/ HandleStale(m.dst, m))
         \/ \E a \in Agents : Deliver(a, m) \/ Share(a, m)

LiveInit == Init /\ took = {} /\ dups = 0

\* The PC dies before any LEADER listing the membership reached anyone (the PC
\* killed right after its agents synced): the PC, master of epoch 1 with its membership, has sent its LEADER listing
\* it (in flight: cfg InitNet <- UnheardNet) and no agent knows any list (Informed <- Unheard);
\* the PC is already down (InitDown <- PCDown: it died right after sending).  Its copies still
\* arrive, late, unless lost (MaxLoss).
Unheard == {}
UnheardNet == {MH(PC, NoNode, 1, NoNode, InitMembers)}
PCDown == {PC}

\* The PC is reconfiguring (two reconfigurations in a row, the LEADER of the first lost or
\* in flight; cfg Init <- ReconfInit): every agent knows the list of epoch 1 (Agents), the PC has
\* won epoch 2 with the votes of both (their floor: 1) and published the list without the
\* strongest agent (ReconfL2), whose LEADER is in flight or lost (ReconfNet); the dropped agent
\* has synced again, so the PC wants it back (want = Agents, no change left) and is about to stand
\* in epoch 3 to publish it (CANDIDATE: Reconfigure); it may die at any moment (MaxFaults).  The
\* state TLC reaches from Init by DropMember, Reconfigure, StartElection, both HandleElect and
\* HandleVote, BecomeMaster, AddMember and Reconfigure, but for the datagrams of epoch 2 that
\* nothing can take any more (its ELECT and VOTEs, already counted; the PC's copies of the list of
\* epoch 1, which every agent knows).  An agent that hears the LEADER of epoch 2 now follows the
\* PC and times out, as one that heard it before the PC stood again.  The PC stands in no epoch
\* after 3 (cfg PCLastEpoch <- ReconfPCLast), the agents up to 4 (MaxEpoch).
ReconfPCLast == 3
ReconfDropped == CHOOSE a \in Agents : \A b \in Agents : Score[b] <= Score[a]
ReconfL2 == Agents \ {ReconfDropped}
\* The LEADER of epoch 2 in flight (cfg ReconfNet <- ReconfLost: lost already, a loss that
\* MaxLoss, the losses after the start, does not count).
ReconfNet == {MH(PC, NoNode, 2, NoNode, ReconfL2)}
ReconfLost == {}
ReconfInit ==
    /\ life = [n \in Nodes |-> IF n = PC THEN "CANDIDATE" ELSE "ACTIVE"]
    /\ epoch = [n \in Nodes |-> 2]
    /\ votedFor = [a \in Agents |-> PC]
    /\ votes = [n \in Nodes |-> IF n = PC THEN Agents ELSE {}]
    /\ leader = [a \in Agents |-> NoNode]
    /\ following = [a \in Agents |-> 0]
    /\ via = [a \in Agents |-> NoNode]
    /\ relays = [a \in Agents |-> {}]
    /\ offered = [a \in Agents |-> {}]
    /\ prevotes = [a \in Agents |-> {}]
    /\ net = ReconfNet
    /\ down = {}
    /\ faults = 0
    /\ lost = 0
    /\ elected = {<<1, PC>>, <<2, PC>>}
    /\ applied = {}
    /\ members = [n \in Nodes |-> IF n = PC THEN ReconfL2 ELSE Agents]
    /\ mepoch = [n \in Nodes |-> IF n = PC THEN 2 ELSE 1]
    /\ floor = [a \in Agents |-> 1]
    /\ want = Agents
    /\ changes = MaxChanges
    /\ lastAction = <<"Init">>

(* Datagrams that can never take effect again (the network of            *)
(* the consuming models explodes with them).  A unicast datagram m is dead *)
(* when the guard of every handler of it at its addressee r is false now  *)
(* and can never be true again: it reads only quantities that never       *)
(* decrease (epoch, mepoch: no step lowers them, a crash keeps them) or a  *)
(* crash for good (the PC down with PCReturns = FALSE).                    *)
(*   VOTE      HandleVoteOk needs m.e = epoch[r]                           *)
(*   PREOK     HandlePreVoteOk needs m.e = epoch[r]                        *)
(*   ROFFER    AcceptRelayOk needs m.e >= epoch[r]                         *)
(*   RACCEPT   HandleAcceptOk needs following[r] = m.e, and following # 0  *)
(*             is always epoch (FollowersAgreeInv: it is set with epoch   *)
(*             and cleared whenever epoch grows)                           *)
(*   STALE     HandleStaleOk needs m.e > epoch[r]                          *)
(*   LEADER copy (dst r) LearnMembersOk needs m.e > mepoch[r]              *)
(*   any, to the PC down for good: every handler needs it up               *)
(* Not RDROP (RelayDroppedOk reads via, which comes back), nor broadcasts  *)
(* (a LEADER or ELECT of an old epoch is answered with EPOCH_STALE), nor   *)
(* commands (the work model is small).  A dead datagram is never enabled, *)
(* never consumed (its handler never runs), never duplicated (Take goes    *)
(* with a handler); Stalled reads ENABLED of handlers only.  What else     *)
(* reads net: the send guards, which read NotInFlight (here:               *)
(* LiveNotInFlight: a dead copy in flight does not hold back a send of the *)
(* same datagram, which merges with it: the step is the same whether the   *)
(* dead copy is there or not, but for dead copies), and Lose (a loss of a  *)
(* dead datagram only uses up the loss budget, and a state with less      *)
(* budget left has fewer behaviours; no fairness reads lost).  So two      *)
(* states that differ only in dead datagrams have the same steps, to      *)
(* states that differ only in dead datagrams, with the same fairness and   *)
(* properties: LiveView leaves them out, and TLC explores one of them.     *)
(* TLC checks the two facts the argument rests on, on every step it takes *)
(* in every model of this module: DeadInertProp (no handler guard of a     *)
(* dead datagram holds) and DeadStaysDeadProp (a dead datagram stays dead).*)
PCGone == life[PC] = "DOWN" /\ ~PCReturns
\* Master x of epoch e is gone and r, not following it directly now, never will again: x is not
\* master in e and never will be (BecomeMaster needs epoch > mepoch, and mepoch[x] >= e), so no
\* LEADER of x in e is sent any more, and r has no copy of one still to take (r follows x in e
\* directly only from such a copy: HandleHeartbeat; AcceptRelay sets a relay).
LedNoMore(x, e, r) ==
    /\ mepoch[x] >= e /\ ~(life[x] = "MASTER" /\ epoch[x] = e)
    /\ ~(life[r] \in Followers /\ leader[r] = x /\ following[r] = e /\ via[r] = NoNode)
    /\ ~\E m \in net : m.t = "HB" /\ m.dst = NoNode /\ m.src = x /\ m.e = e /\ <<m, r>> \notin took
DeadFor(m, r) ==
    \/ r = PC /\ PCGone
    \/ m.t \in {"VOTE", "PREOK", "ROFFER", "RACCEPT"} /\ m.e < epoch[r]
    \/ m.t = "RACCEPT" /\ LedNoMore(m.x, m.e, r)
    \/ m.t = "STALE" /\ m.e <= epoch[r]
    \/ m.t = "HB" /\ m.e <= mepoch[r]
Dead(m) == m.dst # NoNode /\ DeadFor(m, m.dst)
LiveNotInFlight(x) == x \notin net \/ Dead(x)
LiveNet == {m \in net : ~Dead(m)}

\* The checks of the argument above, as properties of every step TLC takes (a step into a
\* state whose view it has seen already included: TLC explores one state of each view, so
\* an invariant would be checked only on the states without the dead datagram).  Inert(m):
\* the guard of every handler of a unicast datagram, at its addressee, is false.
Inert(m) ==
    LET r == m.dst
        s == Loc(r)
    IN ~ \/ HandleVoteOk(r, s, m) \/ HandleStaleOk(r, s, m) \/ AcceptRelayOk(r, s, m)
         \/ HandleAcceptOk(r, s, m) \/ RelayDroppedOk(r, s, m) \/ HandlePreVoteOk(r, s, m)
         \/ LearnMembersOk(r, s, m) \/ ForwardOk(r, s, m) \/ ApplyCommandOk(r, s, m)
DeadInertProp == [][\A m \in net' : Dead(m)' => Inert(m)']_lvars
DeadStaysDeadProp == [][\A m \in net : Dead(m) => (m \in net' => Dead(m)')]_lvars

\* The view of the liveness models: MCElection's (the state without lastAction, which no
\* property reads and no step depends on: two states that differ only in it have the same
\* successors) with the copies taken and the duplicates.
\* With consuming delivery (cfg NotInFlight <- LiveNotInFlight) the dead datagrams are left out
\* (LiveNet, above); FullView keeps them (the check of the reduction).
LiveView == <<life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
              members, mepoch, floor, want, changes,
              LiveNet, down, faults, lost, elected, applied, took, dups>>
FullView == <<StateView, took, dups>>
\* Weak fairness per node and kind of step (grouping all agents under one WF
\* is too weak: one agent's steps would starve another's, and TLC finds such
\* spurious loops at once).  Delivery is fair whatever the datagram: a late
\* copy that a node can take is eventually taken, once.  Commands
\* (SendCommand, ApplyCommand) are not fair: a model may send them
\* (election_live_work), none has to.  The subscript is the view: a step
\* counts for the fairness of its kind only if it changes what the view
\* shows.  A step that changes nothing but dead datagrams or lastAction (an
\* answer sent again whose copy in flight is dead: LiveNotInFlight lets it
\* through, and it merges with that copy) does not discharge the fairness
\* of its kind: with WF_lvars such a step, taken again and again (the view
\* sees a self-loop), stood for "a RELAY_REQ is answered" while a live one
\* never was (TLC, MCElectionLive.cfg: a candidate whose ELECT was lost
\* never got the PREVOTE_OK it needed, a spurious loop).  Without the
\* override (Election's guards) such a step can be taken at most once per
\* dead datagram (the copy stays in flight and holds back the next one), so
\* over infinite behaviours the two subscripts ask the same.
\* ElectFairness: every kind of step but the relay handshake (offer, accept, its answer, drop) and
\* Reconfigure.  A model whose properties hold under it checks them under it (cfg Fairness <-
\* ElectFairness: election_live_crash, election_live_member): weaker fairness, so more behaviours
\* count, and a behaviour that fails a property under Fairness fails it under ElectFairness too (no
\* violation is lost).  TLC evaluates the ENABLED of every fairness conjunct on every step it takes,
\* most of a liveness run's time: 9 of the 40 conjuncts (2 agents) fewer.
ElectFairness ==
    /\ \A a \in Agents :
         /\ WF_LiveView(Only(LiveTimeout(a))) /\ WF_LiveView(LiveRequestRelay(a))
         /\ WF_LiveView(\E m \in net : m.t = "RREQ" /\ Take(a, m) /\ GrantPreVote(a, m))
         /\ WF_LiveView(\E m \in net : m.dst = a /\ Take(a, m) /\ HandlePreVote(a, m))
         /\ WF_LiveView(\E m \in net : m.t = "ELECT" /\ Take(a, m) /\ HandleElect(a, m))
         /\ WF_LiveView(\E m \in net : m.t = "HB" /\ Take(a, m) /\ HandleHeartbeat(a, m))
         /\ WF_LiveView(\E m \in net : m.t = "RREQ" /\ Share(a, m))
         /\ WF_LiveView(\E m \in net : m.dst = a /\ Take(a, m) /\ LearnMembers(a, m))
    /\ \A n \in Nodes :
         /\ WF_LiveView(Only(Stand(n))) /\ WF_LiveView(Only(BecomeMaster(n))) /\ WF_LiveView(LiveHeartbeat(n))
         /\ WF_LiveView(\E m \in net : m.t = "VOTE" /\ m.dst = n /\ Take(n, m) /\ HandleVote(n, m))
         /\ WF_LiveView(\E m \in net : m.t = "STALE" /\ m.dst = n /\ Take(n, m) /\ HandleStale(n, m))
Fairness ==
    /\ ElectFairness
    /\ \A a \in Agents :
         /\ WF_LiveView(\E m \in net : m.t = "RREQ" /\ Take(a, m) /\ OfferRelay(a, m))
         /\ WF_LiveView(\E m \in net : m.dst = a /\ Take(a, m) /\ AcceptRelay(a, m))
         /\ WF_LiveView(\E m \in net : m.dst = a /\ Take(a, m) /\ HandleAccept(a, m))
         /\ WF_LiveView(\E m \in net : m.dst = a /\ Take(a, m) /\ RelayDropped(a, m))
    /\ WF_LiveView(Only(Reconfigure))

LiveSpec == LiveInit /\ [][LiveNext]_lvars /\ Fairness

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
