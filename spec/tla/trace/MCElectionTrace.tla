--------------------------- MODULE MCElectionTrace ---------------------------
(* The check of an --election agent's trace: TraceData (written by         *)
(* ev3conformance.tracecheck: the records and the run's constants, data    *)
(* only) walked by ElectionTrace's step relation.                          *)
EXTENDS TraceData
VARIABLES st, cursor, failed
INSTANCE ElectionTrace
INSTANCE TraceWalk WITH Start <- ElectionStart, Step <- ElectionStep
==============================================================================
