"""Spec -> implementation for reliable reports: every edge of MCReportsReplay's state graph
(Reports.tla with each step's name, spec/tla/MCReportsReplay.tla) replayed against
`ev3-reports-driver` (docs/driver.md "Reports driver"): the library's report buffer, a master's
record of an agent, and the PC's record file.

Mapping (an agent is named by its id, a master "pc" or "im"):
  Make(a)          -> make: a report made
  Send(a)          -> send to the master a reports to (a round of retries: everything the window
                      gives); to the interim master, its record takes each at once (PCTake) and
                      acknowledges what it stored
  TakeAck(a, f)    -> take_ack of the acknowledgement in flight (from the PC or not, from the
                      master a reports to or not)
  Switch, Takeover -> new_master (the agent reports to another master from now on)
  PCTake(m)        -> take by the PC: the report (last 0) or the marker m.seq..m.last, offered with
                      first = m.seq for a marker, else the lowest number the agent holds when it is
                      taken, or the report's number when that is lower (the REPORT's first field was
                      at most both when it was sent)
  PCAck(a)         -> ack: what the PC acknowledges
  PCCrash          -> crash: the PC's records rebuilt from its record file, read back
  PCRestart, Lose  -> check (nothing for the library to do; the state is still compared)
Compared after every step: each agent's made, lo, mk; the PC's record of it (the record file's lines
expanded number by number, against `rec`; `nx` against the record's next); what Send sends to the
PC (the set of datagrams, against the spec's `Sent(a)`); the acknowledgement PCAck sends (the
number of entries of `rec`) and the interim master's after a Send to it (everything made).

Every edge is replayed; a mismatch is classified by (action, differing fields) and counted, and
the edges below a diverged state are counted as "downstream" of it.
"""

from __future__ import annotations

import time

from ev3conformance import graph as gr

MODULE = "MCReportsReplay.tla"
# The graphs replayed: MCReports.cfg's constants (a loss, a duplicate, a PC crash, a switch), then
# a drop marker of two numbers reaching a PC that took its first already.
CFGS = (("reports", "MCReportsReplay.cfg"), ("reports-marker", "MCReportsReplayMarker.cfg"))


def reports_config(c: dict) -> dict:
    return {"type": "config", "cap": c["Cap"]}


def reports_input(la: dict) -> dict:
    n, a = la["name"], la["args"]
    if n == "Make":
        return {"type": "make", "agent": a[0]}
    if n == "Send":
        return {"type": "send", "agent": a[0], "to": a[1]}
    if n == "TakeAck":
        agent, f, ack, current = a
        return {"type": "take_ack", "agent": agent, "n": ack, "pc": f == "pc", "current": current}
    if n in ("Switch", "Takeover"):
        return {"type": "new_master", "agent": a[0]}
    if n == "PCTake":
        m, lo = a
        marker = m["kind"] == "dropped"
        return {"type": "take", "master": "pc", "agent": m["agent"], "seq": m["seq"],
                "last": m["last"] if marker else 0, "first": m["seq"] if marker else min(lo, m["seq"])}
    if n == "PCAck":
        return {"type": "ack", "master": "pc", "agent": a[0]}
    if n == "PCCrash":
        return {"type": "crash"}
    if n in ("PCRestart", "Lose"):
        return {"type": "check"}
    raise ValueError(f"no driver input for {n}")


def record_entries(text: str) -> dict:
    """The record file's text -> {agent: ((seq, kind), ...)}, number by number."""
    out: dict[int, list] = {}
    for line in text.splitlines():
        if not line or line.startswith("#"):
            continue
        f = line.split("\t")
        agent, first, last, kind = int(f[0]), int(f[1]), int(f[2]), f[3]
        out.setdefault(agent, []).extend((s, kind) for s in range(first, last + 1))
    return {a: tuple(e) for a, e in out.items()}


def spec_vars(sv: dict) -> dict:
    v = {}
    for a in sv["made"]:
        v[f"agent[{a}].made"], v[f"agent[{a}].lo"], v[f"agent[{a}].mk"] = sv["made"][a], sv["lo"][a], sv["mk"][a]
        v[f"pc[{a}].rec"] = tuple((e["seq"], e["kind"]) for e in sv["rec"][a])
        v[f"pc[{a}].nx"] = sv["nx"][a]
    return v


