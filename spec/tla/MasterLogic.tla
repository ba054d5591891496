---------------------------- MODULE MasterLogic -----------------------------
(***************************************************************************)
(* The master's logic as pure operators on the master's local state (a     *)
(* record ms), shared by Master.tla (one master, any environment) and      *)
(* Fleet.tla (one master, N agents).  Like AgentLogic for the agent: every *)
(* handler X returns [ms |-> new local state, out |-> the set of datagrams *)
(* [to |-> endpoint, m |-> message] it emits in that step].  The C++       *)
(* master core (master.hpp) has one handler per action, same name:         *)
(*   MasterSync(m, from)   AGENT / PANIC                                   *)
(*   MasterAnswer(m)       ACK / NOT                                       *)
(*   MasterPing(m, from)   PING                                            *)
(*   MasterReport(m)       ACTION_OK/INTERR/ERR, SENSOR_VALUE, EVENT       *)
(*   MasterCommand(id, c)  an operator command for agent id                *)
(*   MasterTick            one resend period: resends, failures, drops     *)
(* The master's state survives a crash only in nextId and msgid (stable    *)
(* storage): CrashMaster(ms).                                              *)
(***************************************************************************)
EXTENDS Naturals, Sequences, FiniteSets, Messages

CONSTANTS
    TDrop,        \* ticks without hearing an agent before it leaves the registry
    MaxResends,   \* an operator command unanswered after this many resends fails
    ExactMsgids,  \* TRUE: one msgid counter, every datagram draws one (the C++
                  \*   core exactly; Master.tla).  FALSE: one counter per agent
                  \*   endpoint, PONG carries msgid 0 and draws none (Fleet.tla,
                  \*   keeps the state space finite; docs/spec.md)
    BUG           \* "none"; or one broken rule (NoPanicResync, NoReconcile,
                  \*   StaleReconcile, AnswerKeepsHi, RestoreWithoutStart, NoBumpNextId, PendingResend, RetryRefused, ReuseIds,
                  \*   PongUnsynced, HeardByTemp)

ASSUME TDrop \in Nat \ {0} /\ MaxResends \in Nat /\ ExactMsgids \in BOOLEAN

NoBehaviour == "NONE"
\* The states the operator can ask an agent to be in.
DesiredStates == {"ACTIVE", "WORKING", "PAUSED"}
\* desired after the agent refused a command and no queued command sets it:
\* the master does not reconcile until the operator commands again.
UnknownDesired == "UNKNOWN"
\* An operator command: a master command type and, for BEHAVIOUR, the name.
Cmd(t, n) == [type |-> t, name |-> n]
Cmd0(t) == Cmd(t, NoBehaviour)

MasterNames == {"MasterSync", "MasterAnswer", "MasterPing", "MasterReport",
                "MasterCommand", "MasterTick"}
ReportTypes == {"ACTION_OK", "ACTION_INTERR", "ACTION_ERR", "SENSOR_VALUE", "EVENT"}

