"""Property: whatever the agent driver is fed (valid and invalid datagrams, duplicates, strangers,
time advances, device and behaviour events), its trace (`--trace`) is a behaviour of AgentLogic:
TLC (ev3conformance.tracecheck) matches every record. A failing sequence shrinks to a short one.

Bounded for `make test`: EV3_TRACE_EXAMPLES examples (default 20; each is one driver run and one
TLC run), derandomized under CI=true (the "ci" profile of conftest.py). The test that the property
can fail: a driver whose trace is corrupted (fake_trace_driver.py) is rejected by the same check.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from ev3conformance import driver as drv
from ev3conformance import tracecheck

REPO = Path(__file__).resolve().parents[3]
BIN = Path(os.environ.get("EV3_BIN") or REPO / "build" / "bin")
AGENT = [str(BIN / "ev3-agent"), "--driver"]
FAKE = [sys.executable, str(Path(__file__).with_name("fake_trace_driver.py"))] + AGENT
EXAMPLES = int(os.environ.get("EV3_TRACE_EXAMPLES", "20"))

TEMP = 50001
TIMERS = {"sync": 5, "heartbeat": 2, "loss": 3, "paused": 6}
CONSTS = {"TSync": 5, "TPing": 2, "TLoss": 3, "TPaused": 6}
COMMANDS = ["PONG", "BEHAVIOUR", "START", "STOP", "PAUSE", "RESUME", "STANDBY", "CONTINUE", "RESTART"]


def recv(src: int, dst: int, msgid: int, type_: str, ref: int = 0, args: tuple = ()) -> dict:
    m = {"src": src, "dst": dst, "msgid": msgid, "type": type_, "ref": ref, "args": args}
    return {"type": "recv", "from": 100 + src, "text": drv.spec_to_wire(m).decode("latin-1")}


# msgids from a small range: copies (duplicates) of earlier datagrams are frequent.
msgids = st.integers(1, 8)
dsts = st.sampled_from([7, 7, 7, 0, TEMP, 8])


@st.composite
def command(draw):
    t = draw(st.sampled_from(COMMANDS))
    args = (draw(st.sampled_from(["wait", "wait", "dance"])),) if t == "BEHAVIOUR" else ()
    ref = draw(st.integers(1, 20)) if t == "PONG" else 0
    return recv(draw(st.sampled_from([1, 1, 1, 9])), draw(dsts), draw(msgids), t, ref, args)


@st.composite
def master(draw):
    return recv(1, draw(st.sampled_from([7, 8])), draw(msgids), "MASTER", draw(st.sampled_from([TEMP, TEMP, 7, 8])))


garbage = st.one_of(
    st.binary(min_size=0, max_size=12).map(lambda b: {"type": "recv", "from": 101, "hex": b.hex()}),
    st.sampled_from(["1:7:1:8:x", "1:7::8", "1:7:1:99", "1:7:4294967296:8", "1:7:1:2", "0:7:1:8"])
      .map(lambda t: {"type": "recv", "from": 101, "text": t}))
events = st.one_of(
    st.sampled_from(["action_ok", "action_failed", "battery_low"]).map(lambda e: {"type": "event", "event": e}),
    st.sampled_from(["OBSTACLE_DETECTED", "PROXIMITY_ALERT"]).map(
        lambda w: {"type": "event", "event": "action_interrupted", "warning": w}),
    st.tuples(st.sampled_from(["device_unplugged", "device_plugged"]), st.sampled_from(["in1", "outB"])).map(
        lambda ep: {"type": "event", "event": ep[0], "devices": 1, "port": ep[1]}),
    st.tuples(st.sampled_from(["OBSTACLE_DETECTED", "PROXIMITY_ALERT", "DEVICE_CONNECTED", "DEVICE_DISCONNECTED"]),
              st.sampled_from(["in1", "in4", "outC"])).map(
        lambda ep: {"type": "event", "event": "robot_event", "name": ep[0], "port": ep[1]}),
    st.just({"type": "event", "event": "sensor_report", "port": "1", "mode": "m", "values": ["3"]}))
advances = st.integers(0, 7).map(lambda ms: {"type": "advance", "ms": ms})
step = st.one_of(command(), command(), master(), garbage, events, advances, advances)


@st.composite
def scenario(draw):
    window = draw(st.sampled_from([1, 2, 50]))
    cfg = {"type": "config", "timers": TIMERS, "behaviours": [{"name": "wait", "devices": 1}],
           "devices": 1, "window": window, "temp_id": TEMP}
    head = [recv(1, 7, 1, "MASTER", TEMP)] if draw(st.booleans()) else []
    # The last ms passes (a Tick record at least): a run that leaves no record would check nothing, and
    # validate refuses an empty trace.
    return window, [cfg] + head + draw(st.lists(step, min_size=1, max_size=30)) + [{"type": "advance", "ms": 1}]


def run_and_validate(argv: list[str], window: int, inputs: list[dict], tmp: Path) -> tracecheck.Result:
    trace = tmp / "agent.ndjson"
    trace.unlink(missing_ok=True)
    p = subprocess.run(argv + ["--trace", str(trace)], input="\n".join(json.dumps(i) for i in inputs) + "\n",
                       text=True, capture_output=True, timeout=60)
    assert p.returncode == 0, p.stderr[-2000:]
    outs = [json.loads(x) for x in p.stdout.splitlines()]
    assert len(outs) == len(inputs), "one output line per input"
    bad = [o for o in outs if "error" in o]
    assert not bad, f"driver refused a well-formed input: {bad[0]}"
    return tracecheck.validate(trace, dict(CONSTS, Window=window), temp_id=TEMP, workdir=tmp / "tlc")


@settings(max_examples=EXAMPLES, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(scenario())
def test_every_driver_trace_is_a_spec_behaviour(tmp_path, sc):
    window, inputs = sc
    r = run_and_validate(AGENT, window, inputs, tmp_path)
    assert r.ok, r.message
    recs = tracecheck.load(tmp_path / "agent.ndjson")
    for a in sorted({x["action"] for x in recs}):
        event(f"took {a}")  # --hypothesis-show-statistics: how often each spec action occurs
    states = {x.get("changed", {}).get("state") for x in recs} - {None}
    event(f"states reached: {len(states)}")


FIXED = [{"type": "config", "timers": TIMERS, "behaviours": [{"name": "wait", "devices": 1}], "temp_id": TEMP},
         recv(1, 7, 1, "MASTER", TEMP), recv(1, 7, 2, "BEHAVIOUR", args=("wait",)), recv(1, 7, 3, "START"),
         {"type": "advance", "ms": 1}]


def test_the_property_rejects_a_wrong_trace(tmp_path):
    assert run_and_validate(AGENT, 50, FIXED, tmp_path).ok
    r = run_and_validate(FAKE, 50, FIXED, tmp_path)
    assert not r.ok
    assert "could not be matched" in r.message


def test_a_named_missing_device_is_the_specs_missing_device(tmp_path):
    """ev3-agent names the missing device in NOT ("missing device: the robot has no touch sensor (wait
    needs it)"); AgentLogic's "missing device" stands for those words (the driver, with no device names,
    says just "missing device"). The driver's trace in the robot's words conforms; another reason does not."""
    inputs = FIXED[:2] + [{"type": "event", "event": "device_unplugged", "devices": 1, "port": "in1"},
                          recv(1, 7, 2, "BEHAVIOUR", args=("wait",)), {"type": "advance", "ms": 1}]
    assert run_and_validate(AGENT, 50, inputs, tmp_path).ok
    plain = (tmp_path / "agent.ndjson").read_text()
    assert '"missing device"' in plain
    consts = dict(CONSTS, Window=50)
    for words, ok in (("missing device: the robot has no touch sensor (wait needs it)", True),
                      ("unknown behaviour", False)):
        t = tmp_path / "words.ndjson"
        t.write_text(plain.replace('"missing device"', json.dumps(words)))
        r = tracecheck.validate(t, consts, temp_id=TEMP, workdir=tmp_path / ("tlc-" + str(ok)))
        assert r.ok == ok, (words, r.message)


# --- the master: `ev3-master --driver --trace` against MasterLogic (exact msgids) ----------------

MASTER = [str(BIN / "ev3-master"), "--driver"]
MCONSTS = {"TDrop": 4, "MaxResends": 2, "Behaviours": ["wait"]}
STATES = ["IDLE", "ACTIVE", "WORKING", "PAUSED", "PANIC"]


@st.composite
def from_agent(draw):
    ep = draw(st.sampled_from([1, 2]))
    kind = draw(st.sampled_from(["AGENT", "PANIC", "ACK", "ACK", "NOT", "PING", "PING", "ACTION_OK"]))
    src = draw(st.sampled_from([50001, 50002, 2, 3])) if kind in ("AGENT", "PANIC") else draw(st.sampled_from([2, 3]))
    dst = 0 if kind in ("AGENT", "PANIC") else 1
    mid = draw(st.integers(1, 9))
    if kind in ("ACK", "NOT"):
        ref, args = draw(st.integers(1, 9)), (("wrong state",) if kind == "NOT" else ())
    elif kind == "PING":
        ref, args = 0, (draw(st.sampled_from(STATES)),)
    elif kind == "AGENT":
        ref, args = 0, ("A",)
    elif kind == "ACTION_OK":
        ref, args = draw(st.integers(0, 3)), ()
    else:
        ref, args = 0, ()
    m = {"src": src, "dst": dst, "msgid": mid, "type": kind, "ref": ref, "args": args}
    return {"type": "recv", "from": ep, "hex": drv.spec_to_wire(m).hex()}


@st.composite
def operator(draw):
    c = draw(st.sampled_from(COMMANDS[1:]))
    d = {"type": "command", "agent": draw(st.sampled_from([2, 3])), "command": c}
    if c == "BEHAVIOUR":
        d["behaviour"] = "wait"
    return d


master_steps = st.one_of(from_agent(), from_agent(), operator(), st.integers(0, 3).map(lambda ms: {"type": "advance", "ms": ms}))


def run_master(argv: list[str], inputs: list[dict], tmp: Path) -> tracecheck.Result:
    trace = tmp / "master.ndjson"
    trace.unlink(missing_ok=True)
    p = subprocess.run(argv + ["--trace", str(trace)], input="\n".join(json.dumps(i) for i in inputs) + "\n",
                       text=True, capture_output=True, timeout=60)
    assert p.returncode == 0, p.stderr[-2000:]
    outs = [json.loads(x) for x in p.stdout.splitlines()]
    assert len(outs) == len(inputs) and not [o for o in outs if "error" in o]
    return tracecheck.validate_master(trace, MCONSTS, workdir=tmp / "tlc")


MCONFIG = {"type": "config", "timers": {"resend": 1, "drop": MCONSTS["TDrop"]}, "max_resends": MCONSTS["MaxResends"]}


@settings(max_examples=max(1, EXAMPLES // 2), deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(st.booleans(), st.lists(master_steps, min_size=1, max_size=25))
def test_every_master_driver_trace_is_a_spec_behaviour(tmp_path, synced, steps):
    # An agent registers first (a MasterSync record at least: a run that leaves no record would check
    # nothing, and validate refuses an empty trace); often it is synced too (the ACK of MASTER #1).
    agent = {"src": 50001, "dst": 0, "msgid": 1, "type": "AGENT", "ref": 0, "args": ("A",)}
    ack = {"src": 2, "dst": 1, "msgid": 2, "type": "ACK", "ref": 1, "args": ()}
    head = [{"type": "recv", "from": 1, "hex": drv.spec_to_wire(x).hex()} for x in ((agent, ack) if synced else (agent,))]
    r = run_master(MASTER, [MCONFIG] + head + steps, tmp_path)
    assert r.ok, r.message


def test_master_trace_check_rejects_a_wrong_trace(tmp_path):
    agent = {"src": 50001, "dst": 0, "msgid": 1, "type": "AGENT", "ref": 0, "args": ("A",)}
    ack = {"src": 2, "dst": 1, "msgid": 2, "type": "ACK", "ref": 1, "args": ()}
    inputs = [MCONFIG, {"type": "recv", "from": 1, "hex": drv.spec_to_wire(agent).hex()},
              {"type": "recv", "from": 1, "hex": drv.spec_to_wire(ack).hex()},
              {"type": "command", "agent": 2, "command": "START"}, {"type": "advance", "ms": 2}]
    assert run_master(MASTER, inputs, tmp_path).ok
    trace = tmp_path / "master.ndjson"
    recs = [json.loads(x) for x in trace.read_text().splitlines()]
    k = next(i for i, r in enumerate(recs) if r["action"] == "MasterCommand")
    recs[k]["changed"]["reg"][0]["mid"] += 1  # the command claims another msgid
    trace.write_text("".join(json.dumps(r) + "\n" for r in recs))
    r = tracecheck.validate_master(trace, MCONSTS, workdir=tmp_path / "tlc2")
    assert not r.ok and f"record {k + 1} of" in r.message
