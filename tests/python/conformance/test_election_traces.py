"""`validate` of `ev3-agent --election` traces (docs/spec.md "Election traces"): AgentLogic composed with
Election.tla's per-agent rules, checked by TLC.

The traces in testdata/ are the three agents of one `make demo` run (tools/demo.py: heartbeat 200 ms,
master timeout 1000 ms, paused timeout 2000 ms, scores 1 / 20 / 40, fresh --state-dir): #1 loses the
PC, stands, wins epoch 2 and steps down when the PC takes epoch 3; #2 relays for #3 (offers, accepts,
226 forwarded datagrams) and follows #1, then the PC; #3 is relayed through #2 in epochs 1 and 2 and
runs #1's commands (EPOCH_CMD through the relay). They must conform; the same traces with one election
record corrupted must be rejected, naming that record."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from ev3conformance import tracecheck

from trace_files import load, nth, write

SCORES = {1: 1, 2: 20, 3: 40}


def consts(agent: int) -> dict:
    return {"TPing": 200, "TLoss": 1000, "TPaused": 2000, "Score": SCORES[agent], "Epoch": 1, "VotedFor": 0}


def records(agent: int) -> list[dict]:
    return load(f"election_demo_agent{agent}")




def test_demo_election_traces_conform(tmp_path):
    paths = [write(tmp_path / f"agent{a}.ndjson", records(a)) for a in (1, 2, 3)]
    for a, p in zip((1, 2, 3), paths):
        assert tracecheck.is_election_trace(records(a))
    results = [tracecheck.validate(p, consts(a)) for a, p in zip((1, 2, 3), paths)]
    for r in results:
        assert r.ok, r.message
        assert "election" in r.message
    assert [r.records for r in results] == [len(records(a)) for a in (1, 2, 3)]


def corrupt(recs: list[dict], action: str, key: str, value, k: int = 0) -> tuple[list[dict], int]:
    recs = [dict(r, changed=dict(r["changed"])) for r in recs]
    i = nth(recs, action, k)
    recs[i]["changed"][key] = value
    return recs, i + 1


@pytest.mark.parametrize("agent, action, key, value", [
    (1, "StartElection", "epoch", 3),          # stands in epoch 3 from epoch 1
    (3, "AcceptRelay", "via", 2),              # follows through another agent than the offer's sender
    (2, "HandleAccept", "offered", [4]),       # keeps the offer it has just taken
])
def test_corrupted_election_record_is_rejected(tmp_path, agent, action, key, value):
    recs, k = corrupt(records(agent), action, key, value)
    r = tracecheck.validate(write(tmp_path / "bad.ndjson", recs), consts(agent))
    assert not r.ok
    assert f"record {k} of {len(recs)} could not be matched by AgentLogic + Election" in r.message, r.message


def test_election_without_a_quorum_is_rejected(tmp_path):
    """The vote that made #1's quorum removed: its BecomeMaster is not enabled (Quorum of votes)."""
    recs = records(1)
    i = nth(recs, "HandleVote")
    recs = recs[:i] + recs[i + 1:]
    k = nth(recs, "BecomeMaster") + 1
    r = tracecheck.validate(write(tmp_path / "bad.ndjson", recs), consts(1))
    assert not r.ok and f"record {k} of" in r.message, r.message
