#!/usr/bin/env python3
"""ev3-master's throughput on loopback against a raw UDP echo, in the same run (docs/benchmarks.md,
"Master throughput against a raw UDP echo").

    python3 bench/master_throughput.py [--rounds N] [--window S] [--bin build/bin] [--echo build/bench/bin/udp_echo]

For each fleet size (100 agents at a 10 ms heartbeat, 1,000 at 100 ms, 10,000 at 1 s: 30,000
datagrams a second each, with the copies), ev3-loadgen (one UDP socket per agent, each a real
agent core) loads first ev3-master and then udp_echo (recvmmsg/sendmmsg, no protocol), or the other
way round in every other round. The figure is the server's throughput: datagrams handled per second
of the server's CPU time (its utime + stime over the measurement window, against the answers
ev3-loadgen received in it: a PONG's 3 copies for a PING's 3, an echo for each datagram), so that
ev3-loadgen sharing the 2 cores does not cap it. The ratio is the
master's throughput over the echo's, taken within a round; the table gives the median of the rounds
and their range. With the echo, the agents never sync: they send AGENT and then PANIC at the
heartbeat, the same datagram rate. Exit status 0 whatever the figures: this measures.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
FLEETS = [(100, 10), (1000, 100), (10000, 1000)]  # (agents, heartbeat ms): 30,000 datagrams a second each
PORT = 24777


def one(server: list[str], agents: int, hb: int, window: float, settle: float, loadgen: Path) -> dict:
    """One measurement: the server started, ev3-loadgen against it, the server stopped."""
    proc = subprocess.Popen(server, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        time.sleep(0.3)
        if proc.poll() is not None:
            raise SystemExit(f"master_throughput: {server[0]} exited: {proc.stderr.read().decode(errors='replace')}")
        out = subprocess.run([str(loadgen), "--master", f"127.0.0.1:{PORT}", "--agents", str(agents),
                              "--heartbeat-ms", str(hb), "--ramp-s", "2", "--settle-s", str(settle),
                              "--duration-s", str(window), "--master-pid", str(proc.pid), "--json"],
                             capture_output=True, text=True, timeout=settle + window + 120)
        if out.returncode != 0:
            raise SystemExit(f"master_throughput: ev3-loadgen failed: {out.stderr[-2000:]}")
        r = json.loads(out.stdout.strip().splitlines()[-1])
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    cpu = r["cpu_master"] * r["window_s"]  # the server's CPU seconds in the window (clock ticks: 10 ms)
    # Handled: the answers that came back (a PONG's 3 copies for a PING's 3, an echo for each),
    # so that what a full socket buffer dropped is not counted as handled.
    return {"sent": r["sent"], "received": r["received"], "cpu": cpu, "rate": r["sent"] / r["window_s"],
            "throughput": r["received"] / cpu if cpu > 0 else float("inf"), "synced": r["synced_at_end"]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--window", type=float, default=15.0, help="measurement window, s (default 15)")
    ap.add_argument("--bin", type=Path, default=REPO / "build" / "bin")
    ap.add_argument("--echo", type=Path, default=REPO / "build" / "bench" / "bin" / "udp_echo")
    a = ap.parse_args()
    for exe in (a.bin / "ev3-master", a.bin / "ev3-loadgen", a.echo):
        if not exe.is_file():
            ap.error(f"{exe} is missing (make build; the echo: make bench)")
    if a.rounds < 1 or a.window <= 0:
        ap.error("--rounds and --window must be positive")
    master = [str(a.bin / "ev3-master"), "--port", str(PORT), "--bind", "127.0.0.1"]
    echo = [str(a.echo), "--bind", "127.0.0.1", "--port", str(PORT)]
    rows = []
    for agents, hb in FLEETS:
        ratios, ms, es = [], [], []
        for rnd in range(a.rounds):
            order = [("master", master, 30.0), ("echo", echo, 3.0)]
            if rnd % 2:
                order.reverse()
            got = {name: one(cmd, agents, hb, a.window, settle, a.bin / "ev3-loadgen") for name, cmd, settle in order}
            m, e = got["master"], got["echo"]
            if m["synced"] < agents:
                print(f"master_throughput: only {m['synced']} of {agents} agents synced with the master", file=sys.stderr)
            ratios.append(m["throughput"] / e["throughput"])
            ms.append(m)
            es.append(e)
            print(f"{agents} agents, round {rnd + 1}: master {m['throughput']:,.0f}/s of CPU ({m['rate']:,.0f}/s offered, "
                  f"{m['received']:,} of {m['sent']:,} answered, {m['cpu']:.2f} s CPU), echo {e['throughput']:,.0f}/s "
                  f"({e['received']:,} of {e['sent']:,}, {e['cpu']:.2f} s): {ratios[-1]:.2f}x", file=sys.stderr)
        rows.append((agents, hb, ms, es, ratios))
    print("| agents (heartbeat) | datagrams offered / s | ev3-master: datagrams per CPU-second | udp_echo | master / echo |")
    print("|---|---:|---:|---:|---:|")
    for agents, hb, ms, es, ratios in rows:
        med = statistics.median
        print(f"| {agents:,} ({hb} ms) | {med(x['rate'] for x in ms):,.0f} | {med(x['throughput'] for x in ms):,.0f} | "
              f"{med(x['throughput'] for x in es):,.0f} | **{med(ratios):.2f}x** ({min(ratios):.2f}-{max(ratios):.2f}x) |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
