---------------------------- MODULE MCMergedTrace ----------------------------
(* The check of a whole run: TraceData (written by ev3conformance.merged:  *)
(* the merged records and the nodes' start, data only) walked by           *)
(* MergedTrace.                                                            *)
EXTENDS TraceData
VARIABLES loc, elected, applied, cursor
INSTANCE MergedTrace
==============================================================================
