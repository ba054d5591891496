------------------------- MODULE MCThesisElection --------------------------
(***************************************************************************)
(* The thesis' election with three agents A = 2, B = 3, C = 4 (ids as the *)
(* master assigns them).  The thesis' own example: A and C cannot reach   *)
(* each other (the link is cut both ways) and only B's datagrams may be   *)
(* lost.  Scores: C is the weakest, then A, then B.                        *)
(* Expected: TLC reports AtMostOneMasterInv violated (exit code 12).      *)
(***************************************************************************)
EXTENDS ThesisElection, TLC

MCAgents == {2, 3, 4}
MCScore == (2 :> 10) @@ (3 :> 30) @@ (4 :> 5)
MCCut == {<<2, 4>>, <<4, 2>>}
MCLossyLinks == {<<3, 2>>, <<3, 4>>}
=============================================================================
