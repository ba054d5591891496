#!/usr/bin/env python3
"""make demo: a master and three agents on this machine (loopback), narrated.

Phases (each a function; relay and election are one more phase to add when the core has them):
  1. sync       ev3-master and three ev3-agent start; the fleet syncs (the master's table)
  2. behaviour  `wait seconds=N` is assigned, started, paused, resumed, stopped; another agent
                runs one to the end (ACTION_OK); a third... is left ACTIVE
  3. master     the master is killed (SIGKILL); the agents fall back (WORKING -> PAUSED -> PANIC,
                ACTIVE -> PANIC), read from their NDJSON traces
  4. relay/election  not implemented yet (the core has no relay/election; the spec is being written)
Then a summary: the timeline with times. Logs, traces and the status JSON stay in build/demo/.
Only the standard library: runs wherever `make deps` has run.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

HB, LOSS, PAUSED = 200, 1000, 2000  # short demo timers (ms): heartbeat, master timeout, paused timeout


def free_ports(n: int) -> list[int]:
    socks = []
    try:
        for _ in range(n):
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            s.bind(("127.0.0.1", 0))
            socks.append(s)
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()


class DemoFailed(Exception):
    pass


class Demo:
    def __init__(self, bindir: Path, workdir: Path) -> None:
        self.bin = bindir
        self.dir = workdir
        self.t0 = time.monotonic()
        self.timeline: list[tuple[float, str]] = []
        self.master: subprocess.Popen | None = None
        self.agents: list[subprocess.Popen] = []
        self.master_out_pos = 0
        self.last_table = None
        self.last_table_at = 0.0
        self.trace_pos: dict[int, int] = {}
        self.agent_state: dict[int, str] = {}
        self.ids: list[int] = []

    # --- output -------------------------------------------------------------------------------
    def t(self) -> float:
        return time.monotonic() - self.t0

    def event(self, text: str) -> None:
        self.timeline.append((self.t(), text))
        print(f"[{self.t():5.1f}s] {text}", flush=True)

    def heading(self, text: str) -> None:
        print(f"\n=== {text} ===", flush=True)

    def follow_master(self) -> list[str]:
        """New lines of the master's console (stdout), echoed."""
        path = self.dir / "master.out"
        if not path.exists():
            return []
        data = path.read_bytes()[self.master_out_pos:]
        cut = data.rfind(b"\n") + 1
        self.master_out_pos += cut
        lines = data[:cut].decode(errors="replace").splitlines()
        for line in lines:
            print(f"         master | {line}", flush=True)
        return lines

    def status(self) -> dict:
        try:
            return json.loads((self.dir / "status.json").read_text())
        except (OSError, ValueError):
            return {}

    def show_table(self, force: bool = False) -> None:
        s = self.status()
        rows = [(a["id"], a["address"], a["state"], a["behaviour"] or "-", a["action"]) for a in s.get("agents", [])]
        key = [(r[0], r[2], r[3], r[4]) for r in rows]
        if not force and key == self.last_table and self.t() - self.last_table_at < 5:
            return
        self.last_table, self.last_table_at = key, self.t()
        print(f"         +-- the master's table (--status-json), t={self.t():.1f}s", flush=True)
        print(f"         | {'ID':<4}{'ADDRESS':<18}{'STATE':<9}{'HEARD':<8}{'BEHAVIOUR':<10}ACTION")
        for a in s.get("agents", []):
            print(f"         | {a['id']:<4}{a['address']:<18}{a['state']:<9}{a['last_heard_ms_ago'] / 1000:<8.1f}"
                  f"{a['behaviour'] or '-':<10}{a['action']}")
        if not s.get("agents"):
            print("         | (no agents yet)")
        drops = " ".join(f"{k}={v}" for k, v in s.get("drops", {}).items()) or "none"
        print(f"         | drops: {drops}", flush=True)

    def pump(self, seconds: float, until=None, what: str = "", table: bool = True):
        """Follows the master's output (and the table) for up to `seconds`, or until until() is true."""
        end = time.monotonic() + seconds
        while True:
            lines = self.follow_master()
            if table and self.master and self.master.poll() is None:
                self.show_table()
            if until is not None:
                v = until(lines)
                if v:
                    return v
            if time.monotonic() >= end:
                if until is not None:
                    raise DemoFailed(f"gave up after {seconds:g} s waiting for {what}")
                return None
            time.sleep(0.1)

    # --- programs ---------------------------------------------------------------------------
    def start(self) -> None:
        self.dir.mkdir(parents=True, exist_ok=True)
        for f in self.dir.iterdir():
            f.unlink()
        ports = free_ports(4)
        self.mport, self.aports = ports[0], ports[1:]
        self.master = subprocess.Popen(
            [str(self.bin / "ev3-master"), "--port", str(self.mport), "--bind", "127.0.0.1",
             *sum((["--broadcast", f"127.0.0.1:{p}"] for p in self.aports), []),
             "--agent-timeout-ms", "5000", "--status-json", str(self.dir / "status.json"),
             "--trace", str(self.dir / "master.ndjson"), "--log-file", str(self.dir / "master.log")],
            stdin=subprocess.PIPE, stdout=open(self.dir / "master.out", "wb"), stderr=subprocess.STDOUT)
        self.event(f"started ev3-master on 127.0.0.1:{self.mport} (pid {self.master.pid})")
        for i, p in enumerate(self.aports):
            others = [self.mport] + [q for q in self.aports if q != p]
            a = subprocess.Popen(
                [str(self.bin / "ev3-agent"), "--port", str(p), "--bind", "127.0.0.1", "--model", "A",
                 *sum((["--broadcast", f"127.0.0.1:{q}"] for q in others), []),
                 "--heartbeat-ms", str(HB), "--master-timeout-ms", str(LOSS), "--paused-timeout-ms", str(PAUSED),
                 "--sysfs-root", str(self.dir / "no-sysfs"),
                 "--trace", str(self.dir / f"agent{i + 1}.ndjson"), "--log-file", str(self.dir / f"agent{i + 1}.log")],
                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            self.agents.append(a)
            self.event(f"started ev3-agent #{i + 1} on 127.0.0.1:{p} (pid {a.pid}), heartbeat {HB} ms, "
                       f"master timeout {LOSS} ms")

    def cmd(self, line: str, expect: str = "acknowledged") -> None:
        assert self.master and self.master.stdin
        self.master.stdin.write((line + "\n").encode())
        self.master.stdin.flush()
        self.event(f"operator> {line}")
        self.pump(3, lambda ls: any(expect in l or "refused" in l or "timed out" in l or "error" in l for l in ls),
                  f"the answer to '{line}'")

    def agent_states(self) -> dict[int, str]:
        """Each agent's state, read from its NDJSON trace (records with changed.state)."""
        for i in range(len(self.agents)):
            path = self.dir / f"agent{i + 1}.ndjson"
            if not path.exists():
                continue
            with open(path, "rb") as f:
                f.seek(self.trace_pos.get(i, 0))
                data = f.read()
            cut = data.rfind(b"\n") + 1
            self.trace_pos[i] = self.trace_pos.get(i, 0) + cut
            for line in data[:cut].splitlines():
                rec = json.loads(line)
                st = rec.get("changed", {}).get("state")
                if st and self.agent_state.get(i) != st:
                    old = self.agent_state.get(i, "?")
                    self.agent_state[i] = st
                    if self.phase_master_lost_started:
                        self.event(f"agent #{i + 1} (trace): {old} -> {st} by {rec['action']}")
        return self.agent_state

    phase_master_lost_started = False

    def stop_all(self) -> None:
        for a in self.agents:
            if a.poll() is None:
                a.send_signal(signal.SIGTERM)
        if self.master and self.master.poll() is None:
            self.master.send_signal(signal.SIGTERM)
        for p in [*self.agents, self.master]:
            if p is None:
                continue
            try:
                p.wait(5)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()

    # --- phases -------------------------------------------------------------------------------
    def phase_sync(self) -> None:
        self.heading("1. the fleet syncs")
        def synced(_):
            ags = self.status().get("agents", [])
            return ags if len(ags) == 3 and all(a["state"] == "ACTIVE" for a in ags) else None
        ags = self.pump(10, synced, "three ACTIVE agents")
        self.ids = [a["id"] for a in ags]
        self.show_table(force=True)
        self.event(f"fleet synced: agents {', '.join(map(str, self.ids))} ACTIVE")

    def wait_state(self, agent: int, state: str) -> None:
        def ok(_):
            return any(a["id"] == agent and a["state"] == state for a in self.status().get("agents", []))
        self.pump(4, ok, f"agent {agent} {state}")
        self.event(f"agent {agent} is {state} (its PING says so)")

    def phase_behaviour(self) -> None:
        a, b, _ = self.ids
        self.heading(f"2. behaviour 'wait' on agent {a}: assign, start, pause, resume, stop")
        self.cmd(f"behaviour {a} wait seconds=4")
        self.cmd(f"start {a}")
        self.wait_state(a, "WORKING")
        self.pump(1.5)
        self.cmd(f"pause {a}")
        self.wait_state(a, "PAUSED")
        self.pump(1.5)
        self.cmd(f"resume {a}")
        self.wait_state(a, "WORKING")
        self.pump(1.0)
        self.cmd(f"stop {a}")
        self.wait_state(a, "ACTIVE")
        self.heading(f"   agent {b} runs 'wait seconds=1.5' to the end; agent {a} starts a long one")
        self.cmd(f"behaviour {b} wait seconds=1.5")
        self.cmd(f"start {b}")
        self.pump(4, lambda ls: any(f"agent {b}: ACTION_OK" in l for l in ls), f"ACTION_OK from agent {b}")
        self.event(f"agent {b} reported ACTION_OK: its wait is over")
        self.cmd(f"behaviour {a} wait seconds=60")
        self.cmd(f"start {a}")
        self.wait_state(a, "WORKING")
        self.show_table(force=True)

    def phase_master_lost(self) -> None:
        self.heading("3. the master is killed (SIGKILL): the agents fall back")
        self.agent_states()  # states so far
        self.phase_master_lost_started = True
        assert self.master
        self.master.send_signal(signal.SIGKILL)
        self.master.wait()
        self.event(f"master killed (SIGKILL); agents' states now: "
                   + ", ".join(f"#{i + 1} {s}" for i, s in sorted(self.agent_state.items())))
        end = time.monotonic() + 3 * PAUSED / 1000 + 3
        while time.monotonic() < end:
            st = self.agent_states()
            if len(st) == 3 and all(s == "PANIC" for s in st.values()):
                break
            time.sleep(0.1)
        else:
            raise DemoFailed("the agents did not all reach PANIC")
        self.event("every agent is in PANIC (broadcasting PANIC, waiting for a master)")

    def phase_relay_election(self) -> None:
        self.heading("4. relay and election")
        self.event("relay and election are NOT implemented yet (core lacks them; their TLA+ spec is being "
                   "written): no new master takes over")

    def summary(self) -> None:
        self.heading("summary")
        for t, text in self.timeline:
            print(f"  {t:5.1f}s  {text}")
        print(f"\n  logs, NDJSON traces and the last status JSON: {self.dir}/")
        print("  not shown (not implemented yet): relay through a synced agent, election of a new master.")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", type=Path, default=Path(__file__).resolve().parents[1] / "build" / "bin")
    ap.add_argument("--dir", type=Path, default=Path(__file__).resolve().parents[1] / "build" / "demo")
    args = ap.parse_args()
    for exe in ("ev3-agent", "ev3-master"):
        if not (args.bin / exe).is_file():
            print(f"demo: {args.bin / exe} is missing (run make build)", file=sys.stderr)
            return 1
    d = Demo(args.bin, args.dir)
    ok = True
    try:
        d.start()
        d.phase_sync()
        d.phase_behaviour()
        d.phase_master_lost()
        d.phase_relay_election()  # the place for relay/election phases once the core has them
    except DemoFailed as e:
        d.event(f"DEMO FAILED: {e}")
        ok = False
    except KeyboardInterrupt:
        d.event("interrupted")
        ok = False
    finally:
        d.stop_all()
    d.summary()
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
