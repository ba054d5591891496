"""What `validate` makes of traces that cannot show anything (docs/spec.md "A check that cannot fail is
an error"): an empty trace, another node's trace, lines that are not records, datagrams that do not
decode are errors naming the cause, never a pass; a last line cut by a kill is left out and said so.
And the Python side only converts data: the TraceData module it writes holds values only (every
definition parses back as a TLA+ value), the TLA+ logic is in spec/tla/trace/."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

from ev3conformance import tla, tracecheck

SAMPLES = tracecheck.SAMPLES
AGENT = {"TSync": 5, "TPing": 2, "TLoss": 3, "TPaused": 6}
MASTER = {"TDrop": 4, "TResend": 1, "MaxResends": 2}


def sample(name: str) -> list[dict]:
    return [json.loads(x) for x in (SAMPLES / name).read_text().splitlines() if x.strip()]


def write(path: Path, recs: list[dict], tail: str = "") -> Path:
    path.write_text("".join(json.dumps(r) + "\n" for r in recs) + tail)
    return path


def test_an_empty_trace_is_an_error(tmp_path):
    for text in ("", "\n\n  \n"):
        p = tmp_path / "empty.ndjson"
        p.write_text(text)
        for r in (tracecheck.validate(p, AGENT), tracecheck.validate_master(p, MASTER)):
            assert not r.ok and r.no_records and r.records == 0
            assert "no records: the trace is empty" in r.message, r.message


def test_a_missing_trace_is_an_error(tmp_path):
    r = tracecheck.validate(tmp_path / "nowhere.ndjson", AGENT)
    assert not r.ok and "cannot read the trace" in r.message


def test_another_nodes_trace_is_an_error(tmp_path):
    agent = write(tmp_path / "agent.ndjson", sample("agent.ndjson"))
    master = write(tmp_path / "master.ndjson", sample("master.ndjson"))
    r = tracecheck.validate_master(agent, MASTER)
    assert not r.ok and r.no_records
    assert "no master records: the trace holds agent (15)" in r.message, r.message
    r = tracecheck.validate(master, AGENT)
    assert not r.ok and r.no_records
    assert "no agent records: the trace holds master (11)" in r.message, r.message
    # an agent-master's records are named by their node; none of them: an error too
    r = tracecheck.validate_master(agent, MASTER, node="master:2:2")
    assert not r.ok and "no master:2:2 records" in r.message


def test_lines_that_are_not_records_are_errors(tmp_path):
    recs = sample("agent.ndjson")
    lines = [json.dumps(r) for r in recs]
    cases = {
        "not JSON": lines[:3] + ['{"node": "agent", "action"'] + lines[3:],      # cut inside the trace
        "not a trace record": lines[:3] + ['{"node": "agent", "args": {}}'] + lines[3:],  # no action
        "\"changed\" is not an object": lines[:3] + ['{"node": "agent", "action": "Tick", "changed": 3}'],
    }
    for what, ls in cases.items():
        p = tmp_path / "bad.ndjson"
        p.write_text("\n".join(ls) + "\n")
        r = tracecheck.validate(p, AGENT)
        assert not r.ok and "line 4" in r.message and what in r.message, r.message
    p = tmp_path / "garbage.ndjson"  # a last line that is not the start of a record: not a cut, an error
    p.write_text("\n".join(lines) + "\n\x00\x17garbage")
    r = tracecheck.validate(p, AGENT)
    assert not r.ok and f"line {len(lines) + 1} is not JSON" in r.message, r.message


def test_a_datagram_that_does_not_decode_names_its_record(tmp_path):
    recs = sample("agent.ndjson")
    k = next(i for i, r in enumerate(recs) if r["action"] == "RecvStart")
    recs[k]["args"]["msg"] = "1:7:3:99"  # no message type 99
    r = tracecheck.validate(write(tmp_path / "t.ndjson", recs), AGENT)
    assert not r.ok and f"record {k + 1} of {len(recs)}: its datagram does not decode" in r.message, r.message


def test_a_cut_last_line_is_left_out_and_said(tmp_path):
    """A master killed with SIGKILL leaves its last record half written: the records before it are
    checked, and the result says one line was left out (and which records of other nodes it did not check)."""
    recs = sample("agent.ndjson") + [{"node": "master:7:2", "action": "Heartbeat", "args": {}, "now": 9,
                                      "changed": {"msgid": 2}}]
    r = tracecheck.validate(write(tmp_path / "cut.ndjson", recs, tail='{"node":"agent","action":"Ti'), AGENT)
    assert r.ok, r.message
    assert r.records == len(recs) - 1
    assert "its last line was cut (28 bytes, left out)" in r.message, r.message
    assert "1 records of other nodes not checked here (nodes: agent (15), master:7:2 (1))" in r.message


def test_the_cli_fails_on_an_empty_trace(tmp_path):
    p = tmp_path / "empty.ndjson"
    p.write_text("")
    for extra in ([], ["--master"]):
        cli = subprocess.run([sys.executable, "-m", "ev3conformance.cli", "validate", *extra, str(p)],
                             capture_output=True, text=True)
        assert cli.returncode == 1, cli.stdout + cli.stderr
        assert f"FAIL {p}: no records: the trace is empty" in cli.stdout, cli.stdout


def _definitions(module: str) -> dict[str, str]:
    """TraceData's definitions `Name == text` (the header and footer lines aside)."""
    body = module.split("\n", 1)[1].rsplit("====", 1)[0]
    body = "\n".join(x for x in body.splitlines() if not x.startswith("\\*"))
    parts = re.split(r"^(\w+) == ", body, flags=re.M)
    assert parts[0].strip() == "", parts[0]
    return dict(zip(parts[1::2], parts[2::2]))


