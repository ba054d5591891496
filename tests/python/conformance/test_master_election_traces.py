"""`validate --master` of `ev3-master --election` traces (docs/spec.md "Election master traces"):
MasterLogic composed with Election.tla's rules of the PC (node 1), checked by TLC.

The traces in testdata/ are the two runs of the PC master in the `make demo` run whose agents are
election_demo_agent*.ndjson.gz (tools/demo.py: --agent-timeout-ms 5000, resend 500 ms, 10 resends):
master1 starts fresh (MASTER of epoch 1), registers the three agents, runs the operator's commands and
is killed (SIGKILL); master2 restarts from the state file (next id 5, msgid 4101, epoch 1, members
2,3,4: a CANDIDATE), stands in epoch 2 (one vote), again in epoch 3, wins with the votes of 3 and 2,
adopts the three members as they PING and stops them. They must conform; the same traces with one
record corrupted must be rejected, naming that record. The kinds the demo's PC does not show (HandleStale,
HandleHeartbeat, MasterRoute, MasterHandover) are appended to master2 as the core writes them: the
correct record is accepted, a corrupted one rejected. The Master core an elected agent ran (its records
in the agent's trace, node master:ID:EPOCH) is checked the same way, as node ID."""
from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from ev3conformance import tracecheck

from trace_files import load, nth, write

TIMERS = {"TDrop": 5000, "TResend": 500, "MaxResends": 10}
CONSTS = {
    1: dict(TIMERS, Election=True, Life="MASTER", Epoch=1, Members=[]),
    2: dict(TIMERS, Election=True, Life="CANDIDATE", Epoch=1, Members=[2, 3, 4], NextId=5, FirstMsgid=4101),
}
WHAT = "could not be matched by MasterLogic + Election (the PC's rules)"


def records(run: int) -> list[dict]:
    return load(f"election_demo_master{run}")




def check(tmp_path: Path, run: int, recs: list[dict]):
    return tracecheck.validate_master(write(tmp_path / f"master{run}.ndjson", recs), CONSTS[run])


def rejected_at(r, k: int, n: int) -> None:
    assert not r.ok
    assert f"record {k} of {n} {WHAT}" in r.message, r.message


def test_demo_master_traces_conform(tmp_path):
    for run in (1, 2):
        recs = records(run)
        assert tracecheck.is_master_election_trace(recs)
        r = check(tmp_path, run, recs)
        assert r.ok, r.message
        assert r.records == len(recs) and "election" in r.message
    acts = {r["action"] for r in records(2)}
    assert {"StartElection", "HandleVote", "BecomeMaster", "Heartbeat", "MasterPing", "MasterCommand"} <= acts


def test_a_trace_cut_by_sigkill_is_read_up_to_its_last_whole_record(tmp_path):
    text = "".join(json.dumps(r) + "\n" for r in records(1))
    p = tmp_path / "cut.ndjson"
    p.write_text(text + text.splitlines()[-1][:57])   # the kill cut the next line
    r = tracecheck.validate_master(p, CONSTS[1])
    assert r.ok and r.records == len(records(1)), r.message


def corrupt(recs, action, k, edit):
    recs = copy.deepcopy(recs)
    i = nth(recs, action, k)
    edit(recs[i])
    return recs, i + 1


@pytest.mark.parametrize("run, action, k, edit", [
    # StartElection from epoch 1 claiming epoch 3 (Election: epoch + 1)
    (2, "StartElection", 0, lambda r: r["changed"].update(epoch=3)),
    # the vote of 3 counted twice, as 3 and 9 (9 voted for nobody: votes \cup {m.src})
    (2, "HandleVote", 1, lambda r: r["changed"].update(votes=[3, 9])),
    # a LEADER that draws no msgid
    (1, "Heartbeat", 0, lambda r: r["changed"].pop("msgid")),
    # the member adopted at its PING with the desired state of a fresh entry (must be UNKNOWN)
    (2, "MasterPing", 0, lambda r: r["changed"]["reg"][0].update(desired="ACTIVE")),
    # BecomeMaster into another role
    (2, "BecomeMaster", 0, lambda r: r["changed"].update(life="CANDIDATE")),
])
def test_corrupted_record_is_rejected(tmp_path, run, action, k, edit):
    recs, k1 = corrupt(records(run), action, k, edit)
    rejected_at(check(tmp_path, run, recs), k1, len(recs))


