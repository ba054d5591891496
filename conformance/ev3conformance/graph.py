"""TLC's state graph of a model (`-dump dot,actionlabels`), parsed, and an edge-covering path set.

Every node's label is the state (ag/out/lastAction for the agent model); the spec action of an
edge is the target state's `lastAction` (TLC labels edges with the bare name, usually "Next").
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import tempfile
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

from ev3conformance import tla

ROOT = Path(os.environ.get("EV3_ROOT") or Path(__file__).resolve().parents[2])
SPEC = ROOT / "spec" / "tla"
JAR = ROOT / ".tools" / "tla2tools.jar"
BUILD = ROOT / "build" / "conformance"
JAVA = ["java", "-XX:+UseParallelGC", "-Xss16m"]
# Most TLC runs of this package (trace checks, simulations) take seconds: there the JVM's optimising
# compiler (C2) costs more CPU than it wins back, so they run on its first compiler alone; a state
# graph's dump (minutes for MCAgent) keeps C2 (docs/spec.md "Commands").
C1_ONLY = ["-XX:TieredStopAtLevel=1"]


def tlc(module: str, cfg: str, extra: list[str], workers: int = 1, cwd: Path = SPEC,
        timeout: float | None = None, short: bool = True) -> tuple[int, str]:
    """Runs TLC on module with cfg; own -metadir; returns (exit status, output). short: a run of
    seconds (C1_ONLY)."""
    BUILD.mkdir(parents=True, exist_ok=True)
    md = tempfile.mkdtemp(prefix="meta-", dir=BUILD)
    # Its own java.io.tmpdir too: TLC extracts the standard modules (Naturals.tla, ...) there, and
    # parallel runs sharing /tmp race on those files (tlaplus/tlaplus#378).
    cmd = JAVA + (C1_ONLY if short else []) + [f"-Djava.io.tmpdir={md}", "-cp", str(JAR), "tlc2.TLC", "-workers", str(workers),
                  "-metadir", md, "-config", cfg] + extra + [module]
    try:
        p = subprocess.run(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                           timeout=timeout)
    finally:
        shutil.rmtree(md, ignore_errors=True)
    return p.returncode, p.stdout


def cfg_constants(module: str, cfg: str, cwd: Path = SPEC) -> dict:
    """The constants of a model: `X = v` from the cfg, `X <- Y` resolved from `Y == v` in the module."""
    text = (cwd / cfg).read_text()
    mod = (cwd / (module[:-4] if module.endswith(".tla") else module)).with_suffix(".tla").read_text()
    out = {}
    body = text.split("CONSTANTS", 1)[1] if "CONSTANTS" in text else text.split("CONSTANT", 1)[1]
    for line in body.splitlines():
        line = line.split("\\*")[0].strip()
        if re.match(r"^(SPECIFICATION|INVARIANTS?|PROPERTIES|PROPERTY|INIT|NEXT|CHECK_DEADLOCK)\b", line):
            break
        m = re.match(r"(\w+)\s*=\s*(.+)$", line)
        if m:
            try:
                out[m.group(1)] = tla.parse_value(m.group(2))
            except tla.TlaParseError:
                out[m.group(1)] = m.group(2)
            continue
        m = re.match(r"(\w+)\s*<-\s*(\w+)$", line)
        if m:
            d = re.search(r"^" + m.group(2) + r"\s*==\s*(.+)$", mod, re.M)
            try:
                out[m.group(1)] = tla.parse_value(d.group(1)) if d else m.group(2)
            except tla.TlaParseError:
                out[m.group(1)] = d.group(1).strip()  # an expression (e.g. MCOpTypes == Commands)
    return out


@dataclass
class Graph:
    states: dict[str, dict] = field(default_factory=dict)  # node id -> parsed state
    edges: list[tuple[str, str]] = field(default_factory=list)
    init: list[str] = field(default_factory=list)
    out: dict[str, list[int]] = field(default_factory=dict)  # node -> indices into edges


_NODE = re.compile(r'^(-?\d+) \[label="((?:[^"\\]|\\.)*)"(,style = filled)?\]')
_EDGE = re.compile(r'^(-?\d+) -> (-?\d+)')


def _unescape(label: str) -> str:
    return re.sub(r'\\(.)', lambda m: "\n" if m.group(1) == "n" else m.group(1), label)


def parse_dot(path: Path) -> Graph:
    g = Graph()
    seen = set()
    with open(path) as f:
        for line in f:
            m = _EDGE.match(line)
            if m:
                e = (m.group(1), m.group(2))
                if e in seen:
                    continue
                seen.add(e)
                g.out.setdefault(e[0], []).append(len(g.edges))
                g.edges.append(e)
                continue
            m = _NODE.match(line)
            if m:
                g.states[m.group(1)] = tla.parse_state(_unescape(m.group(2)))
                if m.group(3):
                    g.init.append(m.group(1))
    return g


def spec_digest(module: str, cfg: str, cwd: Path = SPEC) -> str:
    """What a model's state graph depends on: every module of @p cwd, the cfg, the TLC jar."""
    h = hashlib.sha256(f"{module.removesuffix('.tla')} {cfg}".encode())
    for f in sorted(Path(cwd).glob("*.tla")) + [Path(cwd) / cfg]:
        h.update(f.name.encode() + b"\0" + f.read_bytes() + b"\0")
    h.update(str(JAR.stat().st_size if JAR.exists() else 0).encode())
    return h.hexdigest()


