"""Whole-run trace validation: the NDJSON traces of every node of one real run merged into one
behaviour and checked by TLC against the composed spec's own invariants: System.tla (with
Election.tla) INSTANCEd in spec/tla/trace/MergedTrace.tla with the run mapped onto its variables
(docs/spec.md "Whole-run traces").

The merge is a topological order of the run's happens-before graph, never of wall clocks (each
process has its own): every trace file is one process and keeps its order (an agent's records and
those of the Master core it ran while elected, node master:ID:EPOCH, are written by one process),
and the receive of a datagram comes after the record that sent it. A datagram is its sender's id
and msgid: a record with `changed.msgid` (the node's next msgid after it: agent cores, the PC
master, Master cores) sent the msgids from the node's previous value up to that one (a Reports.tla
record, left out of the walk, sends too: its msgids count as sent by the node's record before it); a relay
forwards a datagram unchanged, with its sender and msgid. A receive whose send is in no trace of
the set (a node that was not traced, a datagram older than the traces) is allowed and counted in
the summary; a cycle of the graph is an error naming its records; a datagram two traced nodes
could have sent is an error too.

As tracecheck does, this module only converts data: each merged record with the fields the check
reads (and whether its receive was paired with its send), the nodes' start, the agent nodes, the
PC's runs, the Master cores, the agents' ids and timeout, written as TraceData.tla (definitions of
values); the properties are TLA+ (System's, by name), checked by TLC, whose verdict is read back: invariant
Walked violated = every record was walked and no property failed; another invariant violated =
the run breaks it, named with the records TLC's last state points at.
"""

from __future__ import annotations

import heapq
import json
import re
import shutil
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from ev3conformance import graph as gr
from ev3conformance import tla, tracecheck, wire

MODULE = "MCMergedTrace"
PC_ID = 1            # the PC master's id (AgentLogic's MasterId)
FIRST_SPAN = 64      # a node's first sending record: the msgids it may have sent below its new value
GLOBAL_VARS = ("id", "epoch", "leader", "following", "life", "via", "relays", "votedFor")
TLOSS = tracecheck.DEFAULTS["TLoss"]   # the agents' heartbeat timeout (ms): ev3-agent's default
TRACE_GLOBS = ("*.ndjson", "*.nd")
_NONE_EM = {"t": "NONE", "src": 0, "e": 0, "x": 0}
_NONE_M = {"t": "NONE", "src": 0}


# What a conforming run satisfies: System.tla's and Election.tla's invariants, by name (MCMergedTrace.cfg).
CHECKED = ("AtMostOneMasterPerEpochInv, FollowersAgreeInv, RelayOneHopInv, NoRelayCycleInv, StaleMasterFencedInv, "
           "LifecycleInv, NoUnsupervisedMotionInv, ObeyedNewestEpochInv, HandoverStepsDownInv hold")


class MergeError(ValueError):
    """The traces cannot be merged (a cycle, a datagram two nodes could have sent, no record)."""


@dataclass
class Rec:
    file: int      # index of its trace file
    k: int         # its place in that file (0-based)
    node: str      # the node that wrote it
    r: dict        # the record as read
    sent_to: int | None = None  # the node's next msgid after the Reports records left out after it


@dataclass
class Stream:
    """One node's records in one file, with the msgid ranges its records sent."""
    file: int
    node: str
    ids: set[int]
    sends: list[tuple[int | None, int, int]] = field(default_factory=list)  # (from or None, to, rec k)
    # a master's records that send again a msgid sent before (a MASTER re-sent to an agent that
    # announced itself again, a resend): (rec k, the node's epoch at it, the msgids pending in it)
    resends: list[tuple[int, int, set[int]]] = field(default_factory=list)
    # the node's epoch from each record on: (rec k, epoch), the first (-1, its epoch at start)
    epochs: list[tuple[int, int]] = field(default_factory=list)

    def epoch_at(self, k: int) -> int:
        """The node's epoch at its record @p k."""
        e = self.epochs[0][1] if self.epochs else 1
        for rk, ep in self.epochs:
            if rk > k:
                break
            e = ep
        return e


@dataclass
class Merged:
    files: list[Path]
    order: list[Rec]                  # the merged behaviour
    nodes: dict[str, dict]            # node label -> its start [id, epoch, leader, following]
    agents: list[str]                 # labels of the agent cores
    pairs: int = 0                    # receives matched with their send
    paired: set = field(default_factory=set)            # (file, k) of those receives
    late: set = field(default_factory=set)              # (file, k) of unsent receives past the sender's last record
    outside: Counter = field(default_factory=Counter)   # sender id (not traced) -> its receives
    unsent: Counter = field(default_factory=Counter)    # sender id (traced) -> receives of msgids no record sent
    undecodable: int = 0
    cut: list[str] = field(default_factory=list)

    def label(self, rec: Rec) -> str:
        return _label(self.files[rec.file], rec.node)

    def where(self, rec: Rec) -> str:
        r = rec.r
        msg = r.get("args", {}).get("msg")
        return (f"{self.files[rec.file].name} record {rec.k + 1} (node {rec.node}, {r.get('action')}"
                f"{', msg ' + msg if msg else ''}, changed {json.dumps(r.get('changed', {}))[:160]})")


