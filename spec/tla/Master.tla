------------------------------- MODULE Master --------------------------------
(***************************************************************************)
(* One master against any environment: datagrams from up to |Eps| agents  *)
(* (AGENT, PANIC, PING, ACK, NOT, reports, with any of MsgIds as msgid)   *)
(* arrive at any time and as often as the environment likes (copies,       *)
(* resends, stale and reordered messages are all covered); the operator    *)
(* gives commands for registered or unknown ids; time ticks.  Every action *)
(* is one handler of the C++ master core (master.hpp), same name;          *)
(* lastAction records the handler and its arguments, out what the master   *)
(* emitted in that step (a set of [to, m]), so every edge of TLC's state   *)
(* graph (-dump dot,actionlabels) can be replayed against the C++ master.  *)
(* msgids are exact here (ExactMsgids = TRUE: one counter, PONG draws one).*)
(***************************************************************************)
EXTENDS Naturals, Sequences, FiniteSets, Messages

CONSTANTS TDrop, MaxResends, BUG,
          Eps,         \* agent endpoints (C++ peers): integers 1..
          Behaviours,  \* behaviour names the operator may ask for
          MsgIds,      \* msgids the agents' datagrams carry
          OldId,       \* an assigned id the master does not know (PANIC of an earlier session)
          Unknown,     \* an id never registered (operator command for it)
          MaxMsgid,    \* bound: the master's msgid counter (state constraint)
          MaxQueue,    \* bound: operator commands queued per agent
          OpTypes      \* command types the operator uses (bound)

M == INSTANCE MasterLogic WITH ExactMsgids <- TRUE

VARIABLES
    ms,          \* the master's local state (MasterLogic)
    out,         \* datagrams the master emitted in the last step: set of [to, m]
    lastAction   \* [name |-> handler, args |-> its arguments]

vars == <<ms, out, lastAction>>

TempOf(e) == 50000 + e
\* The words of a robot's check on receipt refusing a BEHAVIOUR (AgentLogic CheckReason): any
\* reason but the agent's fixed ones.
CheckRefusal == "line 1 col 7: unknown action 'trun'"
States == {"ACTIVE", "WORKING", "PAUSED"}
\* Operator commands: those of OpTypes (BEHAVIOUR with each name).
OpCmds == {M!Cmd("BEHAVIOUR", b) : b \in Behaviours}
          \cup {M!Cmd0(t) : t \in OpTypes \ {"BEHAVIOUR"}}

\* What agents may send the master, from endpoint e.  The first endpoint
\* (Main) sends everything; the others only join (AGENT): ids are assigned
\* in order, entries coexist and msgids interleave, while the state graph
\* stays small enough to dump.
Main == CHOOSE e \in Eps : \A f \in Eps : e <= f
EnvMsgs(e) ==
  IF e = Main THEN
       {Msg(TempOf(e), Broadcast, 1, "AGENT", 0, <<"A">>)}
  \cup {Msg(OldId, Broadcast, 1, "PANIC", 0, <<>>)}
  \cup UNION {
         {Msg(x.id, Broadcast, i, "PANIC", 0, <<>>) : i \in MsgIds}
    \cup {Msg(x.id, MasterId, i, "PING", 0, <<s>>) : s \in States, i \in MsgIds}
    \cup {Msg(x.id, MasterId, 1, "ACK", r, <<>>) : r \in {x.mid, 0}}
    \cup {Msg(x.id, MasterId, 1, "NOT", x.mid, <<r>>) : r \in {"wrong state", "missing device", CheckRefusal}}
    \cup {Msg(x.id, MasterId, 1, "ACTION_OK", 0, <<>>)}
       : x \in {y \in ms.reg : y.ep = e}}
  ELSE {Msg(TempOf(e), Broadcast, 1, "AGENT", 0, <<"A">>)}

TypeOK ==
    /\ M!MasterType(ms, Eps, Behaviours)
    /\ lastAction.name \in M!MasterNames \cup {"Init"}

Init ==
    /\ ms = M!InitMaster(Eps)
    /\ out = {}
    /\ lastAction = [name |-> "Init", args |-> <<>>]

Do(name, args, r) ==
    /\ ms' = r.ms
    /\ out' = r.out
    /\ lastAction' = [name |-> name, args |-> args]

\* A datagram m from endpoint e: the handler Handler(m) takes it.
Recv(m, e) ==
    /\ M!Handler(m) # "Ignore"
    /\ Do(M!Handler(m), <<m, e>>, M!Receive(ms, m, e))
\* The operator's command c for agent id.
MasterCommand(id, c) == Do("MasterCommand", <<id, c>>, M!MasterCommand(ms, id, c))
\* One resend period.
MasterTick == Do("MasterTick", <<>>, M!MasterTick(ms))

Next ==
    \/ \E e \in Eps : \E m \in EnvMsgs(e) : Recv(m, e)
    \/ \E id \in {x.id : x \in {y \in ms.reg : y.ep = Main}} \cup {Unknown} :
          \E c \in OpCmds : MasterCommand(id, c)
    \/ MasterTick

Spec == Init /\ [][Next]_vars

\* Bounds (MCMaster.cfg).
Bounds == /\ ms.msgid[0] <= MaxMsgid
          /\ \A x \in ms.reg : Len(x.queue) <= MaxQueue

-----------------------------------------------------------------------------
(* Properties of the master alone.                                          *)

\* The registry never holds one id twice, nor two entries for one endpoint.
RegistryInv == \A x, y \in ms.reg : (x.id = y.id \/ x.ep = y.ep) => x = y
\* Ids are handed out in order, never reused: every id in the registry (handed
\* out, or adopted from an agent of an earlier session) is below nextId, so
\* no later agent is given it.
IdsInv == \A x \in ms.reg : x.id < ms.nextId
\* A pending datagram's msgid was drawn: it is below the counter.
MidInv == \A x \in ms.reg : x.pending => x.mid < ms.msgid[0]
\* Only synced entries have commands pending.
PendingInv == \A x \in ms.reg : x.pending /\ x.synced => x.queue # <<>>
\* Every datagram the master sends goes to a registered agent's endpoint.
OutInv == \A o \in out : o.to \in Eps
\* A PING makes the master start a command (reconcile: a msgid drawn in this
\* step) only if it is fresh: its msgid above every msgid heard from that
\* agent before it.
ReconcileFreshProp ==
    [][(lastAction'.name = "MasterPing"
        /\ \E o \in out' : o.m.type \in Commands /\ o.m.msgid >= ms.msgid[0])
       => \A x \in ms.reg : x.id = lastAction'.args[1].src => lastAction'.args[1].msgid > x.hi]_vars
\* A PING or an operator command sends a command only when one starts: never
\* the datagram that was already pending (MasterTick resends that).
NoPendingResendProp ==
    [][lastAction'.name \in {"MasterPing", "MasterCommand"}
       => \A o \in out' : \A x \in ms.reg : ~(x.pending /\ o.m.msgid = x.mid /\ o.to = x.ep)]_vars
\* Reconcile: a fresh PING from a synced agent with nothing pending or queued whose reported
\* state differs from the desired one (Restore has a fix) makes the master start a command.
\* (An agent paused by a lost heartbeat would otherwise never work again.)
ReconcileProp ==
    [][(lastAction'.name = "MasterPing"
        /\ \E x \in ms.reg :
              LET m == lastAction'.args[1] IN
              /\ x.id = m.src /\ x.synced /\ ~x.pending /\ x.queue = <<>>
              /\ m.msgid > x.hi /\ M!Restore(m.args[1], x.desired, x.beh) # <<>>)
       => \E o \in out' : o.m.type \in Commands]_vars
\* A permanent refusal (NOT "unknown behaviour" / "missing device" / the robot's check's reason) of the pending command
\* ends reconciling: the desired state becomes UNKNOWN, so the refused command is not
\* queued again on every PING.
PermanentRefusalProp ==
    [][(lastAction'.name = "MasterAnswer"
        /\ LET m == lastAction'.args[1] IN
           /\ m.type = "NOT" /\ M!PermanentRefusal(m.args[1])
           /\ \E x \in ms.reg : x.id = m.src /\ x.synced /\ x.pending /\ m.ref = x.mid)
       => \A y \in ms'.reg : y.id = lastAction'.args[1].src => y.desired = M!UnknownDesired]_vars
=============================================================================