def test_the_data_module_holds_values_only():
    """Each sample's TraceData: every definition is a TLA+ value (no operator, no expression): the
    trace, a sequence of records, one per record of the node, and the check's constants (make spec's
    TLC run of each sample shows they are the ones the module declares)."""
    spec = json.loads((SAMPLES / "samples.json").read_text())["samples"]
    for s in spec:
        if "run" in s:  # a whole run (MCMergedTrace): test_the_merged_data_module_holds_values_only
            continue
        path = SAMPLES / s["trace"]
        nd = (tracecheck.master_data(path, s["consts"]) if s.get("master")
              else tracecheck.agent_data(path, s["consts"]))
        assert nd.module == s["module"]
        defs = _definitions(nd.data(path))
        values = {k: tla.parse_value(v) for k, v in defs.items()}  # raises on anything but a value
        assert isinstance(values["Trace"], tuple) and len(values["Trace"]) == len(nd.records)
        assert all(isinstance(x, dict) and x["a"] == r["action"] for x, r in zip(values["Trace"], nd.records))
        assert set(values) == {"Trace"} | set(nd.consts)


def test_the_merged_data_module_holds_values_only():
    """The whole run's TraceData (ev3conformance.merged, make spec's sample run): values only, one
    record per record of the run, each naming its node by number; the nodes' start and names, the PC's
    runs, the Master cores, the agents' ids and timeout."""
    from ev3conformance import merged
    m = merged.merge([SAMPLES / "run"])
    defs = _definitions(merged.data_module(m, 400))
    values = {k: tla.parse_value(v) for k, v in defs.items()}  # raises on anything but a value
    assert set(values) == {"Trace", "Start", "NodeNames", "Agents", "PC", "PCs", "Cores", "AgentIds", "TLoss"}
    assert values["TLoss"] == 400 and values["PCs"] == (values["NodeNames"].index("master.nd:master") + 1,)
    assert {c["id"] for c in values["Cores"]} <= values["AgentIds"]
    assert len(values["Trace"]) == len(m.order) == sum(len(tracecheck.load(f)) for f in (SAMPLES / "run").glob("*.nd"))
    assert values["NodeNames"] == tuple(m.nodes) and len(values["Start"]) == len(m.nodes)
    assert all(x["a"] == r.r["action"] and values["NodeNames"][x["n"] - 1] == m.label(r)
               for x, r in zip(values["Trace"], m.order))


