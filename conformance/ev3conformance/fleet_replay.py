"""Spec -> implementation for the fleet: TLC `-simulate` traces of the fleet model (Fleet.tla,
one master and N agents over a lossy, duplicating, reordering network with master crashes)
replayed against one `ev3-master --driver` and one `ev3-agent --driver` per agent.

The traces come from MCFleetSim.tla (spec/tla/): Fleet's Next with each step naming itself in the
history variable `act` (action, datagram, node, operator command, the receiver's handler, the
datagrams the step emits), since TLC's simulation traces carry no action names; each trace draws
a gap (ticks) between faults, so that losses, duplicates and crashes also hit working agents, not
only the first ticks (check_wrapper: with no gap, SimNext reaches exactly Fleet's states). The spec decides
what happens: which datagram is delivered, duplicated or lost, which timers fire, what the operator
commands, when the master crashes and restarts. The implementations produce the datagrams: a
delivery is a `recv` on the destination's driver of the bytes the SOURCE driver emitted for that
spec datagram, so the drivers talk to each other.

Mapping of the spec's steps (the `act` of the target state):

    Deliver(e, dup) to agent a     recv on a's driver (from the master's handle), e's bytes
    Deliver(e, dup) to the master  recv on the master's driver (from a's endpoint); nothing while
                                   the master is down (the spec drops it)
    Lose(e)                        nothing (the bytes are forgotten)
    AgentTimeout(a)                the timeout the core fired at the Tick that made it due, or
                                   `advance 0`
    Operate(a)                     `command` on the master's driver (the entry's id, the command)
    Tick                           `advance 1` on every live agent's driver (+ `event action_ok`
                                   where the spec folds ActionOk into the tick) and on the
                                   master's if up (resend 1 ms = 1 tick, drop = TDrop ms)
    MasterCrash                    the master's driver process is killed
    MasterRestart                  a new master driver process, configured with the crashed
                                   one's next_id and next_msgid (its stable storage)

msgids. Fleet abstracts them (MasterLogic with ExactMsgids = FALSE: one counter per agent
endpoint, PONG msgid 0 and no draw; agents stamp 4*sess + slot). The replay never assumes a spec
msgid equals a real one; it builds tables per trace while the drivers emit:
  - master: (endpoint, spec msgid) <-> real msgid, a bijection, increasing in both per endpoint;
    a resend must carry the same real msgid;
  - agent a: real msgid -> spec stamp, bound when a's driver emits the datagram; the stamps must
    not decrease as the real msgids grow (the spec's "order-preserving image").
Compared through them after every step: every agent's state, led, id, beh, step (mod Steps),
wait, motors, devOk, silence, clk, dedupe window (msgids and ACK refs mapped) and `sess` (answers
the driver sent); the master's up/down, nextId, msgid draws (real draws minus PONGs = the sum of
the spec's per-endpoint draws), and every registry entry (ann, id, ep, synced, pending, mid
mapped, resends while a command is pending, queue, beh, desired, quiet, hi mapped); the datagrams
each step emits (matched one to one with the spec's, msgids and refs mapped); and the datagrams in
flight (the spec's net = the bytes the replay holds).

A mismatch ends its trace (the rest is counted as not replayed); the other traces still run.
Mismatches are classified by (action, differing fields); the first of each class is printed side
by side with the trace up to it.
"""

from __future__ import annotations

import json
import re
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from ev3conformance import driver as drv
from ev3conformance import graph as gr
from ev3conformance import tla
from ev3conformance import wire
from ev3conformance.replay import split_sent, timeout_due
from ev3conformance.sim_replay import Mismatch, SimFigures, SimReplay, SimTrace

SIM_MODULE = "MCFleetSim.tla"
SIM_CFG = "MCFleetSim.cfg"
MASTER_PEER = 100          # the handle under which agents' drivers receive the master's datagrams
MASTER_EP = 0              # Fleet's MasterEp
MASTER_FIRST_MSGID = 1
AGENT_FIELDS = ("state", "led", "id", "beh", "step", "wait", "motors", "devOk", "silence", "clk")
REPORTS = ("ACTION_OK", "ACTION_INTERR", "ACTION_ERR")


