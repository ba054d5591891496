#!/usr/bin/env python3
"""The master core's CPU per datagram with 100 and with 10,000 registered agents (bench_master), now,
with the election on (BM_MasterPingElection), and, when built, with an earlier commit's core
(bench_master_baseline): docs/benchmarks.md, "Master at scale". Each round runs both binaries (in
alternating order) once; a run measures each case 3 times (the median counts). Ratios are taken
within one run (10,000 / 100) or one round (now / before); the table gives their median and range
over the rounds, and the load average around them.

    make bench-master                      # builds build/bench with EV3_MASTER_BASELINE, runs this
    python3 bench/master_scale.py --rounds 7 --bin build/bench/bin
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

CASES = ("BM_MasterPing/100", "BM_MasterPing/10000")
# The same fleet with the election on (the PC's membership, its LEADERs, EPOCH_CMD): this core only.
ELECTION = ("BM_MasterPingElection/100", "BM_MasterPingElection/10000")


def run(binary: Path, min_time: float, cases: tuple[str, ...]) -> dict[str, float]:
    """CPU ns per datagram of each of @cases (median of 3) in one run of @binary."""
    out = subprocess.run([str(binary), "--benchmark_format=json", "--benchmark_repetitions=3",
                          f"--benchmark_min_time={min_time}", "--benchmark_report_aggregates_only=true"],
                         check=True, capture_output=True, text=True).stdout
    got = {}
    for b in json.loads(out)["benchmarks"]:
        if b.get("aggregate_name") == "median" and b["run_name"] in cases:
            got[b["run_name"]] = b["cpu_time"]
    missing = [c for c in cases if c not in got]
    if missing:
        sys.exit(f"master_scale: {binary.name} did not report {missing}")
    return got


def spread(xs: list[float], fmt: str) -> str:
    return f"{fmt.format(statistics.median(xs))} ({fmt.format(min(xs))}-{fmt.format(max(xs))})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bin", default="build/bench/bin", help="where bench_master[_baseline] are")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--min-time", type=float, default=0.3, help="--benchmark_min_time per case")
    a = ap.parse_args()
    now_bin = Path(a.bin) / "bench_master"
    base_bin = Path(a.bin) / "bench_master_baseline"
    if not now_bin.exists():
        sys.exit(f"master_scale: no {now_bin} (make bench-master builds it)")
    bins = {"now": now_bin}
    if base_bin.exists():
        bins["before"] = base_bin
    load0 = os.getloadavg()
    res: dict[str, list[dict[str, float]]] = {k: [] for k in bins}
    for r in range(a.rounds):
        order = list(bins) if r % 2 == 0 else list(reversed(bins))
        for k in order:
            res[k].append(run(bins[k], a.min_time, CASES + ELECTION if k == "now" else CASES))
        print(f"round {r + 1}: " + "; ".join(
            f"{k} " + " ".join(f"{c.split('/')[1]}={res[k][-1][c]:.0f}ns" for c in CASES) for k in bins),
              file=sys.stderr)
    load1 = os.getloadavg()
    print(f"load average (1 min) {load0[0]:.1f} before, {load1[0]:.1f} after; {a.rounds} rounds\n")
    print("| core | 100 agents, ns/datagram | 10,000 agents, ns/datagram | 10,000 / 100 |")
    print("|---|---|---|---|")
    rows = [(k, k, CASES) for k in bins]
    rows.insert(1, ("now, election on", "now", ELECTION))
    for name, k, cases in rows:
        small = [x[cases[0]] for x in res[k]]
        big = [x[cases[1]] for x in res[k]]
        ratio = [x[cases[1]] / x[cases[0]] for x in res[k]]
        print(f"| {name} | {spread(small, '{:.0f}')} | {spread(big, '{:.0f}')} | {spread(ratio, '{:.2f}')}x |")
    if "before" in bins:
        for c in CASES:
            r = [b[c] / n[c] for n, b in zip(res["now"], res["before"])]
            print(f"\nbefore / now, {c.split('/')[1]} agents: {spread(r, '{:.1f}')}x")


if __name__ == "__main__":
    main()
