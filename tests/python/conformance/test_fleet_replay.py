"""The fleet replay (ev3conformance.fleet_replay, `ev3-conformance replay --model fleet`): a few
seeded TLC -simulate traces of MCFleetSim replayed against one ev3-master and three ev3-agent
drivers (must conform); a broken agent driver and corrupted spec traces (must be caught, with the
right class); and the simulation wrapper checked to have Fleet's Next."""
from __future__ import annotations

import copy
import os
import sys
from pathlib import Path

import pytest

from ev3conformance import fleet_replay as fr
from ev3conformance import graph as gr
from ev3conformance import sim_replay
from ev3conformance.tla import Rec

REPO = Path(__file__).resolve().parents[3]
BIN = Path(os.environ.get("EV3_BIN") or REPO / "build" / "bin")
AGENT = [str(BIN / "ev3-agent"), "--driver"]
MASTER = [str(BIN / "ev3-master"), "--driver"]
CONSTS = gr.cfg_constants("MCFleet", fr.SIM_CFG)


@pytest.fixture(scope="module")
def traces(tmp_path_factory):
    files, _ = sim_replay.simulate(fr.SIM_MODULE, fr.SIM_CFG, "fleet-sim", seed=3, num=4, depth=150,
                                   out_dir=tmp_path_factory.mktemp("fleet-sim"))
    assert len(files) == 4
    return [sim_replay.read_trace(p) for p in files]


def _run(traces, agent=AGENT, master=MASTER) -> fr.FleetFigures:
    rp = fr.FleetReplay(CONSTS, agent, master)
    return rp.run((None, t) for t in traces)


def test_fleet_traces_conform(traces):
    f = _run(traces)
    assert not f.classes, "\n".join(rep for _, rep in f.classes.values())
    assert f.traces == 4 and f.matched == f.steps == sum(len(t) - 1 for t in traces)
    # The simulation exercised the protocol, not just ticks: syncs, commands, PONGs, a crash.
    for key in ("Deliver/MasterSync", "Deliver/RecvMaster", "Deliver/MasterAnswer", "Operate",
                "Deliver/RecvBehaviour", "Deliver/RecvStart", "Deliver/RecvPong", "Tick"):
        assert f.actions[key] > 0, key
    assert f.mapped["master"] > 0 and f.mapped["agent"] > 0


def test_fleet_replay_catches_a_broken_agent(traces):
    # fake_driver.py: the real agent driver whose RecvMaster record claims WORKING.
    fake = [sys.executable, str(Path(__file__).with_name("fake_driver.py"))] + AGENT
    f = _run(traces[:1], agent=fake)
    assert f.mismatched_traces == 1 and f.matched < f.steps
    ((act, fields),) = f.classes
    assert act.startswith("Deliver/RecvMaster") and fields == ("agent.state",)
    rep = next(iter(f.classes.values()))[1]
    assert "!! state" in rep and "WORKING" in rep and "the trace up to here" in rep


def _first(trace, pred) -> int:
    return next(k for k in range(1, len(trace)) if pred(trace[k]["act"]))


def test_fleet_replay_catches_a_wrong_spec_state(traces):
    # The spec's registry entry says desired PAUSED right after the operator's START.
    t = copy.deepcopy(traces[0])
    k = _first(t, lambda a: a["name"] == "Operate" and a["cmd"]["type"] == "START")
    ident = t[k]["act"]["id"]
    t[k]["ms"]["reg"] = frozenset(Rec(x, desired="PAUSED") if x["id"] == ident else x for x in t[k]["ms"]["reg"])
    f = _run([t])
    ((act, fields),) = f.classes
    assert act == "Operate" and fields == ("master.desired",)
    assert f.matched == k - 1


def test_fleet_replay_catches_a_missing_datagram(traces):
    # The spec's MasterPing emits no PONG (and has none in flight): the master driver sent one.
    t = copy.deepcopy(traces[0])
    k = _first(t, lambda a: a["name"] == "Deliver" and a["h"] == "MasterPing"
               and any(e["m"]["type"] == "PONG" for e in a["out"]))
    act = t[k]["act"]
    pong = next(e for e in act["out"] if e["m"]["type"] == "PONG")
    t[k]["act"] = Rec(act, out=act["out"] - {pong})
    t[k]["net"] = t[k]["net"] - {pong}
    f = _run([t])
    ((key, fields),) = f.classes
    assert key == "Deliver/MasterPing" and fields == ("emitted",)
    assert "implementation emitted, spec did not: master=>" in next(iter(f.classes.values()))[1]


def test_simulation_wrapper_is_fleet():
    # MCFleetSim's SimNext (no fault gap) reaches exactly Fleet's states: nothing added, none lost.
    r = fr.check_wrapper()
    assert r["equal"], r
    assert r["fleet"][0] > 1000
