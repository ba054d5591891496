------------------------------- MODULE System -------------------------------
(***************************************************************************)
(* The whole fleet in one model (docs/spec.md "The whole system").        *)
(* Election.tla gives the nodes and their rules: the PC                   *)
(* master (id 1) with its epochs and membership, the agents with relay,    *)
(* pre-vote, election and membership, crashes, cuts, and a network that    *)
(* loses (Lose), duplicates (delivery keeps a datagram), reorders (any      *)
(* order) and delivers late (a datagram stays in flight across timeouts,   *)
(* crashes and changes of master, until it is lost).  This module adds     *)
(* what the election model abstracts and the fleet needs:                   *)
(*                                                                         *)
(*  - time: a discrete Tick; each agent's heartbeat timer (silence, the    *)
(*    agent's own counter) restarts on a datagram of the master it follows *)
(*    and fires after T ticks (Timeout: WORKING -> PAUSED, ACTIVE/PAUSED   *)
(*    -> PANIC), replacing Election's oracle "the heartbeat no longer gets *)
(*    through"; a timeout while the master lives (its LEADERs lost or not  *)
(*    sent yet) is a false suspicion, part of every behaviour;             *)
(*  - the heartbeat that keeps a follower (Refresh: a LEADER of the master  *)
(*    it follows restarts its timer and changes nothing else);             *)
(*  - HANDOVER (type 32): an elected agent that hears the LEADER of a newer *)
(*    epoch sends its membership to the new master and steps down (master  *)
(*    core HandleHeartbeat, election/master.hpp); the PC takes it into its *)
(*    registry (MasterHandover), which later reconfigurations publish one  *)
(*    agent at a time (Election "Membership");                             *)
(*  - history variables of the environment, read by the whole-system      *)
(*    invariants: what really reached each agent, not what it believes.    *)
(*                                                                         *)
(* The rules are Election's (XOk / XNext and its actions, by EXTENDS): no  *)
(* rule is restated here.  Commands are EPOCH_CMD(epoch, START): the only  *)
(* lifecycle command that can start motion (ApplyCommand, -> WORKING);     *)
(* STOP, PAUSE, STANDBY only leave WORKING, which no safety property       *)
(* forbids, so they are left out.                                          *)
(***************************************************************************)
EXTENDS Election

CONSTANT
    T   \* ticks of silence after which an agent's heartbeat timer fires (>= 1)

ASSUME T \in Nat \ {0}
\* The timeout is the agent's timer here: Election's Timeout with its oracle off.
ASSUME SpuriousTimeout = TRUE

VARIABLES
    silence,  \* silence[a]: ticks since agent a last restarted its heartbeat timer (its own state)
    heard,    \* history: ticks since a datagram of the master a follows (in the epoch it follows)
              \* reached a, saturated at T + 1 (the environment's view, not the agent's)
    told,     \* history: told[a], the highest epoch that reached a in a LEADER, EPOCH_STALE,
              \* ELECT, LEADER copy or relay offer (what the network told a, whatever a did)
    obeyed,   \* history: [a, src, e, told] for each command that took effect at a
    hnet,     \* HANDOVER datagrams in flight (master -> master; lossy, duplicated, late as net)
    handed    \* history: [src, e] for each HANDOVER sent: src handed over to the master of e

sysvars == <<silence, heard, told, obeyed, hnet, handed>>
allvars == <<vars, sysvars>>

Min2(x, y) == IF x < y THEN x ELSE y
\* The timer fires at T ticks of silence; the broken variant TimerLate one tick later.
Limit == IF BUG = "TimerLate" THEN T + 1 ELSE T

Handovers == [src : Nodes, dst : Nodes, e : 0..MaxEpoch, mem : SUBSET Agents]

SysTypeOK ==
    /\ silence \in [Agents -> 0..Limit]
    /\ heard \in [Agents -> 0..(T + 1)]
    /\ told \in [Agents -> 0..MaxEpoch]
    /\ obeyed \subseteq [a : Agents, src : Nodes, e : 0..MaxEpoch, told : 0..MaxEpoch]
    /\ hnet \subseteq Handovers
    /\ handed \subseteq [src : Nodes, e : 0..MaxEpoch]

SysInit ==
    /\ Init
    /\ silence = [a \in Agents |-> 0]
    /\ heard = [a \in Agents |-> 0]
    /\ told = [a \in Agents |-> 1]
    /\ obeyed = {}
    /\ hnet = {}
    /\ handed = {}

\* Election's variables but lastAction (the name of the step, written by every action), and
\* those but life.
restvars == <<epoch, votedFor, votes, leader, following, via, relays, offered, prevotes, net,
           down, faults, lost, elected, applied, members, mepoch, floor, want, changes>>
evars == <<life, restvars>>

-----------------------------------------------------------------------------
(* Time.                                                                   *)

\* Agent a's heartbeat timer has fired: it follows a master (ACTIVE, WORKING,
\* PAUSED) and has heard nothing from it for Limit ticks.
Due(a) == TimeoutOk(Loc(a)) /\ silence[a] >= Limit

\* One tick: every follower's silence grows, and so does the time since each
\* agent last heard its master.  Timers fire on time: no tick passes while a
\* timer is due (SysTimeout goes first).
Tick ==
    /\ \A a \in Agents : ~Due(a)
    /\ silence' = [a \in Agents |-> IF life[a] \in Followers THEN Min2(silence[a] + 1, Limit) ELSE 0]
    /\ heard' = [a \in Agents |-> Min2(heard[a] + 1, T + 1)]
    /\ lastAction' = <<"Tick">>
    /\ UNCHANGED <<evars, told, obeyed, hnet, handed>>

\* Agent a's timer fires: Election's Timeout (its rule TimeoutOk / TimeoutNext;
\* WORKING -> PAUSED, motion stopped; ACTIVE or PAUSED -> PANIC, relays
\* dropped), and the timer starts again (PAUSED times out to PANIC next).
SysTimeout(a) ==
    /\ Due(a)
    /\ Timeout(a)
    /\ silence' = [silence EXCEPT ![a] = 0]
    /\ UNCHANGED <<heard, told, obeyed, hnet, handed>>

\* Agent a, following master m.src in epoch m.e over a direct link, hears its
\* LEADER again (the heartbeat): its timer restarts, nothing else changes
\* (Election's HandleHeartbeat takes only a LEADER that changes something).
\* The broken variant ResumeOnHeartbeat also puts a PAUSED agent back to work
\* (no command: the motion the master stopped resumes on its own).
RefreshOk(s, m) ==
    /\ m.t = "HB" /\ m.dst = NoNode
    /\ s.life \in Followers /\ s.via = NoNode
    /\ s.leader = m.src /\ s.following = m.e
Refresh(a, m) ==
    /\ RefreshOk(Loc(a), m) /\ Linked(m.src, a)
    /\ silence' = [silence EXCEPT ![a] = 0]
    /\ heard' = IF leader[a] = m.src /\ following[a] = m.e THEN [heard EXCEPT ![a] = 0] ELSE heard
    /\ lastAction' = <<"Refresh", a, m>>
    /\ IF BUG = "ResumeOnHeartbeat" /\ life[a] = "PAUSED"
       THEN /\ life' = [life EXCEPT ![a] = "WORKING"]
            /\ UNCHANGED <<restvars, told, obeyed, hnet, handed>>
       ELSE UNCHANGED <<evars, told, obeyed, hnet, handed>>

-----------------------------------------------------------------------------
(* HANDOVER.                                                               *)

\* Node v hears a LEADER (Election's HandleHeartbeat: its rule
\* HandleHeartbeatOk / HandleHeartbeatNext, the same environment part).  If v
\* is an elected agent's master and the LEADER is of a newer epoch, v's master
\* core hands its membership to the new master (HANDOVER(e, members...), once:
\* v steps down with it) -- election/master.hpp HandleHeartbeat.  The broken variant
\* HandoverKeepsMaster sends HANDOVER but keeps the node a master of its epoch
\* (the master core not stopped).  v's timer restarts on a LEADER it takes (not
\* on an older one, answered EPOCH_STALE).  The PC has no timer and hands
\* nothing over: a newer LEADER makes it stand again (Election).  The broken variant
\* TimerOnStale restarts the timer on an older LEADER too (one the agent answers EPOCH_STALE):
\* the late LEADER of a master it no longer follows keeps it working.
Hands(v, s, m) == v # PC /\ s.life = "MASTER" /\ ~Stale(s, m)
SysHandleHeartbeat(v, m) ==
    LET s == Loc(v) IN
    /\ HandleHeartbeatOk(v, s, m) /\ Linked(m.src, v)
    /\ IF Stale(s, m)
       THEN /\ M("STALE", v, m.src, epoch[v], NoNode) \notin net
            /\ net' = net \cup {M("STALE", v, m.src, epoch[v], NoNode)}
       ELSE net' = IF v # PC /\ MasterChange(s, m) THEN net \cup Drops(v) ELSE net
    /\ SetLoc(v, IF Hands(v, s, m) /\ BUG = "HandoverKeepsMaster" THEN s ELSE HandleHeartbeatNext(v, s, m))
    /\ hnet' = IF Hands(v, s, m)
               THEN hnet \cup {[src |-> v, dst |-> m.src, e |-> m.e, mem |-> members[v]]}
               ELSE hnet
    /\ handed' = IF Hands(v, s, m) THEN handed \cup {[src |-> v, e |-> m.e]} ELSE handed
    /\ silence' = IF v # PC /\ (~Stale(s, m) \/ BUG = "TimerOnStale") THEN [silence EXCEPT ![v] = 0] ELSE silence
    /\ heard' = IF v # PC /\ leader'[v] = m.src /\ following'[v] = m.e THEN [heard EXCEPT ![v] = 0] ELSE heard
    /\ told' = IF v # PC THEN [told EXCEPT ![v] = Max2(@, m.e)] ELSE told
    /\ lastAction' = <<"HandleHeartbeat", v, m>>
    /\ UNCHANGED <<down, faults, lost, elected, applied, obeyed>>

\* The PC, master, gets a HANDOVER of an epoch not newer than its own (election/
\* master.hpp MasterHandoverOk): the agents it lists join its registry (want); the PC
\* publishes them one at a time by reconfiguring (Election Reconfigure), never
\* into the membership of its current epoch (with DynamicMembership, the unsafe
\* rule, the published list follows the registry at once).
MasterHandoverOk(s, h) == h.dst = PC /\ s.life = "MASTER" /\ h.e <= s.epoch
MasterHandover(h) ==
    /\ MasterHandoverOk(Loc(PC), h) /\ Linked(h.src, PC)
    /\ want' = want \cup h.mem
    /\ members' = IF Fixed THEN members ELSE [members EXCEPT ![PC] = want']
    /\ lastAction' = <<"MasterHandover", h>>
    /\ UNCHANGED <<life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   net, down, faults, lost, elected, applied, mepoch, floor, changes, sysvars>>

\* The network loses a HANDOVER (the PC then keeps its registry as it was).
LoseHandover(h) ==
    /\ lost < MaxLoss
    /\ hnet' = hnet \ {h}
    /\ lost' = lost + 1
    /\ lastAction' = <<"LoseHandover", h>>
    /\ UNCHANGED <<life, epoch, votedFor, votes, leader, following, via, relays, offered, prevotes,
                   net, down, faults, elected, applied, members, mepoch, floor, want, changes,
                   silence, heard, told, obeyed, handed>>

-----------------------------------------------------------------------------
(* Election's other actions, unchanged, and what they mean for time and    *)
(* the histories (read from the step's name, lastAction').                  *)

Step == lastAction'
\* The node that acted (every action of ElectionStep but Lose and Reconfigure names one).
Who == IF Step[1] \in {"Lose", "Reconfigure"} THEN NoNode ELSE Step[2]
Got == Step[3]   \* the datagram, for the actions that take one
\* Actions that take a datagram carrying an epoch the receiver is told of.
Telling == {"HandleElect", "HandleStale", "LearnMembers", "AcceptRelay"}

ElectionStep ==
    \/ \E a \in Agents : RequestRelay(a) \/ AddMember(a) \/ DropMember(a)
    \/ Reconfigure
    \/ \E n \in Nodes : StartElection(n) \/ BecomeMaster(n) \/ Heartbeat(n)
                        \/ Crash(n) \/ Restart(n)
    \/ \E s \in Nodes, a \in CmdAgents : SendCommand(s, a)
    \/ \E x, y \in Nodes : Cut(x, y) \/ Heal(x, y)
    \/ \E m \in net :
         \/ Lose(m)
         \/ HandleVote(m.dst, m) \/ HandleStale(m.dst, m)
         \/ \E a \in Agents :
              \/ OfferRelay(a, m) \/ AcceptRelay(a, m) \/ HandleAccept(a, m)
              \/ RelayDropped(a, m) \/ GrantPreVote(a, m) \/ HandlePreVote(a, m)
              \/ HandleElect(a, m) \/ Forward(a, m) \/ ApplyCommand(a, m)
              \/ ShareMembers(a, m) \/ LearnMembers(a, m)

\* After one of Election's steps: an agent's timer restarts when it takes a
\* command of its master (ApplyCommand) or starts following one through a relay
\* (AcceptRelay); it does not run while it follows nobody.  The broken variant
\* TimerOnPeer also restarts it on a peer's RELAY_REQ it answers (OfferRelay):
\* a datagram not from its master.  A command that took
\* effect came from the master the agent follows (so it heard its master), and
\* is recorded with what the network had told the agent by then.
Cmd == Step[1] = "ApplyCommand"
Follow ==
    /\ silence' = [a \in Agents |->
                    IF \/ life'[a] \notin Followers
                       \/ a = Who /\ Step[1] \in {"ApplyCommand", "AcceptRelay"}
                       \/ a = Who /\ Step[1] = "OfferRelay" /\ BUG = "TimerOnPeer"
                    THEN 0 ELSE silence[a]]
    /\ heard' = IF Cmd /\ Got.src = leader[Who] /\ Got.e = following[Who]
                THEN [heard EXCEPT ![Who] = 0] ELSE heard
    /\ told' = IF Step[1] \in Telling /\ Who \in Agents
               THEN [told EXCEPT ![Who] = Max2(@, Got.e)] ELSE told
    /\ obeyed' = IF Cmd
                 THEN obeyed \cup {[a |-> Who, src |-> Got.src, e |-> Got.e, told |-> told[Who]]}
                 ELSE obeyed
    /\ UNCHANGED <<hnet, handed>>

SysNext ==
    \/ Tick
    \/ \E a \in Agents : SysTimeout(a)
    \/ \E m \in net : \/ SysHandleHeartbeat(PC, m)
                      \/ \E a \in Agents : SysHandleHeartbeat(a, m) \/ Refresh(a, m)
    \/ \E h \in hnet : MasterHandover(h) \/ LoseHandover(h)
    \/ ElectionStep /\ Follow

SysSpec == SysInit /\ [][SysNext]_allvars

-----------------------------------------------------------------------------
(* Whole-system properties, over the environment's histories.  With them   *)
(* every invariant of Election (TypeOK, AtMostOneMasterPerEpochInv,         *)
(* FollowersAgreeInv, RelayOneHopInv, NoRelayCycleInv,                      *)
(* StaleMasterFencedInv, LifecycleInv) is checked on this model.            *)

\* No motion without a master: a WORKING agent heard the master it follows,
\* in the epoch it follows, within the timeout (heard is the environment's
\* count, not the agent's timer).
NoUnsupervisedMotionInv ==
    \A a \in Agents : life[a] = "WORKING" => heard[a] <= T

\* No command obeyed from a stale master: a command took effect only if its
\* epoch was at least every epoch the network had told the agent of (a LEADER,
\* EPOCH_STALE, ELECT, LEADER copy or relay offer that reached it).
ObeyedNewestEpochInv ==
    \A r \in obeyed : r.e >= r.told

\* HANDOVER leaves one master: a node that handed the fleet over to the master
\* of epoch e is not a master of an older epoch any more.
HandoverStepsDownInv ==
    \A h \in handed : life[h.src] = "MASTER" => epoch[h.src] > h.e

\* A WORKING agent works for the master whose command it obeyed: a command of
\* the master it follows, in the epoch it follows, took effect at it (obeyed,
\* the environment's record, not the agent's).
WorkingForCommanderInv ==
    \A a \in Agents : life[a] = "WORKING" =>
        \E r \in obeyed : r.a = a /\ r.src = leader[a] /\ r.e = following[a]

\* The lifecycle's rules of the whole system, over every step (action
\* properties: free in states, as AgentLogic's AllowedTransitionsProp): the
\* steps that may move an agent into each state, and the states it may come
\* from.  Motion starts only on a command: WORKING is entered by ApplyCommand
\* alone, from ACTIVE or PAUSED; MASTER by BecomeMaster from CANDIDATE,
\* CANDIDATE by StartElection from PANIC, DOWN by Crash; an agent leaves DOWN
\* by Restart alone, into PANIC.
EnteredBy ==
    [WORKING   |-> {"ApplyCommand"},
     MASTER    |-> {"BecomeMaster"},
     CANDIDATE |-> {"StartElection"},
     DOWN      |-> {"Crash"},
     ACTIVE    |-> {"HandleHeartbeat", "AcceptRelay"},
     PAUSED    |-> {"Timeout", "HandleHeartbeat", "HandleElect", "HandleStale"},
     PANIC     |-> {"Timeout", "RelayDropped", "Restart", "HandleElect", "HandleStale"}]
EnteredFrom ==
    [WORKING   |-> {"ACTIVE", "PAUSED"},
     MASTER    |-> {"CANDIDATE"},
     CANDIDATE |-> {"PANIC"},
     DOWN      |-> Lives \ {"DOWN"},
     ACTIVE    |-> {"PANIC", "CANDIDATE", "MASTER"},
     PAUSED    |-> {"WORKING"},
     PANIC     |-> Lives \ {"PANIC"}]
Moved(a) == life'[a] # life[a]
LifecycleStepProp ==
    [][\A a \in Agents : Moved(a) => lastAction'[1] \in EnteredBy[life'[a]]]_allvars
LifecycleFromProp ==
    [][\A a \in Agents : Moved(a) => life[a] \in EnteredFrom[life'[a]]]_allvars
=============================================================================
