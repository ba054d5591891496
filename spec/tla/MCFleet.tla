------------------------------- MODULE MCFleet -------------------------------
(* Bounds of the fleet models (sizes in MCFleet_*.cfg).                     *)
EXTENDS Fleet

MCBehaviours == {"explore"}
=============================================================================
