"""examples/robot (minirobot: a firmware out of this tree, built against the installed package) with
the real ev3-master over loopback UDP: it syncs, runs `wait` (WORKING), and when the master is
killed goes PAUSED, then PANIC, stands and wins the next epoch, with its election state on disk
before it sends (docs/embedding.md); its LEDs follow in a fake /sys/class/leds. The static armel
build syncs and runs `wait` under qemu-arm. `make test-example` builds both ($EV3_EXAMPLE,
$EV3_EXAMPLE_ARM) and runs this file."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
from pathlib import Path

import pytest

from ev3net import Program, assert_static_armel, free_ports, read_status, wait_until

REPO = Path(__file__).resolve().parents[3]
LEDS = ["led0:red:brick-status", "led0:green:brick-status", "led1:red:brick-status", "led1:green:brick-status"]
# Short timers (ms): heartbeat, master lost (WORKING -> PAUSED), PAUSED -> PANIC, back-off before standing.
TIMERS = ["--timer", "heartbeat=100", "--timer", "loss=600", "--timer", "paused=1200",
          "--timer", "backoff=300", "--timer", "backoff_step=10"]


def _exe(var: str, default: Path) -> Path:
    p = Path(os.environ.get(var) or default)
    if not p.is_file():
        pytest.fail(f"{p} is missing: build it with `make test-example` (or set {var})", pytrace=False)
    return p


@pytest.fixture
def minirobot() -> Path:
    return _exe("EV3_EXAMPLE", REPO / "build" / "example" / "minirobot")


@pytest.fixture
def minirobot_arm() -> Path:
    assert shutil.which("qemu-arm"), "qemu-arm is missing (make deps installs qemu-user)"
    return _exe("EV3_EXAMPLE_ARM", REPO / "build" / "example-arm" / "minirobot")


def start_master(master_exe, tmp: Path, mport: int, rport: int, *extra: str) -> Program:
    """ev3-master on mport, its console on stdin, its fleet in tmp/status.json."""
    return Program(master_exe, ["--port", str(mport), "--bind", "127.0.0.1", "--broadcast", f"127.0.0.1:{rport}",
                                "--status-json", str(tmp / "status.json"), *extra],
                   tmp, "master", stdin=subprocess.PIPE)


def synced_id(tmp: Path) -> int:
    """The id of the one agent of the master's status once it is ACTIVE."""
    def active():
        s = read_status(tmp / "status.json")
        return next((a["id"] for a in (s or {}).get("agents", []) if a["state"] == "ACTIVE"), None)
    return wait_until(active, 10, "the robot ACTIVE in the master's status")


def said(p: Program, text: str, timeout: float = 5) -> None:
    wait_until(lambda: text in p.stdout(), timeout, f"{p.name} to print {text!r}")


