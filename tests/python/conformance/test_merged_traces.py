"""Whole-run trace validation (`ev3-conformance merged`, docs/spec.md "Whole-run traces"): the traces
of every node of one run merged into one behaviour by send/receive and checked by TLC against the
composed spec's own invariants (System.tla and Election.tla INSTANCEd in spec/tla/trace/MergedTrace.tla).

testdata/merged_demo/ is one `make demo` run (tools/demo.py): agents #1-#3 (agent1..3; #1 wins epoch
2 and runs a Master core, node master:ID:2 in its trace), the PC's first run (killed) and its second
(restarted from its state file in epoch 2: stands, wins epoch 3). The run must conform; the same run
with the Master core handing over and staying master must fail naming the record, and so must make
spec's black-box run (spec/tla/trace/samples/run) with a second master planted in an epoch, with an
agent obeying an EPOCH_CMD of an older epoch, or with an agent following a node that was not elected
(the other faults of merged.PLANTS are planted in that run by make spec); every invariant
checked has a fault planted for it; a cycle of the happens-before graph and a receive from outside the
traced nodes are shown with hand-made traces."""
from __future__ import annotations

import gzip
import json
import subprocess
import sys
from pathlib import Path

import pytest

from ev3conformance import merged

from trace_files import DATA, write

RUN = DATA / "merged_demo"
EPOCHS = {"master2.ndjson:master": 2}   # the PC's second run starts from its state file: epoch 2
LOSS = 1000          # the demo's --master-timeout-ms (tools/demo.py)
SAMPLE_LOSS = 400    # the black-box tests' (ev3net.LOSS): make spec's sample run
SAMPLE_RUN = merged.tracecheck.SAMPLES / "run"


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    """The stored demo run, unpacked."""
    d = tmp_path_factory.mktemp("run")
    for f in sorted(RUN.glob("*.ndjson.gz")):
        (d / f.name[:-3]).write_bytes(gzip.decompress(f.read_bytes()))
    return d


def test_the_demo_run_conforms(run):
    r = merged.validate([run], EPOCHS, loss=LOSS)
    assert r.ok, r.message
    m = merged.merge([run], EPOCHS)
    assert r.records == len(m.order) == sum(len(p.read_text().splitlines()) for p in run.glob("*.ndjson"))
    assert r.nodes == 6 and len(m.agents) == 3
    # nearly every receive was matched with its send; the ones from outside are counted in the summary
    assert m.pairs > 1000 and "receives from outside the traced nodes" in r.message


def test_the_merge_keeps_each_process_order_and_puts_receives_after_sends(run):
    m = merged.merge([run], EPOCHS)
    place = {(x.file, x.k): i for i, x in enumerate(m.order)}
    for x in m.order:
        if x.k > 0:
            assert place[(x.file, x.k - 1)] < place[(x.file, x.k)]
    # every LEADER an agent took comes after the BecomeMaster of the node that sent it (or is the PC's)
    became = {}
    for i, x in enumerate(m.order):
        if x.r["action"] == "BecomeMaster" and x.node == "agent":
            became.setdefault(m.label(x), i)
    assert len(became) == 1
    (winner, at), = became.items()
    hb = [i for i, x in enumerate(m.order) if x.r["action"] == "HandleHeartbeat" and x.node == "agent"
          and x.r["args"]["msg"].split(":")[0] not in ("1",) and m.label(x) != winner]
    assert hb and min(hb) > at


def test_a_command_obeyed_from_a_stale_master_fails_naming_the_agent_and_record(tmp_path):
    # make spec's black-box run: agent #3's EPOCH_CMD of node 2 in epoch 2 lowered to epoch 1
    where = merged.plant([SAMPLE_RUN], tmp_path / "bad", "stale-command", SAMPLE_LOSS)
    r = merged.validate([tmp_path / "bad"], loss=SAMPLE_LOSS)
    assert not r.ok
    assert "a command obeyed from a stale master (StaleMasterFenced" in r.message, r.message
    assert where.split(" (")[0] in r.message, (where, r.message)
    assert "agent2.nd:agent obeyed a command of node 2 in epoch 1: epoch 1 is older than the newest the agent " \
           "has seen (2)" in r.message, r.message


