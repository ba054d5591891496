"""The reference ev3dev sysfs trees (tests/data/ev3dev) and their checker, check_tree.py.

Each test copies a reference tree into a temporary directory with the sysfs modes of its manifest
(check_tree.py --materialize), changes one thing the way a faulty simulator or device layer would,
and runs check_tree.py on it as its users do: a clean copy passes; a missing attribute, a wrong
mode, a stray file, a malformed value, a mode-dependent attribute left stale or a device the
reference has and the candidate lacks fails with a line naming it.
"""

from __future__ import annotations

import contextlib
import importlib.util
import io
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parents[2] / "tests" / "data" / "ev3dev"
CHECK = DATA / "check_tree.py"
GENERATIONS = ("stretch", "jessie")
MOTOR0 = {
    "stretch": "devices/platform/ev3-ports/ev3-ports:outB/lego-port/port5/"
               "ev3-ports:outB:lego-ev3-l-motor/tacho-motor/motor0",
    "jessie": "devices/platform/legoev3-ports/lego-port/port5/outB:lego-ev3-l-motor/"
              "tacho-motor/motor0",
}
LED = {"stretch": "class/leds/led0:green:brick-status", "jessie": "class/leds/ev3:left:green:ev3dev"}


def _load_checker():
    spec = importlib.util.spec_from_file_location("check_tree", CHECK)
    module = importlib.util.module_from_spec(spec)
    sys.modules["check_tree"] = module  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module


CHECKER = _load_checker()


def check(*args: str | Path) -> subprocess.CompletedProcess:
    """check_tree.py ARGS, run in this process (one interpreter start per test run, not per
    call); test_the_command_line runs the script itself."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = CHECKER.main([str(a) for a in args])
        except SystemExit as stop:
            if isinstance(stop.code, str):
                print(stop.code, file=sys.stderr)
                code = 1
            else:
                code = stop.code
    return subprocess.CompletedProcess(args, code, out.getvalue(), err.getvalue())


def materialize(tmp_path: Path, generation: str, *overlays: str) -> Path:
    dest = tmp_path / generation
    extra = [a for o in overlays for a in ("--overlay", DATA / "overlays" / o / generation)]
    result = check("--materialize", *extra, DATA / generation, dest)
    assert result.returncode == 0, result.stderr
    return dest


def rewrite(path: Path, text: str) -> None:
    """Replace a file's content, keeping its sysfs mode (even 0444 for a non-root user)."""
    mode = path.stat().st_mode
    path.chmod(0o644)
    path.write_text(text)
    path.chmod(mode)


def problems(result: subprocess.CompletedProcess) -> list[str]:
    assert result.returncode == 1, (result.returncode, result.stdout, result.stderr)
    return result.stdout.splitlines()


