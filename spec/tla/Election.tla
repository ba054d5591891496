------------------------------ MODULE Election ------------------------------
(***************************************************************************)
(* Relay through a peer and vote-based master election for libev3proto     *)
(* (issue 4).  See docs/election.md for the prose.                         *)
(*                                                                         *)
(* Nodes: the PC master (id 1, PC) and the agents.  The fleet is the       *)
(* membership the PC published with epoch 1 (here: all of Agents); a      *)
(* quorum is a strict majority of it.  Every master acts in an epoch; an   *)
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
(* (loss), cut links deliver nothing (partition).                          *)
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
    BUG              \* "None" or the name of a broken variant

PC == 1
Nodes == {PC} \cup Agents
NoNode == 0
Quorum(S) == 2 * Cardinality(S) > Cardinality(Agents)

Followers == {"ACTIVE", "WORKING", "PAUSED"}
Lives == Followers \cup {"PANIC", "CANDIDATE", "MASTER", "DOWN"}
MsgTypes == {"ELECT", "VOTE", "HB", "STALE", "RREQ", "ROFFER", "RACCEPT", "RDROP", "CMD",
             "RELAY", "PREOK"}
Msgs == [t : MsgTypes, src : Nodes, dst : Nodes \cup {NoNode}, e : 0..MaxEpoch,
         x : Nodes \cup {NoNode}]

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
    lastAction  \* the last action and its arguments

vars == <<life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes, net,
          down, faults, lost, elected, applied, lastAction>>

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

-----------------------------------------------------------------------------
Linked(x, y) == {x, y} \notin down
M(t, s, d, e, x) == [t |-> t, src |-> s, dst |-> d, e |-> e, x |-> x]
Drops(a) == {M("RDROP", a, r, epoch[a], NoNode) : r \in relays[a]}

\* The lifecycle state after n learns of a newer epoch than the one it acts in.
SteppedDown(n) ==
    CASE life[n] \in {"MASTER", "CANDIDATE"} -> IF n = PC THEN "CANDIDATE" ELSE "PANIC"
      [] life[n] = "WORKING" -> "PAUSED"
      [] OTHER -> life[n]

Init ==
    /\ life = [n \in Nodes |-> IF n = PC THEN "MASTER" ELSE "ACTIVE"]
    /\ epoch = [n \in Nodes |-> 1]
    /\ votedFor = [a \in Agents |-> NoNode]
    /\ votes = [n \in Nodes |-> {}]
    /\ leader = [a \in Agents |-> PC]
    /\ following = [a \in Agents |-> 1]
    /\ via = [a \in Agents |-> NoNode]
    /\ relays = [a \in Agents |-> {}]
    /\ offered = [a \in Agents |-> {}]
    /\ prevotes = [a \in Agents |-> {}]
    /\ net = {}
    /\ down = {}
    /\ faults = 0
    /\ lost = 0
    /\ elected = {<<1, PC>>}
    /\ applied = {}
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
\* agents it relays for and tells them (RELAY_DROP).
Timeout(a) ==
    /\ life[a] \in Followers
    /\ SpuriousTimeout \/ ~HeartbeatOK(a)
    /\ IF life[a] = "WORKING"
       THEN /\ life' = [life EXCEPT ![a] = "PAUSED"]
            /\ UNCHANGED <<leader, following, via, relays, offered, net>>
       ELSE /\ life' = [life EXCEPT ![a] = "PANIC"]
            /\ leader' = [leader EXCEPT ![a] = NoNode]
            /\ following' = [following EXCEPT ![a] = 0]
            /\ via' = [via EXCEPT ![a] = NoNode]
            /\ IF BUG = "KeepTableOnPanic"
               THEN UNCHANGED <<relays, offered, net>>
               ELSE /\ relays' = [relays EXCEPT ![a] = {}]
                    /\ offered' = [offered EXCEPT ![a] = {}]
                    /\ net' = net \cup Drops(a)
    /\ lastAction' = <<"Timeout", a>>
    /\ UNCHANGED <<epoch, votedFor, votes, prevotes, down, faults, lost, elected, applied>>

-----------------------------------------------------------------------------
(* Relay.                                                                  *)