def test_master_without_a_quorum_is_rejected(tmp_path):
    """The vote of epoch 3 that made the PC's quorum (2 of 3 members) removed: BecomeMaster is not enabled."""
    recs = records(2)
    i = nth(recs, "HandleVote", 2)
    recs = recs[:i] + recs[i + 1:]
    rejected_at(check(tmp_path, 2, recs), nth(recs, "BecomeMaster") + 1, len(recs))


def test_fleet_datagram_while_candidate_is_rejected(tmp_path):
    """A MasterPing before BecomeMaster (the core ignores the fleet's datagrams while CANDIDATE)."""
    recs = records(2)
    b, p = nth(recs, "BecomeMaster"), nth(recs, "MasterPing")
    ping = dict(recs[p], now=recs[b - 1]["now"])
    recs = recs[:b] + [ping] + recs[b:]
    rejected_at(check(tmp_path, 2, recs), b + 1, len(recs))


# --- the kinds the demo does not show, appended to master2 (MASTER of epoch 3, members 2, 3, 4, the
# three registered at endpoints 2, 3, 1), at the time of its last record ------------------------------

def appended(extra: dict) -> list[dict]:
    recs = records(2)
    last = recs[-1]
    rec = {"node": "master", "args": {}, "now": last["now"], "changed": {}}
    rec.update(extra)
    return recs + [rec]


def last_reg(recs: list[dict]) -> list[dict]:
    """The registry at the time of the last record (quiet: ms since heard)."""
    r = next(r for r in reversed(recs) if "reg" in r["changed"])
    reg = copy.deepcopy(r["changed"]["reg"])
    for e in reg:
        e["quiet"] += recs[-1]["now"] - r["now"]
    return reg


def last_msgid(recs: list[dict]) -> int:
    return next(r["changed"]["msgid"] for r in reversed(recs) if "msgid" in r["changed"])


def route_record(epoch: int) -> dict:
    reg = last_reg(records(2))
    for e in reg:
        if e["id"] == 4:
            e["ep"] = 3   # agent 4 is reached through relay 3 (its endpoint)
    return {"action": "MasterRoute", "args": {"msg": f"3:1:900637400:24:{epoch}:4"}, "changed": {"reg": reg}}


EXTENSIONS = {
    # HANDOVER(epoch 2, its registry) from the agent-master of epoch 2: the ids join the membership
    "MasterHandover": ({"action": "MasterHandover", "args": {"msg": "2:1:373755700:32:2:2:3:4"}},
                       {"action": "MasterHandover", "args": {"msg": "2:1:373755700:32:4:2:3:4"}}),  # epoch above ours
    # RELAY_ROUTE(3, 4) from relay 3
    "MasterRoute": (route_record(3), route_record(2)),                                          # an old epoch's route
    # EPOCH_STALE(5): a newer epoch exists, the PC stands again, without the votes of its epoch
    # (Election.tla HandleStaleNext clears them)
    "HandleStale": ({"action": "HandleStale", "args": {"msg": "3:1:900637401:30:5"},
                     "changed": {"life": "CANDIDATE", "epoch": 5, "votes": []}},
                    {"action": "HandleStale", "args": {"msg": "3:1:900637401:30:5"},
                     "changed": {"life": "MASTER", "epoch": 5, "votes": []}}),                                   # stays MASTER
    # LEADER of epoch 2 (older): answered EPOCH_STALE (a msgid), nothing else changes
    "HandleHeartbeat": ({"action": "HandleHeartbeat", "args": {"msg": "2:0:373755701:29:2:2:2:3:4"},
                         "changed": {"msgid": last_msgid(records(2)) + 1}},
                        {"action": "HandleHeartbeat", "args": {"msg": "2:0:373755701:29:2:2:2:3:4"},
                         "changed": {"msgid": last_msgid(records(2)) + 1, "epoch": 2}}),            # adopts it
}


@pytest.mark.parametrize("kind", sorted(EXTENSIONS))
def test_appended_record_checked(tmp_path, kind):
    good, bad = EXTENSIONS[kind]
    r = check(tmp_path, 2, appended(good))
    assert r.ok, r.message
    recs = appended(bad)
    rejected_at(check(tmp_path, 2, recs), len(recs), len(recs))