(***************************************************************************)
(* A registry entry (C++ RegistryEntry):                                   *)
(*  ann      id the agent announced (temporary, or its id when it resyncs) *)
(*  id       assigned id; ep the agent's endpoint (C++ peer)               *)
(*  synced   the agent ACKed MASTER; until then MASTER is the pending one  *)
(*  pending  a datagram waits for its answer: MASTER (~synced) or the      *)
(*           queue's head; mid its msgid, resends how often it was resent  *)
(*  queue    operator commands, head first                                 *)
(*  desired  what the operator last asked: WORKING after START/RESUME,     *)
(*           PAUSED after PAUSE, ACTIVE after STOP/STANDBY (initially);    *)
(*           UNKNOWN after a refusal (NOT) no queued command overrides     *)
(*  beh      the behaviour the agent ACKed last (C++ behaviour)            *)
(*  quiet    ticks since the agent was last heard (C++ now - heard)        *)
(*  hi       highest msgid heard from the agent (C++ last_msgid)           *)
(***************************************************************************)
EntryType(Eps, Behs) ==
    [ann : Nat, id : AssignedIds, ep : Eps, synced : BOOLEAN, pending : BOOLEAN,
     mid : Nat, resends : Nat, queue : Seq([type : Commands, name : Behs \cup {NoBehaviour}]),
     desired : DesiredStates \cup {UnknownDesired}, beh : Behs \cup {NoBehaviour}, quiet : Nat, hi : Nat]

\* msgid counters: one (key 0) or one per endpoint.
MidKeys(Eps) == IF ExactMsgids THEN {0} ELSE Eps
MidKey(ep) == IF ExactMsgids THEN 0 ELSE ep

MasterType(ms, Eps, Behs) ==
    /\ ms.reg \subseteq EntryType(Eps, Behs)
    /\ ms.nextId \in AssignedIds
    /\ ms.msgid \in [MidKeys(Eps) -> Nat \ {0}]

InitMaster(Eps) == [reg |-> {}, nextId |-> 2, msgid |-> [k \in MidKeys(Eps) |-> 1]]

\* A crash: the registry is lost; nextId and msgid survive (stable storage),
\* so ids and msgids are never reused.
CrashMaster(ms) == [ms EXCEPT !.reg = {}, !.nextId = IF BUG = "ReuseIds" THEN 2 ELSE @]

-----------------------------------------------------------------------------
(* Helpers                                                                  *)

Max(a, b) == IF a > b THEN a ELSE b
Draw(ms, ep) == ms.msgid[MidKey(ep)]
Bump(ms, ep) == [ms EXCEPT !.msgid[MidKey(ep)] = @ + 1]
Replace(ms, x, y) == [ms EXCEPT !.reg = (@ \ {x}) \cup {y}]
ById(ms, s) == {x \in ms.reg : x.id = s}
Known(ms, s) == {x \in ms.reg : x.ann = s \/ x.id = s}
Entry(k) == CHOOSE x \in k : TRUE

Send(ep, dst, mid, type, ref, args) ==
    [to |-> ep, m |-> Msg(MasterId, dst, mid, type, ref, args)]
CmdArgs(c) == IF c.type = "BEHAVIOUR" THEN <<c.name>> ELSE <<>>

\* The datagram pending for entry x (same msgid every time), if any.
PendingOut(x) ==
    IF ~x.pending THEN {}
    ELSE IF ~x.synced THEN {Send(x.ep, x.id, x.mid, "MASTER", x.ann, <<>>)}
    ELSE {Send(x.ep, x.id, x.mid, Head(x.queue).type, 0, CmdArgs(Head(x.queue)))}

\* The queue's head (if any) becomes pending with a new msgid (C++ start_next).
\* Returns [ms, x]; ms is the state before x is put back.
StartNext(ms, x) ==
    IF x.queue = <<>>
    THEN [ms |-> ms, x |-> [x EXCEPT !.pending = FALSE]]
    ELSE [ms |-> Bump(ms, x.ep),
          x |-> [x EXCEPT !.pending = TRUE, !.mid = Draw(ms, x.ep), !.resends = 0]]

\* What the operator's command makes the agent's desired state.
DesiredAfter(c, d) ==
    CASE c.type \in {"START", "RESUME"}  -> "WORKING"
      [] c.type = "PAUSE"                -> "PAUSED"
      [] c.type \in {"STOP", "STANDBY"}  -> "ACTIVE"
      [] OTHER                           -> d

\* The commands that bring an agent reporting state st back to desired d.
\* An agent paused by master loss gets RESUME; one that resynced (ACTIVE,
\* behaviour unloaded) gets its behaviour and START again.  ACTIVE cannot be
\* brought to PAUSED without running, so that pair is left alone; nor is an
\* UNKNOWN desired state (after a refusal).  (BUG "RestoreWithoutStart": the
\* behaviour without START; the agent stays ACTIVE and every fresh PING sends
\* the behaviour again: a livelock, which Fleet's CounterBoundInv reports.)
Restore(st, d, beh) ==
    CASE d = "WORKING" /\ st = "PAUSED"  -> <<Cmd0("RESUME")>>
      [] d = "WORKING" /\ st = "ACTIVE" /\ beh # NoBehaviour
                                         -> IF BUG = "RestoreWithoutStart" THEN <<Cmd("BEHAVIOUR", beh)>>
                                            ELSE <<Cmd("BEHAVIOUR", beh), Cmd0("START")>>
      [] d = "PAUSED" /\ st = "WORKING"  -> <<Cmd0("PAUSE")>>
      [] d = "ACTIVE" /\ st \in {"WORKING", "PAUSED"} -> <<Cmd0("STOP")>>
      [] OTHER                           -> <<>>

-----------------------------------------------------------------------------
(* Handlers                                                                 *)

\* AGENT or PANIC from announced id s.  A registered agent is heard and gets
\* its pending datagram again -- a synced entry is heard only from its own id:
\* an agent synced sends with that id, so AGENT or PANIC from the temporary
\* id it announced is a late copy of its first datagrams, or the agent has
\* restarted and drawn the same temporary id again; kept alive by it, the
\* entry would never be dropped and the restarted agent, matched by that id
\* and never re-synced, would stay in PANIC for ever (TLC, fleet_agent_restart:
\* BUG "HeardByTemp"); unheard, the entry is dropped after TDrop and the agent
\* registers anew.  A PANIC from a synced entry's own id with a
\* msgid above every msgid heard from it (not a stale or duplicated copy)
\* re-syncs it: a new MASTER naming that id, its queue kept (resent after
\* the ACK).  An unknown agent gets an entry: its announced id if that is an
\* assigned id (an agent of an earlier session), else the next id; an
\* entry with the same endpoint is replaced; MASTER.  An adopted id s
\* raises nextId past it (nextId = max(nextId, s+1)): no later agent is
\* given an id already in use.
MasterSync(ms, m, from) ==
    LET s == m.src
        k == Known(ms, s)
    IN IF k # {}
       THEN LET x == Entry(k)
                resync == /\ m.type = "PANIC" /\ x.synced /\ s = x.id
                          /\ m.msgid > x.hi /\ BUG # "NoPanicResync"
                \* a synced entry is heard only from its own id (HeardByTemp: also from
                \* the temporary id it announced)
                heard == ~x.synced \/ s = x.id \/ BUG = "HeardByTemp"
                y0 == [x EXCEPT !.quiet = IF heard THEN 0 ELSE @, !.hi = Max(@, m.msgid)]
                y == IF resync
                     THEN [y0 EXCEPT !.synced = FALSE, !.ann = s, !.pending = TRUE,
                                     !.mid = Draw(ms, x.ep), !.resends = 0]
                     ELSE y0
                ms2 == IF resync THEN Bump(ms, x.ep) ELSE ms
            IN [ms |-> Replace(ms2, x, y), out |-> PendingOut(y)]
       ELSE LET nid == IF s \in AssignedIds THEN s ELSE ms.nextId
                y == [ann |-> s, id |-> nid, ep |-> from, synced |-> FALSE, pending |-> TRUE,
                      mid |-> Draw(ms, from), resends |-> 0, queue |-> <<>>,
                      desired |-> "ACTIVE", beh |-> NoBehaviour, quiet |-> 0, hi |-> m.msgid]
            IN [ms |-> [Bump(ms, from) EXCEPT
                          !.reg = {z \in @ : z.ep # from} \cup {y},
                          !.nextId = IF s \notin AssignedIds THEN @ + 1
                                     ELSE IF BUG = "NoBumpNextId" THEN @
                                     ELSE Max(@, s + 1)],
                out |-> PendingOut(y)]

\* Refusals that retrying cannot cure: every reason but the transient ones,
\* "wrong state" and "no behaviour" (the agent may resync or be paused in
\* between, so reconciling goes on after them).  The permanent ones: the robot
\* lacks the behaviour or a device ("unknown behaviour", "missing device"), or
\* its check on receipt refused the request, in its own words ("line 4 col 12:
\* unknown action 'trun' (...)": AgentLogic CheckReason).
TransientRefusals == {"wrong state", "no behaviour"}
PermanentRefusal(r) == r \notin TransientRefusals

\* ACK or NOT carrying the pending msgid: the agent is heard; ACK of MASTER
\* syncs it; an answer to a command ends it (ACK of BEHAVIOUR: beh); the next
\* queued command goes out.  A NOT is no answer to MASTER.  A NOT of a
\* command for a permanent reason makes desired UNKNOWN (commands still
\* queued go out as queued): the master stops reconciling towards a state
\* the robot cannot reach (a refused reconcile is not re-queued on every
\* PING) until the operator commands again.  A transient refusal leaves desired
\* as it is (giving up there loses liveness: TLC found an agent left ACTIVE
\* for good after a "no behaviour" during a resync).  Anything else (stale
\* msgid, unknown sender) only raises hi.  (BUG "AnswerKeepsHi": an answer does
\* not raise hi, so a PING sent before it and delivered after it reconciles.)
MasterAnswer(ms, m) ==
    LET k == ById(ms, m.src) IN
    IF k = {} THEN [ms |-> ms, out |-> {}]
    ELSE LET x == Entry(k)
             y0 == [x EXCEPT !.hi = IF BUG = "AnswerKeepsHi" THEN @ ELSE Max(@, m.msgid)]
             y1 == [y0 EXCEPT !.quiet = 0]
         IN IF ~x.pending \/ m.ref # x.mid THEN [ms |-> Replace(ms, x, y0), out |-> {}]
            ELSE IF ~x.synced /\ m.type = "NOT" THEN [ms |-> Replace(ms, x, y1), out |-> {}]
            ELSE LET y2 == IF ~x.synced
                           THEN [y1 EXCEPT !.synced = TRUE, !.pending = FALSE]
                           ELSE [y1 EXCEPT !.pending = FALSE, !.queue = Tail(@),
                                   !.beh = IF m.type = "ACK" /\ Head(x.queue).type = "BEHAVIOUR"
                                           THEN Head(x.queue).name ELSE @,
                                   !.desired = IF m.type = "NOT" /\ BUG # "RetryRefused"
                                                  /\ PermanentRefusal(m.args[1])
                                               THEN UnknownDesired ELSE @]
                     r == StartNext(ms, y2)
                 IN [ms |-> Replace(r.ms, x, r.x), out |-> PendingOut(r.x)]

\* PING(state) from a registered agent: heard, PONG at once if it is synced (ref: the PING's
\* msgid).  Reconcile: a synced agent with nothing pending or queued whose
\* reported state differs from the desired one gets the commands that
\* restore it (Restore).  An agent paused by a lost heartbeat would never
\* resume without this, nor would one that resynced run its behaviour.
\* Only a fresh PING reconciles: its msgid above every msgid heard from the
\* agent (hi before this PING raises it).  A stale PING -- sent before the
\* agent's last answer, delivered late -- reports a state the agent has
\* left (PING(ACTIVE) overtaken by START's ACK would restart a WORKING
\* behaviour).  With the fleet's coarse stamps (ExactMsgids = FALSE) PINGs
\* between the same two answers carry equal stamps, so there it is >=.
\* Only what reconcile started is sent; a pending datagram is resent by
\* MasterTick (and MasterSync), not by a PING.
\* A PING from an id the master does not know gets no answer, so an agent of
\* a crashed master's session loses its heartbeat and resyncs through PANIC.
\* Nor does a PING from an entry that is not synced (its MASTER unanswered):
\* the agent holds itself synced to someone else -- a late PANIC of its
\* earlier life made this master register it after a crash -- and ignores
\* MASTER while synced; PONGs would keep it from ever losing its heartbeat,
\* so it would never resync (TLC, fleet_late: BUG "PongUnsynced").  Without
\* PONG it panics, and its PANIC gets the pending MASTER.
MasterPing(ms, m, from) ==
    LET k == ById(ms, m.src) IN
    IF k = {} THEN [ms |-> ms, out |-> {}]
    ELSE LET x == Entry(k)
             st == m.args[1]
             y0 == [x EXCEPT !.quiet = 0, !.hi = Max(@, m.msgid)]
             answer == x.synced \/ BUG = "PongUnsynced"
             pong == Send(from, x.id, IF ExactMsgids THEN Draw(ms, from) ELSE 0,
                          "PONG", m.msgid, <<>>)
             ms1 == IF ExactMsgids /\ answer THEN Bump(ms, from) ELSE ms
             fix == Restore(st, x.desired, x.beh)
             fresh == IF ExactMsgids THEN m.msgid > x.hi ELSE m.msgid >= x.hi
             rec == /\ x.synced /\ ~x.pending /\ x.queue = <<>>
                    /\ fix # <<>> /\ BUG # "NoReconcile"
                    /\ fresh \/ BUG = "StaleReconcile"
             r == IF rec THEN StartNext(ms1, [y0 EXCEPT !.queue = fix])
                  ELSE [ms |-> ms1, x |-> y0]
             sent == IF rec \/ BUG = "PendingResend" THEN PendingOut(r.x) ELSE {}
         IN [ms |-> Replace(r.ms, x, r.x),
             out |-> (IF answer THEN {pong} ELSE {}) \cup sent]

\* Reports are consumed (the operator sees them; no protocol state).
MasterReport(ms, m) == [ms |-> ms, out |-> {}]

\* The operator's command c for agent id: queued; sent at once if the agent
\* is synced and nothing is pending (else nothing is sent: a pending
\* datagram is resent by MasterTick).  The desired state follows the command.
\* An unknown id changes nothing (the operator is told).
MasterCommand(ms, id, c) ==
    LET k == ById(ms, id) IN
    IF k = {} THEN [ms |-> ms, out |-> {}]
    ELSE LET x == Entry(k)
             y == [x EXCEPT !.queue = Append(@, c), !.desired = DesiredAfter(c, @)]
             now == x.synced /\ ~x.pending
             r == IF now THEN StartNext(ms, y) ELSE [ms |-> ms, x |-> y]
         IN [ms |-> Replace(r.ms, x, r.x), out |-> IF now \/ BUG = "PendingResend" THEN PendingOut(r.x) ELSE {}]

\* One resend period, every entry in order of id: quiet grows; an entry
\* quiet for TDrop ticks is dropped; a pending datagram is resent, except an
\* operator command already resent MaxResends times, which fails (the next
\* queued command goes out).  MASTER is resent until ACK or drop (its
\* resends are not counted).
RECURSIVE TickEntries(_, _, _)
TickEntries(ms, ids, out) ==
    IF ids = {} THEN [ms |-> ms, out |-> out]
    ELSE LET i == CHOOSE i \in ids : \A j \in ids : i <= j
             x == Entry(ById(ms, i))
             q == [x EXCEPT !.quiet = @ + 1]
         IN IF q.quiet >= TDrop
            THEN TickEntries([ms EXCEPT !.reg = @ \ {x}], ids \ {i}, out)
            ELSE IF ~q.pending
            THEN TickEntries(Replace(ms, x, q), ids \ {i}, out)
            ELSE IF q.synced /\ q.resends >= MaxResends
            THEN LET r == StartNext(ms, [q EXCEPT !.pending = FALSE, !.queue = Tail(@)])
                 IN TickEntries(Replace(r.ms, x, r.x), ids \ {i}, out \cup PendingOut(r.x))
            ELSE LET y == [q EXCEPT !.resends = IF q.synced THEN @ + 1 ELSE @]
                 IN TickEntries(Replace(ms, x, y), ids \ {i}, out \cup PendingOut(y))
MasterTick(ms) == TickEntries(ms, {x.id : x \in ms.reg}, {})

\* Dispatch of a datagram m from endpoint from (C++ handle_datagram): the
\* handler's name, and its effect.  Other types are not for the master.
Handler(m) ==
    CASE m.dst \notin {MasterId, Broadcast}  -> "Ignore"
      [] m.type \in {"AGENT", "PANIC"}       -> "MasterSync"
      [] m.type \in {"ACK", "NOT"}           -> "MasterAnswer"
      [] m.type = "PING"                     -> "MasterPing"
      [] m.type \in ReportTypes              -> "MasterReport"
      [] OTHER                               -> "Ignore"
Receive(ms, m, from) ==
    CASE Handler(m) = "MasterSync"   -> MasterSync(ms, m, from)
      [] Handler(m) = "MasterAnswer" -> MasterAnswer(ms, m)
      [] Handler(m) = "MasterPing"   -> MasterPing(ms, m, from)
      [] OTHER                       -> MasterReport(ms, m)
=============================================================================
