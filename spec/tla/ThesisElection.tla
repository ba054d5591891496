--------------------------- MODULE ThesisElection ---------------------------
(***************************************************************************)
(* The master election of the thesis (section 5.3.2, "Wszyscy agenci      *)
(* traca polaczenie z nadzorca"), modelled exactly as written, so that TLC *)
(* can refute it.                                                          *)
(*                                                                         *)
(*   - every agent broadcasts its personal score;                          *)
(*   - with it, the number of records (scores) it has received so far,    *)
(*     its own included, so that A can learn from B that it misses C;     *)
(*   - it re-broadcasts its score whenever that number grows;             *)
(*   - an agent without the full set of records abstains from the final   *)
(*     vote; "full" is all an agent can know: no agent it has heard of    *)
(*     reports more records than it has (the fleet size is not known:     *)
(*     that is what the counts are for);                                   *)
(*   - "after some time" an agent that takes part in the final vote and   *)
(*     has the lowest score among its records names itself master; with   *)
(*     an equal score the choice is random (here: either may).            *)
(*                                                                         *)
(* The network loses and reorders datagrams: it is a set of datagrams in  *)
(* flight, delivered in any order; any datagram on a lossy link may be     *)
(* lost, and a link in Cut delivers nothing (the thesis' own example: A   *)
(* cannot reach C).  Duplicates are not modelled: receiving a score twice *)
(* changes nothing (a set union and a maximum).  "After some time" is     *)
(* read as generously as possible: an agent decides only once the whole  *)
(* fleet is quiet: every agent has announced its current count and every *)
(* datagram has been delivered or lost ("when all know the scores").     *)
(*                                                                         *)
(* AtMostOneMasterInv is the property the thesis wants and, as it admits,  *)
(* does not have.  TLC finds the split brain.                              *)
(***************************************************************************)
EXTENDS Naturals, FiniteSets

CONSTANTS
    Agents,      \* the agents that lost the master (their ids)
    Score,       \* Score[a]: the agent's personal score (lower = weaker)
    Cut,         \* set of ordered pairs <<from, to>> that deliver nothing
    LossyLinks   \* set of ordered pairs <<from, to>> that may lose a datagram

VARIABLES
    phase,       \* phase[a] \in {"voting", "master", "follower"}
    recs,        \* recs[a]: the agents whose score a has received (itself included)
    heard,       \* heard[a][b]: the largest record count a has received from b
    sent,        \* sent[a]: the record count a last broadcast (0: not yet)
    net,         \* datagrams in flight: [src, dst, score, count]
    lastAction   \* the last action and its arguments (for traces and charts)

vars == <<phase, recs, heard, sent, net, lastAction>>

Msg == [src : Agents, dst : Agents, score : Nat, count : Nat]

TypeOK ==
    /\ phase \in [Agents -> {"voting", "master", "follower"}]
    /\ recs \in [Agents -> SUBSET Agents]
    /\ heard \in [Agents -> [Agents -> 0..Cardinality(Agents)]]
    /\ sent \in [Agents -> 0..Cardinality(Agents)]
    /\ net \subseteq Msg

-----------------------------------------------------------------------------
Init ==
    /\ phase = [a \in Agents |-> "voting"]
    /\ recs = [a \in Agents |-> {a}]
    /\ heard = [a \in Agents |-> [b \in Agents |-> 0]]
    /\ sent = [a \in Agents |-> 0]
    /\ net = {}
    /\ lastAction = <<"Init">>

\* A voting agent a broadcasts its score and its record count, the first
\* time and again each time the count has grown since it last did.
\* Broadcast = one datagram to every other agent.
Broadcast(a) ==
    /\ phase[a] = "voting"
    /\ sent[a] < Cardinality(recs[a])
    /\ sent' = [sent EXCEPT ![a] = Cardinality(recs[a])]
    /\ net' = net \cup {[src |-> a, dst |-> b, score |-> Score[a],
                         count |-> Cardinality(recs[a])] : b \in Agents \ {a}}
    /\ lastAction' = <<"Broadcast", a, Cardinality(recs[a])>>
    /\ UNCHANGED <<phase, recs, heard>>

\* Agent a receives datagram m (over a link that is not cut); it may have
\* received it before.  It records the sender's score and its count.
Receive(a, m) ==
    /\ m \in net
    /\ m.dst = a
    /\ <<m.src, a>> \notin Cut
    /\ net' = net \ {m}
    /\ recs' = [recs EXCEPT ![a] = @ \cup {m.src}]
    /\ heard' = [heard EXCEPT ![a][m.src] = IF m.count > @ THEN m.count ELSE @]
    /\ lastAction' = <<"Receive", m.src, a, m.count>>
    /\ UNCHANGED <<phase, sent>>

\* The network loses datagram m on a lossy link (a cut link loses all).
Lose(m) ==
    /\ m \in net
    /\ <<m.src, m.dst>> \in LossyLinks \cup Cut
    /\ net' = net \ {m}
    /\ lastAction' = <<"Lose", m.src, m.dst, m.count>>
    /\ UNCHANGED <<phase, recs, heard, sent>>

\* a has the full set of records, as far as it can tell: nobody it heard
\* of has more records than a has.
Complete(a) == \A b \in Agents : heard[a][b] <= Cardinality(recs[a])

\* "After some time": every agent has announced its current count and no
\* datagram is in flight any more (the most generous timeout there is).
TimeUp(a) ==
    /\ \A b \in Agents : phase[b] = "voting" => sent[b] = Cardinality(recs[b])
    /\ net = {}

\* "After some time", an agent with the full set and the lowest score
\* among its records names itself master (a tie: either may, at random).
BecomeMaster(a) ==
    /\ phase[a] = "voting"
    /\ TimeUp(a)
    /\ Complete(a)
    /\ \A b \in recs[a] : Score[a] <= Score[b]
    /\ phase' = [phase EXCEPT ![a] = "master"]
    /\ lastAction' = <<"BecomeMaster", a>>
    /\ UNCHANGED <<recs, heard, sent, net>>

\* "After some time", an agent with the full set that is not the lowest
\* takes the lowest one as its master.
BecomeFollower(a) ==
    /\ phase[a] = "voting"
    /\ TimeUp(a)
    /\ Complete(a)
    /\ \E b \in recs[a] : Score[b] < Score[a]
    /\ phase' = [phase EXCEPT ![a] = "follower"]
    /\ lastAction' = <<"BecomeFollower", a>>
    /\ UNCHANGED <<recs, heard, sent, net>>

Next ==
    \/ \E a \in Agents : Broadcast(a) \/ BecomeMaster(a) \/ BecomeFollower(a)
    \/ \E m \in net : Receive(m.dst, m)
    \/ \E m \in net : Lose(m)

Spec == Init /\ [][Next]_vars

-----------------------------------------------------------------------------
\* The property the thesis wants: at most one agent names itself master.
AtMostOneMasterInv ==
    \A a, b \in Agents : phase[a] = "master" /\ phase[b] = "master" => a = b
=============================================================================
