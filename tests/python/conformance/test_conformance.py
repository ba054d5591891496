"""Unit tests of the conformance runner (ev3conformance.replay, .tracecheck): a tiny hand-made
state graph of MCAgent replayed against the real driver (passes) and a broken one (must fail);
a driver trace validated by TLC (passes) and the same trace corrupted (must fail)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from ev3conformance import graph as gr
from ev3conformance import replay, tracecheck

REPO = Path(__file__).resolve().parents[3]
BIN = Path(os.environ.get("EV3_BIN") or REPO / "build" / "bin")
AGENT = [str(BIN / "ev3-agent"), "--driver"]
CONSTS = gr.cfg_constants("MCAgent", "MCAgent.cfg")


def ag(**kw):
    a = {"state": "IDLE", "led": "YELLOW_BLINK", "id": 50000, "beh": "NONE", "step": 0, "wait": "NONE",
         "motors": "OFF", "devOk": True, "silence": 0, "clk": 0, "win": (), "dupActed": False}
    a.update(kw)
    return a


def mini_graph() -> gr.Graph:
    master = {"src": 1, "dst": 2, "msgid": 1, "type": "MASTER", "ref": 50000, "args": ()}
    ack = {"src": 2, "dst": 1, "type": "ACK", "ref": 1, "args": ()}
    win = ({"src": 1, "msgid": 1, "ans": ack},)
    active = dict(state="ACTIVE", led="GREEN_BLINK", id=2, win=win)
    g = gr.Graph()
    g.states = {
        "0": {"ag": ag(), "out": (), "lastAction": {"name": "Init", "args": ()}},
        "1": {"ag": ag(**active), "out": (ack,), "lastAction": {"name": "RecvMaster", "args": (master,)}},
        "2": {"ag": ag(**active, silence=1), "out": ({"src": 2, "dst": 1, "type": "PING", "ref": 0,
                                                     "args": ("ACTIVE",)},),
              "lastAction": {"name": "Tick", "args": ()}},
        "3": {"ag": ag(**dict(active, state="PANIC", led="RED_BLINK")),
              "out": ({"src": 2, "dst": 0, "type": "PANIC", "ref": 0, "args": ()},),
              "lastAction": {"name": "HeartbeatLost", "args": ()}},
    }
    g.init = ["0"]
    for u, v in (("0", "1"), ("1", "2"), ("2", "3")):
        g.out.setdefault(u, []).append(len(g.edges))
        g.edges.append((u, v))
    return g


def test_replay_real_driver_conforms():
    f = replay.AgentReplay(mini_graph(), CONSTS, AGENT).run()
    assert f.replayed == 3 and f.steps == 3 and f.paths == 1


def test_replay_fails_on_a_broken_driver():
    argv = [sys.executable, str(Path(__file__).with_name("fake_driver.py"))] + AGENT
    with pytest.raises(replay.Mismatch) as e:
        replay.AgentReplay(mini_graph(), CONSTS, argv).run()
    assert "state after RecvMaster differs" in e.value.report
    assert "WORKING" in e.value.report and "RecvMaster" in e.value.report


def test_replay_fails_on_a_wrong_spec_message():
    g = mini_graph()
    g.states["2"]["out"] = ()  # the spec says: no PING on this tick
    with pytest.raises(replay.Mismatch) as e:
        replay.AgentReplay(g, CONSTS, AGENT).run()
    assert "emitted messages differ" in e.value.report


def _driver_trace(tmp_path: Path) -> Path:
    trace = tmp_path / "agent.ndjson"
    inputs = [{"type": "config", "timers": {"sync": 5, "heartbeat": 2, "loss": 3, "paused": 6},
               "behaviours": [{"name": "wait", "devices": 0}], "temp_id": 50001},
              {"type": "advance", "ms": 3},
              {"type": "recv", "from": 101, "text": "1:7:1:2:50001"},
              {"type": "recv", "from": 101, "text": "1:7:2:7:wait"},
              {"type": "recv", "from": 101, "text": "1:7:3:8"},
              {"type": "recv", "from": 101, "text": "1:7:3:8"},
              {"type": "event", "event": "action_ok"},
              {"type": "advance", "ms": 10}]
    subprocess.run(AGENT + ["--trace", str(trace)], input="\n".join(json.dumps(i) for i in inputs) + "\n",
                   text=True, capture_output=True, check=True)
    return trace


CHECK = {"TSync": 5, "TPing": 2, "TLoss": 3, "TPaused": 6}


def test_validate_driver_trace(tmp_path):
    r = tracecheck.validate(_driver_trace(tmp_path), CHECK)
    assert r.ok, r.message
    assert r.records >= 8


def test_validate_rejects_a_corrupted_trace(tmp_path):
    trace = _driver_trace(tmp_path)
    recs = [json.loads(x) for x in trace.read_text().splitlines()]
    k = next(i for i, r in enumerate(recs) if r["action"] == "RecvStart")
    recs[k]["changed"]["state"] = "PAUSED"
    trace.write_text("\n".join(json.dumps(r) for r in recs) + "\n")
    r = tracecheck.validate(trace, CHECK)
    assert not r.ok
    assert f"record {k + 1} of" in r.message


def test_master_driver_registers_an_agent_like_the_spec():
    from ev3conformance import driver as drv, master_replay as mr
    d = drv.Driver([str(BIN / "ev3-master"), "--driver"])
    try:
        assert "error" not in d.ask(mr.master_config({"TDrop": 2, "MaxResends": 1}))
        agent = {"src": 50001, "dst": 0, "msgid": 1, "type": "AGENT", "ref": 0, "args": ("A",)}
        out = d.ask(mr.master_input({"name": "MasterSync", "args": (agent, 1)}))
        assert [a["action"] for a in out["actions"]] == ["MasterSync"]
        assert mr.impl_out(out["sent"]) == {(1, 1, 2, 1, "MASTER", 50001, ())}
        e = out["vars"]["reg"][0]
        assert (e["ann"], e["id"], e["ep"], e["synced"], e["pending"], e["mid"]) == (50001, 2, 1, False, True, 1)
        assert "error" in d.ask({"type": "command", "agent": 2, "command": "JUMP"})
    finally:
        d.kill()
        d.close()


def test_agent_driver_reports_model_a_behaviours():
    # "facts" needs no core and changes nothing; validate takes model A's behaviours from it
    from ev3conformance import driver as drv
    d = drv.Driver(AGENT)
    try:
        out = d.ask({"type": "facts"})
        assert out["ok"] is True and out["facts"]["model"] == "A"
        behs = {b["name"]: b["devices"] for b in out["facts"]["behaviours"]}
        assert list(behs)[:2] == ["wait", "drive"] and "custom" in behs
        assert behs["wait"] == 0 and behs["drive"] != 0
        after = d.ask({"type": "advance", "ms": 0})   # a core with the defaults, as if nothing came before
        assert after["in"] == 2 and after["vars"]["state"] == "IDLE" and after["vars"]["id"] == 50000
    finally:
        d.kill()
        d.close()
    assert tracecheck.model_a_behaviours() == list(behs)


def test_an_agent_trace_without_behaviours_needs_the_driver(tmp_path, monkeypatch):
    trace = _driver_trace(tmp_path)
    monkeypatch.setenv("EV3_BIN", str(tmp_path / "no-build"))
    r = tracecheck.validate(trace, CHECK)
    assert not r.ok and "ev3-agent --driver (input facts)" in r.message and "make build" in r.message
    r = tracecheck.validate(trace, dict(CHECK, Behaviours=["wait"]))
    assert r.ok, r.message


def test_a_driver_killed_by_its_cpu_limit_is_no_verdict_and_a_crash_is_a_failure():
    # ev3-conformance mutate runs each mutant's driver under prlimit --cpu: one killed there did not
    # finish (DriverKilled: no verdict), one that crashes failed (a DriverError, not DriverKilled)
    from ev3conformance import driver as drv
    loop = drv.Driver(["prlimit", "--cpu=1", sys.executable, "-c", "while True: pass"])
    try:
        with pytest.raises(drv.DriverKilled):
            loop.ask({"type": "facts"})
    finally:
        loop.close()
    crash = drv.Driver([sys.executable, "-c", "import os, signal, sys; sys.stdin.readline(); "
                        "os.kill(os.getpid(), signal.SIGSEGV)"])
    try:
        with pytest.raises(drv.DriverError) as e:
            crash.ask({"type": "facts"})
    finally:
        crash.close()
    assert not isinstance(e.value, drv.DriverKilled) and "status -11" in str(e.value)
