#!/usr/bin/env python3
"""make demo: a master and three agents on this machine (loopback), each agent running a robot of
ev3-sim (three model A robots in one world, sim/worlds/arena.txt, one FUSE tree each), narrated.

Phases (each a function):
  1. sync       ev3-sim, ev3-master and three ev3-agent start, the agents with --election and
                --sysfs-root on their robot's tree; the fleet syncs (the master's table). The
                --broadcast lists make a line: agent #1 and agent #3 do not hear each other, agent
                #2 hears both (and everyone hears the PC); the web view (ev3-fleet serve, over the
                master's --db and --control) starts and its address is printed
  2. behaviour  `wait seconds=N` is assigned, started, paused, resumed, stopped; another agent
                runs one to the end (ACTION_OK); then the thesis' explore-then-exploit scenario:
                the operator switches on the master's rule `explore-exploit red`, agents #2 and #3
                `explore` the arena (driving, backing off and turning at walls and boxes, reporting
                distance and colour), and the robot whose colour sensor reports the red patch is
                switched to `exploit colour=red` and stays on the patch (checked with ev3-sim); its
                odometry (the agents run with --pose) beside ev3-sim's truth, and the web view's map
                drawing both explorers
  3. master     the master is killed (SIGKILL); the agents fall back (WORKING -> PAUSED -> PANIC,
                ACTIVE -> PANIC), read from their NDJSON traces
  4. election   the weakest agent (lowest --score: #1) stands first and wins epoch 5 (the PC published
                the membership one agent per epoch while the three synced: epochs 2-4); #2 follows it
                directly; #3, which cannot hear #1, asks for a relay (RELAY_REQ), #2 offers
                (RELAY_OFFER), #3 accepts (RELAY_ACCEPT) and leaves PANIC through #2's relay
  5. command    the new master runs its --master-script: `behaviour all wait seconds=2`, `start
                all`; both followers (#3 through the relay) go WORKING and report ACTION_OK
  6. handover   the PC master comes back with its --state-file: it stands in a newer epoch (score 0),
                the agent-master steps down (on the PC's ELECT; it hands the fleet over, HANDOVER,
                only when the PC's LEADER reaches it first: tests/python/blackbox/test_election.py)
With --signed (`make demo SIGNED=1`) every node runs in signed mode (docs/protocol.md "Signed
datagrams") with a fresh key in build/demo/fleet.key, and the summary gives their drops of unsigned,
forged or replayed datagrams (none in a run without an attacker).
Then a summary: the timeline with times, the picture of the robots' paths (ev3-sim's --snapshot,
written when it stops: build/demo/paths.svg), and the NDJSON traces validated by TLC against the spec: the
three agents' (`ev3-conformance validate`: AgentLogic composed with Election.tla's per-agent rules,
docs/spec.md "Election traces"), the master's two runs (`validate --master`: MasterLogic composed
with Election.tla's rules of the PC, "Election master traces") and the Master core the elected agent
ran (its records in that agent's trace, node master:ID:EPOCH: the same check as node ID), and the
whole run: all those traces merged into one behaviour, each receive after its send (`ev3-conformance
merged`, docs/spec.md "Whole-run traces": System.tla's and Election.tla's invariants, among them one
master per epoch, no command obeyed from a stale master, no motion without the master heard within the
timeout); a trace or a run that does not conform fails the demo. Logs, traces and the
status JSON stay in build/demo/. The standard library, the ev3fleet package (fleet/: the web view)
and for the validation the ev3conformance package (conformance/) with TLC: runs wherever `make deps`
has run.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

HB, LOSS, PAUSED = 200, 1000, 2000  # short demo timers (ms): heartbeat, master timeout, paused timeout
SCORES = (1, 20, 40)  # --score of agents #1..#3: the lowest stands first and wins
# Whom each agent's broadcasts reach besides the PC (indices of agents): #1 and #3 do not hear
# each other; #2 hears both. The PC's broadcasts reach everyone.
HEARS = {0: [1], 1: [0, 2], 2: [1]}
WORLD = Path(__file__).resolve().parents[1] / "sim" / "worlds" / "arena.txt"
# Start poses (x cm, y cm, heading deg): robot 1 faces the middle box from the west, robot 2 the
# south-east box, robot 3 the middle box from the north (the agents' ids decide which ones drive).
POSES = ("60,150,0", "375,25,135", "200,275,-90")
# The red patch of arena.txt (x, y, width, height in cm), on robot 3's way down from its start; the
# robot the rule switches to `exploit red` must still be on it (its centre, within PATCH_MARGIN: the
# colour sensor is ahead of the centre) after EXPLOIT_SECONDS.
RED_PATCH = (150, 215, 100, 50)
PATCH_MARGIN = 10
EXPLOIT_SECONDS = 6
MASTER_SCRIPT = "# run by the agent that wins an election (ev3-agent --master-script)\nwait 2\nbehaviour all wait seconds=2\nstart all\n"
TYPES = {21: "RELAY_REQ", 22: "RELAY_OFFER", 23: "RELAY_ACCEPT", 24: "RELAY_ROUTE", 25: "RELAY", 26: "RELAY_DROP",
         27: "ELECT", 28: "VOTE", 29: "LEADER", 30: "EPOCH_STALE", 31: "EPOCH_CMD", 32: "HANDOVER"}


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
    def __init__(self, bindir: Path, workdir: Path, signed: bool = False) -> None:
        self.bin = bindir
        self.signed = signed
        self.dir = workdir
        self.t0 = time.monotonic()
        self.timeline: list[tuple[float, str]] = []
        self.master: subprocess.Popen | None = None
        self.sim: subprocess.Popen | None = None
        self.agents: list[subprocess.Popen] = []
        self.view: subprocess.Popen | None = None
        self.view_url = ""
        self.master_out_pos = 0
        self.last_table = None
        self.last_table_at = 0.0
        self.trace_pos: dict[int, int] = {}
        self.agent_state: dict[int, str] = {}
        self.ids: list[int] = []
        self.id_of: dict[int, int] = {}        # agent index -> assigned id (from its trace)
        self.log_pos: dict[int, int] = {}
        self.following: dict[int, tuple[float, str]] = {}  # agent index -> (when, its last "following ..." line)
        self.master_out = "master.out"
        # Each run of ev3-master: (its trace, the --state-file it started from: key=value, empty when fresh).
        self.master_runs: list[tuple[Path, dict[str, str]]] = []

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
        path = self.dir / self.master_out
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
            if f.is_dir():
                if os.path.ismount(f):
                    subprocess.run(["fusermount3", "-u", "-z", str(f)], check=False)
                shutil.rmtree(f)
            else:
                f.unlink()
        ports = free_ports(4)
        self.mport, self.aports = ports[0], ports[1:]
        self.key: list[str] = []
        if self.signed:
            kf = self.dir / "fleet.key"
            fd = os.open(kf, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
            os.write(fd, os.urandom(32).hex().encode() + b"\n")
            os.close(fd)
            self.key = ["--key-file", str(kf)]
            self.event(f"signed mode: a fresh key in {kf} (mode 0600), given to every node with --key-file")
        self.start_sim()
        self.start_master("master.out")
        self.event(f"started ev3-master --election --state-file on 127.0.0.1:{self.mport} (pid {self.master.pid})")
        (self.dir / "master-script.txt").write_text(MASTER_SCRIPT)
        for i, p in enumerate(self.aports):
            others = [self.mport] + [self.aports[j] for j in HEARS[i]]
            (self.dir / f"state{i + 1}").mkdir()
            a = subprocess.Popen(
                [str(self.bin / "ev3-agent"), "--port", str(p), "--bind", "127.0.0.1", "--model", "A",
                 *sum((["--broadcast", f"127.0.0.1:{q}"] for q in others), []),
                 "--heartbeat-ms", str(HB), "--master-timeout-ms", str(LOSS), "--paused-timeout-ms", str(PAUSED),
                 "--election", "--score", str(SCORES[i]), "--state-dir", str(self.dir / f"state{i + 1}"),
                 "--master-script", str(self.dir / "master-script.txt"),
                 "--sysfs-root", str(self.dir / f"robot{i + 1}"), "--pose", POSES[i],
                 "--trace", str(self.dir / f"agent{i + 1}.ndjson"), "--log-file", str(self.dir / f"agent{i + 1}.log"),
                 *self.key],
                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            self.agents.append(a)
            hears = ", ".join(f"#{j + 1}" for j in HEARS[i])
            self.event(f"started ev3-agent #{i + 1} on 127.0.0.1:{p} (pid {a.pid}), --election --score {SCORES[i]}, "
                       f"--sysfs-root on robot{i + 1}'s tree, its broadcasts reach the PC and {hears}")
        self.start_view()

    def start_view(self) -> None:
        """ev3-fleet serve: the fleet's web page, on 127.0.0.1:8080 or, when that is taken, a free port."""
        port = 8080
        with socket.socket() as probe:
            try:
                probe.bind(("127.0.0.1", port))
            except OSError:
                port = free_ports(1)[0]
        out = self.dir / "view.out"
        self.view = subprocess.Popen(
            [sys.executable, "-m", "ev3fleet.cli", "serve", "--db", str(self.dir / "mission.db"),
             "--control", str(self.dir / "master.sock"), "--world", str(WORLD), "--sim", str(self.bin / "ev3-sim"),
             "--bind", f"127.0.0.1:{port}"],
            stdin=subprocess.DEVNULL, stdout=open(out, "wb"), stderr=subprocess.STDOUT)
        end = time.monotonic() + 15
        while "the fleet's view at" not in out.read_text(errors="replace"):
            if self.view.poll() is not None or time.monotonic() > end:
                raise DemoFailed("ev3-fleet serve did not start: " + out.read_text(errors="replace")[-2000:])
            time.sleep(0.05)
        self.view_url = f"http://127.0.0.1:{port}/"
        self.event(f"started the web view (ev3-fleet serve, pid {self.view.pid}): open {self.view_url} in a browser "
                   f"to watch the fleet, its map and its sensors, and to pause or stop a robot")

    def start_sim(self) -> None:
        """ev3-sim: the arena with three robots at its start poses, one tree each."""
        exe = self.bin / "ev3-sim"
        if not os.path.exists("/dev/fuse"):
            raise DemoFailed("/dev/fuse is missing: ev3-sim serves the robots' trees through FUSE")
        cmd = [str(exe), "--world", str(WORLD), "--snapshot", str(self.dir / "paths.svg"),
               "--status", str(self.dir / "sim-status.json"), "--log-file", str(self.dir / "ev3-sim.log")]
        for i in range(3):
            cmd += ["--sysfs-root", str(self.dir / f"robot{i + 1}"), "--name", f"robot{i + 1}", "--robot", POSES[i]]
        self.sim = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                    stderr=open(self.dir / "ev3-sim.err", "wb"))
        end = time.monotonic() + 10
        while not all((self.dir / f"robot{i + 1}" / "class" / "tacho-motor").is_dir() for i in range(3)):
            if self.sim.poll() is not None or time.monotonic() > end:
                raise DemoFailed("ev3-sim did not mount the robots' trees: "
                                 + (self.dir / "ev3-sim.err").read_text(errors="replace")[-2000:])
            time.sleep(0.05)
        self.event(f"started ev3-sim (pid {self.sim.pid}): {WORLD.name}, robots 1-3 at {', '.join(POSES)}, "
                   f"trees on {self.dir}/robot1..3")

    def start_master(self, out: str) -> None:
        self.master_out, self.master_out_pos = out, 0
        state: dict[str, str] = {}
        try:
            state = dict(line.split("=", 1) for line in (self.dir / "master.state").read_text().splitlines() if "=" in line)
        except OSError:
            pass
        self.master_runs.append((self.dir / out.replace(".out", ".ndjson"), state))
        self.master = subprocess.Popen(
            [str(self.bin / "ev3-master"), "--port", str(self.mport), "--bind", "127.0.0.1",
             *sum((["--broadcast", f"127.0.0.1:{p}"] for p in self.aports), []),
             "--agent-timeout-ms", "5000", "--status-json", str(self.dir / "status.json"),
             "--election", "--state-file", str(self.dir / "master.state"), "--db", str(self.dir / "mission.db"),
             "--control", str(self.dir / "master.sock"),
             "--trace", str(self.dir / out.replace(".out", ".ndjson")),
             "--log-file", str(self.dir / out.replace(".out", ".log")), *self.key],
            stdin=subprocess.PIPE, stdout=open(self.dir / out, "wb"), stderr=subprocess.STDOUT)

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
                if rec.get("changed", {}).get("id"):
                    self.id_of[i] = rec["changed"]["id"]
                st = rec.get("changed", {}).get("state")
                if st and self.agent_state.get(i) != st:
                    old = self.agent_state.get(i, "?")
                    self.agent_state[i] = st
                    if self.phase_master_lost_started:
                        self.event(f"agent #{i + 1} (trace): {old} -> {st} by {rec['action']}")
                        if st == "PANIC":
                            self.reached_panic.add(i)
        return self.agent_state

    phase_master_lost_started = False
    reached_panic: set[int] = set()  # the agents whose trace went to PANIC since the master was killed

    def stop_all(self) -> None:
        for a in self.agents:
            if a.poll() is None:
                a.send_signal(signal.SIGTERM)
        if self.master and self.master.poll() is None:
            self.master.send_signal(signal.SIGTERM)
        if self.view and self.view.poll() is None:
            self.view.send_signal(signal.SIGTERM)
        for p in [*self.agents, self.master, self.view, "sim", self.sim]:
            if p == "sim":  # the agents are gone (their LEDs dark): the picture of the paths
                if self.sim and self.sim.poll() is None:
                    self.sim.send_signal(signal.SIGTERM)  # writes paths.svg, unmounts the trees
                continue
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
        self.phase_explore_exploit()

    def phase_explore_exploit(self) -> None:
        """The thesis' explore-then-exploit scenario: robots 2 and 3 explore the arena; the master's
        rule switches the one whose colour sensor reports the red patch to `exploit red`, which keeps
        it inside the patch."""
        self.agent_states()  # which agent runs which robot (id_of)
        b, c = (self.id_of.get(i) for i in (1, 2))
        if b is None or c is None:
            raise DemoFailed("the agents of robots 2 and 3 are not known from their traces")
        self.heading(f"   agents {b} and {c} explore the arena (ev3-sim); the master's rule switches a robot whose "
                     f"colour sensor reports red to `exploit red`")
        self.cmd("rule explore-exploit red", expect="rule explore-exploit on")
        for x in (b, c):
            self.cmd(f"behaviour {x} explore")
            self.cmd(f"start {x}")
        switched = []

        def on_red(lines):
            for line in lines:
                if "rule explore-exploit: agent " in line:
                    switched.append(int(line.split("rule explore-exploit: agent ", 1)[1].split()[0]))
                    self.event(f"agent {switched[-1]}'s robot reported red while exploring: the rule sent it "
                               f"`exploit colour=red`")
            return bool(switched)
        self.pump(30, on_red, "an exploring robot on the red patch (rule explore-exploit)")
        x = switched[0]
        self.pump(4, lambda _: any(a["id"] == x and a["behaviour"] == "exploit" for a in self.status().get("agents", [])),
                  f"agent {x} acknowledging exploit")
        self.pump(EXPLOIT_SECONDS)  # it drives about the patch, turning back at its edge
        robot = next(i for i, v in self.id_of.items() if v == x) + 1
        pos = self.show_robots().get(f"robot{robot}")
        x0, y0, w, h = RED_PATCH
        if pos is None:
            raise DemoFailed(f"ev3-sim did not say where robot{robot} is")
        inside = x0 - PATCH_MARGIN <= pos[0] <= x0 + w + PATCH_MARGIN and y0 - PATCH_MARGIN <= pos[1] <= y0 + h + PATCH_MARGIN
        if not inside:
            raise DemoFailed(f"robot{robot} (agent {x}) left the red patch while exploiting it: at {pos}")
        self.event(f"after {EXPLOIT_SECONDS} s of `exploit red` robot{robot} (agent {x}) is still on the red patch "
                   f"({pos[0]:.0f}, {pos[1]:.0f}) cm")
        self.check_view(x, pos, (b, c))

    def check_view(self, agent: int, truth: tuple[float, float], explorers: tuple[int, int]) -> None:
        """The robot's own idea of where it is (its last pose report, odometry, in the record) beside
        ev3-sim's truth, and the web view's map drawing both explorers."""
        import sqlite3
        import urllib.request
        db = sqlite3.connect(f"file:{self.dir / 'mission.db'}?mode=ro", uri=True)
        try:
            row = db.execute("SELECT text FROM reports WHERE agent = ? AND text LIKE 'pose:%' ORDER BY seq DESC "
                             "LIMIT 1", (agent,)).fetchone()
        finally:
            db.close()
        if row is None:
            raise DemoFailed(f"agent {agent} reported no pose (odometry) while it explored")
        x_mm, y_mm, heading = row[0].split(":")[2:5]
        off = ((float(x_mm) / 10 - truth[0]) ** 2 + (float(y_mm) / 10 - truth[1]) ** 2) ** 0.5
        self.event(f"agent {agent}'s odometry (its last pose report, up to a second old) says "
                   f"({float(x_mm) / 10:.0f}, {float(y_mm) / 10:.0f}) cm heading {float(heading):.0f} deg: "
                   f"{off:.1f} cm from where ev3-sim has it")
        try:
            with urllib.request.urlopen(self.view_url + "map.svg", timeout=10) as r:
                svg = r.read().decode()
        except OSError as e:
            raise DemoFailed(f"the web view did not answer at {self.view_url}: {e}")
        drawn = [a for a in explorers if f"robot {a}" in svg]
        if len(drawn) != len(explorers):
            raise DemoFailed(f"the web view's map lacks robots {sorted(set(explorers) - set(drawn))}")
        self.event(f"the web view's map ({self.view_url}map.svg) draws the paths of agents "
                   f"{' and '.join(map(str, explorers))} from their pose reports")

    def show_robots(self) -> dict[str, tuple[float, float]]:
        """Where ev3-sim's robots are (its status JSON, written on SIGUSR1): name -> (x, y) cm."""
        if not self.sim or self.sim.poll() is not None:
            return {}
        path = self.dir / "sim-status.json"
        before = path.stat().st_mtime_ns if path.exists() else 0
        self.sim.send_signal(signal.SIGUSR1)
        end = time.monotonic() + 2
        while time.monotonic() < end and (not path.exists() or path.stat().st_mtime_ns == before):
            time.sleep(0.02)
        try:
            robots = json.loads(path.read_text())["robots"]
        except (OSError, ValueError, KeyError):
            return {}
        for r in robots:
            print(f"         ev3-sim | {r['name']}: at ({r['x']:.0f}, {r['y']:.0f}) cm heading {r['heading']:.0f} deg, "
                  f"travelled {r['travelled']:.0f} cm, {r['speed']:.1f} cm/s", flush=True)
        return {r["name"]: (r["x"], r["y"]) for r in robots}

    def phase_master_lost(self) -> None:
        self.heading("3. the master is killed (SIGKILL): the agents fall back")
        self.agent_states()  # states so far
        self.phase_master_lost_started = True
        assert self.master
        self.master.send_signal(signal.SIGKILL)
        self.master.wait()
        self.event("master killed (SIGKILL); agents' states now: "
                   + ", ".join(f"#{i + 1} {s}" for i, s in sorted(self.agent_state.items())))
        # Each agent reaches PANIC (the weakest may win an election as soon as a peer grants it a
        # pre-vote, before the last one has got there: they need not all be in PANIC at once).
        self.reached_panic = set()
        end = time.monotonic() + 3 * PAUSED / 1000 + 3
        while time.monotonic() < end:
            self.agent_states()
            if len(self.reached_panic) == 3:
                break
            time.sleep(0.1)
        else:
            raise DemoFailed("the agents did not all reach PANIC")
        self.event("every agent reached PANIC (broadcasting PANIC, looking for a master)")

    # --- relay and election ---------------------------------------------------------------------
    def name(self, i: int) -> str:
        return f"#{i + 1} (id {self.id_of.get(i, '?')})"

    def agent_log(self, quiet=("behaviour wait", "durable")) -> list[tuple[int, str]]:
        """New lines of the agents' logs (their election / relay / state news), echoed."""
        out = []
        for i in range(len(self.agents)):
            path = self.dir / f"agent{i + 1}.log"
            if not path.exists():
                continue
            data = path.read_bytes()[self.log_pos.get(i, 0):]
            cut = data.rfind(b"\n") + 1
            self.log_pos[i] = self.log_pos.get(i, 0) + cut
            for line in data[:cut].decode(errors="replace").splitlines():
                text = line.split(" agent: ", 1)[-1]
                if any(q in text for q in quiet):
                    continue
                print(f"         agent {self.name(i)} | {text}", flush=True)
                out.append((i, text))
                if text.startswith("following master"):
                    self.following[i] = (self.t(), text)
        return out

    def relay_records(self, i: int) -> list[str]:
        """The relay handshake in agent i's trace: RELAY_REQ sent, RELAY_OFFER / RELAY_ACCEPT taken."""
        rows: list[list] = []
        for line in (self.dir / f"agent{i + 1}.ndjson").read_text().splitlines():
            rec = json.loads(line)
            a = rec["action"]
            if a not in ("RequestRelay", "OfferRelay", "AcceptRelay", "HandleAccept"):
                continue
            msg = rec.get("args", {}).get("msg", "")
            parts = msg.split(":")
            what = f"{TYPES.get(int(parts[3]), parts[3])} from {parts[0]}" if len(parts) > 3 else "RELAY_REQ broadcast"
            row = f"{a:<13} {what:<22} changed {json.dumps(rec.get('changed', {}))[:80]}"
            if rows and rows[-1][0] == row:
                rows[-1][1] += 1
            else:
                rows.append([row, 1])
        return [r if n == 1 else f"{r}  (x{n})" for r, n in rows]

    def watch(self, seconds: float, until, what: str):
        end = time.monotonic() + seconds
        while True:
            self.agent_states()
            got = until(self.agent_log())
            self.follow_master()
            if got:
                return got
            if time.monotonic() >= end:
                raise DemoFailed(f"gave up after {seconds:g} s waiting for {what}")
            time.sleep(0.1)

    def phase_election(self) -> None:
        self.heading("4. election: the weakest agent stands first; #3 gets through #2's relay")
        print(f"         (scores {', '.join(f'#{i + 1}={s}' for i, s in enumerate(SCORES))}; back-off before standing = "
              f"3000 ms + score x 100 ms after PANIC; #1 and #3 cannot hear each other)", flush=True)
        for i in range(3):  # the agents' logs from here on
            p = self.dir / f"agent{i + 1}.log"
            self.log_pos[i] = p.stat().st_size if p.exists() else 0
        won: dict = {}

        def elected(lines):
            for i, text in lines:
                if text.startswith("election: won epoch"):
                    won["i"], won["text"] = i, text
            return "i" in won
        self.watch(12, elected, "an agent to win the election")
        w = won["i"]
        self.winner = w
        e = int(won["text"].split("won epoch ")[1].split()[0])  # 5: the PC published the list in 2, 3, 4
        self.event(f"agent {self.name(w)} won epoch {e} ({won['text'].split('(')[1].rstrip(')').split(')')[0]}, "
                   f"the lowest): it runs a Master core and sends LEADER")
        who = f"following master {self.id_of.get(w)} (epoch {e})"

        def followed(_):
            return all(i == w or who in self.following.get(i, (0, ""))[1] for i in range(3))
        self.watch(10, followed, "the other agents to follow the new master")
        for i in range(3):
            if i != w:
                self.event(f"agent {self.name(i)} is ACTIVE again, {self.following[i][1]}")
        time.sleep(0.4)  # the agents flush their traces every 0.2 s
        self.agent_states()
        print("         +-- agent #3's trace, the relay handshake (epoch 1 relays after the PC died included):", flush=True)
        for r in self.relay_records(2):
            print(f"         | {r}")
        print("         +-- agent #2's trace (the relay):", flush=True)
        for r in self.relay_records(1):
            print(f"         | {r}")

    def phase_new_master_commands(self) -> None:
        w = self.winner
        self.heading(f"5. the new master (agent {self.name(w)}) runs its --master-script")
        print("         " + MASTER_SCRIPT.strip().replace("\n", "\n         "), flush=True)
        done = set()

        def finished(lines):
            for i, text in lines:
                if i == w and "ACTION_OK" in text:
                    done.add(text.split(":")[1].strip())
            return len(done) >= 2
        self.watch(10, finished, "ACTION_OK from both followers")
        self.event(f"the agent-master's commands took effect: {', '.join(sorted(done))} ran 'wait seconds=2' "
                   f"to ACTION_OK (agent #3's EPOCH_CMDs and answers went through #2's relay)")

    def phase_handover(self) -> None:
        self.heading("6. the PC master comes back (same --state-file): it takes the fleet back")
        self.start_master("master2.out")
        self.event(f"restarted ev3-master with its state file (pid {self.master.pid})")

        def back(lines):
            down = [t for i, t in lines if i == self.winner and "stepped down" in t]
            if down:
                # an agent-master that hears the PC's ELECT first steps down on it, without HANDOVER
                how = ("handed the fleet over (HANDOVER)" if "HANDOVER sent" in down[0]
                       else "no HANDOVER: the PC's ELECT came first")
                self.event(f"agent {self.name(self.winner)} stepped down ({how})")
                self.stepped = True
            ags = self.status().get("agents", [])
            return getattr(self, "stepped", False) and len(ags) == 3 and all(a["state"] != "SYNCING" for a in ags)
        self.watch(12, back, "the PC master to take the fleet back")
        self.show_table(force=True)
        self.event("the PC master is master of a newer epoch again: all three agents in its table "
                   "(those that were WORKING are PAUSED: their master changed)")
        self.cmd("stop all")

        def active(_):
            ags = self.status().get("agents", [])
            return len(ags) == 3 and all(a["state"] == "ACTIVE" for a in ags)
        self.watch(5, active, "all three agents ACTIVE")
        self.show_table(force=True)
        self.event("the PC's STOP (EPOCH_CMD of its epoch) took effect: all three agents ACTIVE")

    def summary(self) -> None:
        self.heading("summary")
        for t, text in self.timeline:
            print(f"  {t:5.1f}s  {text}")
        print(f"\n  logs, NDJSON traces and the last status JSON: {self.dir}/")
        print(f"  the mission record: {self.dir / 'mission.db'}; see it again in the web view with\n"
              f"    .venv/bin/ev3-fleet serve --db {self.dir / 'mission.db'} --control {self.dir / 'master.sock'} "
              f"--world {WORLD} --sim {self.bin / 'ev3-sim'}")
        svg = self.dir / "paths.svg"
        print(f"  the robots' paths (ev3-sim --snapshot): {svg}" if svg.exists() else "  no snapshot (ev3-sim did not stop cleanly)")
        if self.signed:
            said = []
            for log in sorted(self.dir.glob("*.log")):
                stops = re.findall(r"stopping \(.*?\); drops: (.*)", log.read_text(errors="replace"))
                if not stops:
                    continue  # a run killed with SIGKILL says nothing
                auth = [x for x in stops[-1].split() if x.startswith("auth:")]
                said.append(f"{log.stem} {' '.join(auth) or 'none'}")
            print(f"  signed mode: datagrams refused (unsigned, wrong key, bad MAC, replay): {'; '.join(said)}")


