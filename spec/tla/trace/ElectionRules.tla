----------------------------- MODULE ElectionRules -----------------------------
(***************************************************************************)
(* Election.tla's per-node operators (XOk: the enabling condition on a     *)
(* node's own state, XNext: its new local state) for a membership Agents,  *)
(* with the model-checking bounds lifted: the trace checks instantiate it  *)
(* and call the same XOk / XNext as the models (nothing of the election    *)
(* logic is copied).  Election's variables are never read by those         *)
(* operators: they are bound to dummies.                                   *)
(***************************************************************************)
CONSTANT Agents   \* the membership quorums count against

\* The largest number TLC's integers hold: the epoch bound of a check.
MaxTLCInt == 2147483647

INSTANCE Election WITH Score <- [n \in {} |-> 0], MaxEpoch <- MaxTLCInt,
       MaxFaults <- 0, Crashes <- FALSE, PCCrash <- FALSE, PCReturns <- FALSE, Partitions <- FALSE,
       MaxLoss <- 0, SpuriousTimeout <- FALSE, CmdAgents <- {}, PreVote <- TRUE, BUG <- "None",
       life <- {}, epoch <- {}, votedFor <- {}, votes <- {}, leader <- {}, following <- {},
       via <- {}, relays <- {}, offered <- {}, prevotes <- {}, net <- {}, down <- {}, faults <- 0,
       lost <- 0, elected <- {}, applied <- {}, members <- {}, mepoch <- {}, floor <- {},
       want <- {}, changes <- 0, Joiners <- {}, MaxChanges <- 0, lastAction <- <<>>
================================================================================
