"""Programs written for a brick against ev3-sim, unmodified, through `ev3-sim exec` (docs/devices.md,
"Running a brick's program"): python-ev3dev2 (pinned in tools/requirements.txt) and a C program that
writes the attributes as ev3dev-lang-cpp does. The simulator's truth (its status: pose, heading,
wheel positions, LEDs) is compared with what the programs asked for and read. Also the tree's
modes, owner and group as on a brick, chmod and chown, POLLPRI on a motor's `state`, and exec's
errors.

Each test starts its own ev3-sim (sim_factory); none starts an agent or a master, so no trace is
written (empty_trace)."""

from __future__ import annotations

import errno
import json
import math
import os
import select
import shutil
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ev3sim_proc import ev3_sim_path

HERE = Path(__file__).resolve().parent
BRICK = HERE / "brick"

# A 2 m x 1.2 m pen. The robot starts at (40, 60) facing +x. After two wheel turns (35.19 cm) its
# colour sensor (8 cm ahead of the axle) is over the red strip and its ultrasonic (11 cm ahead)
# faces the wall at x = 150; after the quarter turn right it drives down to the pen's side y = 0.
WORLD = """\
bounds 0 0 200 120
wall 150 0 150 120
floor red rect 78 0 12 120
start 40 60 0
"""
START_X = 40.0
WHEEL_CM = 5.6                    # model A's 56 mm wheel
WHEEL_BASE_CM = 12.0
WHEEL_TURN_CM = math.pi * WHEEL_CM
BUMPER_CM = 12.0                  # the bumper's face ahead of the axle
BUMPER_TRAVEL_CM = 0.6            # an obstacle this close presses it

# Tolerances of the python-ev3dev2 run against the simulator's truth.
DRIVE_TOL_CM = 1.5     # x after two wheel turns (the body slides a little when the wheels hold)
TURN_TOL_DEG = 3.0     # the heading turned by the quarter turn
SONAR_TOL_CM = 1.0     # the distance read against the geometry of the pose after the drive
STOP_TOL_CM = 0.5      # how far past the press the robot may roll before the program's stop lands
POSITION_TOL = 5       # counts: where run-to-rel-pos with hold leaves a wheel

pytestmark = pytest.mark.empty_trace  # no agent, no master: no trace


def exec_cmd(robot: str, *command: str) -> list[str]:
    """ev3-sim exec with --robot (a name unique to the test) or --sysfs-root (a path)."""
    flag = "--sysfs-root" if robot.startswith("/") else "--robot"
    return [str(ev3_sim_path()), "exec", flag, robot, "--", *command]


def unique_robot() -> list[tuple[str, None]]:
    """One robot named after this process: --robot finds it even if other ev3-sim run."""
    return [(f"ev3dev2-{os.getpid()}", None)]


def motor_dir(root: Path, port: str) -> Path:
    for d in sorted((root / "class" / "tacho-motor").iterdir()):
        if (d / "address").read_text().strip() == f"ev3-ports:{port}":
            return d
    raise AssertionError(f"no motor on {port} in {root}")


def write_attr(path: Path, value: str) -> None:
    fd = os.open(path, os.O_WRONLY)
    try:
        os.write(fd, value.encode())
    finally:
        os.close(fd)


