-------------------------- MODULE MasterElectionTrace --------------------------
(***************************************************************************)
(* The trace of `ev3-master --election`, or of the Master core an elected  *)
(* agent runs, against MasterLogic composed with Election.tla's rules of   *)
(* that node (docs/spec.md "Election master traces"):                      *)
(* MasterElectionStep(r, s) is the set of local states record r leads to   *)
(* from s.                                                                 *)
(*                                                                         *)
(* The local state: MasterLogic's ms with MasterTrace's time map, the      *)
(* node's Election record el (Election.tla's Loc: life, epoch, votes; the  *)
(* agent-only fields NoNode / {}), the membership mem quorums count        *)
(* against, and whether an agent-master has handed its registry over.      *)
(*   - MasterLogic's records (MasterSync, MasterAnswer, MasterPing,        *)
(*     MasterReport) only while MASTER (the core ignores the fleet's       *)
(*     datagrams otherwise), after the master's route bookkeeping (the     *)
(*     core's note_route, not in MasterLogic: the sender's entry moves to  *)
(*     the endpoint it was heard from; a member that PINGs unregistered is *)
(*     adopted as synced with desired UNKNOWN; a member syncing that PINGs *)
(*     is synced).  MasterCommand and MasterTick as MasterLogic; the       *)
(*     registry ticks only while MASTER.                                   *)
(*   - Election.tla's rules by its own operators (ElectionRules):          *)
(*     StartElection, HandleVote (from a member), BecomeMaster (Quorum     *)
(*     over mem), HandleStale; Heartbeat's guard (life MASTER: Election    *)
(*     has no HeartbeatOk operator).  HandleHeartbeat of the PC: an older  *)
(*     LEADER is answered EPOCH_STALE (state unchanged), a newer one makes  *)
(*     the PC stand again (Election's HandleHeartbeat of the PC, the rule   *)
(*     of HandleStale).  HandleElect: the PC ignores ELECT (Election has no *)
(*     HandleElect of the PC).  Every datagram the core sends draws a      *)
(*     msgid (LEADER, ELECT, EPOCH_STALE): the PC's StartElection two when *)
(*     it has a membership (its copy first, Teach; Stood). HandleHeartbeat *)
(*     takes a master's LEADER only (it names its sender: Leads).          *)
(*   - An agent-master (Self # PC): its step-down is Election's rule of    *)
(*     node Self (HandleElect, HandleHeartbeat: HANDOVER sent once,        *)
(*     HandleStale, LearnMembers of a copy of a newer epoch); the trace's  *)
(*     STEPPED_DOWN is any life but MASTER.                                *)
(*   - Time: Heartbeat and StartElection come from the core's deadlines    *)
(*     like MasterTick (nothing of the registry due before their ms; at    *)
(*     the same ms the heartbeat goes first).                              *)
(*   - Extensions Election abstracts (docs/election.md section 5):         *)
(*     MasterRoute (RELAY_ROUTE(epoch, a): only as MASTER of that epoch,   *)
(*     for an entry or a member; the entry moves to the relay's endpoint   *)
(*     or a member is adopted), MasterHandover (HANDOVER(epoch, ids): only *)
(*     as MASTER, epoch not above ours; its assigned ids join mem).        *)
(*   - Not observed: what the master sends (EPOCH_CMD and RELAY wrapping,  *)
(*     LEADER's membership), the election's timers, an entry's `via`.      *)
(* Operator arguments that are states are bound once (x \in {e}): TLC     *)
(* passes them by name and re-evaluates them at every use.                 *)
(*                                                                         *)
(* A record has MasterTrace's fields (m: MasterLogic's datagram; a RELAY   *)
(* is unwrapped: the relay is transparent) and                             *)
(*   em  |-> an Election datagram as Election.tla's [t, src, dst, e, x]    *)
(*           (t "NONE": none),                                             *)
(*   ids |-> HANDOVER's ids,                                               *)
(*   ech |-> the Election variables it changed: life, epoch, votes.        *)
(***************************************************************************)
EXTENDS MasterTrace, Integers

CONSTANTS
    Self,         \* the master's node: the PC (1), or the elected agent whose Master core wrote it
    InitLife,     \* MASTER (fresh), or CANDIDATE (the PC restarted from its state file)
    InitEpoch,    \* the epoch it starts in
    InitMembers,  \* the membership it starts with (Election members[Self])
    InitMEpoch,   \* the epoch that published it (Election mepoch[Self])
    WithMembers   \* the records carry the membership when it changes (members, mepoch: every
                  \* current core); FALSE: an older trace, the membership is the check's alone

PC == 1
\* Election.tla's per-node operators for a membership F.  (Agents is a constant of Election: a
\* membership held in a state is bound first, see QuorumOk.)
E(F) == INSTANCE ElectionRules WITH Agents <- F
\* The rules that do not read the membership.
EP == INSTANCE ElectionRules WITH Agents <- InitMembers

\* The trace's life: the PC's Election life; an agent-master's Master core knows MASTER and
\* STEPPED_DOWN (any other Election life of the node: its agent core carries the node's lifecycle).
View(l) == IF Self = PC \/ l \in {"MASTER", "CANDIDATE"} THEN l ELSE "STEPPED_DOWN"
ElVars == {"life", "epoch", "votes"}
FitsEl(r, before, after) ==
    \A v \in ElVars :
        IF v = "life" THEN View(after.life) = IF v \in DOMAIN r.ech THEN r.ech.life ELSE View(before.life)
        ELSE IF v \in DOMAIN r.ech THEN after[v] = r.ech[v] ELSE after[v] = before[v]
\* The fleet's datagram of record r: to an agent-master, MasterLogic's master (MasterId) is Self.
Dg(r) == IF r.m.dst = Self THEN [r.m EXCEPT !.dst = M!MasterId] ELSE r.m
\* The registry's deadlines (MasterTrace's time map) run only while MASTER.
ElDue(s, t) == IF s.el.life = "MASTER" THEN Due(s, t) ELSE {}
\* The console's `all` (one core call, one record): MasterCommand for every registered id in id order
\* leads from ms to ms2.  (A predicate with each intermediate state bound by \E: a recursive operator
\* returning the state re-evaluates its arguments exponentially.)
RECURSIVE ForAllLeads(_, _, _, _)
ForAllLeads(ms, ids, c, ms2) ==
    IF ids = {} THEN ms = ms2
    ELSE \E i \in {CHOOSE i \in ids : \A j \in ids : i <= j} :
         \E ms1 \in {M!MasterCommand(ms, i, c).ms} : ForAllLeads(ms1, ids \ {i}, c, ms2)
OneCmd(ms) == {M!MasterCommand(ms, id, c).ms : id \in Ids(ms) \cup {1}, c \in Cmds}
\* The registry a MasterCommand record claims (its changed variables over ms).
Claimed(r, ms) == [reg |-> IF "reg" \in DOMAIN r.ch THEN r.ch.reg ELSE ms.reg,
                   nextId |-> IF "nextId" \in DOMAIN r.ch THEN r.ch.nextId ELSE ms.nextId,
                   msgid |-> [k \in {0} |-> IF "msgid" \in DOMAIN r.ch THEN r.ch.msgid ELSE ms.msgid[0]]]
\* A datagram the election side sends (LEADER, ELECT, EPOCH_STALE) draws a msgid.
Drawn(ms) == [ms EXCEPT !.msgid[0] = @ + 1]
\* StartElection's datagrams: ELECT, and first the PC's copy of its membership when it has one
\* (Election Teach: LEADER(mepoch, 0, members...) broadcast).  An older trace (WithMembers FALSE:
\* the check's membership may not be the core's) may have drawn one or two.
Stood(ms, mem) ==
    IF Self # PC THEN {Drawn(ms)}
    ELSE IF ~WithMembers THEN {Drawn(ms), Drawn(Drawn(ms))}
    ELSE IF mem # {} THEN {Drawn(Drawn(ms))} ELSE {Drawn(ms)}
\* A LEADER's x is the leader it names: a master's names its sender, a copy of a membership none.
Leads(m) == m.x = m.src

\* --- master-side extensions (not in MasterLogic; Election abstracts them) ---
\* A member registered without MASTER (it follows our LEADER): synced, desired unknown.
Adopted(i, from) == [ann |-> i, id |-> i, ep |-> from, synced |-> TRUE, pending |-> FALSE, mid |-> 0,
                     resends |-> 0, queue |-> <<>>, desired |-> M!UnknownDesired, beh |-> M!NoBehaviour,
                     quiet |-> 0, hi |-> 0]
\* An adopted id is never handed out again (as MasterSync's for an assigned id): nextId above it.
AdoptedNextId(n, i) == IF n <= i THEN i + 1 ELSE n
\* Where a fleet datagram came from (the core's note_route, before MasterLogic's handler).
Route(ms, m, from, mem) ==
    IF m.src \in Ids(ms) THEN
       LET x == EntryOf(ms, m.src)
           y == [x EXCEPT !.ep = from]
       IN IF m.type = "PING" /\ ~x.synced /\ m.src \in mem
          THEN LET r == M!StartNext(ms, [y EXCEPT !.synced = TRUE, !.pending = FALSE])
               IN M!Replace(r.ms, x, r.x)
          ELSE M!Replace(ms, x, y)
    ELSE IF m.type = "PING" /\ m.src \in mem
         THEN [ms EXCEPT !.reg = @ \cup {Adopted(m.src, from)}, !.nextId = AdoptedNextId(@, m.src)]
    ELSE ms
\* RELAY_ROUTE(e, a) from a relay heard at endpoint from: a is reached there.
RouteTo(ms, a, from) ==
    IF a \in Ids(ms) THEN M!Replace(ms, EntryOf(ms, a), [EntryOf(ms, a) EXCEPT !.ep = from])
    ELSE [ms EXCEPT !.reg = @ \cup {Adopted(a, from)}, !.nextId = AdoptedNextId(@, a)]
\* Election's BecomeMasterOk (a majority of the membership voted) over the membership mem.
QuorumOk(el, mem) == \E F \in {mem} : E(F)!BecomeMasterOk(el)
\* Election want: the PC's membership and the ids handed over but those declared lost
\* (Election DropMember: MasterTick dropped them since they last synced), the agents registered and synced.
SyncedIds(ms) == {x.id : x \in {y \in ms.reg : y.synced}}
Want(s, ms) == ((s.mem \cup s.hand) \ s.lost) \cup SyncedIds(ms)
\* The ids declared lost after record r took registry s0 to ms2: MasterTick's drops join them (DropMember),
\* an agent synced again leaves them.
LostAfter(r, s, s0, ms2) == (s.lost \cup (IF r.a = "MasterTick" THEN Ids(s0) \ Ids(ms2) ELSE {})) \ SyncedIds(ms2)
\* The PC's choice among Election's OneStep(L, w) (election/master.hpp OneStep): the lowest id wanted added,
\* else the lowest id not wanted removed, never down to none.  Election.tla's BecomeMaster may publish
\* any list of OneStep (the safety properties hold for every choice); the trace pins the code's one
\* (intersected with OneStep: a choice outside the spec is no step).
Lowest(S) == CHOOSE i \in S : \A j \in S : i <= j
CodeStep(L, w) ==
    IF w \ L # {} /\ Cardinality(L) < EP!MaxMembers THEN L \cup {Lowest(w \ L)}
    ELSE IF L \ w # {} /\ \E a, b \in L : a # b THEN L \ {Lowest(L \ w)}
    ELSE L

-----------------------------------------------------------------------------
InitEl == [life |-> InitLife, epoch |-> InitEpoch, votes |-> {}, votedFor |-> 0, leader |-> 0,
           following |-> 0, via |-> 0, relays |-> {}, offered |-> {}, prevotes |-> {}]
MasterElectionStart ==
    [ms |-> [reg |-> {}, nextId |-> NextId, msgid |-> [k \in {0} |-> FirstMsgid]], el |-> InitEl,
     mem |-> InitMembers, mep |-> InitMEpoch, hand |-> {}, lost |-> {}, handed |-> FALSE, clock |-> 0,
     sent |-> [i \in {} |-> 0]]

\* The membership the record claims (members, mepoch: a core records them when they
\* change) is the one of the step (the list mem2 of epoch mep2).
FitsMem(r, s, mem2, mep2) ==
    WithMembers => (/\ IF "members" \in DOMAIN r.ech THEN mem2 = r.ech.members ELSE mem2 = s.mem
                    /\ IF "mepoch" \in DOMAIN r.ech THEN mep2 = r.ech.mepoch ELSE mep2 = s.mep)
\* The step of record r from s (registry s0 after time passed) to registry ms2, Election state el2,
\* membership mem2 of epoch mep2 (ticked ids D), if the record's changes fit it.
ElToMep(r, s, s0, ms2, el2, mem2, mep2, D) ==
    IF ~FitsMem(r, s, mem2, mep2) THEN {}
    ELSE {[ms |-> y, el |-> z, mem |-> mem2, mep |-> mep2, hand |-> s.hand, lost |-> LostAfter(r, s, s0, y),
           handed |-> s.handed \/ (r.a = "HandleHeartbeat" /\ Self # PC /\ r.em.e >= s.el.epoch),
           clock |-> r.now, sent |-> NewSent(s, y, D, r.now)]
          : y \in {x \in {ms2} : Fits(r, s0, x)}, z \in {w \in {el2} : FitsEl(r, s.el, w)}}
ElTo(r, s, s0, ms2, el2, mem2, D) == ElToMep(r, s, s0, ms2, el2, mem2, s.mep, D)

\* Record r from s, its registry s0 aged to the record's time.
Act(r, s, s0) ==
    LET t == r.now
        em == r.em
        m == Dg(r)
        el == s.el
        mem == s.mem
    IN
    IF r.a = "MasterTick" THEN
       UNION {UNION {ElTo(r, s, s0, M!TickEntries(pre, D, {}).ms, el, mem, D)
                     : pre \in {[s0 EXCEPT !.reg = {IF x.id \in D THEN [x EXCEPT !.quiet = @ - 1] ELSE x : x \in @}]}}
              : D \in {ElDue(s, t)} \ {{}}}
    ELSE IF r.a = "MasterCommand" THEN
       UNION {UNION {ElTo(r, s, s0, ms2, el, mem, {})
                     : ms2 \in {x \in cr \cup {Claimed(r, s0)} : x \in cr \/ \E c \in Cmds : ForAllLeads(s0, Ids(s0), c, x)}}
              : cr \in {OneCmd(s0)}}
    ELSE IF r.a \in MasterRecv THEN
       IF ~(el.life = "MASTER" /\ m.type # "NONE" /\ M!Handler(m) = r.a) THEN {}
       ELSE UNION {UNION {\* ids exhausted (an agent-master assigns none): an unknown temporary id is ignored
                          IF r.a = "MasterSync" /\ M!Known(s1, m.src) = {} /\ m.src \notin M!AssignedIds
                             /\ s1.nextId > 49999
                          THEN ElTo(r, s, s0, s1, el, mem, {})
                          ELSE ElTo(r, s, s0, M!Receive(s1, m, from).ms, el, mem, {})
                          : s1 \in {Route(s0, m, from, mem \cup s.hand)}}
                   : from \in Eps(r, s) \cup {0}}
    ELSE IF r.a = "Heartbeat" THEN
       \* Election's Heartbeat(n): life[n] = "MASTER"
       IF el.life = "MASTER" THEN ElTo(r, s, s0, Drawn(s0), el, mem, {}) ELSE {}
    ELSE IF r.a = "StartElection" THEN
       IF EP!StartElectionOk(Self, el)
       THEN UNION {ElTo(r, s, s0, ms2, EP!StartElectionNext(Self, el), mem, {}) : ms2 \in Stood(s0, mem)}
       ELSE {}
    ELSE IF r.a = "HandleVote" THEN
       IF em.src \in mem /\ EP!HandleVoteOk(Self, el, em) THEN ElTo(r, s, s0, s0, EP!HandleVoteNext(el, em), mem, {})
       ELSE {}
    ELSE IF r.a = "BecomeMaster" THEN
       \* Election BecomeMaster: a majority of its membership (the PC's first list: none needed), in
       \* an epoch newer than the list's; the PC publishes one step (OneStep) towards Want, an
       \* agent-master the list it counted against.
       IF /\ el.life = "CANDIDATE" /\ el.epoch > s.mep
          /\ QuorumOk(el, mem) \/ (Self = PC /\ mem = {})
       THEN UNION {ElToMep(r, s, s0, Drawn(s0), EP!BecomeMasterNext(el), L, el.epoch, {})
                   : L \in IF Self = PC THEN {CodeStep(mem, Want(s, s0))} \cap EP!OneStep(mem, Want(s, s0))
                          ELSE {mem}}
       ELSE {}
    ELSE IF r.a = "Reconfigure" THEN
       \* Election Reconfigure: the PC as MASTER whose Want differs from its membership stands.
       IF Self = PC /\ el.life = "MASTER" /\ EP!OneStep(mem, Want(s, s0)) # {mem}
       THEN ElTo(r, s, s0, s0, [el EXCEPT !.life = "CANDIDATE"], mem, {})
       ELSE {}
    ELSE IF r.a = "HandleStale" THEN
       IF EP!HandleStaleOk(Self, el, em) THEN ElTo(r, s, s0, s0, EP!HandleStaleNext(Self, el, em), mem, {})
       ELSE {}
    ELSE IF r.a = "HandleHeartbeat" THEN
       IF ~(em.t = "HB" /\ em.src # Self /\ Leads(em)) THEN {}
       ELSE IF em.e < el.epoch THEN
          IF View(el.life) # "STEPPED_DOWN" THEN ElTo(r, s, s0, Drawn(s0), el, mem, {}) ELSE {}
       \* the PC: Election's HandleHeartbeat of the PC (it stands again in the newer epoch)
       ELSE IF Self = PC THEN
          IF EP!HandleHeartbeatOk(PC, el, em) THEN ElTo(r, s, s0, s0, EP!HandleHeartbeatNext(PC, el, em), mem, {})
          ELSE {}
       \* an agent-master: Election's HandleHeartbeat of node Self (it follows the newer master); its
       \* Master core hands the registry over once (HANDOVER: a msgid)
       ELSE IF EP!HandleHeartbeatOk(Self, el, em)
       THEN ElTo(r, s, s0, IF s.handed THEN s0 ELSE Drawn(s0), EP!HandleHeartbeatNext(Self, el, em), mem, {})
       ELSE {}
    ELSE IF r.a = "LearnMembers" THEN
       \* an agent-master hears a copy of a membership (leader 0: the PC's broadcast as it stands, or
       \* a peer's) of a newer epoch: Election's LearnMembers of node Self, whose rule for a newer
       \* epoch is HandleStale's (its Master core steps down, no HANDOVER; the list is its agent core's)
       LET stale == [em EXCEPT !.t = "STALE", !.dst = Self] IN
       IF Self # PC /\ em.t = "HB" /\ em.x = 0 /\ em.dst \in {0, Self} /\ (em.dst = 0 => em.src = PC)
          /\ View(el.life) # "STEPPED_DOWN" /\ EP!HandleStaleOk(Self, el, stale)
       THEN ElTo(r, s, s0, s0, EP!HandleStaleNext(Self, el, stale), mem, {})
       ELSE {}
    ELSE IF r.a = "HandleElect" THEN
       \* an agent-master steps down on a newer ELECT (Election's HandleElect of node Self; the vote
       \* is its agent core's); the PC ignores ELECT (Election has no HandleElect of the PC)
       IF Self # PC /\ em.t = "ELECT" /\ em.e > el.epoch /\ View(el.life) # "STEPPED_DOWN"
          /\ EP!HandleElectOk(Self, el, em, 0, 0)
       THEN ElTo(r, s, s0, s0, EP!HandleElectNext(Self, el, em, 0, 0), mem, {})
       ELSE {}
    ELSE IF r.a = "MasterRoute" THEN
       IF em.t = "ROUTE" /\ em.dst = Self /\ el.life = "MASTER" /\ em.e = el.epoch /\ em.x \in Ids(s0) \cup mem \cup s.hand
       THEN UNION {ElTo(r, s, s0, RouteTo(s0, em.x, from), el, mem, {}) : from \in Eps(r, s) \cup {0}}
       ELSE {}
    ELSE IF r.a = "MasterHandover" THEN
       IF em.t = "HANDOVER" /\ em.dst = Self /\ el.life = "MASTER" /\ em.e <= el.epoch
       THEN {[x EXCEPT !.hand = s.hand \cup (r.ids \cap (M!AssignedIds \ {Self})),
                         !.lost = @ \ r.ids] : x \in ElTo(r, s, s0, s0, el, mem, {})}
       ELSE {}
    ELSE {}

MasterElectionStep(r, s) ==
    LET t == r.now
        k == t - s.clock
    IN
    IF t < s.clock THEN {}
    \* Heartbeat, StartElection, MasterTick come from the core's deadlines: at the first ms anything
    \* of the registry is due (Heartbeat first when both are); the rest find nothing due.
    ELSE IF IF r.a \in {"Heartbeat", "StartElection", "MasterTick"} THEN k > 0 /\ ElDue(s, t - 1) # {}
            ELSE ElDue(s, t) # {}
    THEN {}
    ELSE UNION {Act(r, s, s0) : s0 \in {Age(s.ms, k)}}
================================================================================