def test_a_master_core_that_hands_over_and_stays_master_fails_naming_the_record(run, tmp_path):
    # agent #1's Master core of epoch 2 steps down on the PC's ELECT of epoch 3; planted: it takes a
    # LEADER of epoch 3 instead, sends HANDOVER and stays master (the run has no HANDOVER of its own)
    where = merged.plant([run], tmp_path / "bad", "handover-keeps-master", LOSS)
    r = merged.validate([tmp_path / "bad"], EPOCHS, loss=LOSS)
    assert not r.ok
    assert r.message.startswith("a master that handed over is still master of an older epoch "
                                "(HandoverStepsDownInv)"), r.message
    assert where.split(" (")[0] in r.message and "node 2 handed the fleet over to the master of epoch 3" in r.message


def test_each_fault_is_planted_for_one_invariant_of_the_composed_spec():
    # make spec plants the faults of its sample run (tracemodules.check_modules, samples.json); this file
    # plants two-masters (test_the_command_line), stale-command and handover-keeps-master
    cfg = (merged.tracecheck.TRACE_SPEC / "MCMergedTrace.cfg").read_text()
    # FollowersAgreeInv: test_an_agent_following_a_node_not_elected_fails_naming_it
    assert set(merged.PLANT_INVARIANT.values()) | {"FollowersAgreeInv"} == {w for w in cfg.split() if w.endswith("Inv")}
    sample = json.loads((merged.tracecheck.SAMPLES / "samples.json").read_text())["samples"]
    by_spec = {f for s in sample if "run" in s for f in s["plants"]}
    here = {"two-masters", "stale-command", "handover-keeps-master"}
    assert not by_spec & here and by_spec | here == set(merged.PLANTS)


def test_an_agent_following_a_node_not_elected_fails_naming_it(tmp_path):
    # make spec's black-box run: agent #3's last LEADER of the new master (id 2) recorded as one of id 3
    sample = merged.tracecheck.SAMPLES / "run"
    (tmp_path / "bad").mkdir()
    for f in sample.glob("*.nd"):
        rs = [json.loads(x) for x in f.read_text().splitlines() if x.strip()]
        if f.name == "agent3.nd":
            k = max(i for i, r in enumerate(rs) if r.get("changed", {}).get("leader") == 2)
            rs[k]["changed"]["leader"] = 3
        write(tmp_path / "bad" / f.name, rs)
    r = merged.validate([tmp_path / "bad"], loss=SAMPLE_LOSS)
    assert not r.ok
    assert "an agent follows a node that is not the master of its epoch (FollowersAgree" in r.message, r.message
    assert f"agent3.nd record {k + 1} " in r.message and "agent3.nd:agent follows node 3 in epoch 2" in r.message


def _rec(node, action, msg=None, changed=None):
    return {"node": node, "action": action, "args": {"msg": msg} if msg else {}, "now": 0, "changed": changed or {}}


def test_a_cycle_is_an_error_naming_its_records(tmp_path):
    # the agent takes the master's PONG (msgid 5) before it sends the PING (its msgid 10) that the
    # master answers before sending msgid 5: impossible, whatever the clocks said
    write(tmp_path / "a.ndjson", [_rec("agent", "RecvPong", "1:2:5:6:10"), _rec("agent", "Tick", changed={"id": 2, "msgid": 11})])
    write(tmp_path / "m.ndjson", [_rec("master", "MasterPing", "2:1:10:5:ACTIVE"), _rec("master", "MasterTick",
                                                                                        changed={"msgid": 6})])
    with pytest.raises(merged.MergeError) as e:
        merged.merge([tmp_path])
    msg = str(e.value)
    assert "has a cycle" in msg
    for f, k in (("a.ndjson", 1), ("a.ndjson", 2), ("m.ndjson", 1), ("m.ndjson", 2)):
        assert f"{f} record {k} " in msg, msg
    r = merged.validate([tmp_path])
    assert not r.ok and "cannot merge the traces: the happens-before graph has a cycle" in r.message


