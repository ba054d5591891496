"""Spec -> implementation: replay every edge of TLC's state graph of the one-agent model (MCAgent)
against a driver (docs/driver.md) and compare state and emitted messages after every step.

The paths (graph.cover) are replayed depth-first over their prefix tree: the driver saves a
snapshot at each tree node and restores it before each out-edge, so every path is replayed from
the initial state without replaying shared prefixes again. Inputs are pipelined.
"""

from __future__ import annotations

import json
import time
import zlib
from dataclasses import dataclass, field

from ev3conformance import driver as drv
from ev3conformance import graph as gr
from ev3conformance import tla

TIMEOUTS = {"SyncTimeout", "HeartbeatLost"}
MASTER_PEER = 101  # peer handle the replay gives the master (src 1); other senders: 100 + src


class Mismatch(Exception):
    def __init__(self, report: str) -> None:
        super().__init__(report)
        self.report = report


@dataclass
class Figures(gr.WalkFigures):
    replayed: int = 0
    excluded_urgent: int = 0
    unreachable: int = 0
    sample: int = 1
    left_out: int = 0
    extra: dict = field(default_factory=dict)

    def summary(self, name: str) -> str:
        covered = self.replayed + self.excluded_urgent
        pct = 100.0 * covered / self.edges if self.edges else 0.0
        lines = [
            self.head(name),
            f"  edges replayed and matched      {self.replayed}",
            f"  edges checked as urgent-timeout {self.excluded_urgent}  (spec acts while a timeout is due;"
            f" the core fires it first: its timeout edge was matched instead)",
            f"  edges covered                   {covered} of {self.edges} ({pct:.1f}%)",
            f"  steps replayed {self.steps}  driver inputs {self.inputs}",
            f"  time: TLC {self.tlc_seconds:.1f}s, replay {self.seconds:.1f}s",
        ]
        if self.unreachable:
            lines.insert(3, f"  edges unreachable for the core   {self.unreachable}")
        if self.sample > 1:
            lines.insert(3, f"  edges left out by the sample     {self.left_out}  (--sample {self.sample}: of the"
                            f" {'/'.join(sorted(SAMPLED))} edges, one of each class and one in"
                            f" {self.sample} of the rest are replayed; every other edge is)")
        return "\n".join(lines)


# --- the agent model --------------------------------------------------------------------------

def agent_config(c: dict) -> dict:
    return {"type": "config",
            "timers": {"sync": c["TSync"], "heartbeat": c["TPing"], "loss": c["TLoss"],
                       "paused": c["TPaused"]},
            "model": c["ModelName"],
            # The robot's check on receipt (spec Refused): the driver refuses those with CheckReason.
            "behaviours": [{"name": b, "devices": 1} | ({"refuse": c["CheckReason"]} if b in c.get("Refused", ()) else {})
                           for b in sorted(c["Behaviours"])],
            "devices": 1, "window": c["Window"], "temp_id": c["TempId"], "first_msgid": 1, "now": 0}


def timeout_due(ag: dict, c: dict) -> bool:
    s, sil = ag["state"], ag["silence"]
    return ((s == "IDLE" and sil >= c["TSync"]) or (s in ("ACTIVE", "WORKING") and sil >= c["TLoss"])
            or (s == "PAUSED" and sil >= c["TPaused"]))


def agent_input(la: dict) -> dict | None:
    """The driver input for a spec action (lastAction of the target state); None: no input."""
    n, args = la["name"], la["args"]
    if n in TIMEOUTS:
        # Usually fired already by the input that made it due (Tick); after an event that made it
        # due the core fires it at its next input: "advance 0" is that input.
        return {"type": "advance", "ms": 0}
    if n == "Tick":
        return {"type": "advance", "ms": 1}
    if n in ("RecvMaster", "RecvPong", "RecvBehaviour", "RecvStart", "RecvStop", "RecvPause",
             "RecvResume", "RecvStandby", "RecvContinue", "RecvRestart", "RecvDuplicate", "Ignore"):
        m = args[0]
        return {"type": "recv", "from": 100 + m["src"],
                "text": drv.spec_to_wire(m).decode("latin-1")}
    ev = {"ActionOk": "action_ok", "ActionFailed": "action_failed", "BatteryLow": "battery_low",
          "DeviceUnplugged": "device_unplugged", "DevicePlugged": "device_plugged",
          "SensorReport": "sensor_report", "ActionInterrupted": "action_interrupted",
          "RobotEvent": "robot_event"}[n]
    d = {"type": "event", "event": ev}
    if n == "ActionInterrupted":
        d["warning"] = args[0]
    if n == "ActionFailed":
        d["reason"] = args[0]
    if n in ("DeviceUnplugged", "DevicePlugged"):
        d.update(devices=1, port=args[0])
    if n == "RobotEvent":
        d.update(name=args[0], port=args[1])
    if n == "SensorReport":
        d.update(port="port", mode="mode", values=["value"])
    return d