\* An agent a in PANIC broadcasts a relay request (RELAY_REQ) with its epoch.
\* The request is also a pre-vote: a peer with a master offers a relay, a
\* peer without one answers PREVOTE_OK (GrantPreVote).  A candidate whose
\* election stalled asks again before it stands in the next epoch.
RequestRelay(a) ==
    /\ life[a] \in {"PANIC", "CANDIDATE"}
    /\ M("RREQ", a, NoNode, epoch[a], NoNode) \notin net
    /\ net' = net \cup {M("RREQ", a, NoNode, epoch[a], NoNode)}
    /\ lastAction' = <<"RequestRelay", a>>
    /\ UNCHANGED <<life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   down, faults, lost, elected, applied>>

\* A peer p that follows a master over a direct link receives a's request
\* and offers to relay (RELAY_OFFER with its epoch and master).  Never if p
\* is relayed itself (one hop), never if a has seen a newer epoch than p.
OfferRelay(p, m) ==
    /\ m.t = "RREQ" /\ m.src # p /\ Linked(m.src, p)
    /\ life[p] \in Followers /\ following[p] = epoch[p] /\ leader[p] # NoNode
    /\ BUG = "OfferWhileRelayed" \/ via[p] = NoNode
    /\ m.e <= epoch[p]
    /\ M("ROFFER", p, m.src, epoch[p], leader[p]) \notin net
    /\ net' = net \cup {M("ROFFER", p, m.src, epoch[p], leader[p])}
    /\ offered' = [offered EXCEPT ![p] = @ \cup {m.src}]
    /\ lastAction' = <<"OfferRelay", p, m>>
    /\ UNCHANGED <<life, epoch, votedFor, votes, leader, following, via, relays, prevotes, down,
                   faults, lost, elected, applied>>

\* Relay p gets a's RELAY_ACCEPT: if it answers an offer p made since p
\* last changed master (offers are forgotten on every change: a late
\* accept of an old offer could close a cycle) and p still follows,
\* directly, the same master in the same epoch, it enters a in its table and tells its
\* master the route (RELAY_ROUTE; abstracted: the master reads the table).
HandleAccept(p, m) ==
    /\ m.t = "RACCEPT" /\ m.dst = p /\ Linked(m.src, p)
    /\ life[p] \in Followers /\ following[p] = m.e /\ leader[p] = m.x
    /\ BUG = "OfferWhileRelayed" \/ via[p] = NoNode
    /\ m.src \in offered[p]
    /\ relays' = [relays EXCEPT ![p] = @ \cup {m.src}]
    /\ offered' = [offered EXCEPT ![p] = @ \ {m.src}]
    /\ lastAction' = <<"HandleAccept", p, m>>
    /\ UNCHANGED <<life, epoch, votedFor, votes, leader, following, via, prevotes, net, down,
                   faults, lost, elected, applied>>

\* Agent a in PANIC takes an offer from p (RELAY_ACCEPT to p): it follows
\* p's master through p, in p's epoch if that is not older than its own.
AcceptRelay(a, m) ==
    /\ m.t = "ROFFER" /\ m.dst = a /\ Linked(m.src, a)
    /\ life[a] = "PANIC"
    /\ m.e >= epoch[a]
    /\ life' = [life EXCEPT ![a] = "ACTIVE"]
    /\ votedFor' = IF m.e > epoch[a] THEN [votedFor EXCEPT ![a] = NoNode] ELSE votedFor
    /\ epoch' = [epoch EXCEPT ![a] = m.e]
    /\ leader' = [leader EXCEPT ![a] = m.x]
    /\ following' = [following EXCEPT ![a] = m.e]
    /\ via' = [via EXCEPT ![a] = m.src]
    /\ prevotes' = [prevotes EXCEPT ![a] = {}]
    /\ net' = net \cup {M("RACCEPT", a, m.src, m.e, m.x)}
    /\ lastAction' = <<"AcceptRelay", a, m>>
    /\ UNCHANGED <<votes, relays, offered, down, faults, lost, elected, applied>>

