------------------------------ MODULE MasterTrace ------------------------------
(***************************************************************************)
(* One master's NDJSON trace records (docs/core.md "Trace") against        *)
(* MasterLogic with exact msgids: MasterStep(r, s) is the set of local     *)
(* states record r leads to from s (docs/spec.md "Master trace             *)
(* validation").                                                           *)
(*                                                                         *)
(* A record, as ev3conformance.tracecheck converts it (data only):         *)
(*   [a   |-> the action (MasterLogic's name),                             *)
(*    m   |-> the datagram received, decoded (type "NONE": none),          *)
(*    now |-> its time in ms, from the trace's first record,               *)
(*    ch  |-> the variables it changed: reg, nextId, msgid]                *)
(*                                                                         *)
(* Time.  MasterLogic's MasterTick is one abstract resend period for every *)
(* entry at once.  The C++ core counts ms and keeps per entry a resend     *)
(* deadline (sent + resend) and a drop deadline (heard + drop); `advance`  *)
(* runs one MasterTick at each deadline, acting on the entries due then.   *)
(* The check maps it so (the same map for `ev3-master --driver` traces,    *)
(* resend 1 ms, and for the real program over UDP):                        *)
(*  - 1 tick = 1 ms for quiet and drops: quiet is ms since heard, TDrop    *)
(*    the drop timeout in ms; an entry is dropped at the tick where quiet  *)
(*    reaches TDrop, as in TickEntries.                                    *)
(*  - the resend period is per entry: a pending datagram is due TResend ms *)
(*    after it was sent (its msgid drawn, or last resent by a tick; a      *)
(*    re-announcement's resend does not move it, as in the core).  The     *)
(*    check keeps this time itself (sent), it is not read from the trace.  *)
(*  - a MasterTick record at time t is TickEntries over exactly the        *)
(*    entries due at t (dropped / resent / failed by the spec's own        *)
(*    per-entry rule, in id order); every other entry only ages by the     *)
(*    tick.  It must come at the first ms anything is due (nothing due at  *)
(*    t - 1), and something must be due.                                   *)
(*  - between records time passes with nothing due (else the core would    *)
(*    have ticked first): every entry ages by the elapsed ms.              *)
(* With TResend = 1 every pending datagram is due every ms: the spec's     *)
(* MasterTick exactly (driver traces).                                     *)
(***************************************************************************)
EXTENDS Naturals, Sequences, FiniteSets

CONSTANTS
    TDrop, MaxResends,  \* MasterLogic's: the drop timeout (ms), the resends before a command fails
    TResend,            \* the resend period (ms)
    Behaviours,         \* behaviour names the operator may have used
    NextId, FirstMsgid  \* the first id and msgid the master hands out (a restart: its state file's)

M == INSTANCE MasterLogic WITH ExactMsgids <- TRUE, BUG <- "none"

\* MasterLogic's receive handlers.
MasterRecv == {"MasterSync", "MasterAnswer", "MasterPing", "MasterReport"}
\* MasterLogic's variables a record may list in ch (msgid: the one counter of ExactMsgids).
MasterVars == {"reg", "nextId", "msgid"}
Val(v, s) == IF v = "msgid" THEN s.msgid[0] ELSE s[v]
\* The record's changed variables have its values; the others are as before the action.
Fits(r, before, after) ==
    \A v \in MasterVars : IF v \in DOMAIN r.ch THEN Val(v, after) = r.ch[v] ELSE after[v] = before[v]
\* The endpoints a datagram may have come from (the record does not carry it).
Eps(r, s) == {x.ep : x \in s.ms.reg} \cup (IF "reg" \in DOMAIN r.ch THEN {x.ep : x \in r.ch.reg} ELSE {})
\* The operator's commands.
Cmds == {M!Cmd(t, M!NoBehaviour) : t \in M!Commands \ {"BEHAVIOUR"}}
        \cup {M!Cmd("BEHAVIOUR", b) : b \in Behaviours}
Ids(ms) == {x.id : x \in ms.reg}
EntryOf(ms, i) == CHOOSE x \in ms.reg : x.id = i
\* Time passes k ms with nothing due: every entry's quiet grows by k.
Age(ms, k) == [ms EXCEPT !.reg = {[x EXCEPT !.quiet = x.quiet + k] : x \in ms.reg}]
\* Entry y is due at time t >= s.clock: quiet reaches TDrop, or its pending datagram was sent
\* TResend ms ago (s.sent: the check's own record of when, see NewSent).
DueAt(s, y, t) == y.quiet + (t - s.clock) >= TDrop \/ (y.pending /\ t - s.sent[y.id] >= TResend)
Due(s, t) == {y.id : y \in {x \in s.ms.reg : DueAt(s, x, t)}}
\* When each entry's pending datagram was last sent, after a step from s at time t that produced
\* registry ms2: now if its msgid was drawn in the step (new entry, next command, resync) or a tick
\* resent it (ids D), else as before (a re-announcement resends it without moving its deadline).
NewSent(s, ms2, D, t) ==
    [i \in Ids(ms2) |-> IF i \in D \/ ~\E y \in s.ms.reg : y.id = i /\ y.pending /\ y.mid = EntryOf(ms2, i).mid
                        THEN t ELSE s.sent[i]]
\* The operator's command: MasterCommand for one id (or an unknown one: 1), or for every
\* registered id in id order (the console's `all`: one core call, one record).
RECURSIVE ForAll(_, _, _)
ForAll(ms, ids, c) ==
    IF ids = {} THEN ms
    ELSE LET i == CHOOSE i \in ids : \A j \in ids : i <= j
         IN ForAll(M!MasterCommand(ms, i, c).ms, ids \ {i}, c)
CmdResults(ms) == {M!MasterCommand(ms, id, c).ms : id \in Ids(ms) \cup {1}, c \in Cmds}
                  \cup {ForAll(ms, Ids(ms), c) : c \in Cmds}

-----------------------------------------------------------------------------
(* The master's local state in a check: MasterLogic's ms, the time of the  *)
(* last record (clock) and when each entry's pending datagram was sent.    *)

MasterStart == [ms |-> [reg |-> {}, nextId |-> NextId, msgid |-> [k \in {0} |-> FirstMsgid]],
                clock |-> 0, sent |-> [i \in {} |-> 0]]

\* The step to registry ms2 at time t (ticked ids D), if record r's changes fit it (from ms1).
To(r, s, ms1, ms2, D, t) ==
    {[ms |-> y, clock |-> t, sent |-> NewSent(s, y, D, t)] : y \in {x \in {ms2} : Fits(r, ms1, x)}}

MasterStep(r, s) ==
    LET t == r.now IN
    IF r.a = "MasterTick" THEN
       \* the first ms anything is due: the spec's per-entry tick for the due entries
       IF t > s.clock /\ Due(s, t - 1) = {} /\ Due(s, t) # {} THEN
          LET D == Due(s, t)
              ms1 == Age(s.ms, t - 1 - s.clock)
              tk == M!TickEntries(ms1, D, {})
          IN To(r, s, ms1, [tk.ms EXCEPT !.reg = {IF x.id \in D THEN x ELSE [x EXCEPT !.quiet = x.quiet + 1]
                                                   : x \in tk.ms.reg}], D, t)
       ELSE {}
    ELSE IF t >= s.clock /\ Due(s, t) = {} THEN
       LET ms1 == Age(s.ms, t - s.clock) IN
       IF r.a = "MasterCommand" THEN
          UNION {To(r, s, ms1, ms2, {}, t) : ms2 \in CmdResults(ms1)}
       ELSE IF r.a \in MasterRecv /\ M!Handler(r.m) = r.a THEN
          UNION {To(r, s, ms1, M!Receive(ms1, r.m, from).ms, {}, t) : from \in Eps(r, s) \cup {0}}
       ELSE {}
    ELSE {}
================================================================================