def _label(path: Path, node: str) -> str:
    return f"{path.name}:{node}"


def trace_files(paths: list[Path]) -> list[Path]:
    """The trace files named, a directory standing for its *.ndjson / *.nd files (driver input
    files, *.inputs.ndjson, are not traces)."""
    out: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            found = sorted({f for g in TRACE_GLOBS for f in p.glob(g) if not f.name.endswith(".inputs.ndjson")})
            if not found:
                raise MergeError(f"{p}: no trace files (*.ndjson, *.nd) in this directory")
            out += found
        else:
            out.append(p)
    return out


def _datagram(text: str) -> wire.Message | None:
    try:
        return wire.decode(text.encode("latin-1"))
    except wire.DecodeError:
        return None


def _kind(node: str) -> str:
    if node.startswith("agent"):
        return "agent"
    if node == "master":
        return "pc"
    parts = node.split(":")
    if len(parts) == 3 and parts[0] == "master" and parts[1].isdigit() and parts[2].isdigit():
        return "core"
    return "other"


def _start_epoch(node: str, label: str, epochs: dict[str, int] | None) -> int:
    """A node's epoch before its first record: @p epochs' entry for its label (a PC restarted with
    --epoch), else the epoch a Master core's name gives, else 1."""
    return (epochs or {}).get(label, int(node.split(":")[2]) if _kind(node) == "core" else 1)


def _streams(fi: int, recs: list[Rec], start) -> dict[str, Stream]:
    """The sending nodes of one file: their ids and the msgid ranges of their records (@p start:
    a node's epoch before its first record)."""
    out: dict[str, Stream] = {}
    by_node: dict[str, list[Rec]] = {}
    for x in recs:
        by_node.setdefault(x.node, []).append(x)
    for node, mine in by_node.items():
        kind = _kind(node)
        if kind == "agent":
            ids = {tracecheck.temp_id_of([x.r for x in mine])}
            ids |= {int(x.r["changed"]["id"]) for x in mine if "id" in x.r.get("changed", {})}
        elif kind == "pc":
            ids = {PC_ID}
        elif kind == "core":
            ids = {int(node.split(":")[1])}
        else:
            ids = set()
        s = Stream(fi, node, ids)
        prev = None
        epoch = start(node)
        s.epochs.append((-1, epoch))
        for x in mine:
            ch = x.r.get("changed", {})
            for m in (ch.get("msgid"), x.sent_to):  # its own sends, then those of Reports records after it
                if isinstance(m, int):
                    s.sends.append((prev, m, x.k))
                    prev = m
            if isinstance(ch.get("epoch"), int):
                epoch = ch["epoch"]
                s.epochs.append((x.k, epoch))
            if kind in ("pc", "core") and x.r.get("action") in ("MasterSync", "MasterTick"):
                again = {e["mid"] for e in ch.get("reg", ()) if isinstance(e, dict) and e.get("pending")
                         and isinstance(e.get("mid"), int)}
                if again:
                    s.resends.append((x.k, epoch, again))
        out[node] = s
    return out


def _sender(streams: list[Stream], src: int, msgid: int) -> tuple[Stream, int] | None | str:
    """The record that sent datagram (src, msgid): (stream, record k), None when no traced node
    sent it, or a message when two could have."""
    exact, first = [], []
    for s in streams:
        if src not in s.ids:
            continue
        for lo, hi, k in s.sends:
            if lo is not None and lo <= msgid < hi:
                exact.append((s, k))
                break
            if lo is None and hi - FIRST_SPAN <= msgid < hi:
                first.append((s, k))
                break
    cands = exact or first
    if len(cands) > 1:
        return "; ".join(f"node {s.node} of file #{s.file + 1} record {k + 1}" for s, k in cands)
    return cands[0] if cands else None


def _resent_at(s: Stream, k: int, d: wire.Message) -> int:
    """The record that sent datagram @p d, first sent by record @p k of @p s: an EPOCH_CMD carries
    the epoch its sender was master of when it sent it; sent first in an older epoch, this copy
    was sent again (same msgid) by the first later record of @p s that re-sent it in that epoch.
    Pairing it with its first send would let the merge put its receive before the sender's
    election of that epoch."""
    if d.type_name != "EPOCH_CMD" or not d.params:
        return k
    try:
        e = int(d.params[0])
    except ValueError:
        return k
    if s.epoch_at(k) == e:
        return k  # first sent in that epoch: a receive may be of that first copy
    for rk, epoch, again in s.resends:
        if rk > k and epoch == e and d.msgid in again:
            return rk
    return k


