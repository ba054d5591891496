------------------------------ MODULE MCAgentEnv ------------------------------
(* Bounds of AgentEnv (the one-agent model with the environment's history). *)
EXTENDS AgentEnv

MCBehaviours == {"explore"}
MCRefused    == {}      \* the check on receipt: MCAgent
MCAssignIds  == {2}
MCMsgIds     == {1, 2}
MCPeerSrcs   == {9, 50001}
MCEventPorts == {"in1"}
=============================================================================
