"""End to end: ev3-agent runs model A on ev3-sim's FUSE tree (--sysfs-root), under a real ev3-master
driven through its console. The LEDs follow the lifecycle; `drive` moves the robot; the bumper stops
it within one control tick and the master hears OBSTACLE_DETECTED; an unplugged motor is
DEVICE_DISCONNECTED at the master; a low battery is BATTERY_LOW at the master and a clean exit;
the master killed while driving stops the motors; the robot's events outside an action reach the
master as EVENT with their port. The contact watchdog stops the wheels 500 ms after the master's
last word, and a stalled agent's wheels are stopped by the motor driver. The armel agent under
qemu-arm drives too. A custom behaviour
paused in the middle of a drive and of a turn continues the same action on RESUME (the distance and
the angle asked, not more); after ACTION_ERR (a wheel stalled against a wall), RESTART runs it again
from its first state.

ev3-sim needs /dev/fuse and the armel test qemu-arm: without them these tests FAIL (never skip).
Each test is a few seconds of real time; the agents' NDJSON traces are checked against the spec
like every other agent's (conftest.py)."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ev3net import HB, LOSS, PAUSED, Program, T, free_ports, read_status, wait_until

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "sim"))
from ev3sim_proc import Sim  # noqa: E402

# An open pen: the robot faces +x with 5 m of floor in front of it.
OPEN = "bounds 0 0 600 300\nstart 50 150 0\n"
# A box beside the ultrasonic's ray (y = 150) but in front of the bumper (|y - 150| <= 6): the
# bumper meets it at x = 120 while the ultrasonic still sees the far wall (no PROXIMITY_ALERT).
BOX = "bounds 0 0 600 300\nbox 120 152 30 40\nstart 50 150 0\n"
# A wall ahead: the ultrasonic sees it coming.
WALL = "bounds 0 0 300 300\nwall 200 0 200 300\nstart 50 150 0\n"

# (red, green) of each pattern as the sim's status shows it: (trigger, brightness) of max 255.
PATTERNS = {
    "YELLOW_BLINK": (("timer", 26), ("timer", 255)),
    "GREEN_BLINK": (("none", 0), ("timer", 255)),
    "GREEN": (("none", 0), ("none", 255)),
    "ORANGE": (("none", 255), ("none", 128)),
    "RED_BLINK": (("timer", 255), ("none", 0)),
    "DARK": (("none", 0), ("none", 0)),
}
LEDS = {"left": ("led0:red:brick-status", "led0:green:brick-status"),
        "right": ("led1:red:brick-status", "led1:green:brick-status")}


class Fleet:
    """One ev3-master (console on stdin) and the agents of a test."""

    def __init__(self, master_exe, programs, tmp_path):
        self.master_exe, self.programs, self.tmp = master_exe, programs, tmp_path
        self.mport = free_ports(1)[0]
        self.master: Program | None = None

    def start_master(self, keep: bool = True) -> Program:
        self.status = self.tmp / "master.json"
        m = Program(self.master_exe, ["--port", str(self.mport), "--bind", "127.0.0.1", "--status-json",
                                      str(self.status), "--agent-timeout-ms", "2000", "--resend-ms", "150",
                                      "--log-level", "3"], self.tmp, "master", stdin=subprocess.PIPE)
        if keep:
            self.programs.append(m)
        self.master = m
        return m

    def start_agent(self, exe, root: Path, *extra: str, name: str = "agent", prefix=None) -> Program:
        aport = free_ports(1)[0]
        args = ["--port", str(aport), "--bind", "127.0.0.1", "--broadcast", f"127.0.0.1:{self.mport}",
                "--heartbeat-ms", str(HB), "--master-timeout-ms", str(LOSS), "--paused-timeout-ms",
                str(PAUSED), "--sysfs-root", str(root), "--log-level", "4",
                "--log-file", str(self.tmp / f"{name}.log"), *extra]
        a = Program(Path(prefix) if prefix else exe, ([str(exe)] if prefix else []) + args, self.tmp, name)
        self.programs.append(a)
        return a

    def agent_state(self, state: str, agent: int = 2):
        s = read_status(self.status) or {}
        return any(x["id"] == agent and x["state"] == state for x in s.get("agents", []))

    def say(self, line: str) -> None:
        self.master.write(line)

    def heard(self, pattern: str, timeout: float = 5.0) -> str:
        rx = re.compile(pattern)
        return wait_until(lambda: rx.search(self.master.stdout()) and self.master.stdout(), timeout,
                          f"the master's console to show /{pattern}/")


@pytest.fixture
def fleet(master_exe, programs, tmp_path):
    return Fleet(master_exe, programs, tmp_path)


def leds(sim: Sim) -> str:
    """The pattern both sides of the brick show (their name in PATTERNS), or what they show."""
    got = sim.robot()["leds"]
    seen = set()
    for red, green in LEDS.values():
        seen.add(tuple((got[n]["trigger"], got[n]["brightness"]) for n in (red, green)))
    for name, p in PATTERNS.items():
        if seen == {p}:
            return name
    return repr(seen)


def wait_leds(sim: Sim, pattern: str, timeout: float = 3.0) -> None:
    wait_until(lambda: leds(sim) == pattern, timeout, f"LEDs {pattern} (they show {leds(sim)})")


def motors(sim: Sim) -> dict[str, dict]:
    ports = sim.robot()["ports"]
    return {p: ports[p] for p in ("outB", "outC") if p in ports}


def stopped(sim: Sim) -> bool:
    r = sim.robot()
    return abs(r["speed"]) < 0.01 and all(m["speed"] == 0 and "running" not in m["state"]
                                          for m in motors(sim).values())


def driving(sim: Sim) -> bool:
    return all(m["speed"] > 100 and "running" in m["state"] for m in motors(sim).values())


def test_lifecycle_leds_drive_pause_and_master_lost(sim_factory, fleet, agent_exe):
    """IDLE blinking yellow -> ACTIVE blinking green -> WORKING solid green while `drive` moves the
    robot -> PAUSED solid orange, wheels still -> WORKING again -> the master killed: motors stopped
    at once the core pauses (PAUSED), then PANIC blinking red."""
    sim = sim_factory(OPEN)
    fleet.start_agent(agent_exe, sim.root(), "--sync-timeout-ms", "20000")
    wait_leds(sim, "YELLOW_BLINK")
    fleet.start_master(keep=False)
    try:
        wait_until(lambda: fleet.agent_state("ACTIVE"), 5, "agent 2 ACTIVE at the master")
        wait_leds(sim, "GREEN_BLINK")
        fleet.say("behaviour 2 drive speed=400")
        fleet.heard(r"BEHAVIOUR acknowledged")
        fleet.say("start 2")
        wait_until(lambda: fleet.agent_state("WORKING"), 3, "WORKING")
        wait_leds(sim, "GREEN")
        wait_until(lambda: driving(sim), 2, "both wheels driving")
        x0 = sim.robot()["x"]
        wait_until(lambda: sim.robot()["x"] > x0 + 5, 2, "the robot moving forward (+x)")
        fleet.say("pause 2")
        wait_leds(sim, "ORANGE")
        wait_until(lambda: stopped(sim), 1, "the wheels stopped on PAUSE")
        fleet.say("resume 2")
        wait_leds(sim, "GREEN")
        wait_until(lambda: driving(sim), 2, "driving again after RESUME")
        fleet.master.proc.kill()  # SIGKILL: no goodbye
        fleet.master.proc.wait()
    finally:
        fleet.master.close()
    # The core pauses after --master-timeout-ms: the motors stop in that same call.
    wait_until(lambda: stopped(sim), LOSS / 1000 + 1.0, "the motors stopped after the master was lost")
    wait_leds(sim, "RED_BLINK", PAUSED / 1000 + 2.0)
    assert stopped(sim)


def test_the_watchdog_stops_the_wheels_before_the_core_notices(sim_factory, fleet, agent_exe):
    """The contact watchdog (docs/devices.md): with a master timeout of 3 s, the core would pause the
    robot 3 s after the master's last word; the watchdog stops the wheels 500 ms after it, while the
    core is still WORKING, and says so in the log."""
    sim = sim_factory(OPEN)
    fleet.start_master(keep=False)
    fleet.start_agent(agent_exe, sim.root(), "--master-timeout-ms", "3000", "--paused-timeout-ms", "6000")
    try:
        wait_until(lambda: fleet.agent_state("ACTIVE"), 5, "agent 2 ACTIVE")
        fleet.say("behaviour 2 drive speed=300")
        fleet.heard(r"BEHAVIOUR acknowledged")
        fleet.say("start 2")
        wait_until(lambda: driving(sim), 3, "both wheels driving")
        killed = time.monotonic()
        fleet.master.proc.kill()  # SIGKILL: no goodbye
        fleet.master.proc.wait()
    finally:
        fleet.master.close()
    wait_until(lambda: stopped(sim), 2.0, "the wheels stopped by the watchdog")
    held_after = time.monotonic() - killed
    log = fleet.tmp / "agent.log"
    wait_until(lambda: "watchdog: wheels held" in log.read_text(), 2, "the agent's log of the hold")
    # Stopped well before the core's 3 s master timeout: the watchdog, not the core, stopped them.
    assert held_after < 2.5, held_after
    text = log.read_text()
    assert "state PAUSED" not in text[:text.index("watchdog: wheels held")]


def test_a_stalled_agent_has_its_wheels_stopped_by_the_motor_driver(sim_factory, fleet, agent_exe):
    """SIGSTOP freezes the agent while `drive` runs: nothing in the program can stop the wheels, but
    its RunForever was written as run-timed ending 500 ms after its last contact, so the (simulated)
    motor driver stops them. SIGCONT after 1.2 s (within its master timeout of 3 s: still WORKING):
    the agent hears its master again and the robot drives on."""
    sim = sim_factory(OPEN)
    fleet.start_master()
    agent = fleet.start_agent(agent_exe, sim.root(), "--master-timeout-ms", "3000", "--paused-timeout-ms", "6000")
    wait_until(lambda: fleet.agent_state("ACTIVE"), 5, "agent 2 ACTIVE")
    fleet.say("behaviour 2 drive speed=300")
    fleet.heard(r"BEHAVIOUR acknowledged")
    fleet.say("start 2")
    wait_until(lambda: driving(sim), 3, "both wheels driving")
    agent.proc.send_signal(signal.SIGSTOP)
    frozen = time.monotonic()
    try:
        wait_until(lambda: stopped(sim), 1.0, "the wheels stopped by run-timed's end while the agent is stopped")
        x = sim.robot()["x"]
        time.sleep(max(0.0, 1.2 - (time.monotonic() - frozen)))
        assert abs(sim.robot()["x"] - x) < 0.5, "the robot moved while its agent was stopped"
    finally:
        agent.proc.send_signal(signal.SIGCONT)
    wait_until(lambda: driving(sim), 5, "driving again once the agent runs and hears its master")


def test_bumper_stops_the_drive_within_a_tick(sim_factory, fleet, agent_exe):
    """The bumper meets a box the ultrasonic does not see: ACTION_INTERR OBSTACLE_DETECTED at the
    master, and both motors' `stop` written in the tick that read the press: after the first read of
    the touch sensor's value0 that says 1 and before the next read of it. ev3-sim's verbose log has
    every read and write of the agent, stamped with the simulated time (which runs at real time
    here); the time itself is a benchmark (bench/robot_sim.py), not asserted: a loaded machine wakes
    the agent late, but never lets it read twice before the stop."""
    sim = sim_factory(BOX, args=["--log-level", "4"])
    fleet.start_master()
    fleet.start_agent(agent_exe, sim.root())
    wait_until(lambda: fleet.agent_state("ACTIVE"), 5, "agent 2 ACTIVE")
    fleet.say("behaviour 2 drive speed=500")
    fleet.say("start 2")
    fleet.heard(r"agent 2: ACTION_INTERR \S+ OBSTACLE_DETECTED", 10)
    wait_until(lambda: stopped(sim), 1, "the motors stopped")
    r = sim.robot()
    assert r["bumper"] and r["bumper_pressed_at"] is not None, r
    wait_until(lambda: "event OBSTACLE_DETECTED in1" in (fleet.tmp / "agent.log").read_text(), 2,
               "the agent's log line of the event (the log is flushed every 200 ms)")
    tick = wait_until(lambda: press_tick(sim, r["bumper_pressed_at"]), 2,
                      "ev3-sim's log: the read that saw the press, both stops, the next read")
    seen, stops, next_read = tick
    assert len(stops) == 2 and all(seen <= t for t in stops), tick
    assert next_read is None or max(stops) <= next_read, f"a second read of the bumper before the stop: {tick}"


def press_tick(sim: Sim, press: float):
    """(time of the first touch value0 read saying 1 at or after the press, the two motors' first
    `stop` writes after it, the next read of that value0 or None) from ev3-sim's log, or None while
    the log does not have both stops yet."""
    seen, stops, next_read = None, {}, None
    for line in sim.log.read_text(errors="replace").splitlines():
        m = re.search(r"t=([0-9.]+) s: (read|write) (\S+) (->|<-) '([^']*)'", line)
        if not m:
            continue
        t, what, path, value = float(m.group(1)), m.group(2), m.group(3), m.group(5)
        touch = "ev3-ports:in1" in path and path.endswith("/value0") and what == "read"
        if seen is None:
            if touch and t >= press and value == "1":
                seen = t
        elif touch and next_read is None:
            next_read = t
        elif what == "write" and path.endswith("/command") and value == "stop" and path not in stops:
            stops[path] = t
    if seen is None or len(stops) < 2:
        return None
    return seen, sorted(stops.values()), next_read


def test_unplugged_motor_and_low_battery_reach_the_master(sim_factory, fleet, agent_exe):
    """The colour sensor missing at start: EVENT DEVICE_DISCONNECTED once synced, DEVICE_CONNECTED when
    plugged. A motor unplugged while driving: the drive stops, EVENT DEVICE_DISCONNECTED at the master,
    BEHAVIOUR drive refused naming the motor ("missing device: the robot has no right motor (drive needs
    it)"); plugged back: EVENT DEVICE_CONNECTED. Then the battery drops below 6.2 V: EVENT BATTERY_LOW at
    the master, motors stopped, the agent exits 0."""
    sim = sim_factory(OPEN)
    sim.ctl("unplug in3")  # the colour sensor is missing at start: the master hears it once synced
    fleet.start_master()
    a = fleet.start_agent(agent_exe, sim.root())
    wait_until(lambda: fleet.agent_state("ACTIVE"), 5, "agent 2 ACTIVE")
    fleet.heard(r"agent 2: EVENT DEVICE_DISCONNECTED in3")
    sim.ctl("replug in3")
    fleet.heard(r"agent 2: EVENT DEVICE_CONNECTED in3", 4)
    fleet.say("behaviour 2 drive speed=300")
    fleet.say("start 2")
    wait_until(lambda: driving(sim), 3, "driving")
    sim.ctl("unplug outC")
    fleet.heard(r"agent 2: EVENT DEVICE_DISCONNECTED outC")
    wait_until(lambda: stopped(sim), 1, "the other motor stopped")
    wait_until(lambda: fleet.agent_state("ACTIVE"), 3, "back to ACTIVE (behaviour unloaded)")
    fleet.say("behaviour 2 drive speed=300")
    fleet.heard(r"BEHAVIOUR refused \(NOT\): missing device: the robot has no right motor \(drive needs it\)")
    sim.ctl("replug outC")
    fleet.heard(r"agent 2: EVENT DEVICE_CONNECTED outC", 4)
    sim.ctl("battery 5.9")
    fleet.heard(r"agent 2: EVENT BATTERY_LOW", 8)
    wait_until(lambda: a.proc.poll() is not None, 3, "the agent to exit after BATTERY_LOW")
    assert a.proc.returncode == 0, a.stderr()
    assert stopped(sim)
    assert leds(sim) == "DARK"


def test_normal_events_reach_the_master_with_their_port(sim_factory, fleet, agent_exe):
    """WORKING with `wait` (no motion): the robot is placed with its bumper against the box, the
    bumper closes: EVENT OBSTACLE_DETECTED in1 at the master, no ACTION_INTERR, still WORKING. A
    gyro plugged into the free port in2: EVENT DEVICE_CONNECTED in2. The colour sensor unplugged
    and plugged back: EVENT DEVICE_DISCONNECTED in3, then DEVICE_CONNECTED in3 (spec RobotEvent,
    DeviceUnplugged, DevicePlugged)."""
    sim = sim_factory(BOX)
    fleet.start_master()
    fleet.start_agent(agent_exe, sim.root())
    wait_until(lambda: fleet.agent_state("ACTIVE"), 5, "agent 2 ACTIVE")
    fleet.say("behaviour 2 wait seconds=60")
    fleet.heard(r"BEHAVIOUR acknowledged")
    fleet.say("start 2")
    wait_until(lambda: fleet.agent_state("WORKING"), 3, "WORKING")
    # The bumper's face 0.3 cm short of the box (x = 120): within its 0.6 cm travel, no overlap.
    sim.ctl("place 107.7 150 0")
    wait_until(lambda: sim.robot()["bumper"], 2, "the bumper pressed against the box")
    fleet.heard(r"agent 2: EVENT OBSTACLE_DETECTED in1", 4)
    assert "ACTION_INTERR" not in fleet.master.stdout()
    assert fleet.agent_state("WORKING")
    assert stopped(sim)
    sim.ctl("plug in2 lego-ev3-gyro")
    fleet.heard(r"agent 2: EVENT DEVICE_CONNECTED in2", 4)
    assert fleet.agent_state("WORKING")
    sim.ctl("unplug in3")
    fleet.heard(r"agent 2: EVENT DEVICE_DISCONNECTED in3", 4)
    sim.ctl("replug in3")
    fleet.heard(r"agent 2: EVENT DEVICE_CONNECTED in3", 4)
    out = fleet.master.stdout()
    assert out.count("EVENT OBSTACLE_DETECTED") == 1, out  # one press, one report


def test_a_behaviour_the_robot_cannot_run_is_refused_on_receipt(sim_factory, start_agent, tm):
    """The robot checks a BEHAVIOUR on receipt, before it answers (spec RecvBehaviour,
    Refused). Sent straight from a test master (no console check): a custom definition that does not
    parse gets NOT with `line L col C: ...`, one with an unknown action NOT naming it, one needing
    the gyro (model A has none) NOT naming the device, a built-in with a bad argument NOT naming the
    argument. Nothing was loaded (START: "no behaviour") and nothing moved; a good definition is
    ACKed and runs (its ACTION_OK). Its AGENT announced model A's five devices after the model."""
    sim = sim_factory(OPEN)
    start_agent("--sysfs-root", str(sim.root()))
    _, a, _ = tm.wait_for(lambda m: m.type == T["AGENT"], 3, "AGENT")
    assert a.params == (b"A", b"left motor", b"right motor", b"ultrasonic sensor", b"touch sensor", b"colour sensor")
    tm.sync(2)
    why = tm.refused(2, "BEHAVIOUR", "custom", "behaviour x\nparam speed = 200\nstate a = run $speed ->\n").decode()
    assert re.fullmatch(r"line 3 col \d+: .+", why), why
    why = tm.refused(2, "BEHAVIOUR", "custom", "behaviour spin\nstate turning = trun 90 speed=200 -> turning\n")
    assert why.decode().startswith("line 2 col 17: unknown action 'trun'"), why
    why = tm.refused(2, "BEHAVIOUR", "custom", "behaviour g\nstate a = pause 1s -> a\nwhen gyro > 90 -> end\n")
    assert why == b"line 3 col 6: the robot has no gyro sensor (when gyro needs it)", why
    why = tm.refused(2, "BEHAVIOUR", "drive", "speed=fast")
    assert b"speed=fast" in why, why
    assert tm.refused(2, "START") == b"no behaviour"
    assert stopped(sim)
    tm.ack(2, "BEHAVIOUR", "custom", "behaviour w\nstate a = wait 200ms -> end\n")
    mark = tm.mark()
    tm.ack(2, "START")
    tm.wait_for(lambda m: m.sender == 2 and m.type == T["ACTION_OK"], 3, "ACTION_OK of the checked custom", mark)
    assert not [m for _, m, _ in tm.received(mark) if m.type == T["ACTION_ERR"]]