\* A relayed agent a whose relay p dropped it (RELAY_DROP) goes back to PANIC.
RelayDropped(a, m) ==
    /\ m.t = "RDROP" /\ m.dst = a /\ via[a] = m.src /\ life[a] \in Followers
    /\ life' = [life EXCEPT ![a] = "PANIC"]
    /\ leader' = [leader EXCEPT ![a] = NoNode]
    /\ following' = [following EXCEPT ![a] = 0]
    /\ via' = [via EXCEPT ![a] = NoNode]
    /\ lastAction' = <<"RelayDropped", a, m>>
    /\ UNCHANGED <<epoch, votedFor, votes, relays, offered, prevotes, net, down, faults, lost, elected,
                   applied>>

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
\* stronger than v): it answers PREVOTE_OK.
GrantPreVote(v, m) ==
    /\ m.t = "RREQ" /\ m.src # v /\ Linked(m.src, v)
    /\ life[v] \in {"PANIC", "CANDIDATE"}
    /\ m.e >= epoch[v] /\ Score[m.src] <= Score[v]
    /\ M("PREOK", v, m.src, m.e, NoNode) \notin net
    /\ net' = net \cup {M("PREOK", v, m.src, m.e, NoNode)}
    /\ lastAction' = <<"GrantPreVote", v, m>>
    /\ UNCHANGED <<life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   down, faults, lost, elected, applied>>

\* Agent a, still without a master in the epoch it asked in, counts a
\* PREVOTE_OK.
HandlePreVote(a, m) ==
    /\ m.t = "PREOK" /\ m.dst = a /\ Linked(m.src, a)
    /\ life[a] \in {"PANIC", "CANDIDATE"} /\ m.e = epoch[a]
    /\ m.src \notin prevotes[a]
    /\ prevotes' = [prevotes EXCEPT ![a] = @ \cup {m.src}]
    /\ lastAction' = <<"HandlePreVote", a, m>>
    /\ UNCHANGED <<life, epoch, votedFor, votes, leader, following, via, relays, offered, net,
                   down, faults, lost, elected, applied>>

-----------------------------------------------------------------------------
(* Election.                                                               *)

\* An agent in PANIC (no master, no relay) or a candidate whose election
\* failed stands in the next epoch once a majority of the fleet, itself
\* included, granted it a pre-vote: it votes for itself and broadcasts
\* ELECT with its score.  The PC, once back (CANDIDATE), does the same
\* without pre-vote (it always may take the fleet back).
StartElection(n) ==
    /\ life[n] \in IF n = PC THEN {"CANDIDATE"} ELSE {"PANIC", "CANDIDATE"}
    /\ IF n = PC \/ ~PreVote THEN TRUE ELSE Quorum(prevotes[n] \cup {n})
    /\ epoch[n] < MaxEpoch
    /\ epoch' = [epoch EXCEPT ![n] = @ + 1]
    /\ votedFor' = IF n = PC THEN votedFor ELSE [votedFor EXCEPT ![n] = n]
    /\ votes' = [votes EXCEPT ![n] = IF n = PC THEN {} ELSE {n}]
    /\ life' = [life EXCEPT ![n] = "CANDIDATE"]
    /\ net' = net \cup {M("ELECT", n, NoNode, epoch[n] + 1, NoNode)}
    /\ prevotes' = IF n = PC THEN prevotes ELSE [prevotes EXCEPT ![n] = {}]
    /\ lastAction' = <<"StartElection", n, epoch[n] + 1>>
    /\ UNCHANGED <<leader, following, via, relays, offered, down, faults, lost, elected, applied>>