def check_record(d: Demo) -> bool:
    """The mission record (the master's --db, docs/record.md) against the agents' own traces: every
    report each agent made (its trace's `made`, Reports.tla) is in the record once, as a report or
    within a run the robot dropped, numbers 1..made with no hole."""
    import sqlite3
    d.heading(f"the mission record ({d.dir / 'mission.db'}, ev3-master --db) against the agents' traces")
    db = sqlite3.connect(f"file:{d.dir / 'mission.db'}?mode=ro", uri=True)
    ok = True
    try:
        for i in range(len(d.agents)):
            made, agent = 0, None
            for line in (d.dir / f"agent{i + 1}.ndjson").read_text().splitlines():
                r = json.loads(line)
                if r.get("node", "agent") != "agent":
                    continue
                made = r.get("changed", {}).get("made", made)
                agent = r.get("changed", {}).get("id", agent)
            seqs = sorted(x[0] for x in db.execute("SELECT seq FROM reports WHERE agent = ? AND seq IS NOT NULL",
                                                    (agent,)))
            missing = db.execute("SELECT first, last FROM reports_missing WHERE agent = ?", (agent,)).fetchall()
            covered = set(seqs) | {n for a, b in missing for n in range(a, b + 1)}
            good = len(seqs) == len(set(seqs)) and covered == set(range(1, made + 1))
            ok = ok and good
            print(f"  {d.name(i)}: made {made} reports; the record holds {len(seqs)} "
                  f"and {sum(b - a + 1 for a, b in missing)} dropped: {'every one, once' if good else 'NOT THE SAME'}",
                  flush=True)
    finally:
        db.close()
    return ok


