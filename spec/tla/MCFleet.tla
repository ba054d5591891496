------------------------------- MODULE MCFleet -------------------------------
(* Bounds of the fleet models (sizes in MCFleet_small.cfg, MCFleet_full.cfg). *)
EXTENDS Fleet

MCBehaviours == {"explore"}
=============================================================================
