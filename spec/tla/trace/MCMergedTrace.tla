---------------------------- MODULE MCMergedTrace ----------------------------
(* The check of a whole run: TraceData (written by ev3conformance.merged:  *)
(* the merged records and the nodes' start, data only) walked by           *)
(* MergedTrace, with System's and Election's invariants.                   *)
EXTENDS TraceData
VARIABLES loc, pcrun, elected, applied, heard, told, obeyed, handed, cursor
INSTANCE MergedTrace
==============================================================================
