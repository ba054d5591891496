------------------------------ MODULE MasterEnv -------------------------------
(***************************************************************************)
(* One master (Master.tla, unchanged) and what its environment really did: *)
(* a property stated over what the master was sent, not over its own       *)
(* bookkeeping (as AgentEnv.tla for the agent).                            *)
(*                                                                         *)
(*  - Answers carry real msgids: Master's environment (the replayed model) *)
(*    sends ACK, NOT and ACTION_OK with msgid 1 only; here every answer    *)
(*    carries any of MsgIds, so what the master does with an answer's      *)
(*    msgid (it raises hi, which decides whether a later PING is fresh) is *)
(*    exercised.                                                           *)
(*  - top: history, top[s] the highest msgid of an AGENT, PANIC, PING,    *)
(*    ACK or NOT from sender id s that reached the master (whatever it did *)
(*    with it).  Reports are left out: they change no lifecycle state, so  *)
(*    a PING sent before a report still tells the agent's state.  A PING   *)
(*    is fresh if its msgid is above top of its sender before it; the      *)
(*    master's own hi, which ReconcileFreshProp reads, is not: a master    *)
(*    that forgets to raise hi passes that property.                       *)
(***************************************************************************)
EXTENDS Master

VARIABLE top

envVars == <<ms, out, lastAction, top>>

\* What the agents send besides Master's EnvMsgs: answers (ACK of the pending msgid or of 0,
\* NOT for each kind of reason, ACTION_OK) with any of MsgIds.
Answers(e) ==
  IF e # Main THEN {}
  ELSE UNION {
         {Msg(x.id, MasterId, i, "ACK", r, <<>>) : r \in {x.mid, 0}, i \in MsgIds}
    \cup {Msg(x.id, MasterId, i, "NOT", x.mid, <<r>>) : r \in {"wrong state", "missing device"}, i \in MsgIds}
    \cup {Msg(x.id, MasterId, i, "ACTION_OK", 0, <<>>) : i \in MsgIds}
       : x \in {y \in ms.reg : y.ep = e}}

EnvInit == Init /\ top = <<>>

\* The highest msgid recorded from sender s (0: none).
Top(s) == IF s \in DOMAIN top THEN top[s] ELSE 0

\* A datagram m from endpoint e reaches the master; the environment records it (not a report).
\* An answer carries a msgid not below any recorded from its agent: the agent sends it on the
\* master's datagram, which the master sent after what it had received (an answer overtaken
\* by a newer datagram of its agent, left out, changes neither hi nor top).
Recorded(m) == m.type \notin M!ReportTypes
Deliver(m, e) ==
    /\ m.type \in {"ACK", "NOT"} => m.msgid >= Top(m.src)
    /\ Recv(m, e)
    /\ top' = IF Recorded(m)
              THEN [s \in DOMAIN top \cup {m.src} |-> IF s = m.src THEN M!Max(Top(s), m.msgid) ELSE top[s]]
              ELSE top

EnvNext ==
    \/ \E e \in Eps : \E m \in EnvMsgs(e) \cup Answers(e) : Deliver(m, e)
    \/ /\ \E id \in {x.id : x \in {y \in ms.reg : y.ep = Main}} \cup {Unknown} :
             \E c \in OpCmds : MasterCommand(id, c)
       /\ UNCHANGED top
    \/ MasterTick /\ UNCHANGED top

EnvSpec == EnvInit /\ [][EnvNext]_envVars

\* A PING makes the master start a command (reconcile: a msgid drawn in this step) only if it
\* is fresh by the environment's record: its msgid above every msgid recorded from its sender
\* before it.  A PING the agent sent ahead of its last answer, delivered later than that answer,
\* reports a state the agent has left.
PingFreshProp ==
    [][(lastAction'.name = "MasterPing"
        /\ \E o \in out' : o.m.type \in Commands /\ o.m.msgid >= ms.msgid[0])
       => lastAction'.args[1].msgid > Top(lastAction'.args[1].src)]_envVars
=============================================================================