\* Agent v receives an ELECT of candidate c in epoch e.
\*  - e older than v's epoch: v answers EPOCH_STALE.
\*  - v follows a master it still hears and c is not the PC: ignored (a
\*    healthy follower does not disrupt its master).
\*  - otherwise v adopts e (stepping down if it acts in an older epoch) and
\*    grants its one vote of epoch e to c if it has not voted in e yet and c
\*    is not stronger than v (VOTE).
HandleElect(v, m) ==
    LET c == m.src
        newer == m.e > epoch[v]
        free == newer \/ votedFor[v] \in {NoNode, c} \/ BUG = "DoubleVote"
        grant == free /\ Score[c] <= Score[v]
    IN
    /\ m.t = "ELECT" /\ c # v /\ Linked(c, v) /\ life[v] # "DOWN"
    /\ IF m.e < epoch[v]
       THEN /\ M("STALE", v, c, epoch[v], NoNode) \notin net
            /\ net' = net \cup {M("STALE", v, c, epoch[v], NoNode)}
            /\ UNCHANGED <<life, epoch, votedFor, leader, following, via, relays, offered, prevotes>>
       ELSE /\ ~(life[v] \in Followers /\ HeartbeatOK(v) /\ c # PC)
            /\ newer \/ (grant /\ votedFor[v] # c)
            /\ epoch' = [epoch EXCEPT ![v] = m.e]
            /\ votedFor' = [votedFor EXCEPT ![v] = IF grant THEN c
                                                   ELSE IF newer THEN NoNode ELSE @]
            /\ IF newer
               THEN /\ life' = [life EXCEPT ![v] = SteppedDown(v)]
                    /\ leader' = [leader EXCEPT ![v] = NoNode]
                    /\ following' = [following EXCEPT ![v] = 0]
                    /\ via' = [via EXCEPT ![v] = NoNode]
                    /\ relays' = [relays EXCEPT ![v] = {}]
                    /\ offered' = [offered EXCEPT ![v] = {}]
                    /\ prevotes' = [prevotes EXCEPT ![v] = {}]
               ELSE UNCHANGED <<life, leader, following, via, relays, offered, prevotes>>
            /\ net' = net \cup (IF newer THEN Drops(v) ELSE {})
                          \cup (IF grant THEN {M("VOTE", v, c, m.e, NoNode)} ELSE {})
    /\ lastAction' = <<"HandleElect", v, m>>
    /\ UNCHANGED <<votes, down, faults, lost, elected, applied>>

\* Candidate n counts a VOTE for it in its current epoch.
HandleVote(n, m) ==
    /\ m.t = "VOTE" /\ m.dst = n /\ Linked(m.src, n)
    /\ life[n] = "CANDIDATE" /\ m.e = epoch[n]
    /\ m.src \notin votes[n]
    /\ votes' = [votes EXCEPT ![n] = @ \cup {m.src}]
    /\ lastAction' = <<"HandleVote", n, m>>
    /\ UNCHANGED <<life, epoch, votedFor, leader, following, via, relays, offered, prevotes, net,
                   down, faults, lost, elected, applied>>

\* A candidate with the votes of a majority of the fleet becomes master of
\* its epoch and announces itself (LEADER, also its heartbeat).
BecomeMaster(n) ==
    /\ life[n] = "CANDIDATE"
    /\ IF BUG = "MinorityQuorum" THEN votes[n] # {} ELSE Quorum(votes[n])
    /\ life' = [life EXCEPT ![n] = "MASTER"]
    /\ elected' = elected \cup {<<epoch[n], n>>}
    /\ net' = net \cup {M("HB", n, NoNode, epoch[n], NoNode)}
    /\ lastAction' = <<"BecomeMaster", n, epoch[n]>>
    /\ UNCHANGED <<epoch, votedFor, votes, leader, following, via, relays, offered, prevotes, down,
                   faults, lost, applied>>

\* A master re-sends its heartbeat (LEADER) when the last one was lost.
Heartbeat(n) ==
    /\ life[n] = "MASTER"
    /\ M("HB", n, NoNode, epoch[n], NoNode) \notin net
    /\ net' = net \cup {M("HB", n, NoNode, epoch[n], NoNode)}
    /\ lastAction' = <<"Heartbeat", n>>
    /\ UNCHANGED <<life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   down, faults, lost, elected, applied>>

\* Agent v hears the heartbeat of master s in epoch e over a direct link.
\*  - e older than v's epoch: v answers EPOCH_STALE (the old master steps
\*    down when it gets it) and does not follow.
\*  - otherwise v follows s directly in e: from PANIC, CANDIDATE or MASTER
\*    (an older one: handover) it becomes ACTIVE; a WORKING agent whose
\*    master changes is PAUSED until the new master resumes it.
HandleHeartbeat(v, m) ==
    LET s == m.src
        newer == m.e > epoch[v]
        change == leader[v] # s \/ following[v] # m.e
    IN
    /\ m.t = "HB" /\ s # v /\ Linked(s, v) /\ life[v] # "DOWN"
    /\ IF m.e < epoch[v] /\ BUG # "NoEpochCheck"
       THEN /\ M("STALE", v, s, epoch[v], NoNode) \notin net
            /\ net' = net \cup {M("STALE", v, s, epoch[v], NoNode)}
            /\ UNCHANGED <<life, epoch, votedFor, leader, following, via, relays, offered, prevotes>>
       ELSE /\ change \/ via[v] # NoNode \/ life[v] \notin Followers
            /\ life[v] = "MASTER" => m.e > epoch[v]
            /\ life' = [life EXCEPT ![v] =
                          CASE life[v] \in {"PANIC", "CANDIDATE", "MASTER"} -> "ACTIVE"
                            [] life[v] = "WORKING" /\ change -> "PAUSED"
                            [] OTHER -> life[v]]
            /\ epoch' = [epoch EXCEPT ![v] = IF newer THEN m.e ELSE @]
            /\ votedFor' = IF newer THEN [votedFor EXCEPT ![v] = NoNode] ELSE votedFor
            /\ leader' = [leader EXCEPT ![v] = s]
            /\ following' = [following EXCEPT ![v] = m.e]
            /\ via' = [via EXCEPT ![v] = NoNode]
            /\ prevotes' = [prevotes EXCEPT ![v] = {}]
            /\ IF change
               THEN /\ relays' = [relays EXCEPT ![v] = {}]
                    /\ offered' = [offered EXCEPT ![v] = {}]
                    /\ net' = net \cup Drops(v)
               ELSE UNCHANGED <<relays, offered, net>>
    /\ lastAction' = <<"HandleHeartbeat", v, m>>
    /\ UNCHANGED <<votes, down, faults, lost, elected, applied>>