def dump_args(name: str) -> list[str]:
    """TLC's arguments to dump a model's state graph where dump_graph looks for it."""
    BUILD.mkdir(parents=True, exist_ok=True)
    return ["-dump", "dot,actionlabels", str(BUILD / f"{name}-graph")]


def record_dump(module: str, cfg: str, name: str, out: str, cwd: Path = SPEC) -> None:
    """After a TLC run with dump_args(name) that passed: the dump is of this spec (its key), and
    TLC's counts, so dump_graph takes it instead of running TLC again (make spec, then make
    conformance: one TLC run of MCAgent)."""
    m = re.search(r"([\d,]+) states generated, ([\d,]+) distinct states found", out)
    figs = {"generated": int(m.group(1).replace(",", "")), "distinct": int(m.group(2).replace(",", ""))} if m else {}
    (BUILD / f"{name}-graph.key").write_text(json.dumps({"digest": spec_digest(module, cfg, cwd)} | figs))


def dump_file(module: str, cfg: str, name: str, cwd: Path = SPEC) -> tuple[Path, dict]:
    """The dot file of the model's state graph (TLC -dump dot,actionlabels) and TLC's figures. A
    dump recorded (record_dump) for the same spec is taken as it is (figures: reused); otherwise
    TLC runs here."""
    dump, key = BUILD / f"{name}-graph", BUILD / f"{name}-graph.key"
    try:
        known = json.loads(key.read_text())
    except (OSError, ValueError):
        known = {}
    path = dump if dump.exists() else dump.with_suffix(".dot")
    if known.get("digest") == spec_digest(module, cfg, cwd) and path.exists():
        return path, {k: known[k] for k in ("generated", "distinct") if k in known} | {"reused": True}
    key.unlink(missing_ok=True)
    rc, out = tlc(module, cfg, dump_args(name), cwd=cwd, short=False)
    if rc != 0:
        raise RuntimeError(f"TLC failed (exit {rc}) on {module} {cfg}:\n{out[-3000:]}")
    record_dump(module, cfg, name, out, cwd)
    path = dump if dump.exists() else dump.with_suffix(".dot")
    figs = {}
    m = re.search(r"([\d,]+) states generated, ([\d,]+) distinct states found", out)
    if m:
        figs["generated"] = int(m.group(1).replace(",", ""))
        figs["distinct"] = int(m.group(2).replace(",", ""))
    return path, figs


def dump_graph(module: str, cfg: str, name: str, cwd: Path = SPEC) -> tuple[Graph, dict]:
    """The model's state graph (dump_file) parsed. Returns (graph, figures)."""
    t0 = time.monotonic()
    path, figs = dump_file(module, cfg, name, cwd)
    t1 = time.monotonic()
    g = parse_dot(path)
    figs |= {"tlc_seconds": round(t1 - t0, 1), "parse_seconds": round(time.monotonic() - t1, 1)}
    return g, figs


