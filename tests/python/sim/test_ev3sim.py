"""ev3-sim as a program: its FUSE tree against the reference trees (check_tree.py --live), reads and
writes through held descriptors (os.pread/os.pwrite, as the device layer does), the driver's errors,
unplug/replug, sensor modes against drivers.json, driving, two robots, snapshots, bad input."""

from __future__ import annotations

import errno
import json
import math
import os
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

import pytest

from ev3sim_proc import TREES, ev3_sim_path, mounted

PEN = """\
# a 3 m x 2 m pen with a wall and a box
bounds 0 0 300 200
wall 200 0 200 120
box 120 150 30 30
floor red rect 250 0 50 200
start 50 60 0
start 50 140 0
"""


def check_tree(root, generation="stretch", overlays=()):
    cmd = [sys.executable, str(TREES / "check_tree.py"), "--live"]
    for o in overlays:
        cmd += ["--overlay", str(TREES / "overlays" / o / generation)]
    cmd += [str(TREES / generation), str(root)]
    return subprocess.run(cmd, capture_output=True, text=True)


def attr(root, dev_class, name, attribute):
    return root / "class" / dev_class / name / attribute


def drive(root, speed):
    """Both wheels at speed: the setpoints first, then the two commands back to back (held
    descriptors), so that the wheels start within microseconds even at a high --time-scale."""
    motors = [find_device(root, "tacho-motor", f"ev3-ports:{p}") for p in ("outB", "outC")]
    for m in motors:
        (m / "speed_sp").write_text(str(speed))
    fds = [os.open(m / "command", os.O_WRONLY) for m in motors]
    try:
        for fd in fds:
            os.pwrite(fd, b"run-forever", 0)
    finally:
        for fd in fds:
            os.close(fd)


def find_device(root, dev_class, address):
    for name in sorted(os.listdir(root / "class" / dev_class)):
        if (root / "class" / dev_class / name / "address").read_text().strip() == address:
            return root / "class" / dev_class / name
    return None


class Held:
    """An attribute opened once, read with pread and written with pwrite (one syscall each)."""

    def __init__(self, path, mode=os.O_RDWR):
        self.fd = os.open(path, mode)

    def read(self) -> str:
        return os.pread(self.fd, 4096, 0).decode().rstrip("\n")

    def write(self, value: str) -> None:
        os.pwrite(self.fd, value.encode(), 0)

    def close(self) -> None:
        os.close(self.fd)


def test_tree_matches_the_reference_stretch(start_sim):
    sim = start_sim(PEN)
    r = check_tree(sim.root())
    assert r.returncode == 0, r.stdout + r.stderr


def test_tree_matches_the_reference_jessie_with_a_gyro(start_sim):
    sim = start_sim(PEN, args=["--jessie"])
    r = check_tree(sim.root(), "jessie")
    assert r.returncode == 0, r.stdout + r.stderr
    sim.ctl("plug in2 lego-ev3-gyro")
    sim.wait_for(lambda: len(os.listdir(sim.root() / "class" / "lego-sensor")) == 4)
    r = check_tree(sim.root(), "jessie", ["gyro-in2"])
    assert r.returncode == 0, r.stdout + r.stderr
    # The LEDs' timer trigger brings delay_on/delay_off; the checker demands them then.
    (sim.root() / "class/leds/ev3:left:green:ev3dev/trigger").write_text("timer")
    r = check_tree(sim.root(), "jessie", ["gyro-in2"])
    assert r.returncode == 0, r.stdout + r.stderr
    assert (sim.root() / "class/leds/ev3:left:green:ev3dev/delay_on").read_text() == "500\n"