def test_python_ev3dev2_program_drives_turns_reads_sensors_and_sets_leds(sim_factory):
    sim = sim_factory(WORLD, ["--time-scale", "2"], unique_robot())
    name = sim.robot()["name"]
    t0 = time.monotonic()
    steps = {}
    with subprocess.Popen(exec_cmd(name, sys.executable, str(BRICK / "ev3dev2_drive.py")), text=True,
                          stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE) as prog:
        try:
            # After each move the program prints what it read and waits: the truth is taken then.
            for step in ("drive", "turn", "touch"):
                # (a move that never ends must fail the test, not hang it: python-ev3dev2 waits
                # for the motors with no timeout)
                ready, _, _ = select.select([prog.stdout], [], [], 30)
                assert ready, f"no {step} line from the program in 30 s:\n{sim.log_text()}"
                line = prog.stdout.readline()
                assert line, f"the program ended before {step}:\n{prog.stderr.read()}\n{sim.log_text()}"
                read = json.loads(line)
                assert read["step"] == step, read
                steps[step] = (read, sim.robot())
                prog.stdin.write("\n")
                prog.stdin.flush()
            assert prog.wait(timeout=30) == 0, prog.stderr.read()
        finally:
            if prog.poll() is None:
                prog.kill()
    took = time.monotonic() - t0

    read, truth = steps["drive"]
    assert read["platform"] == "ev3"  # board-info/board0 says LEGO MINDSTORMS EV3
    assert read["ports"] == {"ev3-ports:in1": ["auto", "ev3-analog"], "ev3-ports:in2": ["auto", "no-sensor"],
                             "ev3-ports:in3": ["auto", "ev3-uart"], "ev3-ports:outA": ["auto", "no-motor"],
                             "ev3-ports:outB": ["auto", "tacho-motor"]}
    drive_err = truth["x"] - (START_X + 2 * WHEEL_TURN_CM)
    # Over the red strip, facing the wall at x = 150 from the sensor 11 cm ahead of the axle.
    assert read["colour_at_start"] == "NoColor" and read["colour"] == "Red"
    sonar_err = read["distance"] - (150.0 - (truth["x"] + 11.0))
    heading_after_drive = truth["heading_total"]
    _, truth = steps["turn"]
    turn_err = (truth["heading_total"] - heading_after_drive) - (-193 * WHEEL_CM / WHEEL_BASE_CM)
    read, truth = steps["touch"]
    print(f"ev3dev2 program: {took:.1f} s real; drive error {drive_err:+.2f} cm, turn error {turn_err:+.2f} deg, "
          f"sonar error {sonar_err:+.2f} cm, stopped with the axle {truth['y']:.2f} cm from the side")
    # Two wheel turns forward; a quarter turn right on the spot (193 degrees of each wheel).
    assert abs(drive_err) <= DRIVE_TOL_CM, steps["drive"]
    assert abs(sonar_err) <= SONAR_TOL_CM, steps["drive"]
    assert abs(turn_err) <= TURN_TOL_DEG, steps["turn"]
    # Stopped at the pen's side by the touch sensor: the bumper's face at y = 0, not through it.
    assert read["pressed_in_time"] is True and read["pressed"]
    assert BUMPER_CM - 0.05 <= truth["y"] <= BUMPER_CM + BUMPER_TRAVEL_CM + STOP_TOL_CM, truth
    assert truth["bumper"] and truth["ports"]["in1"]["values"] == [1]
    # The LEDs the program set last: left red, right green, as brightness on the four LEDs.
    leds = {k: v["brightness"] for k, v in truth["leds"].items()}
    assert leds == {"led0:red:brick-status": 255, "led0:green:brick-status": 0,
                    "led1:red:brick-status": 0, "led1:green:brick-status": 255}, leds


def test_c_program_writing_as_ev3dev_lang_cpp_does(sim_factory, tmp_path):
    cc = shutil.which("cc") or shutil.which("gcc")
    assert cc, "no C compiler (cc) to build the test program"
    exe = tmp_path / "lang_cpp_style"
    subprocess.run([cc, "-O2", "-Wall", "-Wextra", "-Werror", "-o", str(exe), str(BRICK / "lang_cpp_style.c")],
                   check=True)
    sim = sim_factory(WORLD, ["--time-scale", "2"])
    r = subprocess.run(exec_cmd(str(sim.root()), str(exe), "720", "400"), capture_output=True, text=True,
                       timeout=30)
    assert r.returncode == 0, f"exit {r.returncode}:\n{r.stdout}\n{r.stderr}\n{sim.log_text()}"
    left, right = (int(v) for v in r.stdout.split())
    truth = sim.robot()
    print(f"C program: positions read {left} {right}; truth {truth['ports']['outB']['position']} "
          f"{truth['ports']['outC']['position']}, x={truth['x']}")
    # run-to-rel-pos with hold: both wheels at their target when the program saw them stop, and
    # held there (the hold loop settles the overshoot meanwhile).
    assert abs(left - 720) <= POSITION_TOL and abs(right - 720) <= POSITION_TOL
    assert abs(truth["ports"]["outB"]["position"] - 720) <= POSITION_TOL
    assert abs(truth["ports"]["outC"]["position"] - 720) <= POSITION_TOL
    assert abs(truth["x"] - (START_X + 2 * WHEEL_TURN_CM)) <= DRIVE_TOL_CM, truth