def test_a_newer_leader_makes_the_pc_stand(tmp_path):
    """LEADER of epoch 4 (docs/core.md deviation 4): HandleStale's rule with its epoch."""
    ok = appended({"action": "HandleHeartbeat", "args": {"msg": "2:0:373755702:29:4:2:2:3:4"},
                   "changed": {"life": "CANDIDATE", "epoch": 4, "votes": []}})
    r = check(tmp_path, 2, ok)
    assert r.ok, r.message


# --- the Master core an elected agent runs (ev3-agent --election --trace: node master:ID:EPOCH) ---------
# election_demo_agent_master: agent #1 (id 2) of a later `make demo` run, master of epoch 2 (members 2,
# 3, 4): heartbeats, the route of agent 4 through relay 3 (RELAY_ROUTE), its --master-script's
# commands, PINGs and answers (agent 4's through the relay), then the PC's ELECT of epoch 3: it steps
# down (HandleElect).

def agent_master_records() -> list[dict]:
    return load("election_demo_agent_master")


def agent_master_consts(recs: list[dict]) -> dict:
    return dict(TIMERS, TDrop=10000, Election=True, Self=2, Epoch=2, Life="MASTER", Members=[2, 3, 4],
                NextId=50000, FirstMsgid=recs[0]["changed"]["msgid"] - 1)


def check_agent_master(tmp_path: Path, recs: list[dict]):
    p = write(tmp_path / "agent1.ndjson", recs)
    runs = tracecheck.agent_master_runs(p)
    assert [n for n, _ in runs] == ["master:2:2"]
    return tracecheck.validate_master(p, agent_master_consts(recs), node="master:2:2")


def test_agent_master_trace_conforms(tmp_path):
    recs = agent_master_records()
    assert {"Heartbeat", "MasterRoute", "MasterCommand", "MasterPing", "HandleElect"} <= {r["action"] for r in recs}
    r = check_agent_master(tmp_path, recs)
    assert r.ok and r.records == len(recs), r.message


def test_an_agent_master_starts_with_the_membership_a_peer_taught_it(tmp_path):
    """The Master core's membership is the newest LEADER its agent core took, from the master
    (HandleHeartbeat) or a peer's copy (LearnMembers, leader 0): here the copy of epoch 7 lists agent
    6, which the PC's LEADER of epoch 6 did not (a run of the lossy PC-killed black-box test: the
    core's PING from agent 6 was refused by a check started with the older list)."""
    recs = [
        {"node": "agent", "action": "HandleHeartbeat", "args": {"msg": "1:0:413304634:29:6:1:2:3:4:5"},
         "now": 10, "changed": {"members": [2, 3, 4, 5], "mepoch": 6, "floor": 6}},
        {"node": "agent", "action": "LearnMembers", "args": {"msg": "5:3:11787827:29:7:0:2:3:4:5:6"},
         "now": 11, "changed": {"members": [2, 3, 4, 5, 6], "mepoch": 7, "floor": 7}},
        {"node": "agent", "action": "HandleHeartbeat", "args": {"msg": "1:0:413304635:29:6:1:2:3:4:5"},
         "now": 12, "changed": {}},  # a late copy of the older LEADER changes nothing
        {"node": "master:3:8", "action": "Heartbeat", "args": {}, "now": 20, "msgid_from": 100,
         "changed": {"msgid": 101}},
    ]
    p = write(tmp_path / "agent1.ndjson", recs)
    (node, c), = tracecheck.agent_master_runs(p)
    assert node == "master:3:8" and c["Members"] == [2, 3, 4, 5, 6] and c["Epoch"] == 8 and c["Self"] == 3


@pytest.mark.parametrize("action, edit", [
    # steps down to epoch 4 on an ELECT of epoch 3
    ("HandleElect", lambda r: r["changed"].update(epoch=4)),
    # the route of an older epoch's relay (RELAY_ROUTE(1, 4))
    ("MasterRoute", lambda r: r["args"].update(msg=r["args"]["msg"].replace(":24:2:", ":24:1:"))),
])
def test_corrupted_agent_master_record_is_rejected(tmp_path, action, edit):
    recs, k = corrupt(agent_master_records(), action, 0, edit)
    rejected_at(check_agent_master(tmp_path, recs), k, len(recs))


def test_agent_master_heartbeat_after_stepping_down_is_rejected(tmp_path):
    recs = agent_master_records()
    hb = dict(recs[nth(recs, "Heartbeat")], now=recs[-1]["now"] + 1000, changed={"msgid": last_msgid(recs) + 1})
    recs = recs + [hb]
    rejected_at(check_agent_master(tmp_path, recs), len(recs), len(recs))