def merge(paths: list[Path], epochs: dict[str, int] | None = None) -> Merged:
    """The traces of @p paths (files or directories) merged: see the module's doc. @p epochs: a
    node label's epoch before its first record, when not 1 (agent cores, the PC; a Master core
    starts in the epoch its name gives). Raises MergeError or tracecheck.TraceError."""
    files = trace_files(paths)
    if not files:
        raise MergeError("no trace files given")
    dup = sorted({f.name for f in files if sum(g.name == f.name for g in files) > 1})
    if dup:
        raise MergeError(f"two trace files named {', '.join(dup)}: the check names nodes by file name")
    per_file: list[list[Rec]] = []
    m = Merged(files, [], {}, [])
    for fi, f in enumerate(files):
        try:
            tf = tracecheck.read_trace(f)
        except tracecheck.TraceError as e:
            raise tracecheck.TraceError(f"{f}: {e}") from e
        if not tf.records:
            raise MergeError(f"{f}: no records (an empty trace shows nothing)")
        if tf.cut:
            m.cut.append(f"{f.name} ({tf.cut} bytes)")
        per_file.append([Rec(fi, k, str(r.get("node", "")), r, tf.sent_after.get(k)) for k, r in enumerate(tf.records)])
    streams: list[Stream] = []
    for fi, recs in enumerate(per_file):
        for node, s in _streams(fi, recs, lambda n: _start_epoch(n, _label(files[fi], n), epochs)).items():
            streams.append(s)
            lab = _label(files[fi], node)
            kind = _kind(node)
            ep = _start_epoch(node, lab, epochs)
            sid = min(s.ids) if kind in ("pc", "core") else (min(s.ids) if s.ids else 0)
            if kind == "agent":
                sid = tracecheck.temp_id_of([x.r for x in recs if x.node == node])
                m.agents.append(lab)
            life = {"agent": "IDLE", "core": "NONE", "pc": "MASTER" if ep == 1 else "CANDIDATE"}.get(kind, "NONE")
            m.nodes[lab] = {"id": sid, "epoch": ep, "leader": 0, "following": 0, "life": life, "via": 0,
                            "relays": frozenset(), "votedFor": 0}
    # the happens-before graph: process order + send -> receive
    succ: dict[tuple[int, int], list[tuple[int, int]]] = {}
    npred: dict[tuple[int, int], int] = {}
    for fi, recs in enumerate(per_file):
        for x in recs:
            npred[(fi, x.k)] = 1 if x.k > 0 else 0
            if x.k > 0:
                succ.setdefault((fi, x.k - 1), []).append((fi, x.k))
    for fi, recs in enumerate(per_file):
        for x in recs:
            text = x.r.get("args", {}).get("msg")
            if not text:
                continue
            d = _datagram(text)
            if d is None:
                m.undecodable += 1
                continue
            s = _sender(streams, d.sender, d.msgid)
            if s is None:
                traced = any(d.sender in st.ids for st in streams)
                (m.unsent if traced else m.outside)[d.sender] += 1
                # sent after a process's last record (lost with a SIGKILL, written through stdio): its own
                if any(st.sends and d.msgid >= st.sends[-1][1] for st in streams if d.sender in st.ids):
                    m.late.add((fi, x.k))
                continue
            if isinstance(s, str):
                raise MergeError(f"datagram {d.sender}:{d.msgid} received by {m.where(x)} could have been sent by "
                                 f"more than one traced node: {s}")
            src = (s[0].file, _resent_at(s[0], s[1], d))
            succ.setdefault(src, []).append((fi, x.k))
            npred[(fi, x.k)] += 1
            m.pairs += 1
            m.paired.add((fi, x.k))
    # Kahn's algorithm: the ready record of the first file first (deterministic; any order would do)
    ready = [key for key, n in npred.items() if n == 0]
    heapq.heapify(ready)
    while ready:
        key = heapq.heappop(ready)
        m.order.append(per_file[key[0]][key[1]])
        for nx in succ.get(key, []):
            npred[nx] -= 1
            if npred[nx] == 0:
                heapq.heappush(ready, nx)
    total = sum(len(r) for r in per_file)
    if len(m.order) < total:
        raise MergeError(_cycle(m, per_file, succ, npred))
    return m


def _cycle(m: Merged, per_file, succ, npred) -> str:
    """A cycle among the records Kahn's algorithm could not place, named record by record."""
    preds: dict[tuple[int, int], list[tuple[int, int]]] = {}
    for a, bs in succ.items():
        for b in bs:
            if npred.get(a, 0) > 0 and npred.get(b, 0) > 0:
                preds.setdefault(b, []).append(a)
    start = next(k for k, n in npred.items() if n > 0)
    seen: dict[tuple[int, int], int] = {}
    path = []
    cur = start
    while cur not in seen:
        seen[cur] = len(path)
        path.append(cur)
        cur = preds[cur][0]
    loop = list(reversed(path[seen[cur]:]))
    rows = "\n".join(f"  {m.where(per_file[f][k])}" for f, k in loop)
    left = sum(1 for n in npred.values() if n > 0)
    return (f"the happens-before graph has a cycle ({left} records cannot be ordered): each record below "
            f"comes before the next (its process order or a datagram it sent), the last before the first:\n{rows}")