def test_committed_trees_are_what_make_trees_writes():
    result = subprocess.run([sys.executable, str(DATA / "make_trees.py"), "--check"],
                            capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stderr


@pytest.mark.parametrize("generation", GENERATIONS)
def test_a_copy_with_sysfs_modes_passes_even_exactly(tmp_path, generation):
    tree = materialize(tmp_path, generation)
    assert check(DATA / generation, tree).returncode == 0
    assert check("--exact", DATA / generation, tree).returncode == 0
    assert (tree / MOTOR0[generation] / "command").stat().st_mode & 0o777 == 0o200
    assert (tree / MOTOR0[generation] / "position").stat().st_mode & 0o777 == 0o644
    assert (tree / MOTOR0[generation] / "speed").stat().st_mode & 0o777 == 0o444
    assert os.readlink(tree / "class/tacho-motor/motor0") == "../../" + MOTOR0[generation]


@pytest.mark.parametrize("generation", GENERATIONS)
def test_a_plain_copy_without_sysfs_modes_fails_on_the_modes(tmp_path, generation):
    tree = tmp_path / "plain"
    shutil.copytree(DATA / generation, tree, symlinks=True)
    (tree / MOTOR0[generation] / "speed").chmod(0o644)
    lines = problems(check(DATA / generation, tree))
    assert f"mode: {MOTOR0[generation]}/speed is 0644, expected 0444" in lines


@pytest.mark.parametrize("generation", GENERATIONS)
def test_a_deleted_attribute_is_named(tmp_path, generation):
    tree = materialize(tmp_path, generation)
    (tree / MOTOR0[generation] / "stop_actions").unlink()
    assert problems(check(DATA / generation, tree)) == [
        f"missing: {MOTOR0[generation]}/stop_actions"]


@pytest.mark.parametrize("generation", GENERATIONS)
def test_a_changed_mode_is_named(tmp_path, generation):
    tree = materialize(tmp_path, generation)
    (tree / MOTOR0[generation] / "position").chmod(0o444)
    (tree / MOTOR0[generation] / "command").chmod(0o644)
    assert problems(check(DATA / generation, tree)) == [
        f"mode: {MOTOR0[generation]}/command is 0644, expected 0200",
        f"mode: {MOTOR0[generation]}/position is 0444, expected 0644"]


def test_an_extra_attribute_and_a_wrong_symlink_are_named(tmp_path):
    tree = materialize(tmp_path, "stretch")
    (tree / MOTOR0["stretch"] / "encoder_polarity").write_text("normal\n")
    link = tree / "class/tacho-motor/motor0"
    link.unlink()
    link.symlink_to("../../devices/" + MOTOR0["stretch"])
    lines = problems(check(DATA / "stretch", tree))
    assert f"extra: {MOTOR0['stretch']}/encoder_polarity" in lines
    assert any(line.startswith("symlink: class/tacho-motor/motor0 -> ../../devices/devices/")
               for line in lines), lines


@pytest.mark.parametrize(("attribute", "text", "expected"), [
    ("position", "12.5\n", "expected an integer"),
    ("speed", "100", "expected an integer"),
    ("state", "running flying\n", "unknown flags ['flying']"),
    ("stop_action", "park\n", "expected one of stop_actions: coast brake hold"),
    ("max_speed", "900\n", "expected '1050\\n'"),
])
def test_malformed_motor_values_are_named(tmp_path, attribute, text, expected):
    tree = materialize(tmp_path, "stretch")
    rewrite(tree / MOTOR0["stretch"] / attribute, text)
    lines = problems(check(DATA / "stretch", tree))
    assert len(lines) == 1 and lines[0].startswith(f"content: {MOTOR0['stretch']}/{attribute}")
    assert expected in lines[0]


def test_dynamic_values_are_judged_by_format_only(tmp_path):
    tree = materialize(tmp_path, "stretch")
    motor = tree / MOTOR0["stretch"]
    for attribute, text in [("position", "-1234\n"), ("speed", "1050\n"), ("speed_sp", "-500\n"),
                            ("state", "running ramping\n"), ("stop_action", "hold\n")]:
        rewrite(motor / attribute, text)
    rewrite(tree / "class/lego-sensor/sensor2/value0", "314\n")
    rewrite(tree / "class/power_supply/lego-ev3-battery/voltage_now", "6912000\n")
    assert check(DATA / "stretch", tree).returncode == 0
    lines = problems(check("--exact", DATA / "stretch", tree))
    assert f"content: {MOTOR0['stretch']}/position is b'-1234\\n', expected the reference's " \
           f"b'0\\n' (--exact)" in lines


def test_sensor_attributes_follow_the_mode(tmp_path):
    tree = materialize(tmp_path, "stretch")
    color = tree / "class/lego-sensor/sensor1"  # lego-ev3-color on in3
    rewrite(color / "mode", "RGB-RAW\n")
    lines = problems(check(DATA / "stretch", tree))
    assert any(line.endswith("lego-sensor/sensor1/num_values is '1\\n', expected '4\\n' in "
                             "mode RGB-RAW") for line in lines), lines
    assert any(line.endswith("sensor1/bin_data_format is 's8\\n', expected 's16\\n' in mode "
                             "RGB-RAW") for line in lines), lines
    for attribute, text in [("num_values", "4\n"), ("units", "\n"), ("bin_data_format", "s16\n"),
                            ("value1", "300\n"), ("value2", "200\n"), ("value3", "40\n")]:
        rewrite(color / attribute, text)
    assert check(DATA / "stretch", tree).returncode == 0
    rewrite(color / "value3", "")  # a value the mode has must read as a number
    assert any("value3" in line and "expected an integer" in line
               for line in problems(check(DATA / "stretch", tree)))


def test_values_beyond_num_values_and_unsupported_reads_fail_on_a_live_tree(tmp_path):
    tree = materialize(tmp_path, "stretch")
    # A plain copy cannot fail a read: check_tree --live demands the errors a brick gives.
    lines = problems(check("--live", DATA / "stretch", tree))
    assert any(line.startswith("content: ") and "sensor0/value1" in line and "ENXIO" in line
               for line in lines)
    assert any("sensor2/poll_ms" in line and "EOPNOTSUPP" in line for line in lines)
    rewrite(tree / "class/lego-sensor/sensor0/value1", "0\n")
    assert any("sensor0/value1 must be an empty placeholder" in line
               for line in problems(check(DATA / "stretch", tree)))


@pytest.mark.parametrize("generation", GENERATIONS)
def test_devices_are_matched_by_address_and_driver_not_by_number(tmp_path, generation):
    tree = materialize(tmp_path, generation)
    motor0 = tree / MOTOR0[generation]
    motor0.rename(motor0.with_name("motor7"))
    (tree / "class/tacho-motor/motor0").unlink()
    (tree / "class/tacho-motor/motor7").symlink_to("../../" + MOTOR0[generation][:-1] + "7")
    assert check(DATA / generation, tree).returncode == 0


@pytest.mark.parametrize("generation", GENERATIONS)
def test_an_unplugged_device_is_named(tmp_path, generation):
    tree = materialize(tmp_path, generation)
    (tree / "class/lego-sensor/sensor2").unlink()  # the ultrasonic sensor on in4
    shutil.rmtree(tree / os.readlink(DATA / generation / "class/lego-sensor/sensor2")
                  .removeprefix("../../"), ignore_errors=True)
    lines = problems(check(DATA / generation, tree))
    address = "ev3-ports:in4" if generation == "stretch" else "in4"
    assert lines[0] == (f"device: no lego-sensor device with driver_name lego-ev3-us and "
                        f"address {address} (the reference's class/lego-sensor/sensor2)")


@pytest.mark.parametrize("generation", GENERATIONS)
def test_led_delay_attributes_exist_exactly_while_the_trigger_is_timer(tmp_path, generation):
    tree = materialize(tmp_path, generation)
    led = tree / LED[generation]
    trigger = (led / "trigger").read_text().replace("[none]", "none").replace(" timer ", " [timer] ")
    rewrite(led / "trigger", trigger)
    lines = problems(check(DATA / generation, tree))
    assert sorted(line.split(": ")[1].split("/")[-1].split(" ")[0] for line in lines) == [
        "delay_off", "delay_on"]
    assert all(line.startswith("missing: ") for line in lines)
    real = tree / os.path.normpath(os.path.join(os.path.dirname(LED[generation]),
                                                os.readlink(led)))
    for name in ("delay_on", "delay_off"):
        (real / name).write_text("500\n")
        (real / name).chmod(0o644)
    assert check(DATA / generation, tree).returncode == 0
    rewrite(led / "trigger", trigger.replace("[timer]", "timer").replace("none", "[none]", 1))
    assert sorted(line.split("/")[-1] for line in problems(check(DATA / generation, tree))) == [
        "delay_off", "delay_on"]


@pytest.mark.parametrize("generation", GENERATIONS)
def test_brightness_above_max_and_a_trigger_list_without_selection_fail(tmp_path, generation):
    tree = materialize(tmp_path, generation)
    rewrite(tree / LED[generation] / "brightness", "256\n")
    rewrite(tree / LED[generation] / "trigger", "none timer heartbeat\n")
    lines = problems(check(DATA / generation, tree))
    assert len(lines) == 2
    assert "above max_brightness" in lines[0] and "exactly one [selected]" in lines[1]


@pytest.mark.parametrize("generation", GENERATIONS)
def test_the_gyro_overlay(tmp_path, generation):
    tree = materialize(tmp_path, generation, "gyro-in2")
    overlay = DATA / "overlays" / "gyro-in2" / generation
    assert check("--overlay", overlay, DATA / generation, tree).returncode == 0
    lines = problems(check(DATA / generation, tree))  # without the overlay the gyro is extra
    assert "extra: class/lego-sensor/sensor3" in lines
    modes = (tree / "class/lego-sensor/sensor3/modes").read_text()
    assert modes.split()[:2] == ["GYRO-ANG", "GYRO-RATE"]


def test_the_generations_differ(tmp_path):
    tree = materialize(tmp_path, "jessie")
    lines = problems(check(DATA / "stretch", tree))
    assert "missing: class/power_supply/lego-ev3-battery" in lines
    assert "extra: class/power_supply/legoev3-battery" in lines


def test_bad_usage_is_refused(tmp_path):
    result = check(tmp_path / "nowhere", tmp_path)
    assert result.returncode == 2 and "is not a directory" in result.stderr
    empty = tmp_path / "empty"
    empty.mkdir()
    result = check(empty, tmp_path)
    assert result.returncode == 1 and "no manifest" in result.stderr


def test_the_command_line(tmp_path):
    tree = materialize(tmp_path, "stretch")
    ok = subprocess.run([sys.executable, str(CHECK), str(DATA / "stretch"), str(tree)],
                        capture_output=True, text=True, check=False)
    assert (ok.returncode, ok.stdout, ok.stderr) == (0, "", "")
    (tree / MOTOR0["stretch"] / "speed").chmod(0o644)
    bad = subprocess.run([sys.executable, str(CHECK), str(DATA / "stretch"), str(tree)],
                         capture_output=True, text=True, check=False)
    assert bad.returncode == 1
    assert bad.stdout == f"mode: {MOTOR0['stretch']}/speed is 0644, expected 0444\n"
    assert "1 difference(s)" in bad.stderr
