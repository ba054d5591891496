"""ev3-reports-driver and the reports replay (ev3conformance.reports_replay) on a hand-made path of
Reports.tla: a report dropped by a buffer of one, the marker and the report sent, taken by the PC,
the PC's crash (its record read back from the record file), its acknowledgement."""

from __future__ import annotations

import copy
import os
from pathlib import Path

from ev3conformance import driver as drv
from ev3conformance import graph as gr
from ev3conformance import reports_replay as rr
from ev3conformance import tla

REPO = Path(__file__).resolve().parents[3]
BIN = Path(os.environ.get("EV3_BIN") or REPO / "build" / "bin")
DRIVER = [str(BIN / "ev3-reports-driver")]


def rep(s):
    return {"agent": 2, "seq": s, "last": s, "kind": "report"}


MARKER = {"agent": 2, "seq": 1, "last": 1, "kind": "dropped"}


def state(name, args=(), **kw):
    s = {"made": {2: 0}, "lo": {2: 1}, "mk": {2: 0}, "cur": {2: "pc"}, "rec": {2: ()}, "nx": {2: 1},
         "acks": {2: {"pc": -1, "im": -1}}, "lastAction": {"name": name, "args": args}}
    for k, v in kw.items():
        s[k] = {2: v}
    return s


def path_graph() -> gr.Graph:
    rec1 = ({"seq": 1, "kind": "dropped"},)
    rec2 = rec1 + ({"seq": 2, "kind": "report"},)
    steps = [
        state("Init"),
        state("Make", (2,), made=1),
        state("Make", (2,), made=2, mk=1),
        state("Send", (2, "pc", frozenset({tla.Rec(MARKER), tla.Rec(rep(2))})), made=2, mk=1),
        state("PCTake", (rep(2), 1), made=2, mk=1),                      # ahead of the next: left
        state("PCTake", (MARKER, 1), made=2, mk=1, rec=rec1, nx=2),      # the marker: 1 dropped
        state("PCTake", (rep(2), 1), made=2, mk=1, rec=rec2, nx=3),      # its copy: stored
        state("PCCrash", (), made=2, mk=1, rec=rec2, nx=3),
        state("PCRestart", (), made=2, mk=1, rec=rec2, nx=3),
        state("PCAck", (2,), made=2, mk=1, rec=rec2, nx=3, acks={"pc": 2, "im": -1}),
        state("TakeAck", (2, "pc", 2, True), made=2, lo=3, mk=2, rec=rec2, nx=3),
    ]
    g = gr.Graph()
    for i, s in enumerate(steps):
        g.states[str(i)] = s
        if i:
            g.out.setdefault(str(i - 1), []).append(len(g.edges))
            g.edges.append((str(i - 1), str(i)))
    g.init = ["0"]
    return g


def test_the_path_conforms():
    f = rr.ReportsReplay(path_graph(), {"Cap": 1}, DRIVER).run()
    assert (f.matched, f.mismatched, f.steps) == (10, 0, 10), f.summary()


def test_a_spec_that_records_the_marker_as_a_report_is_a_mismatch():
    g = path_graph()
    for k in ("5", "6", "7"):
        g.states[k] = copy.deepcopy(g.states[k])
        g.states[k]["rec"][2] = ({"seq": 1, "kind": "report"},) + g.states[k]["rec"][2][1:]
    f = rr.ReportsReplay(g, {"Cap": 1}, DRIVER).run()
    assert f.mismatched == 1 and f.downstream == 5
    (act, fields), (n, report) = next(iter(f.classes.items()))
    assert act == "PCTake" and fields == ("rec",) and "dropped" in report


def test_a_wrong_send_is_a_mismatch():
    g = path_graph()
    g.states["3"] = copy.deepcopy(g.states["3"])
    g.states["3"]["lastAction"]["args"] = (2, "pc", frozenset({tla.Rec(rep(2))}))  # the marker left out
    f = rr.ReportsReplay(g, {"Cap": 1}, DRIVER).run()
    assert ("Send", ("sent",)) in f.classes


def test_the_driver_reads_the_record_back_and_refuses_bad_input():
    d = drv.Driver(DRIVER)
    try:
        assert "error" not in d.ask({"type": "config", "cap": 2})
        for _ in range(3):
            d.ask({"type": "make", "agent": 7})
        sent = d.ask({"type": "send", "agent": 7, "to": "pc"})["sent"]
        assert [(x["seq"], x["last"], x["kind"]) for x in sent] == [(1, 1, "dropped"), (2, 2, "report"), (3, 3, "report")]
        for x in sent:
            d.ask({"type": "take", "master": "pc", "agent": 7, "seq": x["seq"],
                   "last": x["last"] if x["kind"] == "dropped" else 0, "first": x["first"]})
        before = d.ask({"type": "check"})["pc"]["7"]
        after = d.ask({"type": "crash"})
        assert after["pc"]["7"] == before | {"ahead": 0}
        assert rr.record_entries(after["record"]) == {7: ((1, "dropped"), (2, "report"), (3, "report"))}
        assert d.ask({"type": "ack", "agent": 7})["ack"] == 3
        assert "error" in d.ask({"type": "make", "agent": 1})          # not an assigned id
        assert "error" in d.ask({"type": "make", "agent": -65534})     # nor is this (2 modulo 2^16)
        assert "error" in d.ask({"type": "take", "agent": 9, "seq": 0, "first": 1})
        out = d.ask({"type": "take", "agent": 9, "seq": 3, "first": 5})  # first above the number: invalid
        assert out["taken"] == "invalid" and "9" not in out["pc"]       # and no record is opened
        out = d.ask({"type": "ack", "agent": 9})
        assert out["ack"] == 0 and "9" not in out["pc"]
        assert "error" in d.ask({"type": "config", "cap": 0})
        assert "error" in d.ask({"type": "restore", "slot": 9})
        assert "error" in d.ask({"type": "send", "agent": 7, "to": "nobody"})
        assert d.ask({"type": "check"})["agents"]["7"]["made"] == 3     # still working
    finally:
        d.kill()
        d.close()
