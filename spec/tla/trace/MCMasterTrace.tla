---------------------------- MODULE MCMasterTrace ----------------------------
(* The check of one master's trace: TraceData (written by                  *)
(* ev3conformance.tracecheck: the records and the run's constants, data    *)
(* only) walked by MasterTrace's step relation.                            *)
EXTENDS TraceData
VARIABLES st, cursor, failed
INSTANCE MasterTrace
INSTANCE TraceWalk WITH Start <- MasterStart, Step <- MasterStep
==============================================================================
