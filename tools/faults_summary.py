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


def pct(xs: list[float], p: int) -> float | None:
    """The p-th percentile by nearest rank (None of nothing)."""
    if not xs:
        return None
    xs = sorted(xs)
    return xs[min(len(xs) - 1, max(0, -(-p * len(xs) // 100) - 1))]


def sec(x: float | None) -> str:
    return "-" if x is None else f"{x:.2f}"


def ms(x: float | None) -> str:
    return "-" if x is None else f"{x * 1000:.0f} ms"


def figures(rs: list[dict], key: str) -> list[float]:
    return [r[key] for r in rs if r.get(key) is not None]


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
    print("| scenario | runs (signed) | faults | detection p50 | following a master again p50 / p99 / max | "
          "false verdicts | watchdog: bound after the fault (max), stop after the bound (max) | "
          "motors stopped after the fault (max) | others paused by the membership change (max) | "
          "reports recorded (none lost) | BATTERY_LOW not heard | runs failing a check |")
    print("|---|---:|---|---|---|---:|---|---|---|---:|---:|---:|")
    for name, rs in sorted(runs.items()):
        fo = figures(rs, "failover")
        false = sum(r.get("false_master_lost", 0) + r.get("false_agent_lost", 0) for r in rs)
        bound = max(figures(rs, "bound_after_kill"), default=None)
        late = max(figures(rs, "stop_after_bound"), default=None)
        stop = max(figures(rs, "unplug_to_stop") + figures(rs, "drop_to_stop"), default=None)
        reports = figures(rs, "reports")
        pause = max(figures(rs, "membership_pause"), default=None)
        unheard = sum(1 for r in rs if r.get("battery_low_heard") is False)
        bad = failed.get(rs[0].get("test", ""), 0)
        following = "-" if not fo else f"{sec(pct(fo, 50))} / {sec(pct(fo, 99))} / {sec(max(fo))} s"
        detection = pct(figures(rs, "detection"), 50)
        print(f"| {name} | {len(rs)} ({sum(1 for r in rs if r.get('signed'))}) | {rs[0].get('faults', '')} | "
              f"{'-' if detection is None else sec(detection) + ' s'} | {following} | {false} | {ms(bound)}, {ms(late)} | "
              f"{ms(stop)} | {ms(pause)} | {sum(reports) if reports else '-'} | "
              f"{unheard if 'battery_low_heard' in rs[0] else '-'} | {bad} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
