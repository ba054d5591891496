------------------------------- MODULE MCAgent -------------------------------
(* One agent, any environment: the model TLC explores exhaustively; its     *)
(* state graph is the conformance test set and the source of the lifecycle *)
(* diagram.  Bounds live here, not in Agent.tla.                           *)
EXTENDS Agent

\* "broken" stands for every request the robot's check refuses (a custom definition that does
\* not parse or check, one needing a device or an action the robot lacks).
MCBehaviours == {"explore", "broken"}
MCRefused    == {"broken"}
MCAssignIds  == {2}
\* Five fresh commands or MASTERs per life (Agent.tla EnvMsgs: the agent ignores a msgid below one it remembers).
MCMsgIds     == 1..5
MCEventPorts == {"in1"}
=============================================================================