def test_what_a_reports_record_sends_is_sent_where_it_was_not_later(tmp_path):
    # The agent's TakeAck (Reports.tla: left out of the walk) sends msgid 11 (a REPORT its window
    # lets go); the master takes it, then sends msgid 5, which the agent receives before its next
    # Tick sends msgid 12. Counting msgid 11 as that Tick's would make a cycle.
    write(tmp_path / "a.ndjson", [_rec("agent", "Tick", changed={"id": 2, "msgid": 11}),
                                  _rec("agent", "TakeAck", "1:2:0:42:3", changed={"msgid": 12}),
                                  _rec("agent", "RecvPong", "1:2:5:6:10"),
                                  _rec("agent", "Tick", changed={"msgid": 13})])
    write(tmp_path / "m.ndjson", [_rec("master", "MasterPing", "2:1:11:5:ACTIVE"),
                                  _rec("master", "MasterTick", changed={"msgid": 6})])
    m = merged.merge([tmp_path])
    order = [(m.files[x.file].name, x.k) for x in m.order]
    assert order.index(("a.ndjson", 0)) < order.index(("m.ndjson", 0)) < order.index(("m.ndjson", 1)) \
        < order.index(("a.ndjson", 1)), order   # a.ndjson's TakeAck is left out: its RecvPong is record 1


def test_a_receive_from_outside_the_traced_nodes_is_reported(tmp_path):
    write(tmp_path / "a.ndjson", [_rec("agent", "Ignore", "9:0:77:19"), _rec("agent", "RecvPong", "1:2:5:6:10")])
    write(tmp_path / "m.ndjson", [_rec("master", "MasterTick", changed={"msgid": 6})])
    m = merged.merge([tmp_path])
    assert m.pairs == 1 and dict(m.outside) == {9: 1}
    assert [(m.files[x.file].name, x.k) for x in m.order][-1] == ("a.ndjson", 1)   # after the master's send
    assert "1 receives from outside the traced nodes (by sender id: 9 (1))" in merged.summary(m)


def test_the_command_line(tmp_path):
    # the smaller run make spec checks (spec/tla/trace/samples/run: a black-box election test's)
    sample = merged.tracecheck.SAMPLES / "run"
    ok = subprocess.run([sys.executable, "-m", "ev3conformance.cli", "merged", str(sample),
                         "--master-timeout-ms", str(SAMPLE_LOSS)],
                        capture_output=True, text=True)
    assert ok.returncode == 0 and "merged: conforms" in ok.stdout, ok.stdout + ok.stderr
    # a second master planted in an epoch: both named
    where = merged.plant([sample], tmp_path / "bad", "two-masters", SAMPLE_LOSS)
    bad = subprocess.run([sys.executable, "-m", "ev3conformance.cli", "merged", str(tmp_path / "bad"),
                          "--master-timeout-ms", str(SAMPLE_LOSS)], capture_output=True, text=True)
    assert bad.returncode == 1 and "merged: DOES NOT CONFORM" in bad.stdout, bad.stdout + bad.stderr
    assert "two masters in one epoch (AtMostOneMasterPerEpochInv)" in bad.stdout, bad.stdout
    assert where.split(" (")[0] in bad.stdout and bad.stdout.count("became master of epoch 2") == 2, bad.stdout
    usage = subprocess.run([sys.executable, "-m", "ev3conformance.cli", "merged", str(sample), "--epoch", "x"],
                           capture_output=True, text=True)
    assert usage.returncode == 2 and "expected FILE:NODE=EPOCH" in usage.stderr


@pytest.mark.parametrize("pong_msgid, conforms", [(250, True), (3, False)])
def test_motion_needs_a_genuine_master_datagram_within_the_timeout(tmp_path, pong_msgid, conforms):
    # the PC's records sent msgids 36..199; agent #2 works, 900 ms pass, a PONG of the PC arrives, 900 ms
    # more: a PONG past the PC's last recorded msgid was sent after its last record (lost with a kill):
    # genuine, the master was heard 900 ms ago; one below every range the PC's records sent is not its
    # own (only its id): 1,800 ms without the master while WORKING
    write(tmp_path / "m.ndjson", [_rec("master", "MasterTick", changed={"msgid": 100}),
                                  _rec("master", "MasterTick", changed={"msgid": 200})])
    write(tmp_path / "a.ndjson", [
        _rec("agent", "RecvMaster", "1:2:50:2:55481", {"id": 2, "life": "ACTIVE", "leader": 1, "following": 1}),
        _rec("agent", "RecvStart", "1:2:51:8", {"life": "WORKING"}),
        {**_rec("agent", "Tick", changed={"silence": 900}), "args": {"ticks": 900}},
        _rec("agent", "RecvPong", f"1:2:{pong_msgid}:6:1", {"silence": 0}),
        {**_rec("agent", "Tick", changed={"silence": 900}), "args": {"ticks": 900}}])
    r = merged.validate([tmp_path], loss=1000)
    assert r.ok == conforms, r.message
    if not conforms:
        assert r.message.startswith("motion without a master (NoUnsupervisedMotionInv), after merged record 6: "
                                    "a.ndjson record 5 (node agent, Tick"), r.message
        assert "a.ndjson:agent (id 2) is WORKING and no genuine datagram of its master (node 1, epoch 1) " \
               "reached it for more than 1000 ms" in r.message


