---------------------------- MODULE MCReportsReplay ----------------------------
(* Reports with each step's name and what the replay needs of the state     *)
(* before it (lastAction): the model whose full state graph the conformance *)
(* runner replays against the library's reports.hpp and record.hpp         *)
(* (`ev3-conformance replay --model reports`, docs/driver.md "Reports       *)
(* driver").  PCStore is left out: only AckBeforeStore enables it.          *)
EXTENDS Reports

VARIABLE lastAction  \* the step that led here: [name, args]

Did(n, args) == lastAction' = [name |-> n, args |-> args]

ReplayInit == Init /\ lastAction = [name |-> "Init", args |-> <<>>]

\* Send carries what it sends and to whom; TakeAck the acknowledgement taken and whether it came
\* from the master the agent reports to; PCTake the lowest number the agent holds (the REPORT's
\* first field is at most that).
ReplayNext ==
    \/ \E a \in Agents :
        \/ Make(a) /\ Did("Make", <<a>>)
        \/ Send(a) /\ Did("Send", <<a, cur[a], Sent(a)>>)
        \/ Switch(a) /\ Did("Switch", <<a>>)
        \/ Takeover(a) /\ Did("Takeover", <<a>>)
        \/ PCAck(a) /\ Did("PCAck", <<a>>)
    \/ \E a \in Agents, f \in Masters : TakeAck(a, f) /\ Did("TakeAck", <<a, f, acks[a][f], cur[a] = f>>)
    \/ \E m \in net : PCTake(m) /\ Did("PCTake", <<m, lo[m.agent]>>)
    \/ Lose /\ Did("Lose", <<>>)
    \/ PCCrash /\ Did("PCCrash", <<>>)
    \/ PCRestart /\ Did("PCRestart", <<>>)

ReplaySpec == ReplayInit /\ [][ReplayNext]_<<vars, lastAction>>
=============================================================================
