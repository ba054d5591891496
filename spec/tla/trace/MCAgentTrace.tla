---------------------------- MODULE MCAgentTrace ----------------------------
(* The check of one agent's trace: TraceData (written by                   *)
(* ev3conformance.tracecheck: the records and the run's constants, data    *)
(* only) walked by AgentTrace's step relation.                             *)
EXTENDS TraceData
VARIABLES st, cursor, failed
INSTANCE AgentTrace
INSTANCE TraceWalk WITH Start <- AgentStart, Step <- AgentStep
=============================================================================