def master_consts(state: dict[str, str]) -> dict:
    """validate --master's constants for a run of the demo's ev3-master: its timers (--agent-timeout-ms
    5000, resend and max resends: the program's defaults) and, restarted from its --state-file, the
    first id / msgid, epoch and members the file held (Election's Restart(PC): it stands, CANDIDATE)."""
    c = {"TDrop": 5000, "TResend": 500, "MaxResends": 10, "Election": True, "Life": "MASTER", "Epoch": 1, "Members": []}
    if {"next_id", "next_msgid", "epoch"} <= state.keys():
        c.update({"NextId": int(state["next_id"]), "FirstMsgid": int(state["next_msgid"]), "Life": "CANDIDATE",
                  "Epoch": int(state["epoch"]),
                  "Members": [int(x) for x in state.get("members", "").split(",") if x.strip()],
                  "MEpoch": int(state.get("members_epoch", 0) or 0)})
    return c


def validate_traces(d: Demo) -> bool:
    """The traces checked by TLC (two runs at a time): the agents' against AgentLogic + Election (per
    agent), the master's (each run) against MasterLogic + Election's rules of the PC."""
    repo = Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(repo / "conformance"))
    try:
        from concurrent.futures import ThreadPoolExecutor

        from ev3conformance import merged, tracecheck
    except ImportError as e:  # pragma: no cover - make deps installs it
        print(f"\n  trace validation skipped: {e}", flush=True)
        return False
    d.heading("trace validation (TLC: AgentLogic + Election per agent; MasterLogic + Election's PC per master run; "
              "the whole run merged)")
    paths = [d.dir / f"agent{i + 1}.ndjson" for i in range(len(d.agents))]
    jobs: list[tuple[str, object]] = [(f"agent #{i + 1}", i) for i in range(len(paths))]
    jobs += [(f"master ({p.name})", (p, st)) for p, st in d.master_runs if p.exists()]
    # the Master core an agent ran while elected (node master:ID:EPOCH in its trace)
    jobs += [(f"agent #{i + 1}'s {node}", (paths[i], node, c)) for i in range(len(paths)) if paths[i].exists()
             for node, c in tracecheck.agent_master_runs(paths[i])]

    # the whole run: every trace merged into one behaviour (each receive after its send), checked
    # against System's and Election's invariants (the agents' timeout: LOSS)
    runs = [p for p in paths if p.exists()] + [p for p, _ in d.master_runs if p.exists()]
    epochs = {f"{p.name}:master": int(st["epoch"]) for p, st in d.master_runs if "epoch" in st}
    jobs.insert(0, (f"the whole run ({len(runs)} traces merged)", ("merged", runs, epochs)))

    def one(job):
        t = time.monotonic()
        if isinstance(job, tuple) and job[0] == "merged":
            return merged.validate(job[1], job[2], loss=LOSS), time.monotonic() - t
        if isinstance(job, tuple) and len(job) == 3:
            path, node, c = job
            return tracecheck.validate_master(path, c, node=node), time.monotonic() - t
        if isinstance(job, int):
            consts = {"TPing": HB, "TLoss": LOSS, "TPaused": PAUSED, "Election": True, "Score": SCORES[job],
                      "Epoch": 1, "VotedFor": 0}  # fresh --state-dir: epoch 1, no vote
            return tracecheck.validate(paths[job], consts), time.monotonic() - t
        path, state = job
        return tracecheck.validate_master(path, master_consts(state)), time.monotonic() - t

    t0 = time.monotonic()
    with ThreadPoolExecutor(max_workers=tracecheck.jobs_default()) as ex:
        results = list(ex.map(one, [j for _, j in jobs]))
    ok = True
    for (label, _), (r, secs) in zip(jobs, results):
        ok &= r.ok
        first = r.message.splitlines()[0] if r.message else ""
        print(f"  {label}: {'conforms' if r.ok else 'DOES NOT CONFORM'}: {first} ({secs:.1f} s)", flush=True)
        if not r.ok:
            print("\n".join("    " + line for line in r.message.splitlines()[1:]), flush=True)
    print(f"  {sum(r.records for (label, _), (r, _) in zip(jobs, results) if not label.startswith('the whole run'))} "
          f"records in {len(results) - 1} traces and the whole run, "
          f"{time.monotonic() - t0:.1f} s of wall time", flush=True)
    return ok


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", type=Path, default=Path(__file__).resolve().parents[1] / "build" / "bin")
    ap.add_argument("--dir", type=Path, default=Path(__file__).resolve().parents[1] / "build" / "demo")
    ap.add_argument("--signed", action="store_true", help="every node in signed mode, with a fresh key")
    args = ap.parse_args()
    for exe in ("ev3-agent", "ev3-master", "ev3-sim"):
        if not (args.bin / exe).is_file():
            print(f"demo: {args.bin / exe} is missing (run make build)", file=sys.stderr)
            return 1
    d = Demo(args.bin, args.dir, signed=args.signed)
    ok = True
    try:
        d.start()
        d.phase_sync()
        d.phase_behaviour()
        d.phase_master_lost()
        d.phase_election()
        d.phase_new_master_commands()
        d.phase_handover()
    except DemoFailed as e:
        d.event(f"DEMO FAILED: {e}")
        ok = False
    except KeyboardInterrupt:
        d.event("interrupted")
        ok = False
    finally:
        d.stop_all()
    d.summary()
    if ok and not check_record(d):
        ok = False
    if not validate_traces(d):
        ok = False
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