def test_armel_agent_drives_the_simulated_robot(sim_factory, fleet):
    """The static armel ev3-agent under qemu-arm runs model A on ev3-sim: drive moves the robot,
    the ultrasonic sees the wall coming (PROXIMITY_ALERT) and the drive stops short of it."""
    d = os.environ.get("EV3_ARM_BIN")
    assert d, "EV3_ARM_BIN is not set: run this through `make test-blackbox` (it builds `make arm` first)"
    exe = Path(d) / "ev3-agent"
    assert exe.is_file(), f"{exe} is missing: build it with `make arm`"
    qemu = shutil.which("qemu-arm")
    assert qemu, "qemu-arm is missing (make deps installs qemu-user)"
    sim = sim_factory(WALL)
    fleet.start_master()
    fleet.start_agent(exe, sim.root(), name="arm-agent", prefix=qemu)
    wait_until(lambda: fleet.agent_state("ACTIVE"), 10, "the armel agent ACTIVE")
    fleet.say("behaviour 2 drive speed=400")
    fleet.say("start 2")
    wait_until(lambda: driving(sim), 3, "driving")
    fleet.heard(r"agent 2: ACTION_INTERR \S+ PROXIMITY_ALERT", 10)
    wait_until(lambda: stopped(sim), 1, "stopped")
    r = sim.robot()
    assert 200 - 12 - 20 < r["x"] + 12 < 200, r  # the bumper's face stopped within 20 cm of the wall
    assert not r["bumper"]


