#!/usr/bin/env python3
"""The real ev3-agent on ev3-sim: from the bumper's press to both motors' `stop` written, and how far
the robot runs past the ultrasonic's threshold, measured end to end (docs/benchmarks.md "Robot").

  .venv/bin/python bench/robot_sim.py [--bin build/bin] [--presses 30] [--tick-ms 20] [--speed 700]
                             [--stops 3] [--holds 10] [--agent-prefix qemu-arm --agent-bin build/arm/bin]

One ev3-sim (real time, --log-level 4: every write stamped with the simulated time), one ev3-master
(console on stdin), one ev3-agent on the robot's tree. Bumper: each press is a `drive speed=S` from
a random x in front of a box the ultrasonic's ray misses; the press time is ev3-sim's status
(`bumper_pressed_at`), the stop times its log lines `write .../command <- 'stop'`. Ultrasonic: a
`drive speed=S stop=coast|brake|hold` towards a wall; the distance from the point where the sensor
was 20 cm from the wall (PROXIMITY_ALERT's threshold) to where the bumper's face came to rest.
Watchdog: the master stopped (SIGSTOP) while `drive` runs; the delay from the agent's last contact
(the end of the last run-timed written, less 500 ms) to both motors' `stop` in ev3-sim's log.
Prints one table row per series. The simulated clock runs at real time (--time-scale 1), so the
figures are the agent's real-time loop; on a loaded machine late wake-ups show in the maximum.
"""

from __future__ import annotations

import argparse
import os
import random
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "tests" / "python" / "blackbox"), str(REPO / "tests" / "python" / "sim")]
from ev3net import free_ports, wait_until  # noqa: E402  (the black-box tests' helpers)
from ev3sim_proc import Sim  # noqa: E402
BOX = "bounds 0 0 600 300\nbox 160 152 30 40\nstart 60 150 0\n"
WALL = "bounds 0 0 600 300\nwall 300 0 300 300\nstart 60 150 0\n"
FRONT, SENSOR = 12.0, 11.0  # model A in ev3-sim: the bumper's face and the ultrasonic, cm ahead of the axle