def agent_first_msgid(i: int) -> int:
    """The first msgid agent i draws (any value: the replay maps msgids, never equates them)."""
    return 1000 * (i + 1) + 1


# The wrapper is Fleet: the same bounds model-checked with MCFleet's Init/Next and with MCFleetSim's
# SimInit/SimNext (no fault gap, VIEW of Fleet's variables) must reach the same distinct states at
# the same depth. One agent, and every kind of step enabled: loss, duplicate, crash (and restart),
# operator, timeouts, ticks.
CHECK_BOUNDS = {"Behaviours": "MCBehaviours", "UnknownBehaviour": '"dance"', "ModelName": '"A"', "TSync": 2,
                "TPing": 1, "TLoss": 2, "TPaused": 3, "Window": 3, "Steps": 2, "BUG": '"none"',
                "Agents": "{a1}", "TDrop": 3, "MaxResends": 2, "MaxLoss": 1, "MaxDup": 1, "MaxCrashes": 1,
                "MaxOps": 1, "MaxLate": 0, "MaxAgentCrashes": 0, "MaxSuspect": 0}


def check_wrapper(bounds: dict | None = None) -> dict:
    """Model-checks the same bounds with MCFleet (Init, Next) and MCFleetSim (SimInit, SimNext,
    SimFaultGaps = {0}, VIEW FleetVars); returns {"fleet": (distinct, depth), "sim": (...),
    "equal": bool, "seconds": s}."""
    import concurrent.futures as cf
    b = dict(CHECK_BOUNDS, **(bounds or {}))
    consts = "CONSTANTS\n" + "".join(
        f"    {k} {'<-' if k == 'Behaviours' else '='} {v}\n" for k, v in b.items())
    gr.BUILD.mkdir(parents=True, exist_ok=True)
    cfgs = {"fleet": ("MCFleet.tla", consts + "INIT Init\nNEXT Next\nINVARIANT TypeOK\n"),
            "sim": ("MCFleetSim.tla", consts + "    SimFaultGaps = {0}\nINIT SimInit\nNEXT SimNext\n"
                                               "VIEW FleetVars\nINVARIANT TypeOK\n")}
    paths = {}
    for k, (_, text) in cfgs.items():
        paths[k] = gr.BUILD / f"fleet-wrapper-check-{k}.cfg"
        paths[k].write_text(text)
    t0 = time.monotonic()
    with cf.ThreadPoolExecutor(2) as ex:
        futs = {k: ex.submit(gr.tlc, cfgs[k][0], str(paths[k]), []) for k in cfgs}
        outs = {k: f.result() for k, f in futs.items()}
    res = {"seconds": round(time.monotonic() - t0, 1)}
    for k, (rc, out) in outs.items():
        m = re.search(r"states generated, ([\d,]+) distinct states found, 0 states left on queue", out)
        d = re.search(r"The depth of the complete state graph search is (\d+)", out)
        if rc != 0 or not m or not d:
            raise RuntimeError(f"TLC failed on the wrapper check ({k}, exit {rc}):\n{out[-3000:]}")
        res[k] = (int(m.group(1).replace(",", "")), int(d.group(1)))
    res["equal"] = res["fleet"] == res["sim"]
    return res


# --- figures and mismatches -----------------------------------------------------------------------

@dataclass
class FleetFigures(SimFigures):
    mapped: Counter = field(default_factory=Counter)      # msgids bound in the tables

    def title(self) -> str:
        return f"fleet: traces {self.traces} ({self.agents} agents + master; one driver process per node)"

    def details(self) -> list[str]:
        return [f"  driver inputs {self.inputs}  msgids mapped: master {self.mapped['master']}, "
                f"agents {self.mapped['agent']}"]


