"""Spec -> implementation for the master: every edge of MCMaster's state graph (Master.tla, the
master alone against any environment) replayed against `ev3-master --driver` (docs/driver.md).

Mapping: Recv of m from endpoint e -> `recv` (from = e, the datagram of m with its exact msgid);
MasterCommand(id, c) -> `command`; MasterTick -> `advance` by one resend period (1 ms; drop =
TDrop ms, max_resends = MaxResends). The C++ master ticks only when a resend or drop is due, so a
MasterTick edge may show no action; the state after it is compared all the same.
Compared after every step: the action, nextId, msgid, and every registry entry (ann, id, ep,
synced, pending, mid, queue, beh, quiet = ms since heard, hi = highest msgid heard; resends only
while a synced entry has a command pending: the C++ core also counts MASTER resends, the spec does
not, and the count only matters for a pending command), and the set of datagrams sent (to, exact
bytes as spec messages). `desired` has no C++ counterpart (the C++ master does not reconcile).

Unlike the agent replay, a mismatch does not stop the run: every edge is replayed, each mismatch
is classified by (action, differing fields) and counted; edges below a diverged state count as
"downstream" of it. The first example of each class is printed side by side.
"""

from __future__ import annotations

import time


from ev3conformance import driver as drv
from ev3conformance import graph as gr
from ev3conformance import wire

RECV = {"MasterSync", "MasterAnswer", "MasterPing", "MasterReport"}


def master_config(c: dict) -> dict:
    return {"type": "config", "timers": {"resend": 1, "drop": c["TDrop"]}, "max_resends": c["MaxResends"],
            "next_id": 2, "next_msgid": 1, "now": 0}


def master_input(la: dict) -> dict:
    n, a = la["name"], la["args"]
    if n in RECV:
        m, e = a
        return {"type": "recv", "from": e, "hex": drv.spec_to_wire(m).hex()}
    if n == "MasterCommand":
        ident, c = a
        inp = {"type": "command", "agent": ident, "command": c["type"]}
        if c["type"] == "BEHAVIOUR":
            inp["behaviour"] = c["name"]
        return inp
    if n == "MasterTick":
        return {"type": "advance", "ms": 1}
    raise ValueError(f"no driver input for {n}")


def _entry_spec(x: dict) -> dict:
    return {"ann": x["ann"], "id": x["id"], "ep": x["ep"], "synced": x["synced"], "pending": x["pending"],
            "mid": x["mid"], "resends": x["resends"] if x["synced"] and x["pending"] else None,
            "queue": tuple((q["type"], q["name"]) for q in x["queue"]), "beh": x["beh"], "quiet": x["quiet"],
            "hi": x["hi"]}


def _entry_impl(x: dict) -> dict:
    return {"ann": x["ann"], "id": x["id"], "ep": x["ep"], "synced": x["synced"], "pending": x["pending"],
            "mid": x["mid"], "resends": x["resends"] if x["synced"] and x["pending"] else None,
            "queue": tuple((q["type"], q["name"]) for q in x["queue"]), "beh": x["beh"], "quiet": x["quiet_ms"],
            "hi": x["hi"]}


def spec_vars(ms: dict) -> dict:
    v = {"nextId": ms["nextId"], "msgid": ms["msgid"][0]}
    for x in ms["reg"]:
        for k, val in _entry_spec(x).items():
            v[f"reg[{x['id']}].{k}"] = val
    return v


def impl_vars(v: dict) -> dict:
    out = {"nextId": v["nextId"], "msgid": v["msgid"]}
    for x in v["reg"]:
        for k, val in _entry_impl(x).items():
            out[f"reg[{x['id']}].{k}"] = val
    return out


def spec_out(out) -> set:
    s = set()
    for o in out:
        m = o["m"]
        s.add((o["to"], m["src"], m["dst"], m["msgid"], m["type"], m["ref"], tuple(m["args"])))
    return s


def impl_out(sent: list[dict]) -> set:
    s = set()
    for t in sent:
        data = bytes.fromhex(t["hex"])
        src, dst, typ, ref, args = drv.wire_to_spec(data)
        s.add((t["peer"], src, dst, wire.decode(data).msgid, typ, ref, args))
    return s


def _show_action(la: dict) -> str:
    a = la["args"]
    if la["name"] in RECV:
        m, e = a
        return (f"{la['name']}(from {e}: {m['src']}->{m['dst']} #{m['msgid']} {m['type']}"
                f"{' ref ' + str(m['ref']) if m['ref'] else ''}{' ' + str(list(m['args'])) if m['args'] else ''})")
    if la["name"] == "MasterCommand":
        return f"MasterCommand({a[0]}, {a[1]['type']}{' ' + a[1]['name'] if a[1]['type'] == 'BEHAVIOUR' else ''})"
    return la["name"]


