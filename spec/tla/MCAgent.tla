------------------------------- MODULE MCAgent -------------------------------
(* One agent, any environment: the model TLC explores exhaustively; its     *)
(* state graph is the conformance test set and the source of the lifecycle *)
(* diagram.  Bounds live here, not in Agent.tla.                           *)
EXTENDS Agent

MCBehaviours == {"explore"}
MCAssignIds  == {2}
MCMsgIds     == {1, 2}
MCEventPorts == {"in1"}
=============================================================================
