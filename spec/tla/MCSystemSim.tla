----------------------------- MODULE MCSystemSim -----------------------------
(***************************************************************************)
(* Simulation-only wrapper of the whole system (System.tla) for the        *)
(* conformance replay of the election (`ev3-conformance replay --model    *)
(* fleet`, conformance/ev3conformance/system_replay.py, docs/spec.md      *)
(* "Spec -> implementation, fleet").  No wrapper variable: System's        *)
(* lastAction already names every step with its arguments (the node, the *)
(* datagram); the datagrams a step emits are net' \ net and hnet' \ hnet.  *)
(*                                                                         *)
(* SimNext is SysNext filtered (a subset of System's behaviours, every     *)
(* trace is one of System's) where the implementation takes two of the     *)
(* spec's steps on one input, so that the spec takes them one after the    *)
(* other, as the implementation does:                                      *)
(*  - a candidate holding a quorum becomes master at its next step         *)
(*    (the cores run BecomeMaster on the VOTE that completes the quorum);  *)
(*  - the PC back from a crash stands at its next step (its core stands    *)
(*    as it starts: MasterConfig::candidate);                              *)
(*  - ShareMembers(p, m) is taken after p answered m (OfferRelay or        *)
(*    GrantPreVote), not before (the agent core shares its list on the     *)
(*    same RELAY_REQ it answers, after the answer).                        *)
(* One filter keeps to the agent core's rule where it differs from         *)
(* Election's (docs/spec.md "Spec -> implementation, fleet"): a follower    *)
(* that has not timed out ignores a peer's ELECT of its epoch or a newer    *)
(* one (the core's hears_master: its own timer), where Election's          *)
(* HandleElect ignores it only while the master's heartbeat gets through   *)
(* (HeartbeatOK, an oracle of the environment).  The core grants fewer     *)
(* votes than the spec allows, never more.                                 *)
(* One step is added: IgnoreElect, an ELECT delivered to a voter that     *)
(* voted for another candidate in its epoch, which changes nothing but     *)
(* lastAction (System takes no step on it): the replay's probe of the      *)
(* one-vote-per-epoch rule.                                                *)
(* The models of manifest.json do not use this module.                     *)
(***************************************************************************)
EXTENDS MCSystem

\* Candidate n holds a quorum (BecomeMaster's rule: Election BecomeMasterOk, or the PC's
\* first step with no membership).
Ready(n) ==
    /\ life[n] = "CANDIDATE"
    /\ \/ BecomeMasterOk(Loc(n))
       \/ n = PC /\ Fixed /\ epoch[n] > mepoch[PC] /\ members[PC] = {}

Eager ==
    /\ \A n \in Nodes : Ready(n) => lastAction'[1] = "BecomeMaster" /\ lastAction'[2] = n
    /\ lastAction = <<"Restart", PC>> => lastAction'[1] = "StartElection" /\ lastAction'[2] = PC
    /\ lastAction'[1] = "ShareMembers" =>
          LET p == lastAction'[2]
              m == lastAction'[3]
          IN /\ ~OfferRelayOk(p, Loc(p), m)
             /\ ~GrantPreVoteOk(p, Loc(p), m, Score[m.src], Score[p])

\* The agent core's follower ignores a peer's ELECT until its own timer fired (see above).
CoreHears ==
    lastAction'[1] = "HandleElect" =>
        LET v == lastAction'[2]
            m == lastAction'[3]
        IN ~(life[v] \in Followers /\ m.src # PC /\ m.e >= epoch[v])

\* Each behaviour draws whether the PC, once crashed, stays down until an agent is master
\* (patient): a simulation picks among the enabled steps at random, so the PC mostly comes back
\* at once and an agent is rarely elected before it does; with patient = TRUE the PC comes back
\* to a fleet an agent leads and takes it back: in those behaviours it crashes once, and an agent that is master
\* hears the PC's LEADER before its ELECT or an EPOCH_STALE (else it steps down on those, and no
\* HANDOVER is sent: MCSystemHandover's scenario).  It only filters System's behaviours.
VARIABLE patient
SimInit == SysInit /\ patient \in BOOLEAN
Patience ==
    patient =>
        /\ lastAction'[1] = "Crash" => faults = 0
        /\ lastAction' = <<"Restart", PC>> => \E a \in Agents : life[a] = "MASTER"
        /\ lastAction'[1] = "HandleElect" =>
              life[lastAction'[2]] # "MASTER" \/ lastAction'[3].src # PC
        /\ lastAction'[1] = "HandleStale" => lastAction'[2] = PC \/ life[lastAction'[2]] # "MASTER"

\* The one step added: voter v, which has voted in epoch m.e for another candidate, receives the
\* ELECT m of that epoch.  HandleElectOk is false (one vote per epoch): System takes no step, no
\* variable but lastAction changes (a stuttering step of System's state).  The replay delivers it,
\* so that an implementation that grants a second vote (or takes any step) is caught.
IgnoreElect(v, m) ==
    /\ m.t = "ELECT" /\ m.src # v /\ life[v] # "DOWN" /\ Linked(m.src, v)
    /\ m.e = epoch[v] /\ votedFor[v] \notin {NoNode, m.src}
    /\ lastAction' = <<"IgnoreElect", v, m>>
    /\ UNCHANGED <<evars, sysvars>>

SimNext ==
    /\ SysNext \/ \E m \in net, v \in Agents : IgnoreElect(v, m)
    /\ Eager /\ CoreHears /\ Patience /\ UNCHANGED patient
=============================================================================