def test_modes_owner_and_group_as_on_a_brick_and_chmod_chown(sim_factory):
    sim = sim_factory(WORLD, ["--allow-other"])
    root = sim.root()
    motor = motor_dir(root, "outB")
    modes = {a: stat.S_IMODE(os.stat(motor / a).st_mode) for a in ("command", "speed_sp", "state", "address")}
    assert modes == {"command": 0o220, "speed_sp": 0o664, "state": 0o444, "address": 0o444}
    led = root / "class" / "leds" / "led0:red:brick-status"
    assert stat.S_IMODE(os.stat(led / "brightness").st_mode) == 0o664
    battery = root / "class" / "power_supply" / "lego-ev3-battery"
    assert stat.S_IMODE(os.stat(battery / "voltage_now").st_mode) == 0o444
    st = os.stat(motor / "speed_sp")
    assert st.st_uid == os.getuid()
    group = st.st_gid  # group ev3dev, or ev3-sim's own group where the machine has none
    try:
        import grp
        want = grp.getgrnam("ev3dev").gr_gid
    except KeyError:
        want = os.getgid()
    assert group == want

    # A user in the attribute's group writes; another user reads but cannot write (inside the
    # namespace of ev3-sim exec, as a brick's program run as that user would).
    def as_user(gid: int, script: str) -> subprocess.CompletedProcess:
        return subprocess.run(exec_cmd(str(root), "setpriv", "--reuid=65534", f"--regid={gid}", "--clear-groups",
                                       "/bin/sh", "-c", script), capture_output=True, text=True, timeout=10)
    write = "printf 321 > /sys/class/tacho-motor/motor0/speed_sp"
    allowed = as_user(group, write)
    assert allowed.returncode == 0, allowed.stderr
    assert (motor / "speed_sp").read_text() == "321\n"
    other = 65534 if group != 65534 else 65533
    denied = as_user(other, write)
    assert denied.returncode != 0 and "Permission denied" in denied.stderr
    assert as_user(other, "cat /sys/class/tacho-motor/motor0/state").returncode == 0

    # chmod and chown by root, as sysfs allows them.
    os.chmod(motor / "speed_sp", 0o600)
    os.chown(motor / "speed_sp", 65533, 65533)
    st = os.stat(motor / "speed_sp")
    assert (stat.S_IMODE(st.st_mode), st.st_uid, st.st_gid) == (0o600, 65533, 65533)
    assert as_user(group, write).returncode != 0  # no longer the group's
    # A chmod stays while the node lives: the timer trigger adds delay_on/delay_off (the group's),
    # and leaves the LED's other files as they were.
    os.chmod(led / "brightness", 0o600)
    write_attr(led / "trigger", "timer")
    assert stat.S_IMODE(os.stat(led / "brightness").st_mode) == 0o600
    assert stat.S_IMODE(os.stat(led / "delay_on").st_mode) == 0o664
    write_attr(led / "trigger", "none")

    # lego-port: the ports in auto mode; other modes and set_device are not emulated.
    port0 = root / "class" / "lego-port" / "port0"
    assert (port0 / "address").read_text() == "ev3-ports:in1\n" and (port0 / "status").read_text() == "ev3-analog\n"
    assert stat.S_IMODE(os.stat(port0 / "mode").st_mode) == 0o664
    write_attr(port0 / "mode", "auto")
    for attr, value, err in (("mode", "ev3-uart", errno.EOPNOTSUPP), ("mode", "warp", errno.EINVAL),
                             ("set_device", "lego-ev3-touch", errno.EOPNOTSUPP)):
        with pytest.raises(OSError) as e:
            write_attr(port0 / attr, value)
        assert e.value.errno == err, (attr, value, e.value)

    # board-info/board0: what libraries read to know they run on an EV3.
    uevent = (root / "class" / "board-info" / "board0" / "uevent").read_text()
    keys = dict(line.split("=", 1) for line in uevent.splitlines())
    assert keys["BOARD_INFO_MODEL"] == "LEGO MINDSTORMS EV3" and keys["BOARD_INFO_TYPE"] == "main"
    assert list(keys) == ["BOARD_INFO_HW_REV", "BOARD_INFO_MODEL", "BOARD_INFO_ROM_REV",
                          "BOARD_INFO_SERIAL_NUM", "BOARD_INFO_TYPE"]