def impl_vars(out: dict, agents) -> dict:
    v = {}
    rec = record_entries(out["record"])
    for a in agents:
        b = out["agents"].get(str(a), {"made": 0, "lo": 1, "mk": 0})
        v[f"agent[{a}].made"], v[f"agent[{a}].lo"], v[f"agent[{a}].mk"] = b["made"], b["lo"], b["mk"]
        v[f"pc[{a}].rec"] = rec.get(a, ())
        r = out["pc"].get(str(a))
        v[f"pc[{a}].nx"] = r["next"] if r and r["next"] else 1
    return v


def _show_action(la: dict) -> str:
    a = la["args"]
    if la["name"] == "PCTake":
        m = a[0]
        what = f"report {m['seq']}" if m["kind"] == "report" else f"marker {m['seq']}..{m['last']}"
        return f"PCTake({what} of agent {m['agent']}; it holds from {a[1]})"
    if la["name"] == "Send":
        return f"Send({a[0]} to {a[1]})"
    if la["name"] == "TakeAck":
        return f"TakeAck({a[0]}, {a[1]}: {a[2]}{', its current master' if a[3] else ''})"
    return la["name"] + (f"({', '.join(map(str, a))})" if a else "")


class ReportsReplay:
    def __init__(self, g: gr.Graph, consts: dict, argv: list[str], stop_first: bool = False,
                 name: str = "reports") -> None:
        self.g, self.c, self.argv, self.stop_first = g, consts, argv, stop_first
        self.fig = gr.StrictFigures(name=name, states=len(g.states), edges=len(g.edges))

    def run(self) -> gr.StrictFigures:
        g = self.g
        t0 = time.monotonic()
        ps = gr.cover(g)
        self.fig.paths, self.fig.max_path = ps.paths, ps.max_len
        gr.replay_walk(g, self.argv, reports_config(self.c), gr.driver_inputs(g, gr.walk(g, ps), reports_input),
                       self.fig, lambda ei, out: self._compare(g.states[g.edges[ei][0]], g.states[g.edges[ei][1]], out),
                       self._report, self.stop_first)
        self.fig.seconds = time.monotonic() - t0
        return self.fig

    def _compare(self, su: dict, sv: dict, out: dict) -> dict:
        """Differing fields -> (spec, implementation); empty when the step conforms."""
        if "error" in out:
            return {"driver error": (None, out["error"])}
        la = sv["lastAction"]
        diff = {}
        s, i = spec_vars(sv), impl_vars(out, sv["made"].keys())
        for k in sorted(set(s) | set(i)):
            if s.get(k, "<absent>") != i.get(k, "<absent>"):
                diff.setdefault(k.split(".", 1)[1], (s.get(k, "<absent>"), i.get(k, "<absent>")))
        a = la["args"]
        if la["name"] == "Send":
            spec_sent = {(m["seq"], m["last"], m["kind"]) for m in a[2]}
            impl_sent = {(x["seq"], x["last"], x["kind"]) for x in out.get("sent", [])}
            if a[1] == "pc" and spec_sent != impl_sent:
                diff["sent"] = (sorted(spec_sent), sorted(impl_sent))
            # the interim master acknowledges everything made (SendAck("im", a, made[a]))
            if a[1] == "im" and out.get("im_ack") != su["made"][a[0]]:
                diff["ack"] = (su["made"][a[0]], out.get("im_ack"))
        if la["name"] == "PCAck" and out.get("ack") != len(su["rec"][a[0]]):
            # SendAck("pc", a, Stored(a)) (the master core sends no REPORT_ACK 0: it frees nothing)
            diff["ack"] = (len(su["rec"][a[0]]), out.get("ack"))
        return diff

    def _report(self, path: list[int], diff: dict, out: dict) -> str:
        g = self.g
        sv = g.states[g.edges[path[-1]][1]]
        i = impl_vars(out, sv["made"].keys()) if "error" not in out else {}
        lines = gr.mismatch_lines(g, path, _show_action, spec_vars(sv), i, (18, 34))
        for f, (a, b) in diff.items():
            if f in ("sent", "ack", "driver error"):
                lines.append(f"   {f}: spec {a} | implementation {b}")
        return "\n".join(lines)