def spec_vars(ag: dict, c: dict) -> dict:
    win = [[e["src"], e["msgid"], e["ans"]["type"], e["ans"]["src"], e["ans"]["ref"],
            e["ans"]["args"][0] if e["ans"]["args"] else None] for e in ag["win"]]
    return {k: ag[k] for k in ("state", "led", "id", "beh", "step", "wait", "motors", "devOk",
                               "silence", "clk")} | {"win": win}


def impl_vars(v: dict, c: dict) -> dict:
    win = [[e["src"], e["msgid"], e["ans"]["type"], e["ans"]["src"], e["ans"]["ref"],
            e["ans"].get("reason")] for e in v["win"]]
    d = {k: v[k] for k in ("state", "led", "id", "beh", "step", "wait", "motors", "devOk", "silence", "clk")}
    d["step"] = d["step"] % c["Steps"]  # the core counts up; the spec wraps at the model's bound
    d["win"] = win
    return d


def split_sent(out: dict) -> list[list[dict]]:
    """The datagrams an output carries, per action (by msgid: an action sent those below its next_msgid)."""
    acts = out.get("actions", [])
    per = [[] for _ in acts]
    for s in out.get("sent", []):
        mid = drv.msgid_of(bytes.fromhex(s["hex"]))
        for i, a in enumerate(acts):
            if mid < a.get("next_msgid", 1 << 62):
                per[i].append(s)
                break
        else:
            if per:
                per[-1].append(s)
    return per


def sent_as_spec(sent: list[dict], steps: int | None = None) -> list[tuple]:
    res = []
    for s in drv.sent_beyond_reports(sent):
        t = drv.wire_to_spec(bytes.fromhex(s["hex"]))
        if steps and t[2] in ("ACTION_OK", "ACTION_INTERR", "ACTION_ERR"):
            t = (t[0], t[1], t[2], t[3] % steps, t[4])  # action ids count up in the core
        to = s.get("to")
        # Destinations: broadcast <-> dst 0; master <-> dst 1 and the master's peer (0 = not
        # known yet: an unsynced agent answers a command to the master id without an address).
        if to == "broadcast" and t[1] != 0 or to == "master" and (t[1] != 1 or s.get("peer") not in (MASTER_PEER, 0)):
            t = t + (f"to={to} peer={s.get('peer')}",)
        res.append(t)
    return res


# --- replay -------------------------------------------------------------------------------------

def _fmt_diff(spec: dict, impl: dict) -> str:
    rows = [f"    {'variable':10} {'spec':40} implementation"]
    for k in spec:
        mark = "  " if spec[k] == impl.get(k) else "!="
        rows.append(f" {mark} {k:10} {json.dumps(spec[k]):40} {json.dumps(impl.get(k))}")
    return "\n".join(rows)


def _path_text(g: gr.Graph, path: list[int]) -> str:
    lines = []
    for i, e in enumerate(path):
        la = g.states[g.edges[e][1]]["lastAction"]
        lines.append(f"    {i + 1:2}. {la['name']}{tla.show(la['args']) if la['args'] else ''}")
    return "\n".join(lines)


# The datagrams the agent ignores or answers from its window: 78 % of MCAgent's edges (its
# environment sends every msgid of MsgIds from every sender in every state).
SAMPLED = {"Ignore", "RecvDuplicate"}


def msgid_relation(m: dict, win) -> str:
    """Where the msgid of @p m stands against the window's entries from its sender."""
    mine = [e["msgid"] for e in win if e["src"] == m["src"]]
    if not mine:
        return "none"
    if m["msgid"] in mine:
        return "in"
    return "below" if m["msgid"] < max(mine) else "above"