def _msg_text(m: dict) -> str:
    ref = f" ref {m['ref']}" if m["ref"] else ""
    args = f" {list(m['args'])}" if m["args"] else ""
    return f"{m['src']}->{m['dst']} #{m['msgid']} {m['type']}{ref}{args}"


def _node(x) -> str:
    return "master" if x == MASTER_EP else str(x)


def act_text(act: dict) -> str:
    n = act["name"]
    if n == "Deliver":
        e = act["e"]
        return (f"Deliver{' (dup)' if act['dup'] else ''} {_node(e['from'])}=>{_node(e['to'])}: "
                f"{_msg_text(e['m'])}  [{act['h']}]")
    if n == "Lose":
        e = act["e"]
        return f"Lose {_node(e['from'])}=>{_node(e['to'])}: {_msg_text(e['m'])}"
    if n == "AgentTimeout":
        return f"AgentTimeout {act['node']} [{act['h']}]"
    if n == "Operate":
        c = act["cmd"]
        return f"Operate {act['node']}: MasterCommand({act['id']}, {c['type']}" + \
               (f" {c['name']})" if c["type"] == "BEHAVIOUR" else ")")
    return n


def _vars_after(out: dict) -> dict:
    """The variables after an input: those of its last action record (what the core's trace
    says), or the output's when it took no action."""
    acts = out.get("actions") or []
    return acts[-1]["vars"] if acts else out["vars"]


def _show(v) -> str:
    if isinstance(v, list):
        return "[" + ", ".join(_show(x) for x in v) + "]"
    if isinstance(v, (dict, tuple)):
        return tla.show(v)
    return str(v)


def act_key(act: dict) -> str:
    """The action as counted and classified: Deliver by its handler."""
    n = act["name"]
    if n == "Deliver":
        return f"Deliver/{act['h']}" + ("(dup)" if act["dup"] else "")
    if n == "AgentTimeout":
        return f"AgentTimeout/{act['h']}"
    return n


# --- one trace -------------------------------------------------------------------------------------