# --- the data ------------------------------------------------------------------------------------

def _item(m: Merged, x: Rec, idx: dict[str, int]) -> dict:
    r = x.r
    ch = {}
    for k, v in r.get("changed", {}).items():
        if k not in GLOBAL_VARS:
            continue
        if isinstance(v, list):
            ch[k] = frozenset(int(i) for i in v)
        elif isinstance(v, (int, str)) and not isinstance(v, bool):
            ch[k] = v
    em, bm = dict(_NONE_EM), dict(_NONE_M)
    text = r.get("args", {}).get("msg")
    if text:
        d = _datagram(text)
        if d is not None:
            if (d.type_name or "") in tracecheck._EL_TYPES:
                e, _inner, _members = tracecheck._el_msg(text)
                em = {"t": e["t"], "src": e["src"], "e": e["e"], "x": e["x"]}
            else:
                bm = {"t": d.type_name or "?", "src": d.sender}
    ticks = r.get("args", {}).get("ticks", 0) if r.get("action") == "Tick" else 0
    return {"n": idx[m.label(x)], "a": str(r.get("action")), "ch": ch, "em": em, "m": bm,
            "cmd": str(r.get("args", {}).get("cmd", "")), "g": (x.file, x.k) in m.paired or (x.file, x.k) in m.late,
            "sent": "msgid" in r.get("changed", {}), "ticks": int(ticks) if isinstance(ticks, int) else 0}


def node_index(m: Merged) -> dict[str, int]:
    """Each node's number in TraceData (1, 2, ...: its place in NodeNames)."""
    return {lab: i + 1 for i, lab in enumerate(m.nodes)}


def data_module(m: Merged, loss: int = TLOSS) -> str:
    """TraceData for MCMergedTrace: the merged records (n: the node's number), the nodes' start and
    names in that order, the agent nodes, the PC's runs in the order they ran, the Master cores' [id, e]
    (from their names), every id an agent core had, the PC's id, the agents' timeout @p loss."""
    idx = node_index(m)
    pcs = [lab for lab in m.nodes if _kind(lab.split(":", 1)[1]) == "pc"]
    pcs.sort(key=lambda lab: next(i for i, x in enumerate(m.order) if m.label(x) == lab)
             if any(m.label(x) == lab for x in m.order) else len(m.order))
    cores = [{"n": idx[lab], "id": int(lab.split(":")[2]), "e": int(lab.split(":")[3])}
             for lab in m.nodes if _kind(lab.split(":", 1)[1]) == "core"]
    ids = {m.nodes[a]["id"] for a in m.agents}
    for x in m.order:
        if m.label(x) in m.agents and isinstance(x.r.get("changed", {}).get("id"), int):
            ids.add(x.r["changed"]["id"])
    body = ",\n".join("  " + tla.to_tla(_item(m, x, idx)) for x in m.order)
    return "\n".join([
        "---- MODULE TraceData ----",
        "\\* Data only, written by ev3conformance.merged (no TLA+ logic: see spec/tla/trace/MergedTrace.tla).",
        f"\\* {len(m.order)} records of {len(m.nodes)} nodes in {len(m.files)} traces: "
        + " ".join(f.name for f in m.files),
        f"Trace == <<\n{body}\n>>",
        f"Start == {tla.to_tla(tuple(m.nodes.values()))}",
        f"NodeNames == {tla.to_tla(tuple(m.nodes))}",
        f"Agents == {tla.to_tla(frozenset(idx[a] for a in m.agents))}",
        f"PCs == {tla.to_tla(tuple(idx[p] for p in pcs))}",
        "Cores == {" + ", ".join(tla.to_tla(c) for c in cores) + "}",
        f"AgentIds == {tla.to_tla(frozenset(ids))}",
        f"PC == {PC_ID}",
        f"TLoss == {int(loss)}",
        "====", ""])


# --- the check -----------------------------------------------------------------------------------

@dataclass
class Result:
    ok: bool
    records: int
    nodes: int
    message: str
    seconds: float = 0.0


def _last_state(out: str) -> dict:
    """The variables of the last state of TLC's error trace."""
    blocks = re.split(r"^State \d+:.*$", out, flags=re.M)
    text = blocks[-1].split("\n\n")[0] if len(blocks) > 1 else ""
    vals = {}
    for part in re.split(r"^/\\ ", text, flags=re.M):
        if "=" in part:
            name, val = part.split("=", 1)
            vals[name.strip()] = val.strip()
    return vals


