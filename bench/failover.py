#!/usr/bin/env python3
"""Failover of a fleet when its master dies (docs/benchmarks.md, "Failover"): the PC master and
three agents with --election on loopback (no devices), all ACTIVE and knowing the membership; then
the PC is killed (SIGKILL) and the agents' traces say, on the machine's monotonic clock that the
programs' cores run on:

  detection   kill -> the first agent leaves ACTIVE (HeartbeatLost: PANIC). For a WORKING agent
              this is also when its motors stop (PAUSED).
  failover    kill -> every agent follows a new master (an agent's leader is neither none nor the
              PC, directly or through a relay, or the agent is the new master) and still does at
              the end of the run.
  first relay kill -> the first agent that accepts a relay (AcceptRelay), and how many relays were
              accepted and dropped again (RelayDropped) from the kill to the end of the run.

    python3 bench/failover.py --runs 5 --bin build/bin [-- AGENT-FLAGS...]
    python3 bench/failover.py --runs 5 -- --heartbeat-ms 200 --master-timeout-ms 1000
    python3 bench/failover.py --runs 5 --netns     # each program in a network namespace (root)
    python3 bench/failover.py --runs 20 --faults 30 --warm 5   # 30 % loss, dup, reorder on every sender

--faults PCT gives every program (master and agents) --fault-loss, --fault-dup and --fault-reorder PCT
(the transport's fault injection, a seed per program and run); --warm S runs the synced fleet S
seconds before the kill, and any verdict in that time is false: an agent leaving ACTIVE ("master
lost") or the master dropping an agent ("agent lost").

--keep DIR keeps each run's logs and traces (DIR/run-N: master.log, agentI.log, agentI.nd) for a
run worth a look. AGENT-FLAGS (after --) go to every ev3-agent (timers: --heartbeat-ms, --master-timeout-ms, ...).
Each run takes the sync, the failover and --settle seconds more; a run with no failover within
--timeout seconds is reported as such. Prints one line per run and the medians.
"""

from __future__ import annotations

import argparse
import signal
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "python" / "blackbox"))
import netns  # noqa: E402
from ev3net import Program, free_ports, read_status, wait_until  # noqa: E402
from ev3net import trace_records as records  # noqa: E402
from ev3net import agent_lost as lost_verdicts, false_master_lost, knows_members, timeline  # noqa: E402

SCORES = (1, 20, 40)


def one_run(bindir: Path, tmp: Path, agent_flags: list[str], timeout: float, settle: float, lan=None,
            faults: int = 0, warm: float = 0.3, seed: int = 1) -> dict:
    """One run; with @p lan (netns.Lan of 4 nodes) each program in a namespace of its own, all on
    one port and the subnet's broadcast address, instead of loopback ports."""
    if lan:
        mport, aports = 12345, [12345] * 3
        where = [["--broadcast", f"{lan.broadcast()}:12345"]] * 4

        def start(i, exe, args, name):
            return Program(Path("ip"), lan.argv(i, [str(exe), *args])[1:], tmp, name)
    else:
        mport, *aports = free_ports(4)
        ports = [mport, *aports]
        where = [["--bind", "127.0.0.1", *sum((["--broadcast", f"127.0.0.1:{q}"] for q in ports if q != p), [])]
                 for p in ports]

        def start(i, exe, args, name):
            return Program(exe, args, tmp, name)
    def inject(i):
        return (["--fault-loss", str(faults), "--fault-dup", str(faults), "--fault-reorder", str(faults),
                 "--fault-seed", str(seed * 10 + i)] if faults else [])
    progs = []
    try:
        status = tmp / "status.json"
        master = start(0, bindir / "ev3-master",
                       ["--port", str(mport), *where[0], "--election", "--state-file", str(tmp / "m.state"),
                        "--status-json", str(status), "--log-file", str(tmp / "master.log"),
                        f"--trace={tmp / 'master.nd'}", *inject(0)], "master")
        progs.append(master)
        for i, p in enumerate(aports):
            (tmp / f"s{i}").mkdir()
            progs.append(start(i + 1, bindir / "ev3-agent", [
                "--port", str(p), *where[i + 1],
                "--election", "--score", str(SCORES[i]), "--state-dir", str(tmp / f"s{i}"),
                "--sysfs-root", str(tmp / "nosys"), f"--trace={tmp / f'agent{i}.nd'}",
                "--log-file", str(tmp / f"agent{i}.log"), *inject(i + 1), *agent_flags], f"agent{i}"))
        wait_until(lambda: (s := read_status(status)) and len(s["agents"]) == 3 and
                   all(a["state"] == "ACTIVE" for a in s["agents"]), 15, "three ACTIVE agents")
        wait_until(lambda: all(knows_members(records(tmp / f"agent{i}.nd")) for i in range(3)), 10,
                   "every agent to know the membership")
        time.sleep(warm)
        master.stop(signal.SIGKILL)
        kill = int(time.monotonic() * 1000)
        agent_lost = lost_verdicts(master.stdout())
        end = time.monotonic() + timeout

        def settled():
            ts = [timeline(records(tmp / f"agent{i}.nd"), kill) for i in range(3)]
            return all(t["follows"] is not None for t in ts)
        while time.monotonic() < end and not settled():
            time.sleep(0.05)
        time.sleep(settle)
        ts = [timeline(records(tmp / f"agent{i}.nd"), kill) for i in range(3)]
        master_lost = sum(false_master_lost(records(tmp / f"agent{i}.nd"), kill) for i in range(3))
    finally:
        for p in progs:
            p.close()
    lost = [t["lost"] for t in ts if t["lost"] is not None]
    follows = [t["follows"] for t in ts]
    firsts = [t["first_relay"] for t in ts if t["first_relay"] is not None]
    return {"detection": min(lost) if lost else None,
            "failover": max(follows) if all(f is not None for f in follows) else None,
            "first_relay": min(firsts) if firsts else None,
            "relays": sum(t["relays"] for t in ts), "relay_drops": sum(t["relay_drops"] for t in ts),
            "false_master_lost": master_lost, "false_agent_lost": agent_lost}