def test_a_command_sent_again_in_a_newer_epoch_is_received_after_that_send(tmp_path):
    # the PC sends MASTER #10 to agent 5 in epoch 1, wins epoch 2, then syncs the agent again (its
    # announce repeated): the same MASTER #10, stamped with epoch 2. Paired with its first send,
    # the receive could be merged before the PC's election of epoch 2 (a false FollowersAgreeInv,
    # seen in a black-box run); it comes after the send in epoch 2.
    pending = {"reg": [{"ann": 52260, "id": 5, "pending": True, "mid": 10}]}
    write(tmp_path / "a.ndjson", [_rec("agent", "ApplyCommand", "1:5:10:31:2:1%3A5%3A10%3A2%3A52260",
                                       changed={"id": 5})])
    write(tmp_path / "m.ndjson", [_rec("master", "MasterSync", "52260:0:7:1:A", dict(pending, msgid=11)),
                                  _rec("master", "StartElection", changed={"msgid": 12, "epoch": 2}),
                                  _rec("master", "BecomeMaster", changed={"msgid": 13, "life": "MASTER"}),
                                  _rec("master", "MasterSync", "52260:0:8:1:A", pending)])
    m = merged.merge([tmp_path])
    assert m.pairs == 1
    assert [(m.files[x.file].name, x.k) for x in m.order][-1] == ("a.ndjson", 0)   # after m.ndjson record 4


def test_a_restarted_pc_s_re_sends_are_in_the_epoch_it_restarted_in(tmp_path):
    # a PC restarted with --epoch 3 re-sends MASTER #10 before any record changes its epoch: the
    # re-send is of epoch 3 (the stream's bookkeeping once started every PC at epoch 1).
    pending = {"reg": [{"ann": 52260, "id": 5, "pending": True, "mid": 10}]}
    write(tmp_path / "m.ndjson", [_rec("master", "MasterSync", "52260:0:7:1:A", dict(pending, msgid=11)),
                                  _rec("master", "MasterSync", "52260:0:8:1:A", pending)])
    recs = [merged.Rec(0, k, r["node"], r) for k, r in enumerate(json.loads(line) for line in
                                                                 (tmp_path / "m.ndjson").read_text().splitlines())]
    start = lambda epochs: lambda n: merged._start_epoch(n, f"m.ndjson:{n}", epochs)
    assert [e for _, e, _ in merged._streams(0, recs, start({"m.ndjson:master": 3}))["master"].resends] == [3, 3]
    assert [e for _, e, _ in merged._streams(0, recs, start(None))["master"].resends] == [1, 1]


def test_a_command_resent_in_its_own_epoch_may_be_received_from_its_first_send(tmp_path):
    # An elected Master core (3, epoch 6) sends BEHAVIOUR #20 in EPOCH_CMD(6), answers agent 2's PING
    # #7 (sent after the agent took #20), then resends #20 (MasterTick). The agent took the first
    # copy: paired with the resend, its receive would come after the PONG's PING, a cycle (seen at
    # 30 % duplication in a fault scenario); in its own epoch a copy pairs with its first send.
    pending = {"reg": [{"ann": 2, "id": 2, "pending": True, "mid": 20}]}
    write(tmp_path / "a.ndjson", [_rec("agent", "ApplyCommand", "3:2:20:31:6:3%3A2%3A20%3A7%3Adrive", {"id": 2}),
                                  _rec("agent", "Tick", changed={"msgid": 8})])
    write(tmp_path / "m.ndjson", [_rec("master:3:6", "MasterCommand", changed=dict(pending, msgid=21)),
                                  _rec("master:3:6", "MasterPing", "2:3:7:5:WORKING", {"msgid": 22}),
                                  _rec("master:3:6", "MasterTick", changed=pending)])
    m = merged.merge([tmp_path])
    order = [(m.files[x.file].name, x.k) for x in m.order]
    assert order.index(("m.ndjson", 0)) < order.index(("a.ndjson", 0)) < order.index(("a.ndjson", 1)) \
        < order.index(("m.ndjson", 1))