def test_poll_on_state_signals_every_change_at_once(sim_factory):
    sim = sim_factory(WORLD)  # real time
    motor = motor_dir(sim.root(), "outB")
    fd = os.open(motor / "state", os.O_RDONLY)
    try:
        assert os.pread(fd, 4096, 0) == b"\n"
        p = select.poll()
        p.register(fd, select.POLLPRI)
        # Nothing changes: the poll waits its whole timeout.
        t = time.monotonic()
        assert p.poll(200) == []
        assert time.monotonic() - t >= 0.19
        write_attr(motor / "time_sp", "1000")
        write_attr(motor / "speed_sp", "300")
        t_cmd = time.monotonic()
        write_attr(motor / "command", "run-timed")
        # The command changed the state: signalled at once.
        events = p.poll(1000)
        assert events and events[0][1] & select.POLLPRI
        assert os.pread(fd, 4096, 0) == b"running\n"
        # Read again: no event until the motor stops, a second after the command. The bounds leave a
        # loaded machine room and still tell the notify from the poll's own timeout (3 s).
        events = p.poll(3000)
        t_wake = time.monotonic() - t_cmd
        assert events and events[0][1] & select.POLLPRI and events[0][1] & select.POLLERR
        assert os.pread(fd, 4096, 0) == b"\n"
        print(f"POLLPRI on state: woke {t_wake * 1000:.1f} ms after a 1000 ms run-timed command")
        assert 0.9 <= t_wake <= 1.8, t_wake
    finally:
        os.close(fd)


def test_exec_errors_are_clear(sim_factory):
    sim = sim_factory(WORLD)
    root = sim.root()
    r = subprocess.run(exec_cmd("no-such-robot", "true"), capture_output=True, text=True, timeout=10)
    assert r.returncode == 1
    assert "no running ev3-sim serves robot no-such-robot" in r.stderr and str(root) in r.stderr
    r = subprocess.run([str(ev3_sim_path()), "exec", "--sysfs-root", "/tmp", "--", "true"],
                       capture_output=True, text=True, timeout=10)
    assert r.returncode == 1 and "no running ev3-sim serves a tree on /tmp" in r.stderr
    r = subprocess.run([str(ev3_sim_path()), "exec", "--sysfs-root", str(root), "true"], capture_output=True,
                       text=True, timeout=10)
    assert r.returncode == 2 and "the command comes after --" in r.stderr
    r = subprocess.run(exec_cmd(str(root), "/nonexistent/program"), capture_output=True, text=True, timeout=10)
    assert r.returncode == 127 and "cannot run /nonexistent/program" in r.stderr
    r = subprocess.run([str(ev3_sim_path()), "exec", "--sysfs-root", str(root), "--", "true"],
                       user=65534, capture_output=True, text=True, timeout=10)
    assert r.returncode == 1 and "needs root" in r.stderr
    # The command sees the robot's classes; the namespace is its alone: while it runs, no mount on
    # /sys/class is in this process's mount table.
    r = subprocess.run(exec_cmd(str(root), "ls", "/sys/class"), capture_output=True, text=True, timeout=10)
    assert r.returncode == 0 and r.stdout.split() == ["board-info", "leds", "lego-port", "lego-sensor",
                                                      "power_supply", "tacho-motor"]
    with subprocess.Popen(exec_cmd(str(root), "sh", "-c", "ls /sys/class/lego-port >/dev/null && sleep 2"),
                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) as inside:
        try:
            time.sleep(0.5)
            assert inside.poll() is None, "the command ended early"
            mounts = Path("/proc/self/mountinfo").read_text().splitlines()
            assert not [m for m in mounts if m.split()[4] in ("/sys/class", "/sys/devices")], mounts
        finally:
            inside.kill()