@dataclass
class PathSet:
    """Edge-covering paths from the initial states, as a prefix tree.

    `tree[v]` = index of the edge by which v is first reached (BFS: shortest prefixes). The paths
    are: for every edge (u, v), the tree path to u followed by (u, v); prefixes of other paths are
    dropped. Replaying the tree depth-first (snapshot at each tree node) replays every path.
    """
    tree_edge: dict[str, int]
    order: list[str]          # nodes in BFS order
    depth: dict[str, int]
    paths: int
    max_len: int
    unreachable_edges: int

    def path_to(self, g: Graph, v: str) -> list[int]:
        p = []
        while v in self.tree_edge:
            e = self.tree_edge[v]
            p.append(e)
            v = g.edges[e][0]
        return p[::-1]


def cover(g: Graph, ok=None) -> PathSet:
    """Paths over the edges for which ok(edge index) holds (all when ok is None)."""
    ok = ok or (lambda ei: True)
    tree: dict[str, int] = {}
    depth = {v: 0 for v in g.init}
    order = list(g.init)
    q = deque(g.init)
    while q:
        u = q.popleft()
        for ei in g.out.get(u, []):
            v = g.edges[ei][1]
            if ok(ei) and v not in depth:
                depth[v] = depth[u] + 1
                tree[v] = ei
                order.append(v)
                q.append(v)
    tree_edges = set(tree.values())
    # A path ends at every edge that is not a tree edge into a node with successors.
    paths = 0
    max_len = 0
    unreachable = 0
    for ei, (u, v) in enumerate(g.edges):
        if not ok(ei):
            continue
        if u not in depth:
            unreachable += 1
            continue
        if ei in tree_edges and any(ok(x) for x in g.out.get(v, [])):
            continue
        paths += 1
        max_len = max(max_len, depth[u] + 1)
    return PathSet(tree, order, depth, paths, max_len, unreachable)


@dataclass
class WalkFigures:
    """What a spec-graph replay counts (the agent's and the master's add their own outcomes)."""
    states: int = 0
    edges: int = 0
    paths: int = 0
    max_path: int = 0
    steps: int = 0
    inputs: int = 0
    tlc_seconds: float = 0.0
    seconds: float = 0.0

    def head(self, name: str) -> str:
        return f"{name}: states {self.states}  edges {self.edges}  paths {self.paths} (longest {self.max_path})"


@dataclass
class StrictFigures(WalkFigures):
    """What a strict replay counts (master, reports: every edge replayed, mismatches counted and
    classified, see replay_walk)."""
    name: str = ""
    matched: int = 0
    mismatched: int = 0
    downstream: int = 0
    tolerated: int = 0
    classes: dict = field(default_factory=dict)   # (action, fields) -> [count, example report]

    def summary(self) -> str:
        done = self.matched + self.mismatched + self.downstream
        pct = 100.0 * done / self.edges if self.edges else 0
        lines = [self.head(self.name),
                 f"  edges replayed {done} of {self.edges} ({pct:.1f}%)",
                 f"  matched {self.matched}  mismatched {self.mismatched}  below a mismatch {self.downstream}"
                 + (f"  (of the matched, {self.tolerated} with a tolerated known difference)" if self.tolerated else ""),
                 f"  steps replayed {self.steps}  driver inputs {self.inputs}",
                 f"  time: TLC {self.tlc_seconds:.1f}s, replay {self.seconds:.1f}s"]
        for (act, flds), (n, _) in sorted(self.classes.items(), key=lambda kv: -kv[1][0]):
            lines.append(f"  MISMATCH class {act} [{', '.join(flds)}]: {n} edges")
        return "\n".join(lines)


