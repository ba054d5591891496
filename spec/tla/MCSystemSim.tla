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
(*  - the PC back from a crash, or told of a newer epoch (EPOCH_STALE or a *)
(*    newer master's LEADER), stands at its next step (its core stands at  *)
(*    once: become_candidate);                                             *)
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
(* One step is added: Ignore, a datagram delivered that no rule of System *)
(* takes, which changes nothing but lastAction: the replay's probe of the  *)
(* guards (one vote per epoch, copies counted once, older offers refused). *)
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
    /\ lastAction[1] \in {"Restart", "HandleStale", "HandleHeartbeat"} /\ lastAction[2] = PC
       /\ life[PC] = "CANDIDATE" =>
          lastAction'[1] = "StartElection" /\ lastAction'[2] = PC
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
VARIABLES
    patient,  \* drawn at the start: see Patience
    probed    \* history: the (node, datagram) pairs Ignore delivered (below)
SimInit == SysInit /\ patient \in BOOLEAN /\ probed = {}
Patience ==
    patient =>
        /\ lastAction'[1] = "Crash" => faults = 0
        /\ lastAction' = <<"Restart", PC>> => \E a \in Agents : life[a] = "MASTER"
        /\ lastAction'[1] = "HandleElect" =>
              life[lastAction'[2]] # "MASTER" \/ lastAction'[3].src # PC
        /\ lastAction'[1] = "HandleStale" => lastAction'[2] = PC \/ life[lastAction'[2]] # "MASTER"

\* The one step added: node n receives datagram m and no rule takes it -- every receive rule's
\* guard on n's own state (XOk) is false; their environment parts (a link, an answer not in
\* flight yet: net is a set, so answering again changes nothing) are not asked -- under the
\* agent core's rule for a peer's ELECT (CoreHears).  Nothing but lastAction changes (a
\* stuttering step of System's state).  System's traces never deliver a datagram no rule takes;
\* the replay delivers these so that an implementation that takes a step on one (a second vote,
\* a copy counted again, an older offer taken, a pre-vote to a stronger asker, the PC
\* standing again on a LEADER of its own epoch) is caught.
\* The core also answers a repeated ELECT of the candidate it voted for in that epoch (its VOTE
\* again: the same datagram, nothing changes), which HandleElect leaves out.
ElectTaken(v, s, m) ==
    /\ \/ HandleElectOk(v, s, m, Score[m.src], Score[v])
       \/ m.t = "ELECT" /\ m.src # v /\ m.e = s.epoch /\ s.votedFor = m.src
    /\ m.e < s.epoch \/ ~(s.life \in Followers /\ m.src # PC)
Taken(n, m) ==
    LET s == Loc(n) IN
    \/ HandleVoteOk(n, s, m) \/ HandleStaleOk(n, s, m) \/ HandleHeartbeatOk(n, s, m)
    \/ n \in Agents /\ \/ OfferRelayOk(n, s, m) \/ AcceptRelayOk(n, s, m) \/ HandleAcceptOk(n, s, m)
                       \/ RelayDroppedOk(n, s, m) \/ GrantPreVoteOk(n, s, m, Score[m.src], Score[n])
                       \/ HandlePreVoteOk(n, s, m) \/ ElectTaken(n, s, m) \/ ShareMembersOk(n, s, m)
                       \/ LearnMembersOk(n, s, m) \/ RefreshOk(s, m)
\* Each (node, datagram) is probed once, and never two probes in a row (history variable probed):
\* the probes are many (every datagram in flight at every node), so that without these a random
\* walk spends most of its steps on them.
Ignore(n, m) ==
    /\ <<n, m>> \notin probed /\ lastAction[1] # "Ignore"
    /\ probed' = probed \cup {<<n, m>>}
    /\ m.src # n /\ m.dst \in {NoNode, n} /\ life[n] # "DOWN" /\ Linked(m.src, n)
    /\ m.t \in {"ELECT", "VOTE", "HB", "STALE", "RREQ", "ROFFER", "RACCEPT", "RDROP", "PREOK"}
    /\ ~Taken(n, m)
    /\ lastAction' = <<"Ignore", n, m>>
    /\ UNCHANGED <<evars, sysvars>>

SimNext ==
    /\ \/ SysNext /\ UNCHANGED probed
       \/ \E m \in net, n \in Nodes : Ignore(n, m)
    /\ Eager /\ CoreHears /\ Patience /\ UNCHANGED patient
=============================================================================
