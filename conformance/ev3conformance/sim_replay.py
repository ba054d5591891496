"""What the replays of TLC `-simulate` traces have in common: fleet_replay (MCFleetSim: one master
and its agents, Fleet.tla) and system_replay (MCSystemSim: the PC, the agents and the masters they
elect, System.tla) are each a subclass of SimReplay and SimTrace below.

A replay runs TLC -simulate on its wrapper module (one worker, a fixed seed: the same traces every
time), reads each trace file into its states, and replays every trace against driver processes
(docs/driver.md) step by step. A step that does not match ends its trace with a Mismatch (the rest
of the trace is counted as not replayed); the other traces still run. Mismatches are classified by
(action, differing fields); the first report of each class is kept, with the trace up to it.
"""

from __future__ import annotations

import json
import re
import shutil
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from ev3conformance import driver as drv
from ev3conformance import graph as gr
from ev3conformance import tla

HISTORY = 60                   # steps a mismatch report lists before the one that did not match

_STATE = re.compile(r"^STATE_\d+ ==[ \t]*\n", re.M)


def read_trace(path: Path) -> list[dict]:
    """A trace file of `-simulate file=...` (a module of STATE_i definitions) -> its states."""
    text = path.read_text()
    parts = _STATE.split(text)[1:]
    if not parts:
        raise tla.TlaParseError(f"{path}: no states")
    parts[-1] = re.split(r"^={4,}", parts[-1], flags=re.M)[0]
    return [tla.parse_state(p, model_values=True) for p in parts]


def simulate(module: str, cfg: str, prefix: str, seed: int, num: int, depth: int, out_dir: Path | None = None,
             timeout: float | None = None) -> tuple[list[Path], dict]:
    """Runs TLC -simulate on @p module with @p cfg (one worker, fixed seed: the same traces every
    time) and returns the trace files in order and figures. out_dir: default a new directory
    build/conformance/PREFIX-s<seed>-* (runs in parallel do not share it)."""
    if out_dir is None:
        gr.BUILD.mkdir(parents=True, exist_ok=True)
        out_dir = Path(tempfile.mkdtemp(prefix=f"{prefix}-s{seed}-", dir=gr.BUILD))
    else:
        shutil.rmtree(out_dir, ignore_errors=True)
        out_dir.mkdir(parents=True)
    t0 = time.monotonic()
    rc, out = gr.tlc(module, cfg, ["-simulate", f"file={out_dir / 'trace'},num={num}",
                                   "-depth", str(depth), "-seed", str(seed)], timeout=timeout)
    secs = time.monotonic() - t0
    if rc != 0 or "Error:" in out:
        raise RuntimeError(f"TLC -simulate failed (exit {rc}) on {module} {cfg}:\n{out[-4000:]}")
    files = sorted(out_dir.glob("trace_*"), key=lambda p: [int(x) for x in p.name.split("_")[1:]])
    return files, {"tlc_seconds": round(secs, 1), "dir": str(out_dir)}


class Mismatch(Exception):
    """A step of a trace the implementation did not match: what differs, the fields (its class),
    the report."""

    def __init__(self, what: str, fields: tuple, report: str) -> None:
        super().__init__(report)
        self.what, self.fields, self.report = what, fields, report


@dataclass
class SimFigures:
    """What every simulation replay counts; a subclass adds its own counts and lines (title, details)."""
    traces: int = 0
    steps: int = 0             # spec steps in all traces
    matched: int = 0           # steps replayed and matched
    not_replayed: int = 0      # steps after a trace's first mismatch
    mismatched_traces: int = 0
    inputs: int = 0            # driver inputs
    agents: int = 0
    tlc_seconds: float = 0.0
    seconds: float = 0.0
    actions: Counter = field(default_factory=Counter)     # spec action -> steps matched
    classes: dict = field(default_factory=dict)           # (action, fields) -> [count, first report]

    def title(self) -> str:
        raise NotImplementedError

    def details(self) -> list[str]:
        return []

    def summary(self) -> str:
        lines = [self.title(),
                 f"  steps {self.steps}  matched {self.matched}  mismatched traces {self.mismatched_traces}"
                 f"  steps not replayed (after a mismatch) {self.not_replayed}",
                 *self.details(),
                 f"  time: TLC -simulate {self.tlc_seconds:.1f}s, replay {self.seconds:.1f}s"]
        acts = ", ".join(f"{k} {n}" for k, n in sorted(self.actions.items(), key=lambda kv: (-kv[1], kv[0])))
        lines.append(f"  steps matched by action: {acts}")
        for (act, flds), (n, _) in sorted(self.classes.items(), key=lambda kv: -kv[1][0]):
            lines.append(f"  MISMATCH class {act} [{', '.join(flds)}]: {n} traces")
        return "\n".join(lines)