class MasterReplay:
    def __init__(self, g: gr.Graph, consts: dict, argv: list[str], tolerate: tuple = (),
                 stop_first: bool = False, cache: dict | None = None) -> None:
        """tolerate: known classes to let pass (counted in fig.tolerated) to look for others:
        "pending-resend" = the spec re-emits a datagram already pending (PendingOut of an entry
        whose pending datagram did not change) where the core does not. stop_first: end the run
        at the first mismatch (mutation testing)."""
        self.g, self.c, self.argv, self.tolerate = g, consts, argv, set(tolerate)
        self.stop_first = stop_first
        self.cache = cache if cache is not None else {}  # path set and inputs, kept across runs
        self.fig = gr.StrictFigures(name="master", states=len(g.states), edges=len(g.edges))

    def ops(self, ps: gr.PathSet):
        """The replay as a sequence of ops: ('save', d), ('restore', d), ('edge', ei)."""
        return gr.walk(self.g, ps)

    def run(self) -> gr.StrictFigures:
        g = self.g
        t0 = time.monotonic()
        if "ps" not in self.cache:
            self.cache["ps"] = gr.cover(g)
        ps = self.cache["ps"]
        self.fig.paths, self.fig.max_path = ps.paths, ps.max_len
        if "tagged" not in self.cache:
            self.cache["tagged"] = gr.driver_inputs(g, self.ops(ps), master_input)
        gr.replay_walk(g, self.argv, master_config(self.c), self.cache["tagged"], self.fig,
                       lambda ei, out: self._compare(g.states[g.edges[ei][1]], out, g.states[g.edges[ei][0]]),
                       self._report, self.stop_first)
        self.fig.seconds = time.monotonic() - t0
        return self.fig

    def _compare(self, sv: dict, out: dict, su: dict | None = None) -> dict:
        """Differing fields -> (spec, implementation); empty when the step conforms."""
        la = sv["lastAction"]
        diff = {}
        if "error" in out:
            return {"driver error": (None, out["error"])}
        acts = [a["action"] for a in out.get("actions", [])]
        if la["name"] == "MasterTick":
            # The core names its MasterTick record "Tick" (core.hpp: the master's part of Fleet's Tick).
            if acts not in ([], ["MasterTick"], ["Tick"]):
                diff["action"] = ("MasterTick", acts)
        elif acts != [la["name"]]:
            diff["action"] = (la["name"], acts)
        s, i = spec_vars(sv["ms"]), impl_vars(out["vars"])
        for k in sorted(set(s) | set(i)):
            if s.get(k, "<absent>") != i.get(k, "<absent>"):
                fld = k.split(".", 1)[1] if "." in k else k
                if k.startswith("reg[") and (k not in s or k not in i):
                    fld = "registry entries"
                diff.setdefault(fld, (s.get(k, "<absent>"), i.get(k, "<absent>")))
        so, io = spec_out(sv["out"]), impl_out(out.get("sent", []))
        if so != io:
            extra = so - io
            old = {(x["id"], x["mid"]) for x in (su or {}).get("ms", {}).get("reg", ()) if x["pending"]}
            # Only where the finding is (MasterCommand, MasterPing): a MasterTick that does not
            # resend is a fault (mutation M01 survived while this covered every action).
            if ("pending-resend" in self.tolerate and la["name"] in ("MasterCommand", "MasterPing") and io <= so
                    and all(m[0] != 0 and (m[2], m[3]) in old for m in extra)):
                self.fig.tolerated += 1
            else:
                diff["out"] = (sorted(so - io), sorted(io - so))
        return diff

    def _report(self, path: list[int], diff: dict, out: dict) -> str:
        g = self.g
        sv = g.states[g.edges[path[-1]][1]]
        s, i = spec_vars(sv["ms"]), impl_vars(out.get("vars", {"nextId": 0, "msgid": 0, "reg": []}))
        lines = gr.mismatch_lines(g, path, _show_action, s, i, (22, 28))
        if "desired" not in str(diff):
            lines.append("   (spec desired: " + ", ".join(f"{x['id']}:{x['desired']}" for x in sv["ms"]["reg"]) + ")")
        for f, (a, b) in diff.items():
            if f in ("out", "action", "driver error"):
                lines.append(f"   {f}: spec {a} | implementation {b}")
        return "\n".join(lines)
