----------------------------- MODULE MCMasterEnv -----------------------------
(* Bounds of MasterEnv (MCMasterEnv.cfg): one agent endpoint; the rest as MCMaster's. *)
EXTENDS MasterEnv, MCMaster

OneEp == {1}
StartStop == {"START"}
ThreeIds == 1..3
=============================================================================
