#!/usr/bin/env python3
"""The summary table of `make faults` (docs/faults.md): one row per scenario from the runs' figures
(EV3_FAULT_RESULTS, JSON lines written by tests/python/blackbox/test_fault_scenarios.py) and, from
pytest's output (its short summary: `FAILED` / `ERROR` lines), how many runs failed a check (the
scenario's own asserts, and conftest's checks of every trace and of the whole run merged, which
come at teardown).

    python3 tools/faults_summary.py RESULTS.jsonl [--pytest-log OUTPUT]
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections import defaultdict
from pathlib import Path


def pct(xs: list[float], p: int) -> float:
    """The p-th percentile by nearest rank."""
    xs = sorted(xs)
    return xs[min(len(xs) - 1, max(0, -(-p * len(xs) // 100) - 1))]


def failures(log: Path) -> dict[str, int]:
    """Runs (test and seed) pytest's short summary names FAILED or ERROR, per test name."""
    runs = set(re.findall(r"^(?:FAILED|ERROR) \S+::(\w+)\[(\d+)\]", log.read_text(errors="replace"), re.M))
    out: dict[str, int] = defaultdict(int)
    for name, _ in runs:
        out[name] += 1
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", type=Path)
    ap.add_argument("--pytest-log", type=Path, help="pytest's output (-rfE short summary)")
    a = ap.parse_args()
    if not a.results.is_file():
        ap.error(f"{a.results}: no such file (run make faults first)")
    runs: dict[str, list[dict]] = defaultdict(list)
    for n, line in enumerate(a.results.read_text().splitlines(), 1):
        if not line.strip():
            continue
        try:
            r = json.loads(line)
            runs[r["scenario"]].append(r)
        except (ValueError, KeyError) as e:
            print(f"faults_summary: {a.results}:{n}: not a run's figures ({e})", file=sys.stderr)
            return 1
    if a.pytest_log and not a.pytest_log.is_file():
        ap.error(f"{a.pytest_log}: no such file")
    failed = failures(a.pytest_log) if a.pytest_log else {}
    print("| scenario | runs | faults | detection p50 | failover p50 / p99 / max | false verdicts | "
          "watchdog: bound after the kill (max), stop after the bound (max) | runs failing a check |")
    print("|---|---:|---|---|---|---|---|---:|")
    for name, rs in sorted(runs.items()):
        fo = [r["failover"] for r in rs if r.get("failover") is not None]
        de = [r["detection"] for r in rs if r.get("detection") is not None]
        false = sum(r.get("false_master_lost", 0) + r.get("false_agent_lost", 0) for r in rs)
        bound = max((r["bound_after_kill"] for r in rs if r.get("bound_after_kill") is not None), default=None)
        late = max((r["stop_after_bound"] for r in rs if r.get("stop_after_bound") is not None), default=None)
        bad = failed.get(rs[0].get("test", ""), 0)
        print(f"| {name} | {len(rs)} | {rs[0].get('faults', '')} | "
              f"{pct(de, 50):.2f} s | {pct(fo, 50):.2f} / {pct(fo, 99):.2f} / {max(fo):.2f} s | {false} | "
              f"{'-' if bound is None else f'{bound * 1000:.0f} ms'}, {'-' if late is None else f'{late * 1000:.0f} ms'} | "
              f"{bad} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