\* Node n learns from EPOCH_STALE that a newer epoch exists: it adopts it;
\* a master or candidate steps down (an agent to PANIC, the PC to stand
\* again), a follower of an older master stops following it.
HandleStale(n, m) ==
    /\ m.t = "STALE" /\ m.dst = n /\ Linked(m.src, n) /\ life[n] # "DOWN"
    /\ m.e > epoch[n]
    /\ epoch' = [epoch EXCEPT ![n] = m.e]
    /\ life' = [life EXCEPT ![n] = SteppedDown(n)]
    /\ IF n = PC
       THEN UNCHANGED <<votedFor, leader, following, via, relays, offered, prevotes, net>>
       ELSE /\ votedFor' = [votedFor EXCEPT ![n] = NoNode]
            /\ prevotes' = [prevotes EXCEPT ![n] = {}]
            /\ leader' = [leader EXCEPT ![n] = NoNode]
            /\ following' = [following EXCEPT ![n] = 0]
            /\ via' = [via EXCEPT ![n] = NoNode]
            /\ relays' = [relays EXCEPT ![n] = {}]
            /\ offered' = [offered EXCEPT ![n] = {}]
            /\ net' = net \cup Drops(n)
    /\ lastAction' = <<"HandleStale", n, m>>
    /\ UNCHANGED <<votes, down, faults, lost, elected, applied>>

-----------------------------------------------------------------------------
(* Commands, fenced by epoch.                                              *)

\* Master s sends a command (e.g. START, inside EPOCH_CMD with its epoch)
\* to agent a: directly, or, if a follows it through relay p, to p inside
\* RELAY (the whole inner datagram travels on).
SendCommand(s, a) ==
    /\ life[s] = "MASTER"
    /\ \/ /\ M("CMD", s, a, epoch[s], NoNode) \notin net
          /\ net' = net \cup {M("CMD", s, a, epoch[s], NoNode)}
       \/ \E p \in Agents :
            /\ a \in relays[p] /\ leader[p] = s /\ following[p] = epoch[s]
            /\ M("RELAY", s, p, epoch[s], a) \notin net
            /\ net' = net \cup {M("RELAY", s, p, epoch[s], a)}
    /\ lastAction' = <<"SendCommand", s, a>>
    /\ UNCHANGED <<life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   down, faults, lost, elected, applied>>

\* Relay p forwards the inner datagram of a RELAY to the agent it relays
\* for, unchanged (same sender, msgid: the receiver dedupes end to end).
Forward(p, m) ==
    /\ m.t = "RELAY" /\ m.dst = p /\ Linked(m.src, p)
    /\ life[p] \in Followers /\ m.x \in relays[p]
    /\ M("CMD", m.src, m.x, m.e, p) \notin net
    /\ net' = net \cup {M("CMD", m.src, m.x, m.e, p)}
    /\ lastAction' = <<"Forward", p, m>>
    /\ UNCHANGED <<life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   down, faults, lost, elected, applied>>

