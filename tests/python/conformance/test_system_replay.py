"""The election replay (ev3conformance.system_replay, the second half of `ev3-conformance replay
--model fleet`): seeded TLC -simulate traces of MCSystemSim (System.tla: the PC's epochs, relay,
pre-vote, election, HANDOVER, a lossy duplicating network) replayed against the PC's, three agents'
and the elected agents' Master cores' drivers. The traces must conform and contain what they are
there for (elections, relay, HANDOVER, votes refused); an implementation that grants two votes in
one epoch, does not fence an older epoch, or sends no HANDOVER must be caught."""
from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from ev3conformance import sim_replay
from ev3conformance import system_replay as sr

REPO = Path(__file__).resolve().parents[3]
BIN = Path(os.environ.get("EV3_BIN") or REPO / "build" / "bin")
AGENT = [str(BIN / "ev3-agent"), "--driver"]
MASTER = [str(BIN / "ev3-master"), "--driver"]
FAKE = [sys.executable, str(Path(__file__).with_name("fake_election_driver.py"))]


@pytest.fixture(scope="module")
def traces(tmp_path_factory):
    files, _ = sim_replay.simulate(sr.SIM_MODULE, sr.SIM_CFG, "system-sim", seed=5, num=12, depth=150,
                                   out_dir=tmp_path_factory.mktemp("system-sim"))
    assert len(files) == 12
    return [sim_replay.read_trace(p) for p in files]


def _run(traces, agent=AGENT, master=MASTER) -> sr.SystemFigures:
    return sr.SystemReplay(agent, master).run((None, t) for t in traces)


def _count(traces, name: str) -> int:
    return sum(1 for t in traces for s in t[1:] if s["lastAction"][0] == name)


def test_election_traces_conform(traces):
    f = _run(traces)
    assert not f.classes, "\n".join(rep for _, rep in f.classes.values())
    assert f.traces == 12 and f.matched == f.steps == sum(len(t) - 1 for t in traces)
    # The traces exercise the election, not only ticks: the PC lost and back, pre-votes, candidacies,
    # votes (and votes refused), agents and the PC elected, relays, HANDOVER sent and taken.
    for name in ("Crash", "Restart", "GrantPreVote", "HandlePreVote", "StartElection", "HandleElect",
                 "HandleVote", "Ignore", "BecomeMaster", "OfferRelay", "AcceptRelay", "HandleAccept",
                 "ShareMembers", "MasterHandover", "Lose", "Timeout", "Tick", "Refresh"):
        assert f.actions[name] > 0, name
        assert f.actions[name] == _count(traces, name)
    assert f.elected > 0 and f.pc_elected > 0 and f.handed > 0 and f.handovers > 0
    # the PC hears an elected agent's LEADER (Election's HandleHeartbeat of the PC)
    assert any(s["lastAction"][0] == "HandleHeartbeat" and s["lastAction"][1] == sr.PC for t in traces for s in t[1:])
    # late datagrams: a datagram of an older epoch delivered (answered EPOCH_STALE)
    assert any(s["lastAction"][0] == "HandleElect" and s["lastAction"][2]["e"] < sr.at(t[k - 1]["epoch"], s["lastAction"][1])
               for t in traces for k, s in enumerate(t) if k)
    assert f.late > 0 and f.again > 0


@pytest.mark.parametrize("fault, action, fields", [
    ("double-vote", "Ignore", ("emitted",)),
    ("ignore-epoch", "HandleElect", ("emitted",)),
])
def test_a_broken_agent_is_caught(traces, fault, action, fields):
    f = _run(traces, agent=FAKE + [fault] + AGENT)
    assert f.mismatched_traces > 0 and f.matched < f.steps
    assert (action, fields) in f.classes, list(f.classes)
    rep = f.classes[(action, fields)][1]
    assert "implementation emitted, not in the spec's net" in rep and "the trace up to here" in rep
    if fault == "double-vote":
        assert "VOTE" in rep.split("implementation emitted, not in the spec's net:")[1].splitlines()[0]


def test_an_elected_agent_that_does_not_hand_over_is_caught(traces):
    f = _run(traces, master=FAKE + ["no-handover"] + MASTER)
    assert ("HandleHeartbeat", ("emitted",)) in f.classes, list(f.classes)
    rep = f.classes[("HandleHeartbeat", ("emitted",))][1]
    assert "spec emits, implementation did not: HANDOVER" in rep