class _Trace(SimTrace):
    """The replay of one trace: drivers, msgid tables, datagrams in flight."""

    def __init__(self, rp: "FleetReplay", idx: int, path: Path | None, states: list[dict]) -> None:
        super().__init__(rp, idx, path, states)
        self.c = rp.c
        init = states[0]
        self.agents = sorted(init["ag"].keys())
        self.ep_of = {a: i + 1 for i, a in enumerate(self.agents)}
        self.agent_at = {i + 1: a for i, a in enumerate(self.agents)}
        self.now = 0
        self.adrv: dict = {}
        self.mdrv: drv.Driver | None = None
        self.avars: dict = {}          # agent -> vars after the last action the spec has taken
        self.mvars: dict = {}
        self.held: dict = {a: [] for a in self.agents}   # actions the core took ahead of the spec
        self.answers = Counter()       # ACK/NOT datagrams each agent's driver sent (spec sess)
        self.pongs = 0                 # PONGs the master's drivers sent (each draws a real msgid)
        self.tm: dict = {}             # (agent, spec msgid) -> real msgid (master's datagrams)
        self.tm_inv: dict = {}         # real msgid -> (agent, spec msgid)
        self.tm_last: dict = {}        # agent -> (last spec msgid, last real msgid)
        self.phi: dict = {a: {} for a in self.agents}    # agent -> real msgid -> spec stamp
        self.phi_last: dict = {}       # agent -> (last real msgid, its stamp)
        self.inflight: dict = {}       # spec datagram (net element) -> [bytes, ...]

    # -- drivers --
    def start(self) -> None:
        init = self.states[0]
        for i, a in enumerate(self.agents):
            d = self.rp.agent_driver(a)
            self.adrv[a] = d
            out = self._ask(d, str(a), {
                "type": "config",
                "timers": {"sync": self.c["TSync"], "heartbeat": self.c["TPing"], "loss": self.c["TLoss"],
                           "paused": self.c["TPaused"]},
                "model": self.c["ModelName"],
                "behaviours": [{"name": b, "devices": 1} for b in sorted(self.c["Behaviours"])],
                "devices": 1, "window": self.c["Window"], "temp_id": init["ag"][a]["id"],
                "first_msgid": agent_first_msgid(i), "now": 0})
            self.avars[a] = out["vars"]
        self.mdrv = self.rp.master_driver()
        self._master_config(2, MASTER_FIRST_MSGID)
        self.compare("Init")

    def _master_config(self, next_id: int, next_msgid: int) -> None:
        out = self._ask(self.mdrv, "master", {
            "type": "config", "timers": {"resend": 1, "drop": self.c["TDrop"]},
            "max_resends": self.c["MaxResends"], "next_id": next_id, "next_msgid": next_msgid,
            "now": self.now})
        self.mvars = out["vars"]

    # -- msgid tables --
    def mid_of(self, a, real: int):
        """A real msgid of the master's sent to agent a as the spec's msgid (or a marker)."""
        hit = self.tm_inv.get(real)
        if hit is None:
            return f"real#{real} (never sent)"
        if hit[0] != a:
            return f"real#{real} (sent to {hit[0]})"
        return hit[1]

    def stamp_of(self, a, real: int):
        if a is None:
            return f"real#{real} (unknown endpoint)"
        st = self.phi[a].get(real)
        return st if st is not None else f"real#{real} (not sent by {a})"

    # -- views in spec terms --
    def spec_agent(self, s: dict, a) -> dict:
        ag = s["ag"][a]
        v = {k: ag[k] for k in AGENT_FIELDS}
        v["win"] = [(e["src"], e["msgid"], e["ans"]["type"], e["ans"]["src"], e["ans"]["ref"],
                     e["ans"]["args"][0] if e["ans"]["args"] else None) for e in ag["win"]]
        v["sess"] = s["sess"][a]
        return v

    def impl_agent(self, a) -> dict:
        x = self.avars[a]
        v = {k: x[k] for k in AGENT_FIELDS}
        v["step"] = v["step"] % self.c["Steps"]
        v["win"] = [(e["src"], self.mid_of(a, e["msgid"]), e["ans"]["type"], e["ans"]["src"],
                     self.mid_of(a, e["ans"]["ref"]), e["ans"].get("reason")) for e in x["win"]]
        v["sess"] = self.answers[a]
        return v

    def spec_master(self, s: dict) -> dict:
        ms = s["ms"]
        v = {"up": s["up"], "nextId": ms["nextId"], "msgid draws": sum(n - 1 for n in ms["msgid"].values())}
        if s["up"]:
            for x in ms["reg"]:
                v.update({f"reg[{x['id']}].{k}": val for k, val in self._entry_spec(x).items()})
        return v

    @staticmethod
    def _entry_spec(x: dict) -> dict:
        return {"ann": x["ann"], "ep": str(x["ep"]), "synced": x["synced"], "pending": x["pending"],
                "mid": x["mid"], "resends": x["resends"] if x["synced"] and x["pending"] else None,
                "queue": tuple((q["type"], q["name"]) for q in x["queue"]), "beh": x["beh"],
                "desired": x["desired"], "quiet": x["quiet"], "hi": x["hi"]}

    def impl_master(self) -> dict:
        x = self.mvars
        v = {"up": self.mdrv is not None, "nextId": x["nextId"],
             "msgid draws": x["msgid"] - MASTER_FIRST_MSGID - self.pongs}
        if self.mdrv is None:
            return v
        for e in x["reg"]:
            a = self.agent_at.get(e["ep"])
            ent = {"ann": e["ann"], "ep": str(a) if a is not None else f"peer {e['ep']}",
                   "synced": e["synced"], "pending": e["pending"], "mid": self.mid_of(a, e["mid"]),
                   "resends": e["resends"] if e["synced"] and e["pending"] else None,
                   "queue": tuple((q["type"], q["name"]) for q in e["queue"]), "beh": e["beh"],
                   "desired": e.get("desired", "<not reported>"), "quiet": e["quiet_ms"],
                   "hi": self.stamp_of(a, e["hi"])}
            v.update({f"reg[{e['id']}].{k}": val for k, val in ent.items()})
        return v

    # -- comparison after a step --
    def diffs(self, s: dict) -> dict:
        """node -> {field: (spec, implementation)} for every node that differs."""
        out = {}
        for a in self.agents:
            sv, iv = self.spec_agent(s, a), self.impl_agent(a)
            d = {k: (sv[k], iv.get(k)) for k in sv if sv[k] != iv.get(k)}
            if d:
                out[str(a)] = d
        sv, iv = self.spec_master(s), self.impl_master()
        d = {}
        for k in sorted(set(sv) | set(iv)):
            if sv.get(k, "<absent>") != iv.get(k, "<absent>"):
                d[k] = (sv.get(k, "<absent>"), iv.get(k, "<absent>"))
        if d:
            out["master"] = d
        return out

    def compare(self, what: str) -> None:
        s = self.states[self.k]
        d = self.diffs(s)
        if d:
            fields = []
            for node, dd in d.items():
                for k in dd:
                    f = k.split(".", 1)[1] if k.startswith("reg[") else k
                    fields.append(f"{'master' if node == 'master' else 'agent'}.{f}")
            self.fail(f"state after {what} differs", tuple(sorted(set(fields))), "")
        net = set(s["net"])
        have = set(self.inflight)
        if net != have:
            self.fail("datagrams in flight differ", ("in flight",),
                      "  in flight, spec only:           " + "; ".join(self._dg(e) for e in net - have) +
                      "\n  in flight, implementation only: " + "; ".join(self._dg(e) for e in have - net))

    @staticmethod
    def _dg(e: dict) -> str:
        return f"{_node(e['from'])}=>{_node(e['to'])} {_msg_text(e['m'])}"

    # -- emitted datagrams --
    def _as_spec(self, node, sent: dict) -> tuple[dict, int, bytes]:
        """A datagram a driver sent -> (the spec datagram it must be, msgid unknown = None; real
        msgid; bytes). Refs and known msgids translated through the tables."""
        data = bytes.fromhex(sent["hex"])
        msg = wire.decode(data)
        src, dst, typ, ref, args = drv.wire_to_spec(data)
        if node == "master":
            to = self.agent_at.get(sent.get("peer"), f"peer {sent.get('peer')}")
            if sent.get("to") != "peer":
                to = f"{sent.get('to')} {to}"
            if typ == "PONG":
                mid, ref = 0, self.stamp_of(to if to in self.phi else None, ref)
            else:
                hit = self.tm_inv.get(msg.msgid)
                mid = (hit[1] if hit[0] == to else f"real#{msg.msgid} (sent to {hit[0]})") if hit else None
            frm = MASTER_EP
        else:
            a = node
            frm, to = a, MASTER_EP
            want = {0: "broadcast", 1: "master"}.get(dst)
            if sent.get("to") != want or (want == "master" and sent.get("peer") not in (MASTER_PEER, 0)):
                to = f"{sent.get('to')} peer {sent.get('peer')}"
            if typ in ("ACK", "NOT"):
                ref = self.mid_of(a, ref)
            elif typ in REPORTS:
                ref = ref % self.c["Steps"]
            mid = None
        return ({"from": frm, "to": to, "m": {"src": src, "dst": dst, "msgid": mid, "type": typ, "ref": ref,
                                              "args": args}}, msg.msgid, data)

    def emitted(self, spec_out, sent: list[tuple]) -> None:
        """Matches what the drivers sent in this step (node, sent record) one to one with the
        spec's emitted datagrams; binds msgids; the bytes go in flight."""
        left = set(spec_out)
        extra = []
        sent = [(node, x) for node, s in sent for x in drv.sent_beyond_reports([s])]
        for node, s in sent:
            cand, real, data = self._as_spec(node, s)
            hits = [e for e in left if e["from"] == cand["from"] and e["to"] == cand["to"]
                    and all(e["m"][k] == cand["m"][k] for k in ("src", "dst", "type", "ref", "args"))
                    and (cand["m"]["msgid"] is None or e["m"]["msgid"] == cand["m"]["msgid"])]
            if not hits:
                extra.append(self._show_cand(cand, real))
                continue
            e = min(hits, key=lambda x: x["m"]["msgid"])
            err = self._bind(node, e, real, cand)
            if err:
                self.fail("msgid mapping", ("msgid mapping",), f"  {err}")
            left.discard(e)
            self.inflight.setdefault(e, []).append(data)
        if extra or left:
            self.fail("emitted datagrams differ", ("emitted",),
                      "  spec emits, implementation did not: " + ("; ".join(self._dg(e) for e in left) or "-") +
                      "\n  implementation emitted, spec did not: " + ("; ".join(extra) or "-"))

    @staticmethod
    def _show_cand(c: dict, real: int) -> str:
        m = c["m"]
        return f"{_node(c['from'])}=>{_node(c['to'])} {m['src']}->{m['dst']} #real {real} {m['type']}" + \
               (f" ref {m['ref']}" if m["ref"] else "") + (f" {list(m['args'])}" if m["args"] else "")

    def _bind(self, node, e: dict, real: int, cand: dict) -> str | None:
        k = e["m"]["msgid"]
        if node == "master":
            if e["m"]["type"] == "PONG":
                self.pongs += 1
                return None
            a = e["to"]
            if (a, k) in self.tm:
                if self.tm[(a, k)] != real:
                    return (f"the master sent spec msgid {k} to {a} as real {real}; it was real "
                            f"{self.tm[(a, k)]} before")
                return None
            if real in self.tm_inv:
                return f"real msgid {real} already stands for {self.tm_inv[real]}"
            lk, lr = self.tm_last.get(a, (0, 0))
            if not (k > lk and real > lr):
                return (f"master msgids to {a} out of order: spec {lk} -> {k}, real {lr} -> {real}")
            self.tm[(a, k)] = real
            self.tm_inv[real] = (a, k)
            self.tm_last[a] = (k, real)
            self.rp.fig.mapped["master"] += 1
            return None
        a = node
        if e["m"]["type"] in ("ACK", "NOT"):
            self.answers[a] += 1
        if real in self.phi[a]:
            return f"{a} sent real msgid {real} twice"
        lr, ls = self.phi_last.get(a, (0, -1))
        if real <= lr or k < ls:
            return (f"{a}'s stamps not order-preserving: real {lr} -> {real}, spec stamp {ls} -> {k}")
        self.phi[a][real] = k
        self.phi_last[a] = (real, k)
        self.rp.fig.mapped["agent"] += 1
        return None

    def settle(self) -> None:
        """Forgets the bytes of datagrams the spec no longer has in flight (delivered, lost)."""
        net = set(self.states[self.k]["net"])
        for e in list(self.inflight):
            if e not in net:
                del self.inflight[e]

    # -- steps --
    def step(self) -> None:
        s0, s1 = self.states[self.k - 1], self.states[self.k]
        act = s1["act"]
        n = act["name"]
        sent: list[tuple] = []
        if n == "Deliver":
            e = act["e"]
            if e not in self.inflight:
                self.fail("no bytes", ("internal",), "  the spec delivers a datagram no driver emitted")
            data = self.inflight[e][-1]
            if e["to"] == MASTER_EP:
                if act["h"] != "Down":
                    out = self._ask(self.mdrv, "master", {"type": "recv", "from": self.ep_of[e["from"]],
                                                         "hex": data.hex()})
                    names = [x["action"] for x in out["actions"]]
                    if names != [act["h"]] and not (act["h"] == "Ignore" and names == []):
                        self.fail(f"action: spec {act['h']}, implementation {names}", ("action",), "")
                    self.mvars = _vars_after(out)
                    sent = [("master", x) for x in out["sent"]]
            else:
                a = e["to"]
                self._owes(a)
                out = self._ask(self.adrv[a], str(a), {"type": "recv", "from": MASTER_PEER, "hex": data.hex()})
                names = [x["action"] for x in out["actions"]]
                if names != [act["h"]]:
                    self.fail(f"action: spec {act['h']}, implementation {names}", ("action",), "")
                self.avars[a] = _vars_after(out)
                sent = [(a, x) for x in out["sent"]]
        elif n == "Lose":
            pass
        elif n == "AgentTimeout":
            a = act["node"]
            if self.held[a]:
                rec, snt = self.held[a].pop(0)
            else:
                out = self._ask(self.adrv[a], str(a), {"type": "advance", "ms": 0})
                if not out["actions"]:
                    self.fail(f"action: spec {act['h']}, implementation none (advance 0)", ("action",), "")
                per = split_sent(out)
                rec, snt = out["actions"][0], per[0]
                self.held[a] = list(zip(out["actions"][1:], per[1:]))
            if rec["action"] != act["h"]:
                self.fail(f"action: spec {act['h']}, implementation {rec['action']}", ("action",), "")
            self.avars[a] = rec["vars"]
            sent = [(a, x) for x in snt]
        elif n == "Operate":
            c = act["cmd"]
            inp = {"type": "command", "agent": act["id"], "command": c["type"]}
            if c["type"] == "BEHAVIOUR":
                inp["behaviour"] = c["name"]
            out = self._ask(self.mdrv, "master", inp)
            names = [x["action"] for x in out["actions"]]
            if names != ["MasterCommand"]:
                self.fail(f"action: spec MasterCommand, implementation {names}", ("action",), "")
            self.mvars = _vars_after(out)
            sent = [("master", x) for x in out["sent"]]
        elif n == "MasterCrash":
            kept = {"nextId": self.mvars["nextId"], "msgid": self.mvars["msgid"], "reg": []}
            self.rp.close(self.mdrv)
            self.mdrv = None
            self.mvars = kept
        elif n == "MasterRestart":
            kept = self.mvars
            self.mdrv = self.rp.master_driver()
            self._master_config(kept["nextId"], kept["msgid"])
        elif n == "Tick":
            sent = self._tick(s0, s1, act)
        else:
            self.fail(f"unknown action {n}", ("internal",), "")
        self.emitted(act.get("out", frozenset()), sent)
        self.settle()
        self.compare(act_key(act))

    def _owes(self, a) -> None:
        if self.held[a]:
            self.fail(f"the implementation took {self.held[a][0][0]['action']} at the last Tick; the spec "
                      f"has not (its timeout is not due)", ("early timeout",), "")

    def _tick(self, s0: dict, s1: dict, act: dict) -> list[tuple]:
        sent = []
        for a in self.agents:
            if s0["ag"][a]["state"] == "OFF":
                continue
            self._owes(a)
            out = self._ask(self.adrv[a], str(a), {"type": "advance", "ms": 1})
            acts, per = out["actions"], split_sent(out)
            if not acts or acts[0]["action"] != "Tick" or acts[0]["args"].get("ticks", 1) != 1:
                self.fail(f"{a}: spec Tick, implementation {[x['action'] for x in acts]}", ("action",), "")
            self.avars[a] = acts[0]["vars"]
            sent += [(a, x) for x in per[0]]
            self.held[a] = list(zip(acts[1:], per[1:]))
            due = timeout_due(s1["ag"][a], self.c)
            if self.held[a] and not due:
                self._owes(a)
            fold = any(e["from"] == a and e["m"]["type"] == "ACTION_OK" for e in act["out"])
            if fold:
                out = self._ask(self.adrv[a], str(a), {"type": "event", "event": "action_ok"})
                names = [x["action"] for x in out["actions"]]
                if names != ["ActionOk"]:
                    self.fail(f"{a}: spec ActionOk (in Tick), implementation {names}", ("action",), "")
                self.avars[a] = _vars_after(out)
                sent += [(a, x) for x in out["sent"]]
        if s0["up"]:
            out = self._ask(self.mdrv, "master", {"type": "advance", "ms": 1})
            names = [x["action"] for x in out["actions"]]
            if names not in ([], ["Tick"], ["MasterTick"]):
                self.fail(f"master: spec MasterTick, implementation {names}", ("action",), "")
            self.mvars = _vars_after(out)
            sent += [("master", x) for x in out["sent"]]
        self.now += 1
        return sent

    # -- reports --
    def key(self, k: int) -> str:
        return act_key(self.states[k]["act"])

    def text(self, k: int) -> str:
        return act_text(self.states[k]["act"]) if k else "Init"

    def fail(self, what: str, fields: tuple, detail: str) -> None:
        act = self.states[self.k]["act"] if self.k else {"name": "Init"}
        lines = [self.where(), f"  {what}"]
        if detail:
            lines.append(detail)
        s = self.states[self.k]
        d = self.diffs(s) if self.mvars and self.avars else {}
        for node in [str(a) for a in self.agents] + ["master"]:
            if node == "master":
                sv, iv = self.spec_master(s), self.impl_master()
            else:
                a = next(x for x in self.agents if str(x) == node)
                sv, iv = self.spec_agent(s, a), self.impl_agent(a)
            if node not in d and node not in what:
                continue
            lines.append(f"  {node} (spec | implementation):")
            for k in sorted(set(sv) | set(iv), key=lambda k: (k.startswith("reg["), k)):
                a_, b_ = sv.get(k, "<absent>"), iv.get(k, "<absent>")
                mark = "!!" if a_ != b_ else "  "
                lines.append(f"   {mark} {k:22} {_show(a_):44} | {_show(b_)}")
        if act.get("name") != "Init":
            lines.append("  spec emits: " + ("; ".join(self._dg(e) for e in act.get("out", ())) or "-"))
        for node, out in self.last_out.items():
            if node in what or node in d or (act.get("name") == "Deliver" and
                                              str(act["e"]["to"] if act["e"]["to"] != MASTER_EP else "master") == node):
                lines.append(f"  {node}'s last driver output: {json.dumps(out)[:1500]}")
        raise Mismatch(what, fields, "\n".join(lines + self.history()))