def _explain(m: Merged, inv: str, out: str, loss: int) -> str:
    """What invariant @p inv (System's or Election's, MergedTrace) found, named with the records."""
    st = _last_state(out)
    try:
        cursor = int(st.get("cursor", "0"))
        val = {k: tla.parse_value(st[k]) for k in ("elected", "applied", "obeyed", "handed", "loc", "heard", "told")
               if k in st}
    except (ValueError, KeyError) as e:
        return f"{inv} is violated (TLC's last state could not be read: {e})"
    elected, applied = val.get("elected", frozenset()), val.get("applied", frozenset())
    loc, heard = val.get("loc", ()), val.get("heard", ())
    at = lambda i: m.where(m.order[i - 1]) if 1 <= i <= len(m.order) else "(the start: the PC is master of epoch 1)"
    names = list(m.nodes)
    name = lambda n: names[n - 1] if isinstance(n, int) and 1 <= n <= len(names) else str(n)
    last = cursor - 1
    after = f"after merged record {last}: {at(last)}"
    masters = {(x["e"], x["id"]) for x in elected}
    el = ", ".join(f"epoch {e}: node {i}" for e, i in sorted(masters))
    agents = [(n, s) for n, s in enumerate(loc, 1) if name(n) in m.agents]
    if inv == "AtMostOneMasterPerEpochInv":
        by_e: dict[int, list] = {}
        for x in elected:
            by_e.setdefault(x["e"], []).append(x)
        rows = []
        for e, xs in sorted(by_e.items()):
            if len({x["id"] for x in xs}) > 1:
                rows += [f"  node id {x['id']} became master of epoch {e} at merged record {x['at']}: {at(x['at'])}"
                         for x in sorted(xs, key=lambda x: x["at"])]
        return f"two masters in one epoch ({inv}):\n" + "\n".join(rows)
    if inv == "StaleMasterFencedInv":
        rows = []
        for c in sorted(applied, key=lambda c: c["at"]):
            if c["e"] != c["seen"] or (c["e"], c["src"]) not in masters:
                why = (f"epoch {c['e']} is older than the newest the agent has seen ({c['seen']})"
                       if c["e"] < c["seen"] else
                       f"epoch {c['e']} is not the agent's ({c['seen']})" if c["e"] != c["seen"] else
                       f"node {c['src']} was not elected master of epoch {c['e']} before it")
                rows.append(f"  agent {name(c['a'])} obeyed a command of node {c['src']} in epoch {c['e']}: {why}; "
                            f"merged record {c['at']}: {at(c['at'])}")
        return f"a command obeyed from a stale master ({inv}; elected so far: {el}):\n" + "\n".join(rows)
    if inv == "ObeyedNewestEpochInv":
        rows = [f"  agent {name(c['a'])} obeyed a command of node {c['src']} in epoch {c['e']} after epoch "
                f"{c['told']} had reached it; merged record {c['at']}: {at(c['at'])}"
                for c in sorted(val.get("obeyed", ()), key=lambda c: c["at"]) if c["e"] < c["told"]]
        return f"a command obeyed from a stale master ({inv}: older than an epoch the agent was told of):\n" + \
            "\n".join(rows)
    if inv == "FollowersAgreeInv":
        rows = [f"  {name(n)} follows node {s['leader']} in epoch {s['following']} (its epoch {s['epoch']})"
                for n, s in agents if s["following"] != 0 and
                (s["following"] != s["epoch"] or (s["following"], s["leader"]) not in masters)]
        return (f"an agent follows a node that is not the master of its epoch ({inv}; elected so far: "
                f"{el}), {after}:\n" + "\n".join(rows))
    if inv == "NoUnsupervisedMotionInv":
        rows = [f"  {name(n)} (id {s['id']}) is WORKING and no genuine datagram of its master (node {s['leader']}, "
                f"epoch {s['following']}) reached it for more than {loss} ms"
                for n, s in agents if s["life"] == "WORKING" and n <= len(heard) and heard[n - 1] > loss]
        return f"motion without a master ({inv}), {after}:\n" + "\n".join(rows)
    if inv == "HandoverStepsDownInv":
        rows = [f"  node {h['src']} handed the fleet over to the master of epoch {h['e']} at merged record {h['at']}: "
                f"{at(h['at'])}" for h in sorted(val.get("handed", ()), key=lambda h: h["at"])]
        return f"a master that handed over is still master of an older epoch ({inv}), {after}:\n" + "\n".join(rows)
    rows = [f"  {name(n)} (id {s['id']}): {s['life']}, leader {s['leader']}, following {s['following']}, "
            f"epoch {s['epoch']}, via {s['via']}, relays {sorted(s['relays'])}" for n, s in agents]
    return f"{inv} is violated {after}; the agents then:\n" + "\n".join(rows)


def summary(m: Merged) -> str:
    outside = ", ".join(f"{s} ({n})" for s, n in sorted(m.outside.items()))
    nodes = Counter(m.label(x) for x in m.order)
    parts = [f"{len(m.order)} records of {len(m.nodes)} nodes in {len(m.files)} traces merged "
             f"({', '.join(f'{k} {v}' for k, v in nodes.items())}); {m.pairs} receives ordered after their send",
             f"{sum(m.outside.values())} receives from outside the traced nodes"
             + (f" (by sender id: {outside})" if outside else "")]
    if m.unsent:
        unsent = ", ".join(f"{s} ({n})" for s, n in sorted(m.unsent.items()))
        parts.append(f"{sum(m.unsent.values())} receives of datagrams of traced nodes that no record of theirs "
                     f"sent (by sender id: {unsent}: sent after the sender's last record, by a kill's lost records "
                     f"or LEAVING at exit, or before its trace began), not ordered; {len(m.late)} of them past "
                     f"the sender's last recorded msgid, taken as its own (genuine)")
    if m.undecodable:
        parts.append(f"{m.undecodable} undecodable datagrams not ordered")
    if m.cut:
        parts.append(f"last lines cut by a kill left out: {', '.join(m.cut)}")
    return "; ".join(parts)