def fmt(ms) -> str:
    return "-" if ms is None else f"{ms / 1000:.2f} s"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--bin", default=str(ROOT / "build" / "bin"), help="where ev3-master and ev3-agent are")
    ap.add_argument("--timeout", type=float, default=30.0, help="seconds to wait for the failover (default 30)")
    ap.add_argument("--settle", type=float, default=1.0, help="seconds watched after it (default 1)")
    ap.add_argument("--keep", metavar="DIR", help="keep each run's logs and traces in DIR/run-N (new directories)")
    ap.add_argument("--netns", action="store_true", help="each program in a network namespace on one bridge "
                    "(root; real broadcast) instead of loopback")
    ap.add_argument("--faults", type=int, default=0, metavar="PCT",
                    help="loss, duplication and reordering of PCT %% on every sender (default 0)")
    ap.add_argument("--warm", type=float, default=0.3, metavar="S",
                    help="seconds the synced fleet runs before the kill (default 0.3)")
    ap.add_argument("agent_flags", nargs="*", help="flags for every ev3-agent (after --)")
    a = ap.parse_args()
    if a.runs < 1:
        ap.error("--runs must be 1 or more")
    if not 0 <= a.faults <= 100:
        ap.error("--faults must be 0..100")
    if a.warm < 0:
        ap.error("--warm must not be negative")
    bindir = Path(a.bin)
    for exe in ("ev3-master", "ev3-agent"):
        if not (bindir / exe).exists():
            ap.error(f"{bindir / exe} is missing: build first (make build) or give --bin")
    if a.keep and any((Path(a.keep) / f"run-{k + 1}").exists() for k in range(a.runs)):
        ap.error(f"--keep {a.keep}: it holds run-N directories already; give a new directory")
    if a.netns and (why := netns.available()):
        ap.error(f"--netns: {why}")
    print(f"failover: PC master + 3 agents {'in network namespaces on a bridge' if a.netns else 'on loopback'}, "
          f"agent flags: {' '.join(a.agent_flags) or '(defaults)'}"
          f"{f', {a.faults} % loss, duplication and reordering' if a.faults else ''}, {a.warm} s before the kill")
    res = []
    for k in range(a.runs):
        lan = netns.Lan(4) if a.netns else None
        try:
            with tempfile.TemporaryDirectory(prefix="ev3failover.") as d:
                run_dir = Path(d)
                if a.keep:
                    run_dir = Path(a.keep) / f"run-{k + 1}"
                    run_dir.mkdir(parents=True)
                r = one_run(bindir, run_dir, a.agent_flags, a.timeout, a.settle, lan, a.faults, a.warm, k + 1)
        finally:
            if lan:
                lan.close()
        res.append(r)
        print(f"  run {k + 1}: detection {fmt(r['detection'])}  failover {fmt(r['failover'])}  "
              f"first relay {fmt(r['first_relay'])}  relays accepted {r['relays']}, dropped {r['relay_drops']}  "
              f"false verdicts: master lost {r['false_master_lost']}, agent lost {r['false_agent_lost']}",
              flush=True)
    for key in ("detection", "failover"):
        xs = sorted(r[key] for r in res if r[key] is not None)
        if xs:
            p99 = xs[min(len(xs) - 1, -(-99 * len(xs) // 100) - 1)]  # nearest rank
            print(f"  {key}: median {fmt(statistics.median(xs))}, p99 {fmt(p99)} (min {fmt(xs[0])}, max "
                  f"{fmt(xs[-1])}, {len(xs)} of {len(res)} runs)")
        else:
            print(f"  {key}: none of {len(res)} runs")
    print(f"  false verdicts: master lost {sum(r['false_master_lost'] for r in res)}, agent lost "
          f"{sum(r['false_agent_lost'] for r in res)} (in {a.warm * len(res):.0f} s of the synced fleet before the kills)")
    return 0 if all(r["failover"] is not None for r in res) else 1


if __name__ == "__main__":
    sys.exit(main())
