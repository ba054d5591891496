------------------------ MODULE MCMasterElectionTrace ------------------------
(* The check of an --election master's trace (or of an agent-master's      *)
(* Master core): TraceData (written by ev3conformance.tracecheck: the      *)
(* records and the run's constants, data only) walked by                   *)
(* MasterElectionTrace's step relation.                                    *)
EXTENDS TraceData
VARIABLES st, cursor, failed
INSTANCE MasterElectionTrace
INSTANCE TraceWalk WITH Start <- MasterElectionStart, Step <- MasterElectionStep
==============================================================================