def validate(paths: list[Path], epochs: dict[str, int] | None = None, workdir: Path | None = None,
             loss: int = TLOSS) -> Result:
    """Merge the traces of @p paths and check the run with TLC (MCMergedTrace: System's and
    Election's invariants), @p loss the agents' heartbeat timeout (ms, --master-timeout-ms). A run
    that cannot be merged is a failed check, its message naming why."""
    t0 = time.monotonic()
    try:
        m = merge([Path(p) for p in paths], epochs)
    except (MergeError, tracecheck.TraceError) as e:
        return Result(False, 0, 0, f"cannot merge the traces: {e}", time.monotonic() - t0)
    wd = Path(workdir or (gr.BUILD / "traces"))
    wd.mkdir(parents=True, exist_ok=True)
    d = Path(tempfile.mkdtemp(prefix="merged-", dir=wd))
    for f in (list(tracecheck.TRACE_SPEC.glob("MergedTrace.tla")) + list(tracecheck.TRACE_SPEC.glob(f"{MODULE}.*"))
              + [gr.SPEC / "System.tla", gr.SPEC / "Election.tla"]):
        shutil.copy(f, d / f.name)
    (d / "TraceData.tla").write_text(data_module(m, loss))
    rc, out = gr.tlc(f"{MODULE}.tla", f"{MODULE}.cfg", [], cwd=d)
    secs = time.monotonic() - t0
    n = len(m.order)
    inv = re.search(r"Invariant (\w+) is violated", out)
    if rc == 12 and inv and inv.group(1) == "Walked":  # every record walked, no other invariant violated
        cur = _last_state(out).get("cursor")
        if cur is not None and int(cur) == n + 1:
            shutil.rmtree(d, ignore_errors=True)
            return Result(True, n, len(m.nodes), f"{summary(m)}; {CHECKED}", secs)
        return Result(False, n, len(m.nodes), f"TLC's walk ended at record {cur}, the merge has {n} "
                                              f"(check kept in {d})", secs)
    if rc == 12 and inv:
        return Result(False, n, len(m.nodes), f"{_explain(m, inv.group(1), out, loss)}\n({summary(m)}; check kept in {d})",
                      secs)
    return Result(False, n, len(m.nodes), f"TLC failed (exit {rc}); check in {d}:\n{out[-2500:]}", secs)


# --- faults planted in a real run: the check's own test (make spec, tests/python/test_merged.py) ---

PLANTS = {
    "two-masters": "a second node becomes master of an epoch another node won: a BecomeMaster record "
                   "inserted in its trace after the record where its epoch became that one "
                   "(AtMostOneMasterPerEpochInv)",
    "stale-command": "an agent obeys an EPOCH_CMD of an older epoch: the epoch of an obeyed EPOCH_CMD "
                     "in its trace lowered by one (StaleMasterFencedInv)",
    "spoofed-master": "a WORKING agent keeps working on datagrams that only claim to be its master's: the "
                      "sender of every bare or LEADER datagram of its master it receives after it started "
                      "working changed to an id no traced node has, until one of its Tick records passes the "
                      "timeout (NoUnsupervisedMotionInv; the record named is that Tick)",
    "newer-epoch-ignored": "an agent hears a LEADER of a newer epoch (the epoch of an EPOCH_CMD it then obeys, "
                           "plus one) and changes nothing: a HandleHeartbeat record inserted before the "
                           "ApplyCommand, which is named (ObeyedNewestEpochInv)",
    "handover-keeps-master": "an elected agent's Master core that steps down on a newer epoch stays master "
                             "after handing over: the STEPPED_DOWN left out of its record that took the newer "
                             "LEADER and sent HANDOVER, or, when it stepped down otherwise (an ELECT), that "
                             "record made one (a LEADER of that epoch, the same datagram's sender and msgid; "
                             "HANDOVER sent) (HandoverStepsDownInv)",
    "relay-relayed": "an agent that enters a peer in its relay table is itself relayed: via set to "
                     "another agent in that HandleAccept record (RelayOneHopInv)",
    "relay-self": "an agent enters itself in its relay table: its id added to the relays of a HandleAccept "
                  "record (NoRelayCycleInv)",
    "panic-following": "an agent that panics on heartbeat loss keeps following its master: leader and "
                       "following left out of that HeartbeatLost record (LifecycleInv)",
}


# The invariant each planted fault breaks, exactly that one: the last "(Name)" of its description.
PLANT_INVARIANT = {k: re.findall(r"\((\w+Inv)", v)[-1] for k, v in PLANTS.items()}


