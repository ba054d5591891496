----------------------------- MODULE ElectionTrace -----------------------------
(***************************************************************************)
(* The trace of an agent run with --election against AgentLogic composed   *)
(* with Election.tla's per-agent rules (docs/spec.md "Election traces"):   *)
(* ElectionStep(r, s) is the set of local states record r leads to from s. *)
(*                                                                         *)
(* A per-agent projection.  The agent's own Election variables (life,      *)
(* epoch, votedFor, votes, leader, following, via, relays, offered,        *)
(* prevotes: Election.tla's Loc record) are checked with Election.tla's    *)
(* own per-node operators (ElectionRules); the environment (links, the     *)
(* network, the other nodes) is not observed, so its guards are taken as   *)
(* satisfiable and a received datagram is the record's.  The lifecycle     *)
(* variables are checked with AgentLogic as for any agent (AgentTrace);    *)
(* the two compose as docs/election.md section 5 maps them (life           *)
(* CANDIDATE / MASTER = state PANIC; the followed master is AgentLogic's   *)
(* MasterId).                                                              *)
(*                                                                         *)
(* A record has AgentTrace's fields (ch: AgentLogic's variables) and       *)
(*   em  |-> an Election datagram as Election.tla's [t, src, dst, e, x],   *)
(*           plus sc (the score it carries) and tgt (RELAY's target);      *)
(*           t "NONE": none,                                               *)
(*   im  |-> the datagram inside an EPOCH_CMD (AgentLogic's; "NONE"),      *)
(*   cmd |-> ApplyCommand: the AgentLogic handler that took im,            *)
(*   ech |-> the Election variables it changed.                            *)
(***************************************************************************)
EXTENDS AgentTrace, FiniteSets

CONSTANTS
    Fleet,         \* the members the LEADERs in the trace list (quorums count against it)
    Score,         \* the agent's --score, if ScoreKnown
    ScoreKnown,    \* FALSE: the score is unknown, both outcomes of every comparison are allowed
    InitEpoch,     \* the epoch the agent starts from (its --state-dir; 1)
    InitVotedFor,  \* the vote it starts from (0: none)
    InitMembers,   \* the membership it starts with (its --state-dir; none)
    InitMEpoch,    \* the epoch of that membership (0: none known)
    InitFloor,     \* its floor (0)
    WithMembers    \* the records carry the membership (members, mepoch, floor: every current core);
                   \* FALSE: an older trace, quorums count against Fleet

E == INSTANCE ElectionRules WITH Agents <- Fleet

\* The agent's own score, or both outcomes of every comparison when unknown.
MyScores == IF ScoreKnown THEN {Score} ELSE {0, E!MaxTLCInt}

ElectionActions == {"RequestRelay", "OfferRelay", "HandleAccept", "AcceptRelay", "RelayDropped",
                    "GrantPreVote", "HandlePreVote", "StartElection", "HandleElect", "HandleVote",
                    "BecomeMaster", "HandleHeartbeat", "HandleStale", "Forward", "ApplyCommand",
                    "ShareMembers", "LearnMembers"}
\* With the membership: quorums count against the agent's own list (Election Fleet(s)).
ElVars == {"life", "epoch", "votedFor", "votes", "leader", "following", "via", "relays", "offered",
           "prevotes", "members", "mepoch", "floor"}
\* votes is compared while the agent is a candidate: the core clears it when the candidacy ends
\* (BecomeMaster, a LEADER heard), Election.tla keeps the last set, read only by a CANDIDATE.
FitsEl(r, before, after) ==
    \A v \in ElVars \cap DOMAIN before :
        IF v = "votes" /\ after.life # "CANDIDATE" THEN TRUE
        ELSE IF v \in DOMAIN r.ech THEN after[v] = r.ech[v] ELSE after[v] = before[v]

-----------------------------------------------------------------------------
(* The composition (docs/spec.md "Election traces").                       *)

\* life CANDIDATE / MASTER are the lifecycle's PANIC; otherwise life is the lifecycle state.
StateOf(life) == IF life \in {"CANDIDATE", "MASTER"} THEN "PANIC" ELSE life
LifeOf(st, old) == IF old \in {"CANDIDATE", "MASTER"} /\ st = "PANIC" THEN old ELSE st
\* AgentLogic's master is MasterId; the agent follows master c (el.leader, else the PC; the sender of an
\* EPOCH_CMD): the lifecycle sees c as MasterId and MasterId as c (a swap: dedupe keys stay distinct).
Cur(s) == IF s.leader # 0 THEN s.leader ELSE L!MasterId
Swap(x, c) == IF x = c THEN L!MasterId ELSE IF x = L!MasterId THEN c ELSE x
SwapMsg(m, c) == [m EXCEPT !.src = Swap(@, c)]
SwapAg(a, c) == [a EXCEPT !.win = [i \in 1..Len(a.win) |-> [a.win[i] EXCEPT !.src = Swap(@, c)]]]
Handled(a, m, c) == L!Handler(SwapAg(a, c), SwapMsg(m, c))
Received(h, a, m, c, v) == SwapAg(Recv(h, SwapAg(a, c), SwapMsg(m, c), v).ag, c)
\* A bare command or MASTER counts as epoch 1: past epoch 1 it is fenced (ignored, EPOCH_STALE).
BareFenced(s, a, m) == s.epoch > 1 /\ L!Answered(m) /\ L!AddressedTo(a, m)
\* The lifecycle after Election step s -> s2 of agent a: the state follows life; a WORKING agent paused
\* (master changed, newer epoch) stops its motors; PANIC -> ACTIVE (a LEADER, a relay taken) restarts the
\* periodic phase; -> PANIC (RELAY_DROP) is HeartbeatLost's; hearing a master resets the silence.
Follow(a, s2, heard) ==
    LET st == StateOf(s2.life)
        b == CASE st = a.state -> a
               [] st = "PAUSED" /\ a.state = "WORKING" -> [L!Goto(a, "PAUSED") EXCEPT !.motors = "OFF"]
               [] st = "ACTIVE" /\ a.state = "PANIC" -> [L!Goto(a, "ACTIVE") EXCEPT !.clk = 0]
               [] st = "PANIC" -> [L!Goto(L!Stopped(a), "PANIC") EXCEPT !.silence = 0, !.clk = 0]
               [] OTHER -> [a EXCEPT !.state = "none"]
    IN IF heard THEN [b EXCEPT !.silence = 0] ELSE b
\* RELAY's x: the relayed agent (the target, or the sender when it goes to the master).
FwdMsg(m, s) == IF m.tgt = s.leader THEN [m EXCEPT !.x = m.src] ELSE [m EXCEPT !.x = m.tgt]
\* A LEADER's x is the leader it names (Election.tla reads none): a master's names its sender; a
\* copy of a membership names none (0).  The PC's broadcast copy as it stands is Election's copy to
\* each agent (Teach): to agent me.
Leads(m) == m.x = m.src
CopyTo(m, me) == IF m.dst = E!NoNode /\ m.src = E!PC THEN [m EXCEPT !.dst = me] ELSE m
\* The agent's Election step for record r from s (its id me, its score sv): the set of new local
\* states, empty when the action is not enabled on the agent's own state.  A receive handler not
\* enabled there must be a stutter (the core answering a copy again: a VOTE re-sent, a LEADER of
\* the master it follows), except AcceptRelay and HandlePreVote, which the core takes only where
\* Election enables them (an older offer, a PREVOTE_OK already counted: Ignore).
IfOk(ok, s2) == IF ok THEN {s2} ELSE {}
ElSteps(r, s, me, sv) ==
    LET m == r.em IN
    CASE r.a = "RequestRelay" -> IfOk(E!RequestRelayOk(s), s)
      [] r.a = "StartElection" -> IfOk(E!StartElectionOk(me, s), E!StartElectionNext(me, s))
      [] r.a = "BecomeMaster" ->
           IfOk(E!BecomeMasterOk(s), E!Learned(E!BecomeMasterNext(s), E!Get(s, "members", {}), s.epoch))
      [] r.a = "GrantPreVote" -> IfOk(E!GrantPreVoteOk(me, s, m, m.sc, sv), s)
      [] r.a = "Forward" -> IfOk(E!ForwardOk(me, s, FwdMsg(m, s)), s)
      [] r.a = "OfferRelay" -> {IF E!OfferRelayOk(me, s, m) THEN E!OfferRelayNext(s, m) ELSE s}
      [] r.a = "HandleAccept" -> {IF E!HandleAcceptOk(me, s, m) THEN E!HandleAcceptNext(s, m) ELSE s}
      [] r.a = "AcceptRelay" -> IfOk(E!AcceptRelayOk(me, s, m), E!AcceptRelayNext(s, m))
      [] r.a = "RelayDropped" -> {IF E!RelayDroppedOk(me, s, m) THEN E!RelayDroppedNext(s) ELSE s}
      [] r.a = "HandlePreVote" -> IfOk(E!HandlePreVoteOk(me, s, m), E!HandlePreVoteNext(s, m))
      [] r.a = "HandleElect" ->
           {IF E!HandleElectOk(me, s, m, m.sc, sv) THEN E!HandleElectNext(me, s, m, m.sc, sv) ELSE s}
      [] r.a = "HandleVote" -> {IF E!HandleVoteOk(me, s, m) THEN E!HandleVoteNext(s, m) ELSE s}
      [] r.a = "HandleHeartbeat" ->
           IF ~Leads(m) THEN {}
           ELSE {IF E!HandleHeartbeatOk(me, s, m) THEN E!HandleHeartbeatNext(me, s, m) ELSE s}
      [] r.a = "HandleStale" -> {IF E!HandleStaleOk(me, s, m) THEN E!HandleStaleNext(me, s, m) ELSE s}
      [] r.a = "ShareMembers" -> IfOk(E!ShareMembersOk(me, s, m), s)
      [] r.a = "LearnMembers" ->
           IfOk(m.x = E!NoNode /\ E!LearnMembersOk(me, s, CopyTo(m, me)), E!LearnMembersNext(me, s, CopyTo(m, me)))
      [] OTHER -> {}
\* Agent me following master c in epoch e after a MASTER (bare: the PC, epoch 1; inside EPOCH_CMD: its sender
\* and epoch): Election's rule for hearing c's heartbeat; the lifecycle gives the state.
\* (MASTER carries no membership: the agent keeps the one it knows.)
Synced(me, s, c, e, st) ==
    LET t == [E!HandleHeartbeatNext(me, s, E!M("HB", c, 0, e, 0)) EXCEPT !.life = LifeOf(st, s.life)] IN
    IF WithMembers THEN [t EXCEPT !.members = s.members, !.mepoch = s.mepoch, !.floor = s.floor] ELSE t
\* The rest of the agent's Election state when only the lifecycle moved to a2.
Mirror(s, a2) == [s EXCEPT !.life = LifeOf(a2.state, s.life)]

-----------------------------------------------------------------------------
(* The agent's local state in a check: AgentLogic's ag and Election's el.  *)

InitElOld == [life |-> "IDLE", epoch |-> InitEpoch, votedFor |-> InitVotedFor, votes |-> {}, leader |-> 0,
              following |-> 0, via |-> 0, relays |-> {}, offered |-> {}, prevotes |-> {}]
InitEl == IF WithMembers
          THEN [f \in DOMAIN InitElOld \cup {"members", "mepoch", "floor"} |->
                  IF f = "members" THEN InitMembers ELSE IF f = "mepoch" THEN InitMEpoch
                  ELSE IF f = "floor" THEN InitFloor ELSE InitElOld[f]]
          ELSE InitElOld
ElectionStart == [ag |-> L!InitAgent(TempId), el |-> InitEl]

\* The step to ag = a2, el = s2, if both fit record r (from s).
To(r, s, a2, s2) == {x \in {[ag |-> a2, el |-> s2]} : Fits(r, s.ag, x.ag) /\ FitsEl(r, s.el, x.el)}

ElectionStep(r, s) ==
    LET ag == s.ag
        el == s.el
    IN
    IF r.a = "Tick" THEN
       IF L!TickOk(ag) /\ L!TickOk(Adv(ag, r.n - 1)) THEN To(r, s, L!Tick(Adv(ag, r.n - 1)).ag, el) ELSE {}
    ELSE IF r.a = "ApplyCommand" THEN
       \* EPOCH_CMD of master c in epoch e: the inner datagram goes to AgentLogic's handler r.cmd
       \* (c seen as the master); a MASTER syncs a masterless agent in e, anything else passes the
       \* fence (Election's Obeys: c is the master it follows in e, its highest epoch).
       LET c == r.em.src
           a2 == Received(r.cmd, ag, r.im, c, r.v)
       IN IF ~(/\ ag.state # "OFF" /\ r.em.t = "CMD" /\ r.im.type # "NONE" /\ r.im.src = c
               /\ Handled(ag, r.im, c) = r.cmd) THEN {}
          ELSE IF r.im.type = "MASTER"
          THEN IF r.em.e >= el.epoch
               THEN To(r, s, a2, IF r.cmd = "RecvMaster" THEN Synced(ag.id, el, c, r.em.e, a2.state) ELSE el)
               ELSE {}
          ELSE IF E!Obeys(el, r.em) THEN To(r, s, a2, Mirror(el, a2)) ELSE {}
    ELSE IF r.a \in ElectionActions THEN
       \* An Election action: its rule on the agent's own state (environment guards satisfiable).
       UNION {UNION {To(r, s, Follow(ag, s2, r.a \in {"HandleHeartbeat", "AcceptRelay"} /\ r.em.e >= el.epoch), s2)
                     : s2 \in ElSteps(r, el, ag.id, sv)}
              : sv \in MyScores}
    ELSE IF r.em.t # "NONE" THEN
       \* an Election datagram no Election handler took: the environment's guards may all fail
       IF r.a = "Ignore" THEN To(r, s, ag, el) ELSE {}
    ELSE IF r.m.type # "NONE" THEN
       IF ag.state = "OFF" THEN {}
       ELSE IF BareFenced(el, ag, r.m) THEN (IF r.a = "Ignore" THEN To(r, s, ag, el) ELSE {})
       ELSE IF Handled(ag, r.m, Cur(el)) # r.a THEN {}
       ELSE LET a2 == Received(r.a, ag, r.m, Cur(el), r.v) IN
            To(r, s, a2, IF r.a = "RecvMaster" THEN Synced(ag.id, el, Cur(el), 1, a2.state) ELSE Mirror(el, a2))
    ELSE IF ~IntOk(r, ag) THEN {}
    ELSE LET a2 == Internal(r, ag).ag IN
         IF r.a # "HeartbeatLost" THEN To(r, s, a2, Mirror(el, a2))
         ELSE IF E!TimeoutOk(el) THEN To(r, s, a2, E!TimeoutNext(el))
         ELSE {}
================================================================================
