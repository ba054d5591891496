------------------------------- MODULE Reports -------------------------------
(***************************************************************************)
(* Reports that survive master loss.  An agent numbers its reports        *)
(* (SENSOR_VALUE, ACTION_OK/INTERR/ERR, EVENT) 1, 2, 3, ... and keeps     *)
(* each in a bounded buffer until the PC master acknowledges it; the PC    *)
(* stores a report only as the next of that agent's record and then       *)
(* acknowledges cumulatively (the number of reports stored).  The record  *)
(* of a mission is the PC's: an interim master (an agent elected while    *)
(* the PC is gone) takes the reports sent to it and acknowledges them, but *)
(* its acknowledgement frees nothing, so the agent still holds them when   *)
(* the PC returns and delivers them to the PC, in order, once.  A full     *)
(* buffer drops its oldest report and keeps a drop marker in its place    *)
(* (one range, however many are dropped), which travels as one datagram   *)
(* (first..last, as REPORT_DROPPED on the wire); the PC records the       *)
(* marker's numbers from its next on as dropped: the record has no hole,  *)
(* and a drop is never silent.                                            *)
(*                                                                         *)
(* The election and the relay are abstracted to the master an agent       *)
(* reports to (`cur`), which changes within a budget, and the PC's return *)
(* (Takeover).  The network loses (a budget), duplicates (a budget) and    *)
(* reorders (a set) datagrams; the agent may send everything it holds at   *)
(* any time, and the PC its acknowledgement, which stand for their         *)
(* retries.  The PC may crash and restart: its record is durable (a crash *)
(* keeps it), what it has not stored is lost.                             *)
(***************************************************************************)
EXTENDS Integers, Sequences, FiniteSets

CONSTANTS
    Agents,      \* the agents (model values)
    Cap,         \* the buffer's bound: reports held at once (a drop marker not counted)
    MaxReports,  \* reports each agent makes, in all
    MaxLoss,     \* datagrams the network may lose, in all
    MaxDup,      \* datagrams the network may deliver twice, in all
    MaxCrash,    \* PC crashes, in all
    MaxSwitch,   \* times an agent starts reporting to the interim master (an election), in all
    BUG          \* "none", or a broken variant: "AckBeforeStore", "ForgetfulWindow", "HandoverLoses",
                 \*   "SilentDrop", "GapAsDrop"

ASSUME Cap >= 1 /\ MaxReports >= 1
ASSUME BUG \in {"none", "AckBeforeStore", "ForgetfulWindow", "HandoverLoses", "SilentDrop",
                 "GapAsDrop"}

Masters == {"pc", "im"}   \* the PC master and an interim master
Seqs == 1..MaxReports
Kinds == {"report", "dropped"}

VARIABLES
    made,     \* made[a]: reports agent a has made (numbered 1..made[a])
    lo,       \* lo[a]: the lowest number a still holds (all below: acknowledged by the PC)
    mk,       \* mk[a]: lo[a]..mk[a] are held as a drop marker (their reports were dropped)
    cur,      \* cur[a]: the master agent a reports to
    rec,      \* rec[a]: the PC's record of agent a: a sequence of [seq, kind] (durable)
    nx,       \* nx[a]: the number the PC takes next from a (Len(rec[a]) + 1; 0: not known)
    inbox,    \* inbox[a]: taken by the PC, not stored yet (AckBeforeStore only; volatile)
    pcup,     \* the PC runs
    net,      \* reports and drop markers in flight to the PC
    acks,     \* acks[a][f]: the highest ACK in flight from master f to agent a (-1: none).  A
              \*   lower ACK delivered first amounts to a TakeAck, then the later PCAck: the same
              \*   reachable states as a set of ACKs each delivered or lost (checked)
    budget,   \* [loss, dup, crash, switch]: what the environment may still do
    dropped,  \* history: dropped[a]: the numbers whose reports a's bound dropped
    sentrep   \* history: sentrep[a]: the numbers a has sent as reports it held (not as a marker's)

vars == <<made, lo, mk, cur, rec, nx, inbox, pcup, net, acks, budget, dropped, sentrep>>

\* Report s of agent a (REPORT on the wire), and the drop marker f..l (REPORT_DROPPED), on their
\* way to a master: the numbers seq..last, of one kind.
Report(a, s) == [agent |-> a, seq |-> s, last |-> s, kind |-> "report"]
Marker(a, f, l) == [agent |-> a, seq |-> f, last |-> l, kind |-> "dropped"]
Datagrams == {Report(a, s) : a \in Agents, s \in Seqs} \cup
             {Marker(a, f, l) : a \in Agents, f \in Seqs, l \in Seqs}

\* What a holds as a report (not dropped): mk[a] + 1 .. made[a].
Held(a) == made[a] - mk[a]
Stored(a) == Len(rec[a])

TypeOK ==
    /\ made \in [Agents -> 0..MaxReports]
    /\ lo \in [Agents -> 1..MaxReports + 1]
    /\ mk \in [Agents -> 0..MaxReports]
    /\ cur \in [Agents -> Masters]
    /\ rec \in [Agents -> Seq([seq : Seqs, kind : Kinds])]
    /\ nx \in [Agents -> 0..MaxReports + 1]
    /\ inbox \in [Agents -> Seq([seq : Seqs, kind : Kinds])]
    /\ pcup \in BOOLEAN
    /\ net \subseteq Datagrams
    /\ acks \in [Agents -> [Masters -> -1..MaxReports]]
    /\ budget \in [loss : 0..MaxLoss, dup : 0..MaxDup, crash : 0..MaxCrash, switch : 0..MaxSwitch]
    /\ dropped \in [Agents -> SUBSET Seqs]
    /\ sentrep \in [Agents -> SUBSET Seqs]

Init ==
    /\ made = [a \in Agents |-> 0]
    /\ lo = [a \in Agents |-> 1]
    /\ mk = [a \in Agents |-> 0]
    /\ cur = [a \in Agents |-> "pc"]
    /\ rec = [a \in Agents |-> <<>>]
    /\ nx = [a \in Agents |-> 1]
    /\ inbox = [a \in Agents |-> <<>>]
    /\ pcup = TRUE
    /\ net = {}
    /\ acks = [a \in Agents |-> [f \in Masters |-> -1]]
    /\ budget = [loss |-> MaxLoss, dup |-> MaxDup, crash |-> MaxCrash, switch |-> MaxSwitch]
    /\ dropped = [a \in Agents |-> {}]
    /\ sentrep = [a \in Agents |-> {}]

\* The datagram leaves the network when taken, unless the network delivers it twice (dup budget).
Taken(m) == \/ net' = net \ {m} /\ UNCHANGED budget
            \/ budget.dup > 0 /\ net' = net /\ budget' = [budget EXCEPT !.dup = @ - 1]

\* Sending an acknowledgement of n from f to a: the highest in flight stays.
SendAck(f, a, n) == acks' = [acks EXCEPT ![a][f] = IF n > @ THEN n ELSE @]

(***************************************************************************)
(* Agent steps.                                                            *)
(***************************************************************************)

\* Make: a makes its next report; if that puts Cap + 1 reports in the buffer, the oldest is
\* dropped and joins the drop marker.
Make(a) ==
    /\ made[a] < MaxReports
    /\ made' = [made EXCEPT ![a] = @ + 1]
    /\ IF made[a] + 1 - mk[a] > Cap
       THEN /\ mk' = [mk EXCEPT ![a] = @ + 1]
            /\ dropped' = [dropped EXCEPT ![a] = @ \cup {mk[a] + 1}]
       ELSE UNCHANGED <<mk, dropped>>
    /\ UNCHANGED <<lo, cur, rec, nx, inbox, pcup, net, acks, budget, sentrep>>

\* Send: a sends everything it holds, its drop marker (when it holds one) and its reports, to the
\* master it reports to (a round of its retries, at any time; SilentDrop: the marker is kept but
\* never sent, so the PC never learns of the drop).  To the PC: into the network.  The interim
\* master takes them at once (to show and act on them) and acknowledges them all (its part of the
\* network and its record are not modelled: they matter only to HandoverLoses).
MarkerOut(a) == IF mk[a] >= lo[a] /\ BUG # "SilentDrop" THEN {Marker(a, lo[a], mk[a])} ELSE {}
Sent(a) == {Report(a, s) : s \in mk[a] + 1..made[a]} \cup MarkerOut(a)
Send(a) ==
    /\ Sent(a) # {}
    /\ IF cur[a] = "pc"
       THEN /\ net' = net \cup Sent(a)
            /\ UNCHANGED acks
       ELSE /\ SendAck("im", a, made[a])
            /\ UNCHANGED net
    /\ sentrep' = [sentrep EXCEPT ![a] = @ \cup {m.seq : m \in {x \in Sent(a) : x.kind = "report" /\ x.seq \notin dropped[a]}}]
    /\ UNCHANGED <<made, lo, mk, cur, rec, nx, inbox, pcup, budget, dropped>>

\* TakeAck: a takes the acknowledgement in flight from f of its first n numbers.  The PC's frees
\* them (a marker's part too); the interim master's frees nothing (HandoverLoses: it frees, as
\* if the interim master's HANDOVER carried its record to the PC; it carries the registry only).
TakeAck(a, f) ==
    /\ acks[a][f] >= 0
    /\ LET n == acks[a][f]
           l == IF (f = "pc" \/ BUG = "HandoverLoses") /\ n + 1 > lo[a] THEN n + 1 ELSE lo[a]
       IN /\ lo' = [lo EXCEPT ![a] = l]
          /\ mk' = [mk EXCEPT ![a] = IF l - 1 > @ THEN l - 1 ELSE @]
    /\ acks' = [acks EXCEPT ![a][f] = -1]
    /\ UNCHANGED <<made, cur, rec, nx, inbox, pcup, net, budget, dropped, sentrep>>

\* Switch: the PC is lost to a and a elects (or follows) an interim master.
Switch(a) ==
    /\ cur[a] = "pc" /\ budget.switch > 0
    /\ cur' = [cur EXCEPT ![a] = "im"]
    /\ budget' = [budget EXCEPT !.switch = @ - 1]
    /\ UNCHANGED <<made, lo, mk, rec, nx, inbox, pcup, net, acks, dropped, sentrep>>

\* Takeover: the PC, running, takes a back (HANDOVER, or a follows the PC again).
Takeover(a) ==
    /\ cur[a] = "im" /\ pcup
    /\ cur' = [cur EXCEPT ![a] = "pc"]
    /\ UNCHANGED <<made, lo, mk, rec, nx, inbox, pcup, net, acks, budget, dropped, sentrep>>

(***************************************************************************)
(* PC steps.                                                               *)
(***************************************************************************)

\* Entries(f, l, k): the record's entries for numbers f..l, of kind k.
Entries(f, l, k) == [i \in 1..l - f + 1 |-> [seq |-> f + i - 1, kind |-> k]]

\* PCTake: the PC takes m of agent a if m covers the next number of a's record: a report that is
\* the next, or a marker from at most the next to at least it, whose numbers from the next on are
\* recorded as dropped (a copy, or one ahead of a lost one, is left).  It stores them, then may
\* acknowledge (PCAck).  AckBeforeStore: it acknowledges at once and stores later (PCStore): a
\* crash in between loses them.  ForgetfulWindow: after a restart the PC does not know where a's
\* record ends (nx = 0) and takes whatever comes first as the next.  GapAsDrop: a datagram ahead
\* of the next makes the PC record the numbers between as dropped (they were lost or are late, not
\* dropped).
PCTake(m) ==
    /\ pcup /\ m \in net
    /\ LET a == m.agent
           next == (IF nx[a] = 0 THEN m.seq ELSE nx[a]) + Len(inbox[a])
       IN IF m.seq <= next /\ next <= m.last
          THEN IF BUG = "AckBeforeStore"
               THEN /\ inbox' = [inbox EXCEPT ![a] = @ \o Entries(next, m.last, m.kind)]
                    /\ SendAck("pc", a, m.last)
                    /\ UNCHANGED <<rec, nx>>
               ELSE /\ rec' = [rec EXCEPT ![a] = @ \o Entries(next, m.last, m.kind)]
                    /\ nx' = [nx EXCEPT ![a] = m.last + 1]
                    /\ UNCHANGED <<inbox, acks>>
          ELSE IF BUG = "GapAsDrop" /\ nx[a] > 0 /\ m.seq > next
          THEN /\ rec' = [rec EXCEPT ![a] = @ \o Entries(next, m.seq - 1, "dropped")
                                              \o Entries(m.seq, m.last, m.kind)]
               /\ nx' = [nx EXCEPT ![a] = m.last + 1]
               /\ UNCHANGED <<inbox, acks>>
          ELSE UNCHANGED <<rec, nx, inbox, acks>>
    /\ Taken(m)
    /\ UNCHANGED <<made, lo, mk, cur, pcup, dropped, sentrep>>

\* PCStore: (AckBeforeStore) the PC stores the oldest number it took and acknowledged.
PCStore(a) ==
    /\ pcup /\ inbox[a] # <<>>
    /\ rec' = [rec EXCEPT ![a] = Append(@, Head(inbox[a]))]
    /\ nx' = [nx EXCEPT ![a] = Head(inbox[a]).seq + 1]
    /\ inbox' = [inbox EXCEPT ![a] = Tail(@)]
    /\ UNCHANGED <<made, lo, mk, cur, pcup, net, acks, budget, dropped, sentrep>>

\* PCAck: the PC acknowledges the first numbers of a up to the last it stored (cumulative), any
\* time.
PCAck(a) ==
    /\ pcup
    /\ SendAck("pc", a, Stored(a))
    /\ UNCHANGED <<made, lo, mk, cur, rec, nx, inbox, pcup, net, budget, dropped, sentrep>>

\* PCCrash: the PC stops; its record stays (durable), what it had not stored is gone
\* (ForgetfulWindow: where each record ends is forgotten too).
PCCrash ==
    /\ pcup /\ budget.crash > 0
    /\ pcup' = FALSE
    /\ inbox' = [a \in Agents |-> <<>>]
    /\ nx' = IF BUG = "ForgetfulWindow" THEN [a \in Agents |-> 0]
             ELSE [a \in Agents |-> Stored(a) + 1]
    /\ budget' = [budget EXCEPT !.crash = @ - 1]
    /\ UNCHANGED <<made, lo, mk, cur, rec, net, acks, dropped, sentrep>>

\* PCRestart: the PC runs again, with its record.
PCRestart ==
    /\ ~pcup
    /\ pcup' = TRUE
    /\ UNCHANGED <<made, lo, mk, cur, rec, nx, inbox, net, acks, budget, dropped, sentrep>>

(***************************************************************************)
(* The network.                                                            *)
(***************************************************************************)

\* Lose: the network loses a datagram (a report, or an acknowledgement).
Lose ==
    /\ budget.loss > 0
    /\ budget' = [budget EXCEPT !.loss = @ - 1]
    /\ \/ \E m \in net : net' = net \ {m} /\ UNCHANGED acks
       \/ \E a \in Agents, f \in Masters : acks[a][f] >= 0 /\ acks' = [acks EXCEPT ![a][f] = -1]
                                           /\ UNCHANGED net
    /\ UNCHANGED <<made, lo, mk, cur, rec, nx, inbox, pcup, dropped, sentrep>>

Next ==
    \/ \E a \in Agents : Make(a) \/ Send(a) \/ Switch(a) \/ Takeover(a) \/ PCStore(a) \/ PCAck(a)
    \/ \E a \in Agents, f \in Masters : TakeAck(a, f)
    \/ \E m \in net : PCTake(m)
    \/ Lose \/ PCCrash \/ PCRestart

Spec == Init /\ [][Next]_vars

\* Every step of an agent, a master or the network is weakly fair; the faults (Lose, PCCrash,
\* Switch) are not, and each has a budget.
Fairness ==
    /\ \A a \in Agents :
        /\ WF_vars(Make(a)) /\ WF_vars(Takeover(a)) /\ WF_vars(PCStore(a)) /\ WF_vars(PCAck(a))
        /\ WF_vars(Send(a))
        /\ \A s \in Seqs : WF_vars(\E m \in net : m.agent = a /\ m.seq = s /\ PCTake(m))
        /\ \A f \in Masters : WF_vars(TakeAck(a, f))
    /\ WF_vars(PCRestart)

FairSpec == Spec /\ Fairness

(***************************************************************************)
(* Properties.                                                             *)
(***************************************************************************)

\* What an agent freed, the PC acknowledged, and what the PC acknowledged is in its record.
AckedRecordedInv ==
    \A a \in Agents : lo[a] - 1 <= Stored(a) /\ acks[a]["pc"] <= Stored(a)

\* No number is recorded twice (InOrderInv implies it; checked alone, it names the failure).
NoDuplicateInv ==
    \A a \in Agents : \A i, j \in 1..Stored(a) : i # j => rec[a][i].seq # rec[a][j].seq

\* Per agent, the record is 1, 2, 3, ... in order, with no hole.
InOrderInv ==
    \A a \in Agents : \A i \in 1..Stored(a) : rec[a][i].seq = i

\* The buffer: the marker lies below the reports, and at most Cap reports are held.
BufferInv ==
    \A a \in Agents : lo[a] - 1 <= mk[a] /\ mk[a] <= made[a] /\ Held(a) <= Cap

\* A report is dropped only from a full buffer: Cap newer ones were made after it.
DropOnlyWhenFullInv ==
    \A a \in Agents : \A s \in dropped[a] : s + Cap <= made[a]

\* A number is recorded as a report only if the agent sent it as one (a drop is never silent:
\* its number is not recorded as a report the PC never had).
ReportsRecordedInv ==
    \A a \in Agents : \A i \in 1..Stored(a) :
        rec[a][i].kind = "report" => rec[a][i].seq \in sentrep[a]

\* A number is recorded as dropped only if the agent's bound dropped its report (a report sent,
\* then dropped, and taken is recorded as the report).
DropsRecordedInv ==
    \A a \in Agents : \A i \in 1..Stored(a) :
        rec[a][i].kind = "dropped" => rec[a][i].seq \in dropped[a]

\* Eventually (the faults are bounded) every number is recorded, as a report or as dropped, and
\* freed.  It rests on the PC taking each agent back (Takeover is weakly fair: the election ends
\* with the PC in command again).
EverythingRecorded ==
    <>[](\A a \in Agents : Stored(a) = MaxReports /\ lo[a] = MaxReports + 1)

=============================================================================
