------------------------------ MODULE Election ------------------------------
(***************************************************************************)
(* Relay through a peer and vote-based master election for libev3proto.    *)
(* See docs/election.md for the prose.                                     *)
(*                                                                         *)
(* Nodes: the PC master (id 1, PC) and the agents.  The fleet is the       *)
(* membership the master of an epoch published with it (LEADER), one per   *)
(* epoch, changed only by the PC one agent at a time (section             *)
(* Membership); a quorum is a strict majority of the list a node knows.    *)
(* Every master acts in an epoch; an                                        *)
(* agent grants one vote per epoch (votedFor, kept on the SD card, like    *)
(* Raft's), follows only the highest epoch it has seen, and obeys commands *)
(* only from the master it follows in that epoch.  The thesis' spirit is   *)
(* kept: candidates announce their score and a voter grants only a         *)
(* candidate at most as strong as itself, so the weakest agent of a        *)
(* connected majority is the one that can win; the PC (score 0) always    *)
(* can, which is how it takes the fleet back.                              *)
(*                                                                         *)
(* The agent lifecycle of the fleet spec is abstracted to the states that  *)
(* matter here: ACTIVE / WORKING / PAUSED (following a master), PANIC (no  *)
(* master), CANDIDATE, MASTER, DOWN (crashed).  Its rules are kept:        *)
(* heartbeat lost in WORKING -> PAUSED, in ACTIVE or PAUSED -> PANIC; a    *)
(* message from a master -> ACTIVE; WORKING only on a master's command.    *)
(*                                                                         *)
(* Network: a set of datagrams; delivery does not remove one (so it may be *)
(* delivered again: duplication), any order (reordering), Lose removes one *)
(* (loss), cut links deliver nothing (partition).  Every handler of a      *)
(* datagram m leaves the network as Received(m, net): net itself here; the *)
(* liveness models (MCElectionLive) replace it by a delivery that consumes *)
(* the datagram unless a bounded Duplicate fault keeps a copy.            *)
(*                                                                         *)
(* BUG selects a deliberately broken variant (the MC cfgs); "None" is the *)
(* protocol.                                                               *)
(***************************************************************************)
EXTENDS Naturals, FiniteSets

CONSTANTS
    Agents,          \* agent ids (2..49999)
    Score,           \* Score[n]: a node's score, lower = weaker; Score[PC] = 0
    MaxEpoch,        \* bound on epochs (model checking)
    MaxFaults,       \* bound on crashes and link cuts (model checking)
    Crashes,         \* TRUE: agents may crash and restart
    PCCrash,         \* TRUE: the PC master may crash
    PCReturns,       \* TRUE: the PC master may come back after a crash
    Partitions,      \* TRUE: links may be cut and healed
    MaxLoss,         \* bound on datagrams lost (model checking)
    SpuriousTimeout, \* TRUE: a heartbeat may time out although the master lives
    CmdAgents,       \* the agents masters send commands to (model checking)
    PreVote,         \* TRUE: an agent stands only with a majority of pre-votes
    Joiners,         \* agents the PC registers after the start: no membership known at first
    MaxChanges,      \* bound on the PC's membership changes (an agent added or dropped)
    BUG              \* "None" or the name of a broken variant

PC == 1
Nodes == {PC} \cup Agents
NoNode == 0
\* A strict majority of membership L: an empty membership has none.
QuorumOf(S, L) == L # {} /\ 2 * Cardinality(S \cap L) > Cardinality(L)
InitMembers == Agents \ Joiners

Followers == {"ACTIVE", "WORKING", "PAUSED"}
Lives == Followers \cup {"PANIC", "CANDIDATE", "MASTER", "DOWN"}
MsgTypes == {"ELECT", "VOTE", "HB", "STALE", "RREQ", "ROFFER", "RACCEPT", "RDROP", "CMD",
             "RELAY", "PREOK"}
Msgs == [t : MsgTypes, src : Nodes, dst : Nodes \cup {NoNode}, e : 0..MaxEpoch,
         x : Nodes \cup {NoNode}, k : 0..MaxEpoch, mem : SUBSET Agents]

VARIABLES
    life,       \* life[n]: lifecycle state (the PC: CANDIDATE, MASTER or DOWN)
    epoch,      \* epoch[n]: the highest epoch n has seen (persistent)
    votedFor,   \* votedFor[a]: whom agent a voted for in epoch[a], or NoNode (persistent)
    votes,      \* votes[n]: the agents that voted for candidate n in epoch[n]
    leader,     \* leader[a]: the master agent a follows, or NoNode
    following,  \* following[a]: the epoch of that master, or 0
    via,        \* via[a]: the peer relaying for a, or NoNode (direct link)
    relays,     \* relays[a]: the agents a relays for
    offered,    \* offered[a]: agents a offered to relay for since it last changed master
    prevotes,   \* prevotes[a]: peers that answered a's RELAY_REQ of epoch[a] with PREVOTE_OK
    net,        \* datagrams in flight
    down,       \* cut links, each a set {x, y}
    faults,     \* crashes and cuts so far
    lost,       \* datagrams lost so far
    elected,    \* history: <<e, n>> when n became master in epoch e
    applied,    \* history: [a, src, e, seen] when a command took effect
    members,    \* members[n]: the membership n counts quorums against (the PC: of its epoch)
    mepoch,     \* mepoch[n]: the epoch of the master that published members[n] (0: none known)
    floor,      \* floor[a]: no list older than this epoch is current (persistent)
    want,       \* the PC's registry: the membership it wants (agents added and dropped)
    changes,    \* membership changes so far
    lastAction  \* the last action and its arguments

mvars == <<members, mepoch, floor, want, changes>>
vars == <<life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes, net,
          down, faults, lost, elected, applied, members, mepoch, floor, want, changes, lastAction>>

TypeOK ==
    /\ life \in [Nodes -> Lives]
    /\ epoch \in [Nodes -> 0..MaxEpoch]
    /\ votedFor \in [Agents -> Nodes \cup {NoNode}]
    /\ votes \in [Nodes -> SUBSET Agents]
    /\ leader \in [Agents -> Nodes \cup {NoNode}]
    /\ following \in [Agents -> 0..MaxEpoch]
    /\ via \in [Agents -> Agents \cup {NoNode}]
    /\ relays \in [Agents -> SUBSET Agents]
    /\ offered \in [Agents -> SUBSET Agents]
    /\ prevotes \in [Agents -> SUBSET Agents]
    /\ net \subseteq Msgs
    /\ down \subseteq SUBSET Nodes
    /\ faults \in 0..MaxFaults
    /\ lost \in 0..MaxLoss
    /\ elected \subseteq (1..MaxEpoch) \X Nodes
    /\ applied \subseteq [a : Agents, src : Nodes, e : 0..MaxEpoch, seen : 0..MaxEpoch]
    /\ members \in [Nodes -> SUBSET Agents]
    /\ mepoch \in [Nodes -> 0..MaxEpoch]
    /\ floor \in [Agents -> 0..MaxEpoch]
    /\ want \subseteq Agents
    /\ changes \in 0..MaxChanges

-----------------------------------------------------------------------------
Linked(x, y) == {x, y} \notin down
M(t, s, d, e, x) == [t |-> t, src |-> s, dst |-> d, e |-> e, x |-> x, k |-> 0, mem |-> {}]
\* A datagram that carries a membership epoch k (ELECT, RELAY_REQ: the list the sender knows) or
\* a membership L (LEADER, from its master or copied by a peer).
MK(t, s, d, e, k) == [M(t, s, d, e, NoNode) EXCEPT !.k = k]
MH(s, d, e, x, L) == [M("HB", s, d, e, x) EXCEPT !.mem = L]
Drops(a) == {M("RDROP", a, r, epoch[a], NoNode) : r \in relays[a]}
\* The datagrams in flight after datagram m was received: all of them (the copy
\* received stays: it may arrive again, unbounded duplication).  The liveness
\* models override it (cfg: Received <- LiveReceived, MCElectionLive.tla).
Received(m, N) == N
\* A datagram x may be sent: no copy of it is in flight (a set holds one: sending it again would
\* merge with that copy).  The liveness models override it (cfg: NotInFlight <- LiveNotInFlight,
\* MCElectionLive.tla): a copy in flight that can never take effect again does not count.
NotInFlight(x) == x \notin net

-----------------------------------------------------------------------------
(* One node's own variables as a record (its "local state"), and the      *)
(* rules of each action on it.  Every action X below is an enabling        *)
(* condition on the node's own state XOk(n, s, m) (s = Loc(n)), the         *)
(* environment's part (links, the network, the other nodes), and the new   *)
(* local state XNext(..): these operators are the one definition of each   *)
(* rule, used by the actions here and by the check of a single agent's     *)
(* trace (conformance/ev3conformance/tracecheck.py, docs/spec.md           *)
(* "Election traces"), which sees only the agent's own variables.  The PC  *)
(* has no votedFor, leader, following, via, relays, offered, prevotes:     *)
(* NoNode / 0 / {} in its record, never written back.                      *)

Own(f, n, none) == IF n \in Agents THEN f[n] ELSE none
Loc(n) == [life |-> life[n], epoch |-> epoch[n], votes |-> votes[n],
           votedFor |-> Own(votedFor, n, NoNode), leader |-> Own(leader, n, NoNode),
           following |-> Own(following, n, 0), via |-> Own(via, n, NoNode),
           relays |-> Own(relays, n, {}), offered |-> Own(offered, n, {}),
           prevotes |-> Own(prevotes, n, {}),
           members |-> members[n], mepoch |-> mepoch[n], floor |-> Own(floor, n, 0)]
Put(f, n, x) == IF n \in Agents THEN [f EXCEPT ![n] = x] ELSE f
SetLoc(n, s) ==
    /\ life' = [life EXCEPT ![n] = s.life]
    /\ epoch' = [epoch EXCEPT ![n] = s.epoch]
    /\ votes' = [votes EXCEPT ![n] = s.votes]
    /\ votedFor' = Put(votedFor, n, s.votedFor)
    /\ leader' = Put(leader, n, s.leader)
    /\ following' = Put(following, n, s.following)
    /\ via' = Put(via, n, s.via)
    /\ relays' = Put(relays, n, s.relays)
    /\ offered' = Put(offered, n, s.offered)
    /\ prevotes' = Put(prevotes, n, s.prevotes)
    /\ members' = [members EXCEPT ![n] = s.members]
    /\ mepoch' = [mepoch EXCEPT ![n] = s.mepoch]
    /\ floor' = Put(floor, n, s.floor)
    /\ UNCHANGED <<want, changes>>

\* Membership.  A node's record may lack the membership fields (the
\* single-agent trace checks, whose quorums count against the trace's fleet,
\* Agents): Get reads a field with a default, Fleet(s) is the membership.
Get(r, f, d) == IF f \in DOMAIN r THEN r[f] ELSE d
Fleet(s) == Get(s, "members", Agents)
Max2(x, y) == IF x > y THEN x ELSE y
\* A node's record after it learned that a membership of epoch e exists.
Raised(s, e) == IF "floor" \in DOMAIN s THEN [s EXCEPT !.floor = Max2(@, e)] ELSE s
\* ... and after it learned that membership L is the one of epoch e.
Learned(s, L, e) ==
    IF "members" \in DOMAIN s THEN Raised([s EXCEPT !.members = L, !.mepoch = e], e) ELSE s
\* BUG "DynamicMembership" is the unsafe rule: the PC
\* changes its list in place, LEADER carries the current one, each agent
\* counts quorums against the list it last heard; no floor.
Fixed == BUG # "DynamicMembership"

\* The lifecycle state after n learns of a newer epoch than the one it acts in.
SteppedDown(n, s) ==
    CASE s.life \in {"MASTER", "CANDIDATE"} -> IF n = PC THEN "CANDIDATE" ELSE "PANIC"
      [] s.life = "WORKING" -> "PAUSED"
      [] OTHER -> s.life

\* The start, as the models may override it (cfg: Informed <- .., InitNet <- .., InitDown <- ..;
\* MCElectionLive: the PC dead before its LEADER reached anyone): the agents that know the PC's
\* membership (it published it at epoch 1), the datagrams in flight, the nodes that are down
\* (each a fault already).
Informed == InitMembers
InitNet == {}
InitDown == {}

Init ==
    /\ life = [n \in Nodes |-> IF n \in InitDown THEN "DOWN" ELSE IF n = PC THEN "MASTER" ELSE "ACTIVE"]
    /\ epoch = [n \in Nodes |-> 1]
    /\ votedFor = [a \in Agents |-> NoNode]
    /\ votes = [n \in Nodes |-> {}]
    /\ leader = [a \in Agents |-> PC]
    /\ following = [a \in Agents |-> 1]
    /\ via = [a \in Agents |-> NoNode]
    /\ relays = [a \in Agents |-> {}]
    /\ offered = [a \in Agents |-> {}]
    /\ prevotes = [a \in Agents |-> {}]
    /\ net = InitNet
    /\ down = {}
    /\ faults = Cardinality(InitDown)
    /\ lost = 0
    /\ elected = {<<1, PC>>}
    /\ applied = {}
    /\ members = [n \in Nodes |-> IF n = PC \/ n \in Informed THEN InitMembers ELSE {}]
    /\ mepoch = [n \in Nodes |-> IF n = PC \/ n \in Informed THEN 1 ELSE 0]
    /\ floor = [a \in Agents |-> IF a \in Informed THEN 1 ELSE 0]
    /\ want = InitMembers
    /\ changes = 0
    /\ lastAction = <<"Init">>

-----------------------------------------------------------------------------
(* Lifecycle, as the fleet spec has it.                                    *)

\* The heartbeat of a following agent a gets through: its master is master
\* in that epoch and the link (direct, or through a relay that still relays
\* a and has its own direct link) is up.
HeartbeatOK(a) ==
    /\ leader[a] # NoNode
    /\ life[leader[a]] = "MASTER" /\ epoch[leader[a]] = following[a]
    /\ IF via[a] = NoNode
       THEN Linked(a, leader[a])
       ELSE /\ a \in relays[via[a]] /\ via[via[a]] = NoNode
            /\ leader[via[a]] = leader[a] /\ following[via[a]] = following[a]
            /\ Linked(a, via[a]) /\ Linked(via[a], leader[a])

\* Agent a misses heartbeats past the threshold: WORKING -> PAUSED (behaviour
\* stopped), ACTIVE or PAUSED -> PANIC.  An agent that panics drops the
\* agents it relays for and tells them (RELAY_DROP).  The broken variant
\* PauseFromActive (the name of the same broken rule in AgentLogic) pauses an
\* ACTIVE agent instead (System's LifecycleFromProp: PAUSED only from WORKING).
TimeoutOk(s) == s.life \in Followers
TimeoutNext(s) ==
    IF s.life = "WORKING" \/ (BUG = "PauseFromActive" /\ s.life = "ACTIVE") THEN [s EXCEPT !.life = "PAUSED"]
    ELSE LET t == [s EXCEPT !.life = "PANIC", !.leader = NoNode, !.following = 0, !.via = NoNode]
         IN IF BUG = "KeepTableOnPanic" THEN t ELSE [t EXCEPT !.relays = {}, !.offered = {}]
Timeout(a) ==
    /\ TimeoutOk(Loc(a))
    /\ SpuriousTimeout \/ ~HeartbeatOK(a)
    /\ SetLoc(a, TimeoutNext(Loc(a)))
    /\ net' = IF life[a] = "WORKING" \/ BUG = "KeepTableOnPanic" THEN net ELSE net \cup Drops(a)
    /\ lastAction' = <<"Timeout", a>>
    /\ UNCHANGED <<down, faults, lost, elected, applied>>

-----------------------------------------------------------------------------
(* Relay.                                                                  *)

\* An agent a in PANIC broadcasts a relay request (RELAY_REQ) with its epoch.
\* The request is also a pre-vote: a peer with a master offers a relay, a
\* peer without one answers PREVOTE_OK (GrantPreVote).  A candidate whose
\* election stalled asks again before it stands in the next epoch.  The
\* request carries the epoch of the membership a knows (0: none), so that a
\* peer that knows a newer one tells it (ShareMembers).
RequestRelayOk(s) == s.life \in {"PANIC", "CANDIDATE"}
RequestRelay(a) ==
    /\ RequestRelayOk(Loc(a))
    /\ NotInFlight(MK("RREQ", a, NoNode, epoch[a], mepoch[a]))
    /\ net' = net \cup {MK("RREQ", a, NoNode, epoch[a], mepoch[a])}
    /\ lastAction' = <<"RequestRelay", a>>
    /\ UNCHANGED <<mvars, life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   down, faults, lost, elected, applied>>

\* A peer p that follows a master over a direct link receives a's request
\* and offers to relay (RELAY_OFFER with its epoch and master).  Never if p
\* is relayed itself (one hop), never if a has seen a newer epoch than p.
OfferRelayOk(p, s, m) ==
    /\ m.t = "RREQ" /\ m.src # p
    /\ s.life \in Followers /\ s.following = s.epoch /\ s.leader # NoNode
    /\ BUG = "OfferWhileRelayed" \/ s.via = NoNode
    /\ m.e <= s.epoch
OfferRelayNext(s, m) == [s EXCEPT !.offered = @ \cup {m.src}]
OfferRelay(p, m) ==
    /\ OfferRelayOk(p, Loc(p), m) /\ Linked(m.src, p)
    /\ NotInFlight(M("ROFFER", p, m.src, epoch[p], leader[p]))
    /\ net' = Received(m, net) \cup {M("ROFFER", p, m.src, epoch[p], leader[p])}
    /\ SetLoc(p, OfferRelayNext(Loc(p), m))
    /\ lastAction' = <<"OfferRelay", p, m>>
    /\ UNCHANGED <<down, faults, lost, elected, applied>>

\* Relay p gets a's RELAY_ACCEPT: if it answers an offer p made since p
\* last changed master (offers are forgotten on every change: a late
\* accept of an old offer could close a cycle) and p still follows,
\* directly, the same master in the same epoch, it enters a in its table and tells its
\* master the route (RELAY_ROUTE; abstracted: the master reads the table).
HandleAcceptOk(p, s, m) ==
    /\ m.t = "RACCEPT" /\ m.dst = p
    /\ s.life \in Followers /\ s.following = m.e /\ s.leader = m.x
    /\ BUG = "OfferWhileRelayed" \/ s.via = NoNode
    /\ m.src \in s.offered
HandleAcceptNext(s, m) == [s EXCEPT !.relays = @ \cup {m.src}, !.offered = @ \ {m.src}]
HandleAccept(p, m) ==
    /\ HandleAcceptOk(p, Loc(p), m) /\ Linked(m.src, p)
    /\ SetLoc(p, HandleAcceptNext(Loc(p), m))
    /\ net' = Received(m, net)
    /\ lastAction' = <<"HandleAccept", p, m>>
    /\ UNCHANGED <<down, faults, lost, elected, applied>>

\* Agent a in PANIC takes an offer from p (RELAY_ACCEPT to p): it follows
\* p's master through p, in p's epoch if that is not older than its own.
AcceptRelayOk(a, s, m) ==
    /\ m.t = "ROFFER" /\ m.dst = a
    /\ s.life = "PANIC"
    /\ m.e >= s.epoch
AcceptRelayNext(s, m) ==
    [s EXCEPT !.life = "ACTIVE", !.votedFor = IF m.e > s.epoch THEN NoNode ELSE @,
              !.epoch = m.e, !.leader = m.x, !.following = m.e, !.via = m.src, !.prevotes = {}]
AcceptRelay(a, m) ==
    /\ AcceptRelayOk(a, Loc(a), m) /\ Linked(m.src, a)
    /\ SetLoc(a, AcceptRelayNext(Loc(a), m))
    /\ net' = Received(m, net) \cup {M("RACCEPT", a, m.src, m.e, m.x)}
    /\ lastAction' = <<"AcceptRelay", a, m>>
    /\ UNCHANGED <<down, faults, lost, elected, applied>>

\* A relayed agent a whose relay p dropped it (RELAY_DROP) goes back to PANIC.
RelayDroppedOk(a, s, m) == m.t = "RDROP" /\ m.dst = a /\ s.via = m.src /\ s.life \in Followers
RelayDroppedNext(s) == [s EXCEPT !.life = "PANIC", !.leader = NoNode, !.following = 0, !.via = NoNode]
RelayDropped(a, m) ==
    /\ RelayDroppedOk(a, Loc(a), m)
    /\ SetLoc(a, RelayDroppedNext(Loc(a)))
    /\ net' = Received(m, net)
    /\ lastAction' = <<"RelayDropped", a, m>>
    /\ UNCHANGED <<down, faults, lost, elected, applied>>

-----------------------------------------------------------------------------
(* Pre-vote.  An agent stands only when a majority of the fleet (itself    *)
(* included) has no master: a peer that still hears its master never       *)
(* grants one, so an agent cut off from a live master keeps its epoch and  *)
(* takes a relay offer instead of raising an epoch nobody will follow.     *)
(* Pre-votes change nothing but the asker's count: safety never rests on   *)
(* them (PreVote = FALSE drops the requirement; the safety models pass    *)
(* either way, the relay liveness model fails without it).                 *)

\* Agent v, without a master (PANIC or CANDIDATE), receives a's RELAY_REQ of
\* epoch e >= its own and would vote for a in the next epoch (a is not
\* stronger than v: sa, sv are their scores): it answers PREVOTE_OK.
GrantPreVoteOk(v, s, m, sa, sv) ==
    /\ m.t = "RREQ" /\ m.src # v
    /\ s.life \in {"PANIC", "CANDIDATE"}
    /\ m.e >= s.epoch /\ sa <= sv
GrantPreVote(v, m) ==
    /\ GrantPreVoteOk(v, Loc(v), m, Score[m.src], Score[v]) /\ Linked(m.src, v)
    /\ NotInFlight(M("PREOK", v, m.src, m.e, NoNode))
    /\ net' = Received(m, net) \cup {M("PREOK", v, m.src, m.e, NoNode)}
    /\ lastAction' = <<"GrantPreVote", v, m>>
    /\ UNCHANGED <<mvars, life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   down, faults, lost, elected, applied>>

\* Agent a, still without a master in the epoch it asked in, counts a
\* PREVOTE_OK.
HandlePreVoteOk(a, s, m) ==
    /\ m.t = "PREOK" /\ m.dst = a
    /\ s.life \in {"PANIC", "CANDIDATE"} /\ m.e = s.epoch
    /\ m.src \notin s.prevotes
HandlePreVoteNext(s, m) == [s EXCEPT !.prevotes = @ \cup {m.src}]
HandlePreVote(a, m) ==
    /\ HandlePreVoteOk(a, Loc(a), m) /\ Linked(m.src, a)
    /\ SetLoc(a, HandlePreVoteNext(Loc(a), m))
    /\ net' = Received(m, net)
    /\ lastAction' = <<"HandlePreVote", a, m>>
    /\ UNCHANGED <<down, faults, lost, elected, applied>>

-----------------------------------------------------------------------------
(* Election.                                                               *)

\* An agent in PANIC (no master, no relay) or a candidate whose election
\* failed stands in the next epoch once a majority of the fleet, itself
\* included, granted it a pre-vote: it votes for itself and broadcasts
\* ELECT with its score.  The PC, once back (CANDIDATE), does the same
\* without pre-vote (it always may take the fleet back).
StartElectionOk(n, s) ==
    /\ s.life \in IF n = PC THEN {"CANDIDATE"} ELSE {"PANIC", "CANDIDATE"}
    /\ IF n = PC \/ ~PreVote THEN TRUE ELSE QuorumOf(s.prevotes \cup {n}, Fleet(s))
    /\ n # PC => Get(s, "mepoch", 0) >= Get(s, "floor", 0)
    /\ s.epoch < MaxEpoch
StartElectionNext(n, s) ==
    [s EXCEPT !.epoch = @ + 1, !.votedFor = IF n = PC THEN @ ELSE n,
              !.votes = IF n = PC THEN {} ELSE {n}, !.life = "CANDIDATE",
              !.prevotes = IF n = PC THEN @ ELSE {}]
\* The PC stands with a copy of its membership (LEADER(mepoch, 0, members),
\* broadcast: here one copy per agent): a voter that missed the LEADERs of
\* the PC's epoch learns the list (LearnMembers) and can grant (Knows).
\* With BUG "VoteUnknown" (see Knows) it sends none.
Teach(n) ==
    IF n = PC /\ Fixed /\ BUG # "VoteUnknown" /\ members[PC] # {}
    THEN {MH(PC, a, mepoch[PC], NoNode, members[PC]) : a \in Agents}
    ELSE {}
StartElection(n) ==
    /\ StartElectionOk(n, Loc(n))
    /\ SetLoc(n, StartElectionNext(n, Loc(n)))
    /\ net' = net \cup {MK("ELECT", n, NoNode, epoch[n] + 1, mepoch[n])} \cup Teach(n)
    /\ lastAction' = <<"StartElection", n, epoch[n] + 1>>
    /\ UNCHANGED <<down, faults, lost, elected, applied>>

\* Agent v receives an ELECT of candidate c in epoch e (sc, sv: the scores
\* of c and v).
\*  - e older than v's epoch: v answers EPOCH_STALE.
\*  - v follows a master it still hears and c is not the PC: ignored (a
\*    healthy follower does not disrupt its master; HeartbeatOK is the
\*    environment's part, in HandleElect).
\*  - otherwise v adopts e (stepping down if it acts in an older epoch) and
\*    grants its one vote of epoch e to c if it has not voted in e yet and c
\*    is not stronger than v (VOTE).
\* A voter grants the PC only if it knows a membership at least as new as the
\* one the PC counts its votes against (epoch k, ELECT's third parameter):
\* so its floor never rises above the list it knows, and whoever voted for
\* the PC can still stand if the PC dies before its next list reached
\* anyone.  With BUG "VoteUnknown" it grants without knowing it and the PC
\* sends no copy of its list (Teach): a vote then raises the floor past any
\* list the voter knows.  A record without a membership (a single-agent
\* trace of an older core) knows it.
Knows(s, k) == BUG = "VoteUnknown" \/ ~("mepoch" \in DOMAIN s) \/ s.mepoch >= k
ElectGrant(s, m, sc, sv) ==
    /\ m.e > s.epoch \/ s.votedFor \in {NoNode, m.src} \/ BUG = "DoubleVote"
    /\ sc <= sv
    /\ m.src = PC \/ ~Fixed \/ Get(m, "k", 0) >= Get(s, "floor", 0)
    /\ m.src = PC /\ Fixed => Knows(s, Get(m, "k", 0))
\* A vote for the PC (its ELECT carries the epoch k of its membership): no
\* membership older than k is current any more (the PC may be replacing it).
Voted(s, m, grant) == IF grant /\ m.src = PC /\ Fixed THEN Raised(s, Get(m, "k", 0)) ELSE s
HandleElectOk(v, s, m, sc, sv) ==
    /\ m.t = "ELECT" /\ m.src # v /\ s.life # "DOWN"
    /\ \/ m.e < s.epoch
       \/ m.e > s.epoch
       \/ ElectGrant(s, m, sc, sv) /\ s.votedFor # m.src
HandleElectNext(v, s, m, sc, sv) ==
    LET grant == ElectGrant(s, m, sc, sv) IN
    CASE m.e < s.epoch -> s
      [] m.e > s.epoch ->
           Voted([s EXCEPT !.epoch = m.e, !.votedFor = IF grant THEN m.src ELSE NoNode,
                           !.life = SteppedDown(v, s), !.leader = NoNode, !.following = 0,
                           !.via = NoNode, !.relays = {}, !.offered = {}, !.prevotes = {}], m, grant)
      [] OTHER -> Voted([s EXCEPT !.votedFor = IF grant THEN m.src ELSE @], m, grant)
HandleElect(v, m) ==
    LET c == m.src
        sc == Score[c]
    IN
    /\ HandleElectOk(v, Loc(v), m, sc, Score[v]) /\ Linked(c, v)
    /\ IF m.e < epoch[v]
       THEN /\ NotInFlight(M("STALE", v, c, epoch[v], NoNode))
            /\ net' = Received(m, net) \cup {M("STALE", v, c, epoch[v], NoNode)}
       ELSE /\ ~(life[v] \in Followers /\ HeartbeatOK(v) /\ c # PC)
            /\ net' = Received(m, net) \cup (IF m.e > epoch[v] THEN Drops(v) ELSE {})
                          \cup (IF ElectGrant(Loc(v), m, sc, Score[v])
                                THEN {M("VOTE", v, c, m.e, NoNode)} ELSE {})
    /\ SetLoc(v, HandleElectNext(v, Loc(v), m, sc, Score[v]))
    /\ lastAction' = <<"HandleElect", v, m>>
    /\ UNCHANGED <<down, faults, lost, elected, applied>>

\* Candidate n counts a VOTE for it in its current epoch.
HandleVoteOk(n, s, m) ==
    /\ m.t = "VOTE" /\ m.dst = n
    /\ s.life = "CANDIDATE" /\ m.e = s.epoch
    /\ m.src \notin s.votes
HandleVoteNext(s, m) == [s EXCEPT !.votes = @ \cup {m.src}]
HandleVote(n, m) ==
    /\ m.t = "VOTE" /\ m.dst = n   \* first: Loc(n) needs a node
    /\ HandleVoteOk(n, Loc(n), m) /\ Linked(m.src, n)
    /\ SetLoc(n, HandleVoteNext(Loc(n), m))
    /\ net' = Received(m, net)
    /\ lastAction' = <<"HandleVote", n, m>>
    /\ UNCHANGED <<down, faults, lost, elected, applied>>

\* A candidate with the votes of a majority of the fleet becomes master of
\* its epoch and announces itself (LEADER, also its heartbeat).
\* A new master publishes the membership it counted against; the PC
\* publishes it changed by one agent towards its registry (want), never to
\* an empty one: so the PC's membership is empty only if it always was (a
\* fresh start), nobody knows a membership, and the PC needs no vote.
\* The list stops growing at MaxMembers, all that one LEADER carries (election/
\* common.hpp kMaxMembership); a full list still sheds an agent that is not wanted.
MaxMembers == 30
OneStep(L, w) ==
    LET grow == IF Cardinality(L) < MaxMembers THEN {L \cup {a} : a \in w \ L} ELSE {}
        S == (grow \cup {L \ {a} : a \in L \ w}) \ {{}}
    IN IF S = {} THEN {L} ELSE S
\* A candidate has stood in an epoch newer than the one of its membership (StartElection since
\* the PC's Reconfigure): without it the PC, whose votes of its epoch are still counted, would
\* publish a second membership in the epoch it has published one in already.
BecomeMasterOk(s) ==
    /\ s.life = "CANDIDATE"
    /\ s.epoch > Get(s, "mepoch", 0)
    /\ IF BUG = "MinorityQuorum" THEN s.votes # {} ELSE QuorumOf(s.votes, Fleet(s))
BecomeMasterNext(s) == [s EXCEPT !.life = "MASTER"]
BecomeMaster(n) ==
    LET s == Loc(n) IN
    /\ \/ BecomeMasterOk(s)
       \/ n = PC /\ Fixed /\ s.life = "CANDIDATE" /\ s.epoch > mepoch[PC] /\ members[PC] = {}
    /\ \E L \in IF n # PC THEN {members[n]} ELSE IF Fixed THEN OneStep(members[PC], want) ELSE {want} :
         /\ SetLoc(n, Learned(BecomeMasterNext(s), L, epoch[n]))
         /\ net' = net \cup {MH(n, NoNode, epoch[n], NoNode, L)}
    /\ elected' = elected \cup {<<epoch[n], n>>}
    /\ lastAction' = <<"BecomeMaster", n, epoch[n]>>
    /\ UNCHANGED <<down, faults, lost, applied>>

\* A master re-sends its heartbeat (LEADER) when the last one was lost.
Heartbeat(n) ==
    /\ life[n] = "MASTER"
    /\ NotInFlight(MH(n, NoNode, epoch[n], NoNode, members[n]))
    /\ net' = net \cup {MH(n, NoNode, epoch[n], NoNode, members[n])}
    /\ lastAction' = <<"Heartbeat", n>>
    /\ UNCHANGED <<mvars, life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   down, faults, lost, elected, applied>>

\* Node n learns from EPOCH_STALE that a newer epoch exists: it adopts it;
\* a master or candidate steps down (an agent to PANIC, the PC to stand
\* again), a follower of an older master stops following it.
HandleStaleOk(n, s, m) == m.t = "STALE" /\ m.dst = n /\ s.life # "DOWN" /\ m.e > s.epoch
HandleStaleNext(n, s, m) ==
    LET t == [s EXCEPT !.epoch = m.e, !.life = SteppedDown(n, s), !.votes = {}] IN
    IF n = PC THEN t
    ELSE [t EXCEPT !.votedFor = NoNode, !.prevotes = {}, !.leader = NoNode, !.following = 0,
                   !.via = NoNode, !.relays = {}, !.offered = {}]

\* Node v hears the heartbeat of master s in epoch e over a direct link.
\*  - e older than v's epoch: v answers EPOCH_STALE (the old master steps
\*    down when it gets it) and does not follow.
\*  - otherwise agent v follows s directly in e: from PANIC, CANDIDATE or
\*    MASTER (an older one: handover) it becomes ACTIVE; a WORKING agent
\*    whose master changes is PAUSED until the new master resumes it.
\*  - the PC follows nobody: a LEADER of a newer epoch is HandleStale's rule
\*    with its epoch (the PC adopts it and stands again, its votes of the
\*    older epoch void); one of its own epoch changes nothing (election/
\*    master.hpp HandleHeartbeat, the PC's part).
Stale(s, m) == m.e < s.epoch /\ BUG # "NoEpochCheck"
MasterChange(s, m) == s.leader # m.src \/ s.following # m.e
NewMembers(s, m) == "members" \in DOMAIN s /\ (s.members # m.mem \/ s.mepoch # m.e)
HandleHeartbeatOk(v, s, m) ==
    /\ m.t = "HB" /\ m.dst = NoNode /\ m.src # v /\ s.life # "DOWN"
    /\ v = PC => m.e # s.epoch
    /\ ~Stale(s, m) =>
         /\ MasterChange(s, m) \/ s.via # NoNode \/ s.life \notin Followers \/ NewMembers(s, m)
         /\ s.life = "MASTER" => m.e > s.epoch
HandleHeartbeatNext(v, s, m) ==
    IF Stale(s, m) THEN s
    ELSE IF v = PC THEN HandleStaleNext(PC, s, m)
    ELSE LET t == [s EXCEPT !.life = CASE s.life \in {"PANIC", "CANDIDATE", "MASTER"} -> "ACTIVE"
                                       [] s.life = "WORKING" /\ MasterChange(s, m) -> "PAUSED"
                                       [] OTHER -> s.life,
                            !.epoch = IF m.e > s.epoch THEN m.e ELSE @,
                            !.votedFor = IF m.e > s.epoch THEN NoNode ELSE @,
                            !.leader = m.src, !.following = m.e, !.via = NoNode, !.prevotes = {}]
             u == Learned(t, Get(m, "mem", {}), m.e)
         IN IF MasterChange(s, m) THEN [u EXCEPT !.relays = {}, !.offered = {}] ELSE u
HandleHeartbeat(v, m) ==
    /\ HandleHeartbeatOk(v, Loc(v), m) /\ Linked(m.src, v)
    /\ IF Stale(Loc(v), m)
       THEN /\ NotInFlight(M("STALE", v, m.src, epoch[v], NoNode))
            /\ net' = Received(m, net) \cup {M("STALE", v, m.src, epoch[v], NoNode)}
       ELSE net' = Received(m, net) \cup (IF v # PC /\ MasterChange(Loc(v), m) THEN Drops(v) ELSE {})
    /\ SetLoc(v, HandleHeartbeatNext(v, Loc(v), m))
    /\ lastAction' = <<"HandleHeartbeat", v, m>>
    /\ UNCHANGED <<down, faults, lost, elected, applied>>

\* Node n receives EPOCH_STALE (HandleStaleOk / HandleStaleNext above).
HandleStale(n, m) ==
    /\ m.t = "STALE" /\ m.dst = n   \* first: Loc(n) needs a node
    /\ HandleStaleOk(n, Loc(n), m) /\ Linked(m.src, n)
    /\ SetLoc(n, HandleStaleNext(n, Loc(n), m))
    /\ net' = Received(m, net) \cup (IF n = PC THEN {} ELSE Drops(n))
    /\ lastAction' = <<"HandleStale", n, m>>
    /\ UNCHANGED <<down, faults, lost, elected, applied>>

-----------------------------------------------------------------------------
(* Membership.  Every master publishes one membership for its            *)
(* whole epoch (LEADER); an agent keeps the last one it learned and the     *)
(* epoch of the master that published it (mepoch), and counts quorums       *)
(* against it.  Only the PC changes the membership, and only by winning a   *)
(* new epoch with a majority of its old one (Reconfigure); a vote for the   *)
(* PC raises the voter's floor to that epoch: it grants no candidate whose  *)
(* membership is older (ElectGrant), and stands only with one at least as   *)
(* new (StartElectionOk).  A membership is learned from the master's LEADER *)
(* or from a peer: an agent that knows a newer one than a RELAY_REQ says    *)
(* its sender knows answers with a copy of its LEADER, LEADER(epoch, 0,     *)
(* members...) to the asker (0: no master claimed).                        *)

\* Peer p, not master, receives a's RELAY_REQ, and knows a newer membership
\* than a does: it sends a the copy.
ShareMembersOk(p, s, m) ==
    /\ BUG # "NoShare"
    /\ m.t = "RREQ" /\ m.src # p
    /\ s.life \notin {"MASTER", "DOWN"}
    /\ Get(s, "mepoch", 0) > m.k
ShareMembers(p, m) ==
    /\ ShareMembersOk(p, Loc(p), m) /\ Linked(m.src, p)
    /\ NotInFlight(MH(p, m.src, mepoch[p], NoNode, members[p]))
    /\ net' = net \cup {MH(p, m.src, mepoch[p], NoNode, members[p])}
    /\ lastAction' = <<"ShareMembers", p, m>>
    /\ UNCHANGED <<mvars, life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   down, faults, lost, elected, applied>>

\* Agent a receives a copy of a LEADER of epoch e newer than the membership it
\* knows: it learns the membership; an epoch newer than its own is adopted as
\* from EPOCH_STALE (a master or candidate steps down; no master followed).
LearnMembersOk(a, s, m) ==
    /\ m.t = "HB" /\ m.dst = a /\ s.life # "DOWN"
    /\ m.e > Get(s, "mepoch", 0)
LearnMembersNext(a, s, m) ==
    Learned(IF m.e > s.epoch THEN HandleStaleNext(a, s, m) ELSE s, m.mem, m.e)
LearnMembers(a, m) ==
    /\ m.t = "HB" /\ m.dst = a   \* first: the copy is a's
    /\ LearnMembersOk(a, Loc(a), m) /\ Linked(m.src, a)
    /\ SetLoc(a, LearnMembersNext(a, Loc(a), m))
    /\ net' = Received(m, net) \cup (IF m.e > epoch[a] THEN Drops(a) ELSE {})
    /\ lastAction' = <<"LearnMembers", a, m>>
    /\ UNCHANGED <<down, faults, lost, elected, applied>>

\* The PC (MASTER) registers agent a (AddMember) or declares it lost and
\* drops it (DropMember): its registry (want) changes.  With the bug the
\* membership it publishes changes with it, in the same epoch.
AddMember(a) ==
    /\ life[PC] = "MASTER" /\ a \notin want /\ changes < MaxChanges
    /\ want' = want \cup {a}
    /\ changes' = changes + 1
    /\ members' = IF Fixed THEN members ELSE [members EXCEPT ![PC] = want']
    /\ lastAction' = <<"AddMember", a>>
    /\ UNCHANGED <<mepoch, floor, life, epoch, votedFor, votes, leader, following, via, relays,
                   offered, prevotes, net, down, faults, lost, elected, applied>>
DropMember(a) ==
    /\ life[PC] = "MASTER" /\ a \in want /\ changes < MaxChanges
    /\ want' = want \ {a}
    /\ changes' = changes + 1
    /\ members' = IF Fixed THEN members ELSE [members EXCEPT ![PC] = want']
    /\ lastAction' = <<"DropMember", a>>
    /\ UNCHANGED <<mepoch, floor, life, epoch, votedFor, votes, leader, following, via, relays,
                   offered, prevotes, net, down, faults, lost, elected, applied>>

\* The PC (MASTER) whose registry differs from the membership of its epoch
\* stands in the next epoch (StartElection) to publish it (BecomeMaster).
ReconfigureOk(s, w) == Fixed /\ s.life = "MASTER" /\ OneStep(Fleet(s), w) # {Fleet(s)}
Reconfigure ==
    /\ ReconfigureOk(Loc(PC), want)
    /\ life' = [life EXCEPT ![PC] = "CANDIDATE"]
    /\ lastAction' = <<"Reconfigure">>
    /\ UNCHANGED <<mvars, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   net, down, faults, lost, elected, applied>>

-----------------------------------------------------------------------------
(* Commands, fenced by epoch.                                              *)

\* Master s sends a command (e.g. START, inside EPOCH_CMD with its epoch)
\* to agent a: directly, or, if a follows it through relay p, to p inside
\* RELAY (the whole inner datagram travels on).
SendCommand(s, a) ==
    /\ life[s] = "MASTER"
    /\ \/ /\ NotInFlight(M("CMD", s, a, epoch[s], NoNode))
          /\ net' = net \cup {M("CMD", s, a, epoch[s], NoNode)}
       \/ \E p \in Agents :
            /\ a \in relays[p] /\ leader[p] = s /\ following[p] = epoch[s]
            /\ NotInFlight(M("RELAY", s, p, epoch[s], a))
            /\ net' = net \cup {M("RELAY", s, p, epoch[s], a)}
    /\ lastAction' = <<"SendCommand", s, a>>
    /\ UNCHANGED <<mvars, life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   down, faults, lost, elected, applied>>

\* Relay p forwards the inner datagram of a RELAY to the agent it relays
\* for, unchanged (same sender, msgid: the receiver dedupes end to end).
ForwardOk(p, s, m) == m.t = "RELAY" /\ m.dst = p /\ s.life \in Followers /\ m.x \in s.relays
Forward(p, m) ==
    /\ ForwardOk(p, Loc(p), m) /\ Linked(m.src, p)
    /\ NotInFlight(M("CMD", m.src, m.x, m.e, p))
    /\ net' = Received(m, net) \cup {M("CMD", m.src, m.x, m.e, p)}
    /\ lastAction' = <<"Forward", p, m>>
    /\ UNCHANGED <<mvars, life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   down, faults, lost, elected, applied>>

\* Agent a receives a command of master s in epoch e (directly, or from its
\* relay).  It takes effect only if a follows s in e and e is the highest
\* epoch a has seen (the fence, Obeys): ACTIVE or PAUSED -> WORKING.
Obeys(s, m) == BUG = "NoFencing" \/ (s.leader = m.src /\ s.following = m.e /\ m.e = s.epoch)
ApplyCommandOk(a, s, m) ==
    /\ m.t = "CMD" /\ m.dst = a
    /\ s.life \in {"ACTIVE", "PAUSED"}
    /\ Obeys(s, m)
ApplyCommandNext(s) == [s EXCEPT !.life = "WORKING"]
ApplyCommand(a, m) ==
    /\ ApplyCommandOk(a, Loc(a), m)
    /\ Linked(IF m.x = NoNode THEN m.src ELSE m.x, a)
    /\ SetLoc(a, ApplyCommandNext(Loc(a)))
    /\ applied' = applied \cup {[a |-> a, src |-> m.src, e |-> m.e, seen |-> epoch[a]]}
    /\ net' = Received(m, net)
    /\ lastAction' = <<"ApplyCommand", a, m>>
    /\ UNCHANGED <<down, faults, lost, elected>>

-----------------------------------------------------------------------------
(* Faults.                                                                 *)

\* Node n crashes: it loses everything but epoch, votedFor and the membership
\* it knows (members, mepoch, floor: on disk).
Crash(n) ==
    /\ n = PC => PCCrash
    /\ n # PC => Crashes
    /\ life[n] # "DOWN" /\ faults < MaxFaults
    /\ life' = [life EXCEPT ![n] = "DOWN"]
    /\ faults' = faults + 1
    /\ votes' = [votes EXCEPT ![n] = {}]
    /\ UNCHANGED <<members, mepoch, floor, want, changes>>  \* on disk (the PC: its state file)
    /\ IF n = PC
       THEN UNCHANGED <<votedFor, leader, following, via, relays, offered, prevotes>>
       ELSE /\ prevotes' = [prevotes EXCEPT ![n] = {}]
            /\ votedFor' = IF BUG = "ForgetVote" THEN [votedFor EXCEPT ![n] = NoNode]
                           ELSE votedFor
            /\ leader' = [leader EXCEPT ![n] = NoNode]
            /\ following' = [following EXCEPT ![n] = 0]
            /\ via' = [via EXCEPT ![n] = NoNode]
            /\ relays' = [relays EXCEPT ![n] = {}]
            /\ offered' = [offered EXCEPT ![n] = {}]
    /\ lastAction' = <<"Crash", n>>
    /\ UNCHANGED <<epoch, net, down, lost, elected, applied>>

\* A crashed node starts again: an agent finds no master (PANIC), the PC
\* comes back and stands for election to take the fleet back.
Restart(n) ==
    /\ life[n] = "DOWN"
    /\ n = PC => PCReturns
    /\ life' = [life EXCEPT ![n] = IF n = PC THEN "CANDIDATE" ELSE "PANIC"]
    /\ lastAction' = <<"Restart", n>>
    /\ UNCHANGED <<mvars, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes, net,
                   down, faults, lost, elected, applied>>

\* The link between x and y breaks (partition) or comes back.
Cut(x, y) ==
    /\ Partitions /\ x # y /\ {x, y} \notin down /\ faults < MaxFaults
    /\ down' = down \cup {{x, y}}
    /\ faults' = faults + 1
    /\ lastAction' = <<"Cut", x, y>>
    /\ UNCHANGED <<mvars, life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   net, lost, elected, applied>>

Heal(x, y) ==
    /\ {x, y} \in down
    /\ down' = down \ {{x, y}}
    /\ lastAction' = <<"Heal", x, y>>
    /\ UNCHANGED <<mvars, life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   net, faults, lost, elected, applied>>

\* The network loses datagram m.
Lose(m) ==
    /\ lost < MaxLoss
    /\ net' = net \ {m}
    /\ lost' = lost + 1
    /\ lastAction' = <<"Lose", m>>
    /\ UNCHANGED <<mvars, life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   down, faults, elected, applied>>

-----------------------------------------------------------------------------
Next ==
    \/ \E a \in Agents : Timeout(a) \/ RequestRelay(a) \/ AddMember(a) \/ DropMember(a)
    \/ Reconfigure
    \/ \E n \in Nodes : StartElection(n) \/ BecomeMaster(n) \/ Heartbeat(n)
                        \/ Crash(n) \/ Restart(n)
    \/ \E s \in Nodes, a \in CmdAgents : SendCommand(s, a)
    \/ \E x, y \in Nodes : Cut(x, y) \/ Heal(x, y)
    \/ \E m \in net :
         \/ Lose(m)
         \/ HandleVote(m.dst, m) \/ HandleStale(m.dst, m) \/ HandleHeartbeat(PC, m)
         \/ \E a \in Agents :
              \/ OfferRelay(a, m) \/ AcceptRelay(a, m) \/ HandleAccept(a, m)
              \/ RelayDropped(a, m) \/ GrantPreVote(a, m) \/ HandlePreVote(a, m)
              \/ HandleElect(a, m) \/ HandleHeartbeat(a, m)
              \/ Forward(a, m) \/ ApplyCommand(a, m)
              \/ ShareMembers(a, m) \/ LearnMembers(a, m)

Spec == Init /\ [][Next]_vars

-----------------------------------------------------------------------------
(* Properties.                                                             *)

\* At most one master per epoch, over the whole history.
AtMostOneMasterPerEpochInv ==
    \A x, y \in elected : x[1] = y[1] => x[2] = y[2]

\* No agent follows an epoch lower than one it has seen, and whoever it
\* follows was elected master of that epoch: all followers of epoch e agree.
FollowersAgreeInv ==
    \A a \in Agents : following[a] # 0 =>
        /\ following[a] = epoch[a]
        /\ <<following[a], leader[a]>> \in elected

\* A relay is never relayed itself: every relayed datagram makes one hop.
RelayOneHopInv ==
    \A p \in Agents : relays[p] # {} => via[p] = NoNode

\* The relay graph (p -> a when p relays for a) has no cycle.
RECURSIVE Reach(_, _)
Reach(S, k) == IF k = 0 THEN S ELSE Reach(S \cup UNION {relays[p] : p \in S}, k - 1)
NoRelayCycleInv ==
    \A a \in Agents : a \notin Reach(relays[a], Cardinality(Agents))

\* No command from a fenced master takes effect: a command took effect at
\* an agent only in the highest epoch that agent had seen, and only from
\* the master elected in that epoch.
StaleMasterFencedInv ==
    \A r \in applied : r.e = r.seen /\ <<r.e, r.src>> \in elected

\* A WORKING agent whose master is gone (its heartbeat no longer gets through:
\* the master crashed, stepped down, or its relay dropped it) leaves WORKING
\* (to PAUSED: Timeout).  Liveness, under MCElectionLive's fairness; an agent
\* that never times out in WORKING fails it (FreezeOnLoss, MCElectionLive).
MasterGoneLeavesWorkingProp ==
    \A a \in Agents : (life[a] = "WORKING" /\ ~HeartbeatOK(a)) ~> life[a] # "WORKING"

\* A voter never raises its floor above the membership it knows (Knows): so
\* whoever can vote can also stand (StartElectionOk needs mepoch >= floor)
\* once the PC is gone.  VoteUnknown breaks it (election_member).
FloorKnownInv == \A a \in Agents : floor[a] <= mepoch[a]

\* The one case left in which the fleet waits for the PC: nobody knows a
\* membership that lists an agent, and then the PC's own list has at most
\* one agent: its first step, which needs no vote (BecomeMaster of a fresh
\* PC).  Every later step needs the vote of a majority of the list before,
\* and a voter knows that list (Knows), so it has a list to stand with.
\* Holds from the start of a fresh fleet (Init); a model that starts with a
\* longer list published but unknown (MCElectionLiveUnheard2.cfg: {2, 3} at
\* epoch 1, Informed <- Unheard) starts outside it.  VoteUnknown breaks it
\* (election_fresh).
OnlyFirstStepUnknownInv ==
    (\A a \in Agents : members[a] = {}) => Cardinality(members[PC]) <= 1

\* Lifecycle rules kept by the abstraction: a WORKING agent is supervised
\* (it follows a master in its current epoch); a master does not work.
LifecycleInv ==
    \A a \in Agents :
        /\ life[a] = "WORKING" => following[a] = epoch[a] /\ leader[a] # NoNode
        /\ life[a] \in {"PANIC", "CANDIDATE", "MASTER", "DOWN"} =>
               following[a] = 0 /\ leader[a] = NoNode /\ via[a] = NoNode
=============================================================================