def taught(recs: list[dict], first: int = 4101) -> list[dict]:
    """@p recs (a PC's records, msgids from @p first) as a core since the PC stands with a copy of
    its membership (Election Teach) writes them: each StartElection draws the copy's msgid before
    ELECT's, so every msgid of the PC from then on is one higher per StartElection before it (the
    next msgid, msgid_from, the entries' pending mid, and the ACK / NOT answering one)."""
    stood = [r["changed"]["msgid"] - 1 for r in recs if r["action"] == "StartElection"]  # ELECT's old msgid

    def new(m: int) -> int:
        return m + sum(1 for x in stood if x <= m) if m >= first else m

    out = copy.deepcopy(recs)
    for r in out:
        ch = r["changed"]
        if "msgid" in ch:
            ch["msgid"] = new(ch["msgid"] - 1) + 1
        if "msgid_from" in r:
            r["msgid_from"] = new(r["msgid_from"]) - (1 if r["action"] == "StartElection" else 0)
        for e in ch.get("reg", []):
            e["mid"] = new(e["mid"])
        msg = r.get("args", {}).get("msg")
        if msg:
            f = msg.split(":")
            if f[3] in ("3", "4") and f[1] == "1":  # ACK / NOT to the PC: its first param is our msgid
                f[4] = str(new(int(f[4])))
                r["args"]["msg"] = ":".join(f)
    return out


def reconfigured(added: list[int], teach: bool = True) -> list[dict]:
    """master2 as the core writes it (its BecomeMaster records the membership's epoch,
    mepoch 3; each StartElection sends a copy of the membership first: taught), then HANDOVER(2, 6, 5)
    from the agent-master of epoch 2: the PC wants 5 and 6 besides its list 2, 3, 4, stands in epoch 4
    (Reconfigure, StartElection: the copy and ELECT), gets the votes of 2 and 3 and publishes 2, 3, 4
    and @p added (BecomeMaster). Without @p teach its last StartElection sends ELECT alone (the core
    before Teach)."""
    recs = taught(records(2))
    recs[nth(recs, "BecomeMaster")]["changed"]["mepoch"] = 3
    now, mid = recs[-1]["now"], last_msgid(recs)
    extra = [
        {"action": "MasterHandover", "args": {"msg": "2:1:373755700:32:2:6:5"}, "changed": {}},
        {"action": "Reconfigure", "args": {}, "changed": {"life": "CANDIDATE"}},
        {"action": "StartElection", "args": {}, "changed": {"msgid": mid + 1 + int(teach), "epoch": 4, "votes": []}},
        {"action": "HandleVote", "args": {"msg": "2:1:900637500:28:4:1"}, "changed": {"votes": [2]}},
        {"action": "HandleVote", "args": {"msg": "3:1:900637501:28:4:1"}, "changed": {"votes": [2, 3]}},
        {"action": "BecomeMaster", "args": {},
         "changed": {"msgid": mid + 2 + int(teach), "life": "MASTER", "members": [2, 3, 4] + added, "mepoch": 4}},
    ]
    return recs + [dict(r, node="master", now=now) for r in extra]


def test_reconfigure_publishes_the_lowest_wanted_id(tmp_path):
    """Election.tla's BecomeMaster may publish any one-step list (OneStep: 2, 3, 4 and 5, or 2, 3, 4
    and 6); the master core adds the lowest id wanted (master.hpp OneStep) and the check pins that
    choice (MasterElectionTrace CodeStep): 6 first is rejected at BecomeMaster, as is a list the
    record does not claim (the membership unchanged)."""
    r = check(tmp_path, 2, reconfigured([5]))
    assert r.ok, r.message
    for bad in ([6], []):
        recs = reconfigured(bad)
        rejected_at(check(tmp_path, 2, recs), len(recs), len(recs))


def test_the_pc_stands_with_a_copy_of_its_membership(tmp_path):
    """The PC with a membership stands with a copy of it, LEADER(mepoch, 0, members...), before its
    ELECT (Election Teach): its StartElection draws two msgids (MasterElectionTrace Stood). A core
    that sends ELECT alone is rejected at that StartElection."""
    recs = reconfigured([5], teach=False)
    rejected_at(check(tmp_path, 2, recs), nth(recs, "StartElection", -1) + 1, len(recs))
