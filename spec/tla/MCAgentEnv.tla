------------------------------ MODULE MCAgentEnv ------------------------------
(* Bounds of AgentEnv (the one-agent model with the environment's history). *)
EXTENDS AgentEnv

MCBehaviours == {"explore"}
MCRefused    == {}      \* the check on receipt: MCAgent
MCAssignIds  == {2}
\* Four fresh commands or MASTERs per life: MASTER, BEHAVIOUR, START, PAUSE (Agent.tla EnvMsgs).
MCMsgIds     == 1..4
MCPeerSrcs   == {9, 50001}
MCEventPorts == {"in1"}
\* MCAgentEnvCopies.cfg: the master's datagrams only (no peers, no device events) and three
\* msgids (MASTER, BEHAVIOUR, START reach WORKING; a command in the wrong state is refused), with
\* the environment's history of first answers in the view.
CopiesPeerSrcs   == {}
CopiesEventPorts == {}
CopiesMsgIds     == 1..3
=============================================================================