def test_sync_behaviour_master_killed_paused_panic_elected(minirobot, master_exe, programs, tmp_path):
    mport, rport = free_ports(2)
    leds = tmp_path / "leds"
    for n in LEDS:
        (leds / n).mkdir(parents=True)
        (leds / n / "max_brightness").write_text("255\n")

    def led(i: int) -> tuple[str, str]:
        """(trigger, brightness) of LEDS[i] as the robot last wrote them."""
        try:
            return (leds / LEDS[i] / "trigger").read_text(), (leds / LEDS[i] / "brightness").read_text()
        except FileNotFoundError:
            return "", ""

    state = tmp_path / "robot.state"
    args = ["--port", str(rport), "--bind", "127.0.0.1", "--broadcast", f"127.0.0.1:{mport}",
            "--state", str(state), "--leds", str(leds), *TIMERS]
    master = start_master(master_exe, tmp_path, mport, rport, "--election")
    try:
        robot = Program(minirobot, args, tmp_path, "robot")
        programs.append(robot)
        # Sync: the master registers it; the robot says so; ACTIVE is blinking green.
        rid = synced_id(tmp_path)
        said(robot, f"state ACTIVE (id {rid})")
        wait_until(lambda: led(1) == ("timer", "255") and led(0)[1] == "0", 3, "ACTIVE on the LEDs: green blinking")
        # The PC's LEADER lists the robot: the membership is durable state, on disk at once.
        said(robot, f"members [{rid}] of epoch")
        kv = dict(line.split("=", 1) for line in state.read_text().splitlines())
        assert kv["members"] == str(rid) and int(kv["members_epoch"]) >= 1, kv
        # A behaviour: BEHAVIOUR and START from the console; WORKING is solid green.
        master.write(f"behaviour {rid} wait seconds=60")
        said(master, "BEHAVIOUR acknowledged (ACK)")
        master.write(f"start {rid}")
        said(master, "START acknowledged (ACK)")
        said(robot, "behaviour wait: start")
        said(robot, f"state WORKING (id {rid})")
        wait_until(lambda: led(1) == ("none", "255") and led(3) == ("none", "255"), 3, "WORKING: solid green")
        epoch = int(dict(line.split("=", 1) for line in state.read_text().splitlines())["epoch"])
    finally:
        master.stop(signal.SIGKILL)  # the master dies
        master.close()
    # Master lost: PAUSED (the behaviour paused, orange), then PANIC (the behaviour stopped, red blinking).
    said(robot, f"state PAUSED (id {rid})", 3)
    assert "behaviour wait: pause" in robot.stdout()
    said(robot, f"state PANIC (id {rid})", 4)
    out = robot.stdout()
    assert out.index("state PAUSED") < out.index("behaviour wait: pause") < out.index("state PANIC"), out
    wait_until(lambda: led(0) == ("timer", "255") and led(1)[1] == "0", 3, "PANIC on the LEDs: red blinking")
    # It stands in the next epoch and wins it (the only member): its vote is on disk before its ELECT.
    said(robot, f"election: role master in epoch {epoch + 1}", 5)
    said(robot, f"master of epoch {epoch + 1}: running a Master core")
    out = robot.stdout()
    vote = f"durable: epoch {epoch + 1}, voted for {rid}, members [{rid}]"
    assert vote in out and out.index(vote) < out.index(f"election: role master in epoch {epoch + 1}"), out
    kv = dict(line.split("=", 1) for line in state.read_text().splitlines())
    assert (kv["epoch"], kv["voted_for"], kv["members"]) == (str(epoch + 1), str(rid), str(rid)), kv
    # SIGTERM: exit 0 (the fixture checks it), the LEDs dark.
    assert robot.stop() == 0
    assert robot.stdout().rstrip().endswith("stopped")
    assert [led(i)[1] for i in range(4)] == ["0"] * 4
    # Started again, it reads the same election state back.
    again = Program(minirobot, args, tmp_path, "robot-again")
    programs.append(again)
    said(again, f"state {state}: read back: epoch {epoch + 1}, voted for {rid}, members [{rid}] of epoch {epoch + 1}")


@pytest.mark.parametrize("text, said", [
    ("epoch=3\nvoted_for=2\nmembers=2,x\nmembers_epoch=3\nfloor=3\n", "damaged: members: '2,x'"),
    ("epoch=3\nvoted_for=2\nmembers=2\nmembers_epoch=3\nfloor=2\n", "damaged: floor: 2 is below members_epoch 3"),
])
def test_damaged_state_file_refused(minirobot, tmp_path, text, said):
    """The library's rule (ev3proto/durable.hpp) refuses the file and names the key."""
    state = tmp_path / "robot.state"
    state.write_text(text)
    r = subprocess.run([str(minirobot), "--state", str(state), "--port", "0", "--bind", "127.0.0.1"],
                       capture_output=True, text=True, timeout=10)
    assert r.returncode == 2 and said in r.stderr, r


def test_armel_minirobot_syncs_and_runs_wait_under_qemu(minirobot_arm, master_exe, programs, tmp_path):
    assert_static_armel(minirobot_arm)
    mport, rport = free_ports(2)
    master = start_master(master_exe, tmp_path, mport, rport)
    programs.append(master)
    robot = Program(Path(shutil.which("qemu-arm")),
                    [str(minirobot_arm), "--port", str(rport), "--bind", "127.0.0.1", "--broadcast",
                     f"127.0.0.1:{mport}", "--state", str(tmp_path / "robot.state"), "--leds", str(tmp_path / "none")],
                    tmp_path, "arm-robot")
    programs.append(robot)
    rid = synced_id(tmp_path)
    said(robot, f"state ACTIVE (id {rid})")
    master.write(f"behaviour {rid} wait seconds=0.5")
    said(master, "BEHAVIOUR acknowledged (ACK)")
    master.write(f"start {rid}")
    said(master, f"agent {rid}: ACTION_OK", 5)
    assert "action finished" in robot.stdout(), robot.stdout()