def start_custom(fleet: Fleet, agent_exe, sim: Sim, bhv: Path, text: str) -> None:
    """A master and an agent on sim's robot; once ACTIVE, the behaviour `text` (written to bhv, sent
    by the console's `behaviour 2 custom @FILE`) acknowledged and started."""
    bhv.write_text(text)
    fleet.start_master()
    fleet.start_agent(agent_exe, sim.root())
    wait_until(lambda: fleet.agent_state("ACTIVE"), 5, "agent 2 ACTIVE")
    fleet.say(f"behaviour 2 custom @{bhv}")
    fleet.heard(r"BEHAVIOUR acknowledged")
    fleet.say("start 2")


# A leg of 1 m and a full turn, paused in the middle of each (tests below).
LEG_AND_TURN = """behaviour leg_and_turn
param speed = 250
state leg = drive 1m -> spin
on OBSTACLE_DETECTED, PROXIMITY_ALERT -> end
state spin = turn 360 speed=150 -> end
on OBSTACLE_DETECTED -> end
on PROXIMITY_ALERT -> ignore
"""


def test_pause_and_resume_continue_the_same_action(sim_factory, fleet, agent_exe, tmp_path):
    """A custom behaviour drives 1 m, then turns 360 deg. PAUSE from the master in the middle of the
    drive stops the wheels where they are; RESUME drives on to the same target, not a new 1 m: the
    leg ends 100 cm from the start (x), within 3 cm (the brake's slide at 12 cm/s is 0.6 cm; the
    drive counts whole wheel degrees). Then PAUSE in the middle of the turn, RESUME: the heading
    turns 360 deg in all, within 6 deg. One ACTION_OK per action (ids 0 and 1), none doubled."""
    sim = sim_factory(OPEN)
    r0 = sim.robot()
    start_custom(fleet, agent_exe, sim, tmp_path / "leg_and_turn.bhv", LEG_AND_TURN)
    wait_until(lambda: sim.robot()["x"] > r0["x"] + 25, 10, "the robot 25 cm along its leg")
    fleet.say("pause 2")
    wait_until(lambda: fleet.agent_state("PAUSED"), 3, "PAUSED")
    wait_until(lambda: stopped(sim), 2, "the wheels stopped on PAUSE")
    at_pause = sim.robot()["x"] - r0["x"]
    assert 25 < at_pause < 80, f"paused at {at_pause:.1f} cm: not in the middle of the 100 cm leg"
    time.sleep(1.0)
    assert stopped(sim) and abs(sim.robot()["x"] - r0["x"] - at_pause) < 0.05, "moved while PAUSED"
    fleet.say("resume 2")
    wait_until(lambda: fleet.agent_state("WORKING"), 3, "WORKING again")
    fleet.heard(r"agent 2: ACTION_OK 0\b", 15)
    leg = sim.robot()
    # The turn starts at once (the leg's ACTION_OK is sent as it starts): wait for a third of it.
    h0 = leg["heading_total"]
    # Sideways: the two wheels start and stop by two separate writes (as on a brick, where each
    # tacho motor has its own `command`); a gap of d s between them turns the robot by about d rad
    # at 12 cm/s on a 12 cm track, and the rest of the leg carries that sideways. Quiet, y ends
    # 0.1 cm off; a CI run under load ended 1.02 cm off (gaps of about 15 ms). 3 cm allows 40 ms.
    assert abs(leg["y"] - r0["y"]) < 3.0, leg
    wait_until(lambda: sim.robot()["heading_total"] > h0 + 90, 10, "a quarter of the turn")
    fleet.say("pause 2")
    wait_until(lambda: fleet.agent_state("PAUSED"), 3, "PAUSED in the turn")
    wait_until(lambda: stopped(sim), 2, "the wheels stopped on PAUSE")
    turned_at_pause = sim.robot()["heading_total"] - h0
    assert 90 < turned_at_pause < 300, f"paused {turned_at_pause:.1f} deg into the 360 deg turn"
    fleet.say("resume 2")
    fleet.heard(r"agent 2: ACTION_OK 1\b", 15)
    wait_until(lambda: stopped(sim), 2, "still after the turn")
    end = sim.robot()
    leg_cm = leg["x"] - r0["x"]
    turned = end["heading_total"] - h0
    print(f"leg: paused at {at_pause:.2f} cm, ended at {leg_cm:.2f} cm of 100; "
          f"turn: paused at {turned_at_pause:.1f} deg, ended at {turned:.2f} deg of 360")
    assert abs(leg_cm - 100) < 3.0, f"the leg ended at {leg_cm:.2f} cm, not 100 (restarted or stopped short?)"
    assert abs(turned - 360) < 6.0, f"the turn ended at {turned:.2f} deg, not 360"
    out = fleet.master.stdout()
    assert len(re.findall(r"agent 2: ACTION_OK 0\b", out)) == 1, out
    assert len(re.findall(r"agent 2: ACTION_OK 1\b", out)) == 1, out