# --- the runner --------------------------------------------------------------------------------------

class FleetReplay(SimReplay):
    """One driver process per agent, kept across traces (each trace configures it afresh: Init), and
    the master's (a new process after a crash)."""

    MODULE = SIM_MODULE
    PREFIX = "fleet-sim"
    Trace = _Trace
    Figures = FleetFigures
    DRIVERS_PER_TRACE = False

    def __init__(self, consts: dict, agent_argv: list[str], master_argv: list[str]) -> None:
        if not isinstance(consts.get("Behaviours"), (set, frozenset)):
            raise RuntimeError(f"the cfg's Behaviours did not resolve to a set: {consts.get('Behaviours')!r}")
        super().__init__(agent_argv, master_argv)
        self.c = consts
        self._agents: dict = {}
        self._master: drv.Driver | None = None

    def agent_driver(self, a) -> drv.Driver:
        d = self._agents.get(str(a))
        if d is None or d.proc.poll() is not None:
            d = self._agents[str(a)] = self.driver("agent")
        return d

    def master_driver(self) -> drv.Driver:
        """The running master process, or a new one (after a crash: a new process)."""
        if self._master is None or self._master.proc.poll() is not None:
            self._master = self.driver("master")
        return self._master


def replay_simulation(seed: int, num: int, depth: int, agent_argv: list[str], master_argv: list[str],
                      cfg: str = SIM_CFG) -> FleetFigures:
    """Simulates MCFleetSim and replays its traces (SimReplay.replay_simulation)."""
    consts = gr.cfg_constants("MCFleet", cfg)  # MCBehaviours is defined there
    return FleetReplay(consts, agent_argv, master_argv).replay_simulation(seed, num, depth, cfg)