def test_held_descriptors_and_the_drivers_errors(start_sim):
    sim = start_sim(PEN, args=["--time-scale", "5"])
    motor = find_device(sim.root(), "tacho-motor", "ev3-ports:outB")
    speed_sp = Held(motor / "speed_sp")
    command = Held(motor / "command", os.O_WRONLY)
    position = Held(motor / "position")
    state = Held(motor / "state", os.O_RDONLY)
    try:
        assert position.read() == "0"
        speed_sp.write("500\n")
        command.write("run-forever")
        assert sim.wait_for(lambda: int(position.read()) > 300)
        assert state.read() == "running"
        with pytest.raises(OSError) as e:
            position.write("0")
        assert e.value.errno == errno.EBUSY
        with pytest.raises(OSError) as e:
            command.write("spin")
        assert e.value.errno == errno.EINVAL
        with pytest.raises(OSError) as e:
            speed_sp.write("2000")
        assert e.value.errno == errno.EINVAL
        command.write("stop")
        assert sim.wait_for(lambda: state.read() == "")
    finally:
        for h in (speed_sp, command, position, state):
            h.close()
    # Write-only and read-only attributes cannot be opened the other way (sysfs: EACCES).
    with pytest.raises(PermissionError):
        os.open(motor / "command", os.O_RDONLY)
    with pytest.raises(PermissionError):
        os.open(motor / "max_speed", os.O_WRONLY)
    us = find_device(sim.root(), "lego-sensor", "ev3-ports:in4")
    with pytest.raises(OSError) as e:
        (us / "value1").read_text()
    assert e.value.errno == errno.ENXIO
    with pytest.raises(OSError) as e:
        (us / "poll_ms").read_text()
    assert e.value.errno == errno.EOPNOTSUPP


def test_a_read_never_mixes_two_values(start_sim):
    # sysfs fills a buffer at offset 0 and serves later offsets from it: a reader taking a value in
    # pieces gets one value, not the start of one and the end of a later one.
    sim = start_sim(PEN, args=["--time-scale", "5"])
    motor = find_device(sim.root(), "tacho-motor", "ev3-ports:outB")
    (motor / "speed_sp").write_text("1000")
    (motor / "command").write_text("run-forever")
    sim.wait_for(lambda: int((motor / "position").read_text()) > 1000)
    fd = os.open(motor / "position", os.O_RDONLY)
    other = os.open(motor / "position", os.O_RDONLY)
    try:
        for _ in range(5):
            first = os.pread(fd, 1, 0)
            then = int(os.pread(other, 4096, 0))
            time.sleep(0.05)  # 250 ms simulated: the wheel turns about 250 counts
            rest = os.pread(fd, 4096, 1)
            value = int(first + rest)
            assert abs(value - then) < 20, (value, then)
            assert int(os.pread(other, 4096, 0)) > then + 100
    finally:
        os.close(fd)
        os.close(other)
    (motor / "command").write_text("stop")


def test_unplug_and_replug(start_sim):
    sim = start_sim(PEN)
    root = sim.root()
    motor = find_device(root, "tacho-motor", "ev3-ports:outB")
    assert motor.name == "motor0"
    held = Held(motor / "position")
    try:
        sim.ctl("unplug outB")
        sim.wait_for(lambda: not (root / "class/tacho-motor/motor0").exists())
        with pytest.raises(OSError) as e:
            held.read()
        assert e.value.errno == errno.ENODEV
        with pytest.raises(OSError) as e:
            held.write("0")
        assert e.value.errno == errno.ENODEV
    finally:
        held.close()
    assert os.listdir(root / "class/tacho-motor") == ["motor1"]
    sim.ctl("replug outB")
    sim.wait_for(lambda: (root / "class/tacho-motor/motor2").exists())
    assert (root / "class/tacho-motor/motor2/address").read_text() == "ev3-ports:outB\n"
    r = check_tree(root)
    assert r.returncode == 0, r.stdout + r.stderr
    # Garbage values, then normal again; the battery drop.
    us = find_device(root, "lego-sensor", "ev3-ports:in4")
    sim.ctl("garbage in4 on")
    sim.wait_for(lambda: sim.robot()["ports"]["in4"]["garbage"])
    sim.ctl("battery 6.3")
    sim.wait_for(lambda: int((root / "class/power_supply/lego-ev3-battery/voltage_now").read_text()) < 6300000)
    sim.ctl("garbage in4 off")
    sim.wait_for(lambda: not sim.robot()["ports"]["in4"]["garbage"])
    sim.wait_for(lambda: 0 <= int((us / "value0").read_text()) <= 2550)
    # A bad command is refused (logged), the simulator goes on.
    sim.ctl("unplug outZ")
    sim.wait_for(lambda: "control: error: robot1: unknown port 'outZ'" in sim.log_text())


