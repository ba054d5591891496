"""The election scenarios of `ev3-conformance mutate` (mutate.election_scripts: one agent with the
election on, among the PC and three agents: relay, pre-votes, standing, votes, stepping down, fenced
and stale commands, a master change, a candidate counting) run through `ev3-agent --driver`, each
trace validated by TLC against AgentLogic composed with Election.tla's per-agent rules. They must
conform (else every election mutant would count as caught); each takes the handlers it is there for;
a trace with one record changed is rejected."""
from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

from ev3conformance import mutate, tracecheck

REPO = Path(__file__).resolve().parents[3]
BIN = Path(os.environ.get("EV3_BIN") or REPO / "build" / "bin")


def run(name: str, tmp_path: Path) -> Path:
    trace = tmp_path / f"{name}.ndjson"
    inp = "\n".join(json.dumps(i) for i in mutate.election_scripts()[name]) + "\n"
    p = subprocess.run([str(BIN / "ev3-agent"), "--driver", "--trace", str(trace)], input=inp, text=True,
                       capture_output=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert all("error" not in json.loads(line) for line in p.stdout.splitlines()), p.stdout
    return trace


@pytest.mark.parametrize("name, wanted", [
    ("relay-elect-fence", {"OfferRelay", "HandleAccept", "Forward", "GrantPreVote", "HandlePreVote",
                           "StartElection", "HandleVote", "BecomeMaster", "HandleElect", "HandleHeartbeat",
                           "ApplyCommand", "HandleStale"}),
    ("relayed", {"AcceptRelay", "RelayDropped", "HandleStale", "ApplyCommand"}),
    ("master-change", {"HandleAccept", "RecvStart", "HandleHeartbeat"}),
    ("candidate", {"HandlePreVote", "StartElection", "HandleVote", "BecomeMaster"}),
])
def test_election_scenario_conforms(tmp_path, name, wanted):
    trace = run(name, tmp_path)
    actions = {json.loads(line)["action"] for line in trace.read_text().splitlines()}
    assert wanted <= actions, wanted - actions
    r = tracecheck.validate(trace, mutate.ELECTION_CONSTS, workdir=tmp_path)
    assert r.ok, r.message
    assert "election" in r.message


def test_a_changed_record_is_rejected(tmp_path):
    trace = run("relayed", tmp_path)
    recs = [json.loads(line) for line in trace.read_text().splitlines()]
    k = next(i for i, r in enumerate(recs) if r["action"] == "AcceptRelay")
    recs[k]["changed"]["via"] = 9  # follows through another agent than the offer's sender (8)
    trace.write_text("".join(json.dumps(r) + "\n" for r in recs))
    r = tracecheck.validate(trace, mutate.ELECTION_CONSTS, workdir=tmp_path)
    assert not r.ok
    assert f"record {k + 1} of {len(recs)}" in r.message, r.message


def _drive(inputs: list[dict]) -> list[dict]:
    inp = "\n".join(json.dumps(i) for i in inputs) + "\n"
    p = subprocess.run([str(BIN / "ev3-agent"), "--driver"], input=inp, text=True, capture_output=True, timeout=60)
    assert p.returncode == 0, p.stderr
    return [json.loads(line) for line in p.stdout.splitlines()]


def test_the_driver_restores_the_membership_of_its_state():
    """config's election object carries the membership the agent's state keeps (members,
    members_epoch, floor), as ev3-agent restores it from DIR/ev3-agent.state: a synced agent that
    knows the list of epoch 1 answers a peer that knows none with a copy of it (ShareMembers)."""
    cfg = {"type": "config", "timers": mutate.ELECTION_TIMERS, "behaviours": [{"name": "wait", "devices": 0}],
           "temp_id": 50001, "election": {"enabled": True, "score": 5, "epoch": 1, "members": [7, 8, 9],
                                          "members_epoch": 1, "floor": 1}}
    rx = lambda text: {"type": "recv", "from": int(text.split("->")[0]),  # noqa: E731
                       "text": mutate.datagram(text).decode("latin-1")}
    out = _drive([cfg, {"type": "advance", "ms": 100}, rx("1->7 MASTER #20 50001"), rx("9->0 RELAY_REQ #5 1 30 0")])
    assert all("error" not in o for o in out), out
    sent = [s["text"] for s in out[-1]["sent"]]
    assert any(":".join(["7", "9"]) in t and t.endswith(":1:0:7:8:9") for t in sent), sent


@pytest.mark.parametrize("membership, said", [
    ({"members": [7, 8], "members_epoch": 2, "floor": 1}, "election: floor: 1 is below members_epoch 2"),
    ({"members": [7, 8], "members_epoch": 4, "floor": 4}, "election: members_epoch: 4 is above epoch 3"),
    ({"members": [7, 1]}, "election: members: 1 is not an agent id 2..49999"),
    ({"members": [7, 8]}, "election: members_epoch: missing, but members lists agents"),
])
def test_the_driver_refuses_a_damaged_membership(membership, said):
    cfg = {"type": "config", "election": {"enabled": True, "epoch": 3, **membership}}
    out = _drive([cfg])
    assert said in out[0].get("error", ""), out


def _teach_trace(tmp_path: Path) -> Path:
    """agent 7 follows the PC (list 7, 8, 9 of epoch 1); the PC's ELECT of epoch 3 counts against the
    list of epoch 2, which 7 never heard: no vote (Election Knows); the PC's broadcast copy of that
    list, LEADER(2, 0, 7, 8, 9, 10), teaches it (LearnMembers of Election's copy to 7: Teach); the
    PC's ELECT of epoch 4 gets its vote."""
    trace = tmp_path / "teach.ndjson"
    cfg = {"type": "config", "timers": mutate.ELECTION_TIMERS, "behaviours": [{"name": "wait", "devices": 0}],
           "temp_id": 50001, "election": {"enabled": True, "score": 5}}
    rx = lambda text: {"type": "recv", "from": int(text.split("->")[0]),  # noqa: E731
                       "text": mutate.datagram(text).decode("latin-1")}
    inp = [cfg, {"type": "advance", "ms": 100}, rx("1->7 MASTER #20 50001"), rx("1->0 LEADER #21 1 1 7 8 9"),
           rx("1->0 ELECT #25 3 0 2"), rx("1->0 LEADER #26 2 0 7 8 9 10"), rx("1->0 ELECT #27 4 0 2")]
    p = subprocess.run([str(BIN / "ev3-agent"), "--driver", "--trace", str(trace)],
                       input="\n".join(json.dumps(i) for i in inp) + "\n", text=True, capture_output=True, timeout=60)
    assert p.returncode == 0, p.stderr
    out = [json.loads(line) for line in p.stdout.splitlines()]
    assert all("error" not in o for o in out), out
    assert [s["text"] for s in out[-3]["sent"]] == []  # ELECT of epoch 3: no VOTE
    assert any(":28:4:1" in s["text"] for s in out[-1]["sent"])  # VOTE(4, 1)
    return trace


def test_the_pc_teaches_its_membership_before_a_vote(tmp_path):
    """The agent's trace of Knows and Teach conforms; the same trace with the copy broadcast by an
    agent (Election has none: only the PC broadcasts its list) or with a vote for the PC's ELECT of
    epoch 3 (a list the agent does not know) is rejected at that record."""
    trace = _teach_trace(tmp_path)
    recs = [json.loads(line) for line in trace.read_text().splitlines()]
    assert [r["action"] for r in recs][-3:] == ["HandleElect", "LearnMembers", "HandleElect"]
    r = tracecheck.validate(trace, mutate.ELECTION_CONSTS, workdir=tmp_path)
    assert r.ok, r.message
    n = len(recs)
    for k, edit in ((n - 2, lambda x: x["args"].update(msg="9" + x["args"]["msg"][1:])),
                    (n - 3, lambda x: x["changed"].update(votedFor=1))):
        bad = json.loads(json.dumps(recs))
        edit(bad[k])
        trace.write_text("".join(json.dumps(x) + "\n" for x in bad))
        r = tracecheck.validate(trace, mutate.ELECTION_CONSTS, workdir=tmp_path)
        assert not r.ok and f"record {k + 1} of {n}" in r.message, r.message
