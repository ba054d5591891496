------------------------------- MODULE MCFleet -------------------------------
(* Bounds of the fleet models (sizes in MCFleet_*.cfg).                     *)
EXTENDS Fleet

MCBehaviours == {"explore"}

\* Faults (losses, duplicates, crashes) spent so far.
FaultsSpent == (MaxLoss - budget.loss) + (MaxDup - budget.dup) + (MaxCrashes - budget.crash)
\* State constraint of fleet_full: every behaviour has at most one fault
\* (a loss, a duplicate or a crash).  Fault combinations are checked with
\* two agents (fleet_loss: loss + duplicate; fleet_crash: crash).
AtMostOneFault == FaultsSpent <= 1
=============================================================================