\* Agent a receives a command of master s in epoch e (directly, or from its
\* relay).  It takes effect only if a follows s in e and e is the highest
\* epoch a has seen: ACTIVE or PAUSED -> WORKING.
ApplyCommand(a, m) ==
    /\ m.t = "CMD" /\ m.dst = a
    /\ Linked(IF m.x = NoNode THEN m.src ELSE m.x, a)
    /\ life[a] \in {"ACTIVE", "PAUSED"}
    /\ BUG = "NoFencing" \/ (leader[a] = m.src /\ following[a] = m.e /\ m.e = epoch[a])
    /\ life' = [life EXCEPT ![a] = "WORKING"]
    /\ applied' = applied \cup {[a |-> a, src |-> m.src, e |-> m.e, seen |-> epoch[a]]}
    /\ lastAction' = <<"ApplyCommand", a, m>>
    /\ UNCHANGED <<epoch, votedFor, votes, leader, following, via, relays, offered, prevotes, net,
                   down, faults, lost, elected>>

-----------------------------------------------------------------------------
(* Faults.                                                                 *)

\* Node n crashes: it loses everything but epoch and votedFor (on disk).
Crash(n) ==
    /\ n = PC => PCCrash
    /\ n # PC => Crashes
    /\ life[n] # "DOWN" /\ faults < MaxFaults
    /\ life' = [life EXCEPT ![n] = "DOWN"]
    /\ faults' = faults + 1
    /\ votes' = [votes EXCEPT ![n] = {}]
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
    /\ UNCHANGED <<epoch, votedFor, votes, leader, following, via, relays, offered, prevotes, net,
                   down, faults, lost, elected, applied>>

\* The link between x and y breaks (partition) or comes back.
Cut(x, y) ==
    /\ Partitions /\ x # y /\ {x, y} \notin down /\ faults < MaxFaults
    /\ down' = down \cup {{x, y}}
    /\ faults' = faults + 1
    /\ lastAction' = <<"Cut", x, y>>
    /\ UNCHANGED <<life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   net, lost, elected, applied>>

Heal(x, y) ==
    /\ {x, y} \in down
    /\ down' = down \ {{x, y}}
    /\ lastAction' = <<"Heal", x, y>>
    /\ UNCHANGED <<life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   net, faults, lost, elected, applied>>

\* The network loses datagram m.
Lose(m) ==
    /\ lost < MaxLoss
    /\ net' = net \ {m}
    /\ lost' = lost + 1
    /\ lastAction' = <<"Lose", m>>
    /\ UNCHANGED <<life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   down, faults, elected, applied>>

-----------------------------------------------------------------------------
Next ==
    \/ \E a \in Agents : Timeout(a) \/ RequestRelay(a)
    \/ \E n \in Nodes : StartElection(n) \/ BecomeMaster(n) \/ Heartbeat(n)
                        \/ Crash(n) \/ Restart(n)
    \/ \E s \in Nodes, a \in CmdAgents : SendCommand(s, a)
    \/ \E x, y \in Nodes : Cut(x, y) \/ Heal(x, y)
    \/ \E m \in net :
         \/ Lose(m)
         \/ HandleVote(m.dst, m) \/ HandleStale(m.dst, m)
         \/ \E a \in Agents :
              \/ OfferRelay(a, m) \/ AcceptRelay(a, m) \/ HandleAccept(a, m)
              \/ RelayDropped(a, m) \/ GrantPreVote(a, m) \/ HandlePreVote(a, m)
              \/ HandleElect(a, m) \/ HandleHeartbeat(a, m)
              \/ Forward(a, m) \/ ApplyCommand(a, m)

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

\* Lifecycle rules kept by the abstraction: a WORKING agent is supervised
\* (it follows a master in its current epoch); a master does not work.
LifecycleInv ==
    \A a \in Agents :
        /\ life[a] = "WORKING" => following[a] = epoch[a] /\ leader[a] # NoNode
        /\ life[a] \in {"PANIC", "CANDIDATE", "MASTER", "DOWN"} =>
               following[a] = 0 /\ leader[a] = NoNode /\ via[a] = NoNode
=============================================================================
