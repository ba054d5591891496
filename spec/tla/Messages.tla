------------------------------ MODULE Messages ------------------------------
(***************************************************************************)
(* Wire format v2 as the spec sees it (docs/protocol.md, docs/messages.tsv).*)
(* A message is a record; the type is its name, TypeNum maps it to the     *)
(* number on the wire.  tools/spec.py checks TypeNum against messages.tsv. *)
(*                                                                         *)
(* Params: the one numeric param a type may have first is the field ref  *)
(* (MASTER: announced id; ACK, NOT, PONG: the msgid answered; ACTION_OK,  *)
(* ACTION_INTERR, ACTION_ERR: the action id); 0 when the type has none.   *)
(* The text params follow in args, a sequence of strings.  On the wire:   *)
(* params = <<ref>> \o args for the types in RefTypes, args for the      *)
(* others.  (Keeps every message record the same shape.)     *)
(*                                                                         *)
(* Messages an agent receives carry the sender's msgid.  Messages an agent *)
(* emits (the `out' of a step) carry no msgid: the transport stamps the    *)
(* next msgid of the sender when it sends them (and sends each 3 times).   *)
(***************************************************************************)
EXTENDS Naturals, Sequences

TypeNum == [ AGENT |-> 1, MASTER |-> 2, ACK |-> 3, NOT |-> 4, PING |-> 5,
             PONG |-> 6, BEHAVIOUR |-> 7, START |-> 8, STOP |-> 9,
             PAUSE |-> 10, RESUME |-> 11, STANDBY |-> 12, CONTINUE |-> 13,
             RESTART |-> 14, ACTION_OK |-> 15, ACTION_INTERR |-> 16,
             ACTION_ERR |-> 17, SENSOR_VALUE |-> 18, PANIC |-> 19,
             EVENT |-> 20,
             \* relay and election (Election.tla, docs/election.md)
             RELAY_REQ |-> 21, RELAY_OFFER |-> 22, RELAY_ACCEPT |-> 23,
             RELAY_ROUTE |-> 24, RELAY |-> 25, RELAY_DROP |-> 26, ELECT |-> 27,
             VOTE |-> 28, LEADER |-> 29, EPOCH_STALE |-> 30, EPOCH_CMD |-> 31,
             HANDOVER |-> 32, PREVOTE_OK |-> 33,
             \* reliable reports (Reports.tla, docs/reports.md)
             REPORT |-> 40, REPORT_DROPPED |-> 41, REPORT_ACK |-> 42 ]

TypeNames == DOMAIN TypeNum

MasterId  == 1            \* the master, whoever acts as master
Broadcast == 0            \* receiver 0 = everyone
AssignedIds == 2..49999   \* ids a master assigns (docs/protocol.md "Ids")
TempIds  == 50000..65535  \* temporary ids an unsynced agent draws

\* Master commands: answered with ACK or NOT, acted on at most once.
Commands == {"BEHAVIOUR", "START", "STOP", "PAUSE", "RESUME", "STANDBY",
             "CONTINUE", "RESTART"}

\* A received datagram (decoded).
Msg(src, dst, msgid, type, ref, args) ==
    [src |-> src, dst |-> dst, msgid |-> msgid, type |-> type, ref |-> ref, args |-> args]

\* An emitted message (msgid stamped later by the transport).
Out(src, dst, type, ref, args) ==
    [src |-> src, dst |-> dst, type |-> type, ref |-> ref, args |-> args]

\* Types whose first wire param is the numeric ref.
RefTypes == {"MASTER", "ACK", "NOT", "PONG", "ACTION_OK", "ACTION_INTERR", "ACTION_ERR"}
=============================================================================