def test_msgids_past_tlcs_integers_are_written_modulo_2_31():
    # An ev3-master without a state file seeds its msgids from the wall clock (ev3proto/msgids.hpp):
    # half the time at 2^31 or above, which TLC's 32-bit signed integers cannot hold. to_tla writes
    # them modulo 2^31: equal msgids stay equal, and consecutive ones stay in order below the wrap.
    assert tla.to_tla(5) == "5"
    assert tla.to_tla((1 << 31) - 1) == str((1 << 31) - 1)
    assert tla.to_tla(1 << 31) == "0"
    assert tla.to_tla((1 << 31) + 7) == "7"
    assert tla.to_tla((1 << 32) - 1) == str((1 << 31) - 1)
    seed = 3_000_000_000
    written = [int(tla.to_tla(seed + k)) for k in range(4)]
    assert written == sorted(written) and len(set(written)) == 4 and max(written) < 1 << 31
    assert tla.to_tla({"msgid": seed}) == tla.to_tla({"msgid": seed - (1 << 31)})


def test_a_leave_record_is_checked_and_left_out_of_the_walk(tmp_path):
    recs = sample("agent.ndjson")
    msgid = max((r["changed"]["msgid"] for r in recs if "msgid" in r.get("changed", {})), default=1)
    leave = {"node": "agent", "action": "Leave", "args": {"e": "LEAVING"}, "now": recs[-1]["now"],
             "changed": {"msgid": msgid + 1}}
    tf = tracecheck.read_trace(write(tmp_path / "leave.ndjson", recs + [leave]))
    assert tf.records == recs and tf.beyond["agent"] == 1
    # not the node's last record, or changing more than its msgid: an error naming the line
    for bad, why in ((recs + [leave, recs[-1]], "after its Leave record"),
                     (recs + [dict(leave, changed={"msgid": msgid + 1, "state": "OFF"})],
                      "changes more than the msgid")):
        try:
            tracecheck.read_trace(write(tmp_path / "bad.ndjson", bad))
        except tracecheck.TraceError as e:
            assert why in str(e), e
        else:
            raise AssertionError(f"accepted: {why}")


def _pctake(msg: str, stored: int, after: int | None = None) -> dict:
    r = {"node": "master", "action": "PCTake", "args": {"msg": msg, "stored": stored}, "now": 5, "changed": {}}
    if after is not None:
        r["changed"]["rec"] = {"agent": 2, "stored": after}
    return r


def test_reports_records_are_checked_against_reports_tla_and_left_out_of_the_walk(tmp_path):
    recs = sample("master.ndjson")
    ok = [_pctake("2:1:9:40:1:1:2%3A1%3A9%3A15%3A0", 0, 1),        # the first report: recorded
          _pctake("2:1:10:40:1:1:2%3A1%3A9%3A15%3A0", 1),          # a copy: nothing more
          _pctake("2:1:11:40:3:1:2%3A1%3A11%3A15%3A1", 1),         # ahead of a lost 2: left
          _pctake("2:1:12:41:2:6", 1, 6),                          # the marker 2..6: recorded dropped
          _pctake("2:1:13:40:9:9:2%3A1%3A13%3A15%3A2", 6, 9)]      # 7, 8 skipped, then 9
    tf = tracecheck.read_trace(write(tmp_path / "rep.ndjson", recs + ok))
    assert tf.records == recs and tf.reports["master"] == len(ok)
    take_ack = {"node": "agent", "action": "TakeAck", "args": {"msg": "1:2:0:42:1"}, "now": 3,
                "changed": {"msgid": 12}}
    assert tracecheck.read_trace(write(tmp_path / "ack.ndjson", [take_ack])).reports["agent"] == 1
    bad = [(_pctake("2:1:9:40:2:1:2%3A1%3A9%3A15%3A0", 0, 2), "Reports.tla records 0"),   # 2 before 1
           (_pctake("2:1:9:40:1:1:2%3A1%3A9%3A15%3A0", 0), "Reports.tla records 1"),      # the next, not taken
           (_pctake("2:1:12:41:2:6", 1, 4), "Reports.tla records 6"),                     # part of a marker
           (dict(_pctake("2:1:9:40:1:1:2%3A1%3A9%3A15%3A0", 0, 1), changed={"reg": []}),
            "changes more than the record of reports"),
           (dict(take_ack, changed={"state": "OFF"}), "a TakeAck record changes more than the msgid and lo")]
    for r, why in bad:
        try:
            tracecheck.read_trace(write(tmp_path / "bad.ndjson", [r]))
        except tracecheck.TraceError as e:
            assert why in str(e), e
        else:
            raise AssertionError(f"accepted: {why}")