def _read_all(files: list[Path]) -> dict[Path, list[dict]]:
    return {f: tracecheck.read_trace(f).records for f in files}


def _epochs_of(recs: list[dict], node: str):
    """(index, the node's epoch after that record) for each of @p node's records."""
    e = 1
    for i, r in enumerate(recs):
        if r.get("node") != node:
            continue
        e = int(r.get("changed", {}).get("epoch", e))
        yield i, e


def _agent_recs(rs: list[dict]):
    return [(i, r) for i, r in enumerate(rs) if r.get("node") == "agent"]


def _with_sender(text: str, sender: int, msgid: int | None = None, params: tuple | None = None) -> str:
    d = _datagram(text)
    m = wire.Message(sender, d.receiver, d.msgid if msgid is None else msgid, d.type,
                     d.params if params is None else params)
    return wire.encode(m).decode("latin-1")


# MergedTrace's Commands: AgentLogic's handlers of a master's command.
_COMMANDS = {"RecvMaster", "RecvBehaviour", "RecvStart", "RecvStop", "RecvPause", "RecvResume", "RecvStandby",
             "RecvContinue", "RecvRestart"}


def _plant_spoofed(recs, loss):
    """spoofed-master: see PLANTS."""
    spoof = 9  # no traced node's id (ids 2.. are agents, 1 the PC; the runs stored have fewer than 8 agents)
    for f, rs in recs.items():
        life, leader, start = None, 0, None
        for i, r in _agent_recs(rs):
            ch = r.get("changed", {})
            leader = ch.get("leader", leader)
            if ch.get("life") == "WORKING" and life != "WORKING":
                start, passed, changed = i, 0, {}
            life = ch.get("life", life)
            if start is None or i == start:
                continue
            if life != "WORKING":
                start = None
                continue
            d = _datagram(r.get("args", {}).get("msg", "")) if r.get("args", {}).get("msg") else None
            if d is not None and d.sender == leader:
                if d.type_name in ("EPOCH_CMD", "RELAY") or r.get("action") in _COMMANDS:
                    passed = 0   # a command: kept genuine (a spoofed one would be a stale command)
                else:
                    changed[i] = _with_sender(r["args"]["msg"], spoof)
            if r.get("action") == "Tick":
                passed += int(r.get("args", {}).get("ticks", 0))
                if passed > loss:
                    for k, text in changed.items():
                        rs[k]["args"] = dict(rs[k]["args"], msg=text)
                    return f"{f.name} record {i + 1} (WORKING since record {start + 1}, {len(changed)} datagrams spoofed)"
    return None


def _plant_newer_epoch(recs, loss):
    """newer-epoch-ignored: see PLANTS."""
    lead = next((r["args"]["msg"] for rs in recs.values() for _, r in _agent_recs(rs)
                 if r.get("action") == "HandleHeartbeat" and r.get("args", {}).get("msg")), None)
    for f, rs in recs.items():
        for i, r in _agent_recs(rs):
            if r.get("action") != "ApplyCommand" or r["args"].get("cmd") in (None, "Ignore") or lead is None:
                continue
            d = _datagram(r["args"].get("msg", ""))
            if d is None or d.type_name != "EPOCH_CMD":
                continue
            e = int(d.params[0])
            hb = _datagram(lead)
            text = _with_sender(lead, PC_ID, 999_999_999, (str(e + 1).encode(),) + tuple(hb.params[1:]))
            rs.insert(i, {"node": "agent", "action": "HandleHeartbeat", "args": {"msg": text},
                          "now": r.get("now", 0), "changed": {}})
            return f"{f.name} record {i + 2} (EPOCH_CMD of epoch {e} obeyed after a LEADER of epoch {e + 1})"
    return None


def _plant_handover(recs, loss):
    """handover-keeps-master: see PLANTS."""
    for f, rs in recs.items():
        for i, r in enumerate(rs):
            node, ch = str(r.get("node", "")), r.get("changed", {})
            if _kind(node) != "core" or ch.get("life") != "STEPPED_DOWN" or "epoch" not in ch:
                continue
            d = _datagram(r.get("args", {}).get("msg", ""))
            if r.get("action") == "HandleHeartbeat" and "msgid" in ch and d is not None and d.type_name == "LEADER":
                rs[i] = dict(r, changed={k: v for k, v in ch.items() if k != "life"})   # a real HANDOVER
                return f"{f.name} record {i + 1} (node {node} handed over to epoch {ch['epoch']} and stays master)"
            lead = next((x["args"]["msg"] for x in rs if x.get("action") == "HandleHeartbeat"
                         and _datagram(x.get("args", {}).get("msg", "") or "x") is not None
                         and _datagram(x["args"]["msg"]).type_name == "LEADER"), None)
            if d is None or lead is None:
                continue
            hb = _datagram(lead)
            text = wire.encode(wire.Message(d.sender, 0, d.msgid, hb.type, (str(ch["epoch"]).encode(),) +
                                            tuple(hb.params[1:]))).decode("latin-1")
            last = max((x["changed"]["msgid"] for x in rs[:i] if x.get("node") == node
                        and isinstance(x.get("changed", {}).get("msgid"), int)), default=0)
            rs[i] = dict(r, action="HandleHeartbeat", args={"msg": text},
                         changed={"epoch": ch["epoch"], "msgid": last + 1})
            return f"{f.name} record {i + 1} (node {node} hands over to epoch {ch['epoch']} and stays master)"
    return None