def walk(g: Graph, ps: PathSet, ok=None, leave=None):
    """The replay of every path of @p ps as driver operations, depth-first over the prefix tree:
    ("save", d) snapshots the node reached at depth d in slot d, ("restore", d) goes back to it,
    ("edge", ei) replays edge ei. A tree child is expanded right after the edge into it, so slot
    d + 1 holds it until its subtree is done. Edges for which ok(ei) is false are left out (all are
    replayed when ok is None); so is an edge for which leave(ei) holds unless the tree goes on
    through it (a sample: every state stays reached). Both spec-graph replays (agent, master) walk
    this way."""
    ok = ok or (lambda ei: True)
    leave = leave or (lambda ei: False)
    for root in g.init:
        yield ("save", 0)
        stack = [(root, 0, iter(g.out.get(root, [])))]
        while stack:
            _, d, it = stack[-1]
            ei = next(it, None)
            if ei is None:
                stack.pop()
                continue
            if not ok(ei):
                continue
            v = g.edges[ei][1]
            goes_on = ps.tree_edge.get(v) == ei and g.out.get(v)
            if not goes_on and leave(ei):
                continue
            yield ("restore", d)
            yield ("edge", ei)
            if goes_on:
                yield ("save", d + 1)
                stack.append((v, d + 1, iter(g.out.get(v, []))))


def driver_inputs(g: Graph, ops, edge_input) -> list[tuple]:
    """(op, driver input) for each operation of walk(): save and restore as the drivers take them
    (docs/driver.md), an edge as edge_input(the lastAction of the state it leads to)."""
    res = []
    for op in ops:
        if op[0] in ("save", "restore"):
            res.append((op, {"type": op[0], "slot": op[1]}))
        else:
            res.append((op, edge_input(g.states[g.edges[op[1]][1]]["lastAction"])))
    return res


def replay_walk(g: Graph, argv: list[str], config: dict, tagged: list[tuple], fig, compare, report,
                stop_first: bool = False) -> None:
    """The strict replays (master, reports): a driver (@p argv) configured with @p config is fed the
    inputs @p tagged (driver_inputs()); each edge is compared by compare(edge index, output) ->
    {field: (spec, impl)} (empty: it conforms). Counts into @p fig (inputs, steps, matched,
    mismatched, downstream: below a mismatch) and keeps the first example of each class
    (action, fields) as report(path, diff, output) in fig.classes. stop_first: end at the first
    mismatch."""
    from ev3conformance import driver as drv
    d = drv.Driver(argv)
    try:
        first = d.ask(config)
        if "error" in first:
            raise RuntimeError(f"driver refused the configuration: {first['error']}")
        _compare_walk(g, tagged, d.stream([i for _, i in tagged]), fig, compare, report, stop_first)
    finally:
        d.kill()
        d.close()


def _compare_walk(g: Graph, tagged: list[tuple], outs, fig, compare, report, stop_first: bool) -> None:
    bad_at: dict[int, bool] = {0: False}
    path_at: dict[int, list[int]] = {0: []}
    bad, path = False, []
    for op, _ in tagged:
        _, out = next(outs)
        fig.inputs += 1
        if op[0] == "save":
            bad_at[op[1]], path_at[op[1]] = bad, list(path)
            continue
        if op[0] == "restore":
            bad, path = bad_at[op[1]], list(path_at[op[1]])
            continue
        ei = op[1]
        path = path + [ei]
        fig.steps += 1
        if bad:
            fig.downstream += 1
            continue
        diff = compare(ei, out)
        if not diff:
            fig.matched += 1
            continue
        bad = True
        fig.mismatched += 1
        key = (g.states[g.edges[ei][1]]["lastAction"]["name"], tuple(sorted(diff)))
        if key not in fig.classes:
            fig.classes[key] = [0, report(path, diff, out)]
        fig.classes[key][0] += 1
        if stop_first:
            break


def mismatch_lines(g: Graph, path: list[int], show, spec: dict, impl: dict, width: tuple[int, int]) -> list[str]:
    """The start of a strict replay's mismatch report: the path from the initial state (each
    action as show(lastAction) gives it), then the variables after its last step side by side
    (spec | implementation, !! where they differ), the columns @p width wide."""
    lines = ["  path from the initial state:"]
    for k, ei in enumerate(path):
        lines.append(f"    {k + 1:2}. {show(g.states[g.edges[ei][1]]['lastAction'])}")
    lines.append("  state after the last step (spec | implementation):")
    for k in sorted(set(spec) | set(impl)):
        mark = "  " if spec.get(k) == impl.get(k) else "!!"
        lines.append(f"   {mark} {k:{width[0]}} {spec.get(k, '<absent>')!s:{width[1]}} | {impl.get(k, '<absent>')}")
    return lines
