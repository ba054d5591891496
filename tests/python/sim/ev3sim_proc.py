"""Runs ev3-sim for the tests: start it on a temporary directory, wait until every robot's tree is
mounted, send control commands through its FIFO, read its status, stop it (SIGTERM, exit 0) and
make sure nothing stays mounted."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
TREES = REPO / "tests" / "data" / "ev3dev"
START_TIMEOUT = 10.0


def ev3_sim_path() -> Path:
    return Path(os.environ.get("EV3_BIN") or REPO / "build" / "bin") / "ev3-sim"


def mounted(path: Path) -> bool:
    real = os.path.realpath(path)
    with open("/proc/self/mounts") as f:
        return any(line.split()[1] == real for line in f)


class Sim:
    """One ev3-sim process with one or more robots."""

    def __init__(self, tmp: Path, world: str, robots: list[tuple[str, str | None]],
                 args: list[str] | None = None) -> None:
        """robots: (name, "x,y,heading" or None for the world's start line) per robot."""
        self.tmp = tmp
        self.world = tmp / "world.txt"
        self.world.write_text(world)
        self.control = tmp / "control"
        self.status_file = tmp / "status.json"
        self.snapshot = tmp / "snapshot.svg"
        self.log = tmp / "ev3-sim.log"
        self.roots = {name: tmp / name for name, _ in robots}
        cmd = [str(ev3_sim_path()), "--world", str(self.world), "--control", str(self.control),
               "--status", str(self.status_file), "--snapshot", str(self.snapshot), "--log-level", "3"]
        for name, pose in robots:
            cmd += ["--sysfs-root", str(self.roots[name]), "--name", name]
            if pose is not None:
                cmd += ["--robot", pose]
        cmd += args or []
        self.cmd = cmd
        self._log = open(self.log, "wb")
        self.proc = subprocess.Popen(cmd, stdout=self._log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + START_TIMEOUT
        while not all((root / "class" / "tacho-motor").is_dir() for root in self.roots.values()):
            if self.proc.poll() is not None:
                raise AssertionError(f"ev3-sim exited with {self.proc.returncode}:\n{self.log_text()}")
            if time.monotonic() > deadline:
                raise AssertionError(f"ev3-sim did not mount its trees in {START_TIMEOUT} s:\n{self.log_text()}")
            time.sleep(0.01)

    def log_text(self) -> str:
        self._log.flush()
        return self.log.read_text(errors="replace")[-4000:]

    def root(self, name: str | None = None) -> Path:
        return self.roots[name] if name else next(iter(self.roots.values()))

    def ctl(self, line: str) -> None:
        with open(self.control, "w") as f:
            f.write(line + "\n")

    def status(self) -> dict:
        """The robots' state, as the simulator writes it on `status`."""
        if self.status_file.exists():
            self.status_file.unlink()
        self.ctl(f"status {self.status_file}")
        deadline = time.monotonic() + START_TIMEOUT
        while not self.status_file.exists():
            if time.monotonic() > deadline:
                raise AssertionError(f"no status from ev3-sim:\n{self.log_text()}")
            time.sleep(0.005)
        return json.loads(self.status_file.read_text())

    def robot(self, name: str | None = None) -> dict:
        robots = self.status()["robots"]
        return next(r for r in robots if name is None or r["name"] == name)

    def wait_for(self, what, timeout: float = 5.0, step: float = 0.005):
        """Polls what() until it is true (returns it) or fails after timeout seconds."""
        deadline = time.monotonic() + timeout
        while True:
            value = what()
            if value:
                return value
            if time.monotonic() > deadline:
                raise AssertionError(f"timed out waiting for {what}:\n{self.log_text()}")
            time.sleep(step)

    def stop(self) -> int:
        """SIGTERM; returns the exit status. The mounts must be gone afterwards."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._log.close()
        return self.proc.returncode

    def cleanup(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        for root in self.roots.values():
            if mounted(root):
                subprocess.run(["fusermount3", "-u", "-z", str(root)], check=False)
        if not self._log.closed:
            self._log.close()


def cannot_run() -> str | None:
    """Why ev3-sim cannot run here (the program missing, no usable /dev/fuse), or None. Tests
    fail with it, never skip."""
    exe = ev3_sim_path()
    if not (exe.is_file() and os.access(exe, os.X_OK)):
        return f"{exe} is missing: build it with `make build` (or set EV3_BIN)"
    if not os.path.exists("/dev/fuse") or not os.access("/dev/fuse", os.R_OK | os.W_OK):
        return ("/dev/fuse is missing or not usable: ev3-sim serves the ev3dev tree through FUSE, "
                "so its tests cannot run (load the fuse module, or give the container --device /dev/fuse)")
    return None


class Sims:
    """The ev3-sim processes of one test, each on a fresh directory under tmp."""

    def __init__(self, tmp: Path) -> None:
        self.tmp = tmp
        self.started: list[Sim] = []

    def start(self, world: str, robots=None, args=None) -> Sim:
        d = self.tmp / f"sim{len(self.started) + 1}"
        d.mkdir()
        sim = Sim(d, world, robots or [("robot1", None)], args)
        self.started.append(sim)
        return sim

    def stop_all(self) -> dict:
        """SIGTERM to each (must exit 0, nothing left mounted); returns {dir: (code, log)} of the bad ones."""
        codes = {}
        try:
            for s in self.started:
                codes[str(s.tmp)] = (s.stop(), s)
        finally:
            for s in self.started:
                s.cleanup()
        return {k: (code, s.log_text()) for k, (code, s) in codes.items() if code != 0}