class SimTrace:
    """The replay of one trace: a subclass sets `agents` and gives start() (Init), step() (the step
    at self.k), key(k) and text(k) (step k as counted and as shown), fail() (raises Mismatch)."""

    agents: list

    def __init__(self, rp: "SimReplay", idx: int, path: Path | None, states: list[dict]) -> None:
        self.rp, self.idx, self.path, self.states = rp, idx, path, states
        self.k = 0                     # current step (index into states)
        self.last_out: dict = {}       # node -> last driver output (for reports)

    def _ask(self, d: drv.Driver, node, inp: dict) -> dict:
        out = d.ask(inp)
        self.rp.fig.inputs += 1
        self.last_out[str(node)] = out
        if "error" in out:
            self.fail("driver error", ("driver error",), f"  {node}'s driver answered {json.dumps(inp)} with "
                      f"error: {out['error']}")
        return out

    def key(self, k: int) -> str:
        raise NotImplementedError

    def text(self, k: int) -> str:
        raise NotImplementedError

    def counted(self, k: int) -> None:
        """After step @p k matched: what a subclass counts besides the action."""

    def fail(self, what: str, fields: tuple, detail: str) -> None:
        raise NotImplementedError

    def where(self) -> str:
        """The first line of a mismatch report: the trace and the step."""
        return (f"trace {self.idx}" + (f" ({self.path})" if self.path else "") +
                f", step {self.k} of {len(self.states) - 1}: {self.text(self.k)}")

    def history(self) -> list[str]:
        """The last lines of a mismatch report: the trace up to the step at hand."""
        lines = ["  the trace up to here:"]
        start = max(1, self.k - HISTORY)
        if start > 1:
            lines.append(f"     ... {start - 1} earlier steps (the trace file has them all)")
        for i in range(start, self.k + 1):
            lines.append(f"    {i:3}. {self.text(i)}")
        return lines


class SimReplay:
    """The runner: traces in, figures out. A subclass names its wrapper module (MODULE), the prefix of
    its trace directories (PREFIX), its Trace and Figures classes, and whether every trace gets new
    driver processes (DRIVERS_PER_TRACE) or keeps those of the trace before (each trace configures
    them afresh)."""

    MODULE = ""
    PREFIX = ""
    Trace = SimTrace
    Figures = SimFigures
    DRIVERS_PER_TRACE = True

    def __init__(self, agent_argv: list[str], master_argv: list[str]) -> None:
        self.agent_argv, self.master_argv = agent_argv, master_argv
        self.fig = self.Figures()
        self._open: list[drv.Driver] = []

    def driver(self, kind: str) -> drv.Driver:
        """A new driver process: "agent" or "master"."""
        d = drv.Driver(self.agent_argv if kind == "agent" else self.master_argv)
        self._open.append(d)
        return d

    def close(self, d: drv.Driver) -> None:
        d.kill()
        d.close()
        if d in self._open:
            self._open.remove(d)

    def close_all(self) -> None:
        for d in list(self._open):
            self.close(d)

    def run_trace(self, idx: int, states: list[dict], path: Path | None = None) -> bool:
        """Replays one trace; True when every step matched."""
        t = self.Trace(self, idx, path, states)
        self.fig.traces += 1
        self.fig.agents = max(self.fig.agents, len(t.agents))
        steps = len(states) - 1
        self.fig.steps += steps
        try:
            t.start()
            for k in range(1, len(states)):
                t.k = k
                t.step()
                self.fig.matched += 1
                self.fig.actions[t.key(k)] += 1
                t.counted(k)
            return True
        except Mismatch as m:
            self.fig.mismatched_traces += 1
            self.fig.not_replayed += steps - t.k
            key = (t.key(t.k) if t.k else "Init", m.fields)
            if key not in self.fig.classes:
                self.fig.classes[key] = [0, m.report]
            self.fig.classes[key][0] += 1
            return False
        finally:
            if self.DRIVERS_PER_TRACE:
                self.close_all()

    def run(self, traces) -> SimFigures:
        """traces: iterable of (path or None, states)."""
        t0 = time.monotonic()
        try:
            for i, (path, states) in enumerate(traces):
                self.run_trace(i, states, path)
        finally:
            self.close_all()
        self.fig.seconds = time.monotonic() - t0
        return self.fig

    def replay_simulation(self, seed: int, num: int, depth: int, cfg: str) -> SimFigures:
        """Simulates and replays; the trace files are removed when every trace conforms, kept (their
        paths are in the reports) when one does not."""
        files, figs = simulate(self.MODULE, cfg, self.PREFIX, seed, num, depth)
        self.run((p, read_trace(p)) for p in files)
        self.fig.tlc_seconds = figs["tlc_seconds"]
        if not self.fig.classes:
            shutil.rmtree(figs["dir"], ignore_errors=True)
        return self.fig