def test_sensor_modes_match_drivers_json(start_sim):
    drivers = json.loads((TREES / "drivers.json").read_text())["lego-sensor"]
    sim = start_sim(PEN, args=["--time-scale", "10"])
    sim.ctl("plug in2 lego-ev3-gyro")
    sim.wait_for(lambda: find_device(sim.root(), "lego-sensor", "ev3-ports:in2"))
    for port in ("in1", "in2", "in3", "in4"):
        dev = find_device(sim.root(), "lego-sensor", f"ev3-ports:{port}")
        driver = (dev / "driver_name").read_text().strip()
        modes = drivers[driver]["modes"]
        assert (dev / "modes").read_text().split() == [m["name"] for m in modes]
        for m in modes:
            time.sleep(0.03)  # 300 ms simulated: the ultrasonic's single-shot modes need 250 ms
            (dev / "mode").write_text(m["name"])
            assert (dev / "mode").read_text().strip() == m["name"]
            for field in ("num_values", "decimals", "units", "bin_data_format"):
                assert (dev / field).read_text() == f"{m[field]}\n", (driver, m["name"], field)
            for n in range(8):
                if n < m["num_values"]:
                    int((dev / f"value{n}").read_text())
                else:
                    with pytest.raises(OSError) as e:
                        (dev / f"value{n}").read_text()
                    assert e.value.errno == errno.ENXIO
            assert len((dev / "bin_data").read_bytes()) == 32


def test_a_mode_change_takes_time(start_sim):
    sim = start_sim(PEN)
    us = find_device(sim.root(), "lego-sensor", "ev3-ports:in4")
    fd = os.open(us / "mode", os.O_WRONLY)
    try:
        t0 = time.monotonic()
        os.pwrite(fd, b"US-DIST-IN", 0)
        took = time.monotonic() - t0
    finally:
        os.close(fd)
    assert took >= 0.015, took  # the 20 ms acknowledgement, at time x1
    assert (us / "units").read_text() == "in\n"


def test_driving_into_the_wall_and_the_snapshot(start_sim):
    sim = start_sim(PEN, args=["--time-scale", "5"])
    root = sim.root()
    drive(root, 800)
    touch = find_device(root, "lego-sensor", "ev3-ports:in1")
    # 200 - 50 - 12 = 138 cm to the wall: about 3.5 s simulated.
    sim.wait_for(lambda: (touch / "value0").read_text() == "1\n", timeout=10)
    # The bumper presses 0.6 cm before the body touches; then the body stops at the wall (its
    # front corners: the wheels may have started a step apart, a fraction of a degree).
    def front(r):
        h = math.radians(r["heading"])
        return r["x"] + 12 * math.cos(h) + 7.5 * abs(math.sin(h))

    r = sim.wait_for(lambda: (lambda r: r if front(r) > 199.95 else None)(sim.robot()))
    assert r["bumper"] is True
    assert front(r) <= 200.0 + 0.02  # the status rounds x and heading to 0.01
    sim.wait_for(lambda: "stalled" in sim.robot()["ports"]["outB"]["state"])  # after 100 ms blocked
    os.kill(sim.proc.pid, 10)  # SIGUSR1: snapshot and status now
    sim.wait_for(lambda: sim.snapshot.exists())
    svg = ET.parse(sim.snapshot).getroot()
    ns = "{http://www.w3.org/2000/svg}"
    assert svg.tag == f"{ns}svg"
    assert svg.findall(f"{ns}polyline"), "no path drawn"
    assert len(svg.findall(f"{ns}polygon")) >= 3  # floor patch, box, robot
    assert sim.stop() == 0
    assert not mounted(root)