def sample_leaves(g: gr.Graph, every: int) -> set[int]:
    """The edges a sample of one in @p every leaves out: of the SAMPLED actions' edges, those
    picked neither by a hash of the edge's two states (of their values: TLC's node ids are
    fingerprints that change from run to run; hash mod every = 0) nor
    as the lowest hash of their class (source lifecycle state, action, datagram type, sender,
    addressee, whether it names the agent, its msgid against the window). A function of the graph
    alone (not of the order TLC wrote it in): the same edges every run. Every other edge is kept."""
    if every <= 1:
        return set()
    first: dict[tuple, tuple[int, int]] = {}
    cand: list[tuple[int, int]] = []
    sh = {k: zlib.crc32(json.dumps(st, sort_keys=True).encode()) for k, st in g.states.items()}
    for ei, (u, v) in enumerate(g.edges):
        la = g.states[v]["lastAction"]
        if la["name"] not in SAMPLED:
            continue
        ag, m = g.states[u]["ag"], la["args"][0]
        cls = (ag["state"], la["name"], m["type"], m["src"], m["dst"], m.get("ref") == ag["id"],
               msgid_relation(m, ag["win"]))
        h = zlib.crc32(f"{sh[u]} {sh[v]}".encode())
        if cls not in first or (h, ei) < first[cls]:
            first[cls] = (h, ei)
        if h % every:
            cand.append((h, ei))
    keep = {ei for _, ei in first.values()}
    return {ei for _, ei in cand if ei not in keep}