def _plant_accept(recs, how):
    for f, rs in recs.items():
        ids = {int(x["changed"]["id"]) for x in rs if isinstance(x.get("changed", {}).get("id"), int)}
        others = sorted({int(x["changed"]["id"]) for g in recs.values() for x in g if g is not rs
                         and x.get("node") == "agent" and isinstance(x.get("changed", {}).get("id"), int)})
        for i, r in _agent_recs(rs):
            rel = r.get("changed", {}).get("relays")
            if r.get("action") != "HandleAccept" or not rel or not ids:
                continue
            me = max(ids)
            if how == "relayed":
                other = next((o for o in others if o not in rel), None)
                if other is None:
                    continue
                r["changed"] = dict(r["changed"], via=other)
                return f"{f.name} record {i + 1} (relays {rel} while relayed by {other})"
            r["changed"] = dict(r["changed"], relays=sorted(set(rel) | {me}))
            return f"{f.name} record {i + 1} (agent {me} relays for itself)"
    return None


def _plant_panic(recs, loss):
    """panic-following: see PLANTS."""
    for f, rs in recs.items():
        for i, r in _agent_recs(rs):
            ch = r.get("changed", {})
            if r.get("action") == "HeartbeatLost" and ch.get("life") == "PANIC" and "leader" in ch:
                r["changed"] = {k: v for k, v in ch.items() if k not in ("leader", "following")}
                return f"{f.name} record {i + 1} (PANIC, still following)"
    return None


_PLANTERS = {"spoofed-master": _plant_spoofed, "newer-epoch-ignored": _plant_newer_epoch,
             "handover-keeps-master": _plant_handover,
             "relay-relayed": lambda recs, loss: _plant_accept(recs, "relayed"),
             "relay-self": lambda recs, loss: _plant_accept(recs, "self"), "panic-following": _plant_panic}


def plant(paths: list[Path], out: Path, fault: str, loss: int = TLOSS) -> str:
    """Copies the run's traces to directory @p out with @p fault (PLANTS) planted in one of them;
    returns where (file and record number, as the check names them); @p loss: the agents' timeout the
    check will be given (spoofed-master). Raises MergeError when the run has no place for it (no epoch
    won by an agent, no EPOCH_CMD obeyed, ...)."""
    files = trace_files(paths)
    recs = _read_all(files)
    where = None
    if fault == "two-masters":
        won = {}  # epoch -> file of the agent that won it
        for f, rs in recs.items():
            ep = dict(_epochs_of(rs, "agent"))
            for i, r in enumerate(rs):
                if r.get("node") == "agent" and r.get("action") == "BecomeMaster":
                    won[ep[i]] = f
        for e, winner in sorted(won.items()):
            for f, rs in recs.items():
                if f == winner:
                    continue
                k = next((i for i, x in _epochs_of(rs, "agent") if x == e), None)
                if k is None:
                    continue
                rs.insert(k + 1, {"node": "agent", "action": "BecomeMaster", "args": {},
                                  "now": rs[k].get("now", 0), "changed": {"life": "MASTER"}})
                where = f"{f.name} record {k + 2} (BecomeMaster in epoch {e}, won by {winner.name})"
                break
            if where:
                break
    elif fault == "stale-command":
        for f, rs in recs.items():
            for i, r in enumerate(rs):
                text = r.get("args", {}).get("msg", "")
                if r.get("node") != "agent" or r.get("action") != "ApplyCommand" or r["args"].get("cmd") == "Ignore":
                    continue
                d = _datagram(text)
                if d is None or d.type_name != "EPOCH_CMD" or len(d.params) < 2 or int(d.params[0]) < 2:
                    continue
                e = int(d.params[0])
                older = wire.Message(d.sender, d.receiver, d.msgid, d.type, (str(e - 1).encode(),) + tuple(d.params[1:]))
                r["args"] = dict(r["args"], msg=wire.encode(older).decode("latin-1"))
                where = f"{f.name} record {i + 1} (EPOCH_CMD of node {d.sender} in epoch {e - 1}, was {e})"
                break
            if where:
                break
    elif fault in PLANTS:
        where = _PLANTERS[fault](recs, loss)
    else:
        raise MergeError(f"no such fault {fault!r} (known: {', '.join(PLANTS)})")
    if where is None:
        raise MergeError(f"the run has no place for fault {fault}: {PLANTS[fault]}")
    out.mkdir(parents=True, exist_ok=True)
    for f, rs in recs.items():
        (out / f.name).write_text("".join(json.dumps(r) + "\n" for r in rs))
    return where