def test_two_robots_see_each_other(start_sim):
    world = "bounds 0 0 400 200\n"
    sim = start_sim(world, [("alice", "100,100,0"), ("bob", "200,100,180")], ["--time-scale", "5"])
    a, b = sim.root("alice"), sim.root("bob")
    us_a = find_device(a, "lego-sensor", "ev3-ports:in4")
    us_b = find_device(b, "lego-sensor", "ev3-ports:in4")
    # alice's sensor at x = 111; bob faces her, his bumper at x = 188: 77 cm, both ways.
    assert (us_a / "value0").read_text() == "770\n"
    assert (us_b / "value0").read_text() == "770\n"
    drive(a, 600)
    touch_b = find_device(b, "lego-sensor", "ev3-ports:in1")
    sim.wait_for(lambda: (touch_b / "value0").read_text() == "1\n", timeout=10)
    robots = {r["name"]: r for r in sim.status()["robots"]}
    assert robots["alice"]["bumper"] and robots["bob"]["bumper"]
    assert robots["bob"]["x"] == 200.0  # not pushed


def test_duration_and_exit_outputs(start_sim, tmp_path):
    sim = start_sim(PEN, args=["--time-scale", "20", "--duration", "2"])
    assert sim.proc.wait(timeout=10) == 0
    status = json.loads(sim.status_file.read_text())
    assert status["time"] >= 2.0
    assert len(status["robots"]) == 1
    assert sim.snapshot.exists()
    assert not mounted(sim.root())


def run_sim(args, timeout=10):
    return subprocess.run([str(ev3_sim_path())] + args, capture_output=True, text=True, timeout=timeout)


def test_bad_world_file_exits_2(tmp_path):
    world = tmp_path / "world.txt"
    world.write_text("bounds 0 0 100 100\nwall 0 0 10 10\nwall 0 0 1 1\nfloor blue bxo 1 2 3 4\n")
    r = run_sim(["--world", str(world), "--sysfs-root", str(tmp_path / "r")])
    assert r.returncode == 2
    assert f"{world} line 4 col 12: unknown shape 'bxo'" in r.stderr
    world.write_text("bounds 0 0 100 100\nwall 50 0 50 100\n")
    r = run_sim(["--world", str(world), "--sysfs-root", str(tmp_path / "r"), "--robot", "50,50,0"])
    assert r.returncode == 2
    assert "overlaps a wall" in r.stderr
    r = run_sim(["--world", str(world), "--sysfs-root", str(tmp_path / "r")])
    assert r.returncode == 2
    assert "robot1 has no start pose" in r.stderr
    r = run_sim(["--world", str(tmp_path / "nope.txt"), "--sysfs-root", str(tmp_path / "r")])
    assert r.returncode == 2
    assert "cannot read the world file" in r.stderr
    r = run_sim(["--sysfs-root", str(tmp_path / "r")])
    assert r.returncode == 2
    assert "missing --world" in r.stderr


def test_without_dev_fuse_it_says_so(tmp_path):
    # /dev hidden in a private mount namespace: ev3-sim must name /dev/fuse and exit 1.
    world = tmp_path / "world.txt"
    world.write_text(PEN)
    r = subprocess.run(["unshare", "--mount", "sh", "-c", 'mount -t tmpfs none /dev && exec "$@"', "sh",
                        str(ev3_sim_path()), "--world", str(world), "--sysfs-root", str(tmp_path / "r")],
                       capture_output=True, text=True, timeout=10)
    assert r.returncode == 1, r.stderr
    assert "/dev/fuse is missing" in r.stderr