class AgentReplay:
    def __init__(self, g: gr.Graph, consts: dict, argv: list[str], name: str = "agent",
                 cache: dict | None = None, sample: int = 1) -> None:
        """cache: a dict kept across runs on the same graph (mutation testing): the path set and
        the driver inputs are computed once. sample: replay one in @p sample of the edges where
        the agent ignores a datagram or answers a duplicate (sample_leaves); 1: every edge."""
        self.g, self.c, self.argv, self.name = g, consts, argv, name
        self.cache = cache if cache is not None else {}
        self.fig = Figures(states=len(g.states), edges=len(g.edges))
        self.sample = sample
        self._replayable: list[bool] | None = None
        self.leave = sample_leaves(g, sample)

    def replayable(self, ei: int) -> bool:
        if self._replayable is None:  # each edge's verdict, computed once: the walks ask millions of times
            self._replayable = [not (timeout_due(self.g.states[u]["ag"], self.c)
                                     and self.g.states[v]["lastAction"]["name"] not in TIMEOUTS)
                                for u, v in self.g.edges]
        return self._replayable[ei]

    def ops(self, ps: gr.PathSet):
        """The replay as a sequence of ops: ('save', d), ('restore', d), ('edge', ei)."""
        return gr.walk(self.g, ps, self.replayable, self.leave.__contains__)

    def run(self) -> Figures:
        g = self.g
        t0 = time.monotonic()
        if "ps" not in self.cache:
            self.cache["ps"] = gr.cover(g, self.replayable)
        ps = self.cache["ps"]
        self.fig.paths, self.fig.max_path = ps.paths, ps.max_len
        self.fig.unreachable = ps.unreachable_edges
        self.fig.excluded_urgent = sum(1 for ei in range(len(g.edges)) if not self.replayable(ei)
                                       and g.edges[ei][0] in ps.depth)
        self.fig.unreachable = len(g.edges) - self.fig.excluded_urgent - sum(
            1 for ei in range(len(g.edges)) if self.replayable(ei) and g.edges[ei][0] in ps.depth)
        self.fig.left_out = sum(1 for ei in self.leave if self.replayable(ei) and g.edges[ei][0] in ps.depth
                                and not (ps.tree_edge.get(g.edges[ei][1]) == ei and g.out.get(g.edges[ei][1])))
        d = drv.Driver(self.argv)
        try:
            self._replay(d, ps)
        finally:
            d.kill()
            d.close()
        self.fig.sample = self.sample
        self.fig.seconds = time.monotonic() - t0
        return self.fig

    def _replay(self, d: drv.Driver, ps: gr.PathSet) -> None:
        g, c = self.g, self.c
        first = d.ask(agent_config(c))
        if "error" in first:
            raise Mismatch(f"driver refused the configuration: {first['error']}")
        init = g.init[0]
        self._check_vars(g.states[init]["ag"], first["vars"], [], "Init")
        if "tagged" not in self.cache:
            self.cache["tagged"] = gr.driver_inputs(g, self.ops(ps), agent_input)
            self.cache["lines"] = [inp for _, inp in self.cache["tagged"] if inp is not None]
        tagged, lines = self.cache["tagged"], self.cache["lines"]
        outs = d.stream(lines)
        pending: list[tuple[dict, list]] = []
        saved: dict[int, list] = {}
        cur_path: list[int] = []
        path_at: dict[int, list[int]] = {0: []}
        for op, inp in tagged:
            if op[0] == "save":
                next(outs)
                saved[op[1]] = list(pending)
                path_at[op[1]] = list(cur_path)
                self.fig.inputs += 1
                continue
            if op[0] == "restore":
                next(outs)
                pending = list(saved[op[1]])
                cur_path = list(path_at[op[1]])
                self.fig.inputs += 1
                continue
            ei = op[1]
            u, v = g.edges[ei]
            sv = g.states[v]
            la = sv["lastAction"]
            cur_path.append(ei)
            sent_line, out = next(outs)
            self.fig.inputs += 1
            if "error" in out:
                raise Mismatch(self._report(cur_path, f"driver error: {out['error']} (input {sent_line})", sv, None))
            acts = out.get("actions", [])
            if la["name"] in TIMEOUTS and pending:
                # Fired already by the input that made it due; "advance 0" adds nothing new.
                pending += list(zip(acts, split_sent(out)))
            else:
                if pending:
                    raise Mismatch(self._report(cur_path, f"the implementation took "
                                                          f"{pending[0][0]['action']} on its own",
                                                sv, pending[0][0]))
                if not acts:
                    raise Mismatch(self._report(cur_path, f"the spec takes {la['name']}; the implementation "
                                                          f"took no action (input {sent_line})", sv, out))
                pending = list(zip(acts, split_sent(out)))
            rec, sent = pending.pop(0)
            self.fig.steps += 1
            if rec["action"] != la["name"]:
                raise Mismatch(self._report(cur_path, f"action: spec {la['name']}, implementation "
                                                      f"{rec['action']}", sv, rec))
            if la["name"] == "ActionInterrupted" and rec["args"].get("e") != la["args"][0]:
                raise Mismatch(self._report(cur_path, "ActionInterrupted warning differs", sv, rec))
            if la["name"] == "RobotEvent" and [rec["args"].get("e"), rec["args"].get("p")] != list(la["args"]):
                raise Mismatch(self._report(cur_path, "RobotEvent event or port differs", sv, rec))
            if la["name"] in ("DeviceUnplugged", "DevicePlugged") and rec["args"].get("p") != la["args"][0]:
                raise Mismatch(self._report(cur_path, f"{la['name']} port differs", sv, rec))
            self._check_vars(sv["ag"], rec["vars"], cur_path, la["name"], rec)
            want = [drv.spec_out(m) for m in sv["out"]]
            got = sent_as_spec(sent, c["Steps"])
            if want != got:
                raise Mismatch(self._report(cur_path, "emitted messages differ:\n"
                                            f"      spec out:       {want}\n      implementation: {got}", sv, rec))
            if pending:
                names = {g.states[g.edges[e][1]]["lastAction"]["name"] for e in g.out.get(v, [])}
                if pending[0][0]["action"] not in names:
                    raise Mismatch(self._report(cur_path, f"the implementation then took "
                                                          f"{pending[0][0]['action']}, not enabled in the spec "
                                                          f"state", sv, pending[0][0]))
            self.fig.replayed += 1
        if self.fig.replayed + self.fig.excluded_urgent + self.fig.unreachable + self.fig.left_out != len(g.edges):
            raise Mismatch("internal: not every edge was accounted for")

    def _check_vars(self, ag: dict, impl: dict, path: list[int], name: str, rec=None) -> None:
        s, i = spec_vars(ag, self.c), impl_vars(impl, self.c)
        if s != i:
            raise Mismatch(self._report(path, f"state after {name} differs", {"ag": ag}, rec or {"vars": impl}))

    def _report(self, path: list[int], what: str, sv: dict, rec) -> str:
        lines = [f"MISMATCH ({self.name}): {what}", "  path from the initial state:", _path_text(self.g, path)]
        if rec and "vars" in rec:
            lines.append("  state after the last step:")
            lines.append(_fmt_diff(spec_vars(sv["ag"], self.c), impl_vars(rec["vars"], self.c)))
        if "out" in sv:
            lines.append(f"  spec out: {[drv.spec_out(m) for m in sv['out']]}")
        if rec:
            lines.append(f"  implementation record: {json.dumps(rec)[:1500]}")
        lines.append(f"  driver: {' '.join(self.argv)}")
        return "\n".join(lines)