# Forward 20 cm, then back 1 m into the wall behind: the wheels stall, the action fails (ACTION_ERR).
FORTH_AND_BACK = """behaviour forth_and_back
param speed = 300
state forth = drive 20cm -> back
on OBSTACLE_DETECTED, PROXIMITY_ALERT -> end
state back = drive -1m -> end
on OBSTACLE_DETECTED, PROXIMITY_ALERT -> ignore
"""
# The robot's back (6 cm behind the axle) 24 cm from the wall x = 0; 5 m of floor ahead.
BACK_TO_WALL = "bounds 0 0 600 300\nstart 30 150 0\n"


def test_restart_after_action_err_starts_over(sim_factory, fleet, agent_exe, tmp_path):
    """A custom behaviour drives 20 cm forward, then 1 m back: the wall behind stops the body, the
    wheels stall and the drive fails (ACTION_ERR after the runner's 1 s without progress). The
    robot waits (no motion) until RESTART from the master, which runs the behaviour from its first
    state: the 20 cm forward again (ACTION_OK 0 again, the robot 20 cm from the wall), then back into
    the wall, ACTION_ERR again. Continuing the failed action instead would only push on the wall."""
    sim = sim_factory(BACK_TO_WALL)
    start_custom(fleet, agent_exe, sim, tmp_path / "forth_and_back.bhv", FORTH_AND_BACK)
    xs, travelled = [], []
    for run in (1, 2):
        fleet.heard(r"agent 2: ACTION_OK 0\b" + (r"[\s\S]*agent 2: ACTION_OK 0\b" if run == 2 else ""), 10)
        wait_until(lambda: sim.robot()["x"] < 20, 10, "backing towards the wall")
        out = fleet.heard(r"agent 2: ACTION_ERR 1\b" + (r"[\s\S]*agent 2: ACTION_ERR 1\b" if run == 2 else ""), 10)
        wait_until(lambda: stopped(sim), 2, "the motors stopped after ACTION_ERR")
        r = sim.robot()
        xs.append(r["x"])
        travelled.append(r["travelled"])
        time.sleep(0.5)
        assert stopped(sim), "moved while waiting for RESTART"
        if run == 1:
            fleet.say("restart 2")
    print(f"against the wall at x = {xs[0]:.2f} then {xs[1]:.2f} cm; travelled {travelled[0]:.2f} cm, "
          f"then {travelled[1] - travelled[0]:.2f} cm after RESTART; master's console:\n{out}")
    assert all(abs(x - 6.0) < 0.5 for x in xs), xs  # the robot's back on the wall, not through it
    # The first run: 20 cm forth, 44 cm back; after RESTART 20 cm forth and the same 20 cm back.
    assert abs(travelled[0] - 64.0) < 3.0, travelled
    assert abs(travelled[1] - travelled[0] - 40.0) < 3.0, travelled
    # ACTION_ERR's text names the failure, on the master's console: the back leg's wheel stalled
    # 44 cm, then 20 cm into its 1 m.
    backs = [int(n) for n in re.findall(r"agent 2: ACTION_ERR 1 out[BC] stalled at -(\d+) of -2046 counts", out)]
    assert len(backs) == 2 and abs(backs[0] - 900) < 60 and abs(backs[1] - 410) < 60, backs


def test_the_shipped_explore_travels_whole_as_custom(sim_factory, fleet, agent_exe, tmp_path):
    """behaviours/explore.bhv sent as `custom` (679 bytes in compact form, more than the 512 bytes of
    arguments the agent kept before; it was refused as "unknown behaviour") is acknowledged and the
    robot drives off."""
    text = (Path(__file__).resolve().parents[3] / "behaviours" / "explore.bhv").read_text()
    sim = sim_factory(OPEN)
    start_custom(fleet, agent_exe, sim, tmp_path / "explore.bhv", text)
    wait_until(lambda: driving(sim), 3, "the robot driving (explore's first state)")
    assert "refused" not in fleet.master.stdout()
