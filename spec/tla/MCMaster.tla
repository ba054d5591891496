------------------------------- MODULE MCMaster ------------------------------
(* One master, any environment: the model whose full state graph the        *)
(* conformance runner replays against the C++ master.  Bounds live here.   *)
EXTENDS Master

MCEps == {1, 2}
MCBehaviours == {"explore"}
MCMsgIds == {1, 2}
\* every master command type
MCOpTypes == Commands
=============================================================================
