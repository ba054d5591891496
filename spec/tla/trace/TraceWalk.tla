------------------------------ MODULE TraceWalk ------------------------------
(***************************************************************************)
(* Walks one node's trace with that node's step relation: the behaviour    *)
(* of the check (docs/spec.md "Implementation -> spec (validate)").        *)
(*                                                                         *)
(* A node's trace module (AgentTrace, ElectionTrace, MasterTrace,          *)
(* MasterElectionTrace) gives its initial local state and a step relation  *)
(* as a set: Step(r, s) is the set of local states record r leads to from  *)
(* s, empty when r cannot be matched there.  Each TLC step takes one       *)
(* record.  Both invariants are violated on purpose:                       *)
(*   Matched  (cursor <= Len(Trace)) fails once every record was matched:  *)
(*            the trace conforms;                                          *)
(*   NotStuck (failed = 0) fails when record `failed` has no successor:    *)
(*            the trace does not conform, and that record is named.        *)
(* A trace with no records proves nothing: it is refused by the ASSUME.    *)
(***************************************************************************)
EXTENDS Naturals, Sequences

CONSTANTS
    Trace,       \* the node's records, in the order the node wrote them
    Start,       \* the node's local state before the first record
    Step(_, _)   \* Step(r, s): the local states record r leads to from s

ASSUME Len(Trace) > 0

VARIABLES
    st,      \* the node's local state after the records matched so far
    cursor,  \* the next record
    failed   \* the record that could not be matched, or 0

Init == st = Start /\ cursor = 1 /\ failed = 0

\* The next record is matched: a successor of st by that record's step.
Match ==
    /\ failed = 0 /\ cursor <= Len(Trace)
    /\ \E s2 \in Step(Trace[cursor], st) : st' = s2
    /\ cursor' = cursor + 1
    /\ UNCHANGED failed

\* The next record has no successor: the check stops there and names it.
Stuck ==
    /\ failed = 0 /\ cursor <= Len(Trace)
    /\ Step(Trace[cursor], st) = {}
    /\ failed' = cursor
    /\ UNCHANGED <<st, cursor>>

Next == Match \/ Stuck

Matched == cursor <= Len(Trace)
NotStuck == failed = 0
==============================================================================
