#!/usr/bin/env python3
"""How far each robot's odometry drifts from where it really is over an explore mission
(docs/benchmarks.md "Odometry"): ev3-sim's arena (sim/worlds/arena.txt) with its robots at the
world's start poses, one ev3-agent each told its start pose (--pose), ev3-master with --db; every
robot runs `explore` for --seconds. ev3-sim's status (the true pose) is sampled every 100 ms; each
pose report in the record (SENSOR_VALUE pose ODOM, stamped when the master took it) is compared
with the true pose at that moment, interpolated between two samples.

  .venv/bin/python bench/odometry_drift.py [--bin build/bin] [--seconds 120] [--robots 3] [--speed N]

Prints per robot the distance it travelled (the truth's path), the position error at the end and
its largest, the error per metre travelled, and the heading error at the end and its largest.
"""

from __future__ import annotations

import argparse
import bisect
import math
import os
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "tests" / "python" / "blackbox"), str(REPO / "tests" / "python" / "sim")]
from ev3net import free_ports, wait_until  # noqa: E402  (the black-box tests' helpers)
from ev3sim_proc import Sim  # noqa: E402

WORLD = REPO / "sim" / "worlds" / "arena.txt"


def starts(world: str) -> list[str]:
    return [",".join(line.split()[1:4]) for line in world.splitlines() if line.startswith("start ")]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", type=Path, default=REPO / "build" / "bin")
    ap.add_argument("--seconds", type=float, default=120.0)
    ap.add_argument("--robots", type=int, default=3, choices=(1, 2, 3, 4))
    ap.add_argument("--speed", type=int, help="explore's speed (counts/s; default: the behaviour's)")
    ap.add_argument("--keep", type=Path, help="run in this directory and keep its logs and record")
    args = ap.parse_args()
    os.environ["EV3_BIN"] = str(args.bin)
    world = WORLD.read_text()
    poses = starts(world)[:args.robots]
    with tempfile.TemporaryDirectory(prefix="odometry-") as d:
        tmp = args.keep or Path(d)
        tmp.mkdir(parents=True, exist_ok=True)
        names = [f"robot{i + 1}" for i in range(args.robots)]
        sim = Sim(tmp, world, list(zip(names, poses)))
        mport, *aports = free_ports(1 + args.robots)
        db, status = tmp / "mission.db", tmp / "master.json"
        master = subprocess.Popen([str(args.bin / "ev3-master"), "--port", str(mport), "--bind", "127.0.0.1",
                                   *sum((["--broadcast", f"127.0.0.1:{p}"] for p in aports), []),
                                   "--state-file", str(tmp / "master.state"), "--db", str(db),
                                   "--status-json", str(status), "--log-level", "2"],
                                  stdin=subprocess.PIPE, stdout=open(tmp / "master.out", "wb"), stderr=subprocess.STDOUT)
        agents = [subprocess.Popen([str(args.bin / "ev3-agent"), "--port", str(p), "--bind", "127.0.0.1",
                                    "--broadcast", f"127.0.0.1:{mport}", "--sysfs-root", str(sim.root(n)),
                                    "--pose", pose, "--log-level", "1"],
                                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                  for n, p, pose in zip(names, aports, poses)]
        truth: dict[str, list[tuple[float, float, float, float]]] = {n: [] for n in names}  # t_ms, x, y, heading
        try:
            def active() -> bool:
                try:
                    import json
                    s = json.loads(status.read_text())
                except (OSError, ValueError):
                    return False
                return sum(a["state"] == "ACTIVE" for a in s["agents"]) == args.robots
            wait_until(active, 15, f"{args.robots} ACTIVE agents")
            explore = "behaviour all explore" + (f" speed={args.speed}" if args.speed else "")
            master.stdin.write(f"{explore}\nstart all\n".encode())
            master.stdin.flush()
            end = time.monotonic() + args.seconds
            while time.monotonic() < end:
                t0 = time.time()
                robots = sim.status()["robots"]
                t = (t0 + time.time()) / 2 * 1000
                for r in robots:
                    truth[r["name"]].append((t, r["x"], r["y"], r["heading"]))
                time.sleep(0.1)
            master.stdin.write(b"stop all\n")
            master.stdin.flush()
            time.sleep(1.0)
        finally:
            for p in [*agents, master]:
                p.terminate()
                p.wait(10)
            sim.stop()
        con = sqlite3.connect(db)
        ids = [r[0] for r in con.execute("SELECT id FROM robots ORDER BY first_seen_ms, id")]
        by_port = {r[0]: r[1] for r in con.execute("SELECT id, address FROM robots")}
        port_of = {f"127.0.0.1:{p}": n for n, p in zip(names, aports)}
        print(f"odometry against ev3-sim's truth: {WORLD.name}, {args.robots} robots exploring {args.seconds:.0f} s"
              + (f" at speed={args.speed}" if args.speed else ""))
        print("robot   travelled   reports   position error end / max   per metre   heading error end / max")
        for rid in ids:
            name = port_of.get(by_port[rid])
            if name is None:
                continue
            reports = [(t, float(x) / 10, float(y) / 10, float(h)) for t, x, y, h in (
                (t, *text.split(":")[2:5]) for t, text in con.execute(
                    "SELECT t_ms, text FROM reports WHERE agent = ? AND text LIKE 'pose:%' ORDER BY seq", (rid,)))]
            tr = truth[name]
            times = [s[0] for s in tr]
            errs, herrs = [], []
            for t, x, y, h in reports:
                i = bisect.bisect_left(times, t)
                if i == 0 or i == len(tr):
                    continue
                (ta, xa, ya, ha), (tb, xb, yb, hb) = tr[i - 1], tr[i]
                f = (t - ta) / (tb - ta) if tb > ta else 0.0
                dh = (hb - ha + 180) % 360 - 180
                xt, yt, ht = xa + f * (xb - xa), ya + f * (yb - ya), ha + f * dh
                errs.append(math.hypot(x - xt, y - yt))
                herrs.append(abs((h - ht + 180) % 360 - 180))
            travelled = sum(math.hypot(b[1] - a[1], b[2] - a[2]) for a, b in zip(tr, tr[1:]))
            if not errs:
                print(f"{rid:<7} {travelled / 100:7.2f} m   {len(reports):7d}   (no report inside the sampled time)")
                continue
            print(f"{rid:<7} {travelled / 100:7.2f} m   {len(reports):7d}   {errs[-1]:6.1f} / {max(errs):6.1f} cm"
                  f"          {errs[-1] / max(travelled / 100, 1e-9):5.1f} cm   {herrs[-1]:6.1f} / {max(herrs):5.1f} deg")
    return 0


if __name__ == "__main__":
    sys.exit(main())