class Rig:
    """ev3-sim (debug log: every write stamped with the simulated time), ev3-master (console on
    stdin), ev3-agent on the robot's tree."""

    def __init__(self, args, world: str, tmp: Path) -> None:
        os.environ["EV3_BIN"] = str(args.bin)
        self.sim = Sim(tmp, world, [("robot1", None)], ["--log-level", "4"])
        mport, aport = free_ports(2)
        self.out = tmp / "master.out"
        self.master = subprocess.Popen([str(args.bin / "ev3-master"), "--port", str(mport), "--bind", "127.0.0.1",
                                        "--broadcast", f"127.0.0.1:{aport}", "--log-level", "2"],
                                       stdin=subprocess.PIPE, stdout=open(self.out, "wb"), stderr=subprocess.STDOUT)
        agent = [str(args.agent_bin / "ev3-agent"), "--port", str(aport), "--bind", "127.0.0.1", "--broadcast",
                 f"127.0.0.1:{mport}", "--heartbeat-ms", "200", "--watchdog-ms", "500", "--sysfs-root",
                 str(self.sim.root()), "--tick-ms",
                 str(args.tick_ms), "--log-level", "2", "--log-file", str(tmp / "agent.log")]
        self.agent = subprocess.Popen(([args.agent_prefix] if args.agent_prefix else []) + agent,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        wait_until(lambda: "agent 2 registered" in self.out.read_text(errors="replace"), 15, "the agent to register")

    def say(self, line: str) -> None:
        self.master.stdin.write((line + "\n").encode())
        self.master.stdin.flush()

    def interrupted(self, n: int) -> bool:
        return self.out.read_text(errors="replace").count("ACTION_INTERR") >= n

    def at_rest(self):
        r = self.sim.robot()
        return r if abs(r["speed"]) < 1e-3 else None

    def run(self, behaviour: str, x: float, n: int) -> dict:
        """Places the robot at x, runs the behaviour to its n-th ACTION_INTERR, waits until it rests."""
        self.say("stop 2")
        wait_until(self.at_rest, 5, "the robot at rest")
        self.sim.ctl(f"place {x:.2f} 150 0")
        mark = self.sim.log.stat().st_size
        self.say(f"behaviour 2 {behaviour}")
        self.say("start 2")
        wait_until(lambda: self.interrupted(n), 15, f"ACTION_INTERR #{n}")
        r = wait_until(self.at_rest, 5, "the robot at rest")
        r["mark"] = mark
        return r

    def log_since(self, mark: int) -> str:
        with open(self.sim.log, "rb") as f:
            f.seek(mark)
            return f.read().decode(errors="replace")

    def close(self) -> None:
        for p in (self.agent, self.master):
            p.send_signal(signal.SIGTERM)
            p.wait(10)
        self.sim.stop()
        self.sim.cleanup()


def stops_after(log: str, t0: float) -> list[float]:
    first: dict[str, float] = {}
    for m in re.finditer(r"t=([0-9.]+) s: write (\S+)/command <- 'stop'", log):
        t = float(m.group(1))
        if t >= t0 and m.group(2) not in first:
            first[m.group(2)] = t
    return sorted(first.values())


def bumper(args) -> None:
    with tempfile.TemporaryDirectory(prefix="robot_sim.") as d:
        rig = Rig(args, BOX, Path(d))
        lat = []
        try:
            for i in range(args.presses):
                r = rig.run(f"drive speed={args.speed}", random.uniform(110, 125), i + 1)
                stops = wait_until(lambda: (lambda s: s if len(s) == 2 else None)(
                    stops_after(rig.log_since(r["mark"]), r["bumper_pressed_at"])), 3,
                    f"both motors' stop after press {i + 1} in ev3-sim's log")
                lat.append((stops[-1] - r["bumper_pressed_at"]) * 1000)
        finally:
            rig.close()
    lat.sort()
    p95 = lat[min(len(lat) - 1, int(round(0.95 * (len(lat) - 1))))]
    print(f"| bumper -> both stops written | {args.speed} | {args.tick_ms} | {len(lat)} | "
          f"{statistics.median(lat):.1f} / {p95:.1f} / {lat[-1]:.1f} ms |", flush=True)


def watchdog(args) -> None:
    """The contact watchdog: `drive` runs (RunForever, written as run-timed to the bound), the master
    is stopped (SIGSTOP: no PONG any more) until both motors' `stop` are in ev3-sim's log, then goes
    on (SIGCONT) and the robot drives again. From the log alone: the last run-timed written before
    the stop ends at the bound (its time + time_sp), the last contact was the bound less the
    watchdog (500 ms), and the stop's delay is counted from that contact."""
    with tempfile.TemporaryDirectory(prefix="robot_sim.") as d:
        rig = Rig(args, "bounds 0 0 5000 300\nstart 60 150 0\n", Path(d))
        delay = []
        try:
            rig.say(f"behaviour 2 drive speed={args.speed // 3}")
            rig.say("start 2")
            for i in range(args.holds):
                wait_until(lambda: abs(rig.sim.robot()["speed"]) > 1e-3, 5, "the robot driving")
                time.sleep(0.5)
                mark = rig.sim.log.stat().st_size
                rig.master.send_signal(signal.SIGSTOP)
                try:
                    log = wait_until(lambda: (lambda t: t if len(stops_after(t, 0)) == 2 else None)(rig.log_since(mark)),
                                     3, f"both motors' stop after the master stopped ({i + 1})")
                finally:
                    rig.master.send_signal(signal.SIGCONT)
                before = rig.log_since(0)[:mark + log.index("<- 'stop'")]
                timed = [(float(m.group(1)), int(m.group(2))) for m in
                         re.finditer(r"t=([0-9.]+) s: write \S+/time_sp <- '(\d+)'", before)]
                t, left = timed[-1]
                contact = t + left / 1000 - 0.5
                delay.append((stops_after(log, 0)[-1] - contact) * 1000)
        finally:
            rig.close()
    delay.sort()
    print(f"| master silent: last contact -> both stops written (watchdog 500 ms) | {args.speed // 3} | "
          f"{args.tick_ms} | {len(delay)} | {statistics.median(delay):.1f} / {delay[-1]:.1f} (max) ms |", flush=True)


def ultrasonic(args) -> None:
    wall = 300.0
    with tempfile.TemporaryDirectory(prefix="robot_sim.") as d:
        rig = Rig(args, WALL, Path(d))
        rows = []
        try:
            n = 0
            for how in ("coast", "brake", "hold"):
                past = []
                for _ in range(args.stops):
                    n += 1
                    r = rig.run(f"drive speed={args.speed} stop={how}", random.uniform(150, 170), n)
                    # The sensor was 20 cm from the wall at x = wall - 20 - SENSOR; the robot rests at r["x"].
                    past.append(r["x"] - (wall - 20 - SENSOR))
                rows.append((how, past))
        finally:
            rig.close()
    for how, past in rows:
        print(f"| ultrasonic 20 cm -> rest, stop={how} | {args.speed} | {args.tick_ms} | {len(past)} | "
              f"{min(past):.2f} .. {max(past):.2f} cm past the threshold |", flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", type=Path, default=REPO / "build" / "bin")
    ap.add_argument("--agent-bin", type=Path, default=None, help="where ev3-agent is (default --bin)")
    ap.add_argument("--agent-prefix", default="", help="run the agent under this (qemu-arm)")
    ap.add_argument("--presses", type=int, default=30)
    ap.add_argument("--stops", type=int, default=3, help="ultrasonic runs per stop action")
    ap.add_argument("--holds", type=int, default=10, help="watchdog holds (the master stopped)")
    ap.add_argument("--tick-ms", type=int, default=20)
    ap.add_argument("--speed", type=int, default=700)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    args.agent_bin = args.agent_bin or args.bin
    random.seed(args.seed)
    if not os.path.exists("/dev/fuse"):
        print("robot_sim: /dev/fuse is missing: ev3-sim cannot run", file=sys.stderr)
        return 1
    print("| what | speed (deg/s) | tick (ms) | runs | median / p95 / max, or range |")
    print("|---|---:|---:|---:|---|", flush=True)
    if args.presses > 0:
        bumper(args)
    if args.stops > 0:
        ultrasonic(args)
    if args.holds > 0:
        watchdog(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
