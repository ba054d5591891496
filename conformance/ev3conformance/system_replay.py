"""Spec -> implementation for the election: TLC `-simulate` traces of the whole system (System.tla:
the PC master with epochs, agents with relay, pre-vote, election and membership, time, HANDOVER,
a lossy, duplicating, reordering network that delivers late) replayed against one
`ev3-master --driver` for the PC, one `ev3-agent --driver` per agent and, while an agent is the
elected master of an epoch, one `ev3-master --driver` for the Master core it runs (configured as
node.hpp runs it: MasterConfig::for_elected_agent), the drivers talking to each other.

The traces come from MCSystemSim.tla (spec/tla/): System's SysNext, each step named by System's own
`lastAction` (no wrapper variable for the names), filtered where the cores take two of the spec's
steps on one input (a candidate with a quorum becomes master at once, the PC back from a crash or
told of a newer epoch stands at once, a peer shares its membership after it answered the
RELAY_REQ), to the agent core's rule for a peer's ELECT at a follower (docs/spec.md "Not covered"),
and per behaviour to a PC that stays down until an agent leads (so that it takes the fleet back:
HANDOVER): a subset of System's behaviours. One step is added, Ignore(n, m): a datagram no receive
rule takes, delivered; it changes none of System's variables (the probe of the guards: a second
vote, a copy counted again, an older offer taken would show on it).
The spec decides what happens: which datagram is delivered (again, late), lost, which timer fires,
when the PC crashes and comes back. The implementations produce the datagrams: a delivery is a
`recv` on the receiver's driver of the bytes the SENDER's driver emitted for that spec datagram
(an elected agent's Master core gets the first copy of each, as node.hpp gives it).

Mapping of the spec's steps (lastAction of the target state):

    Tick                      every agent that follows a master (spec: ACTIVE, WORKING, PAUSED)
                              `advance TICK` (T = 1: TICK = loss - 1 ms, so the timer is due
                              after one Tick and fires at the spec's Timeout)
    Timeout(a)                `advance 1` on a: HeartbeatLost
    Refresh, HandleHeartbeat, HandleElect, HandleVote, HandleStale, OfferRelay, AcceptRelay,
    HandleAccept, RelayDropped, GrantPreVote, HandlePreVote, LearnMembers, ShareMembers,
    MasterHandover            `recv` of the datagram's bytes on the receiver (the PC's driver for
                              node 1, else the agent's driver and its Master core's, if one runs);
                              Refresh: the core takes the LEADER as HandleHeartbeat or as no action
                              (its timer restarts either way: silence is compared)
    RequestRelay(a), StartElection(n), Heartbeat(n)
                              the timer the core has for it: the node's clock is advanced to its
                              next deadline until the core takes that action (at most MAX_WAKES
                              times); the PC's and an elected agent's Heartbeat on the Master core
    BecomeMaster(n)           taken by the core on the VOTE that completed the quorum (the spec
                              takes it as the next step: MCSystemSim's Eager); the elected
                              agent's Master core starts (its first LEADER is this step's too)
    Crash(PC), Restart(PC)    the PC's driver process is killed; a new one starts as a candidate
                              with the crashed one's epoch, membership and next msgid (its state
                              file); it stands at once (the spec's next step, Eager)
    Lose, LoseHandover        nothing (the bytes are forgotten)
    Ignore(n, m)              (MCSystemSim's one added step: no rule of System takes m at n)
                              `recv` on n: no action, nothing sent

Compared after every step, for every node: life, epoch, votedFor, votes, leader, following, via,
relays, offered, prevotes, members, mepoch, floor (the PC: life, epoch, votes, members, mepoch,
want), an agent's silence while it follows a master (ms = spec ticks x TICK), whether an elected
agent runs a Master core (exactly while it is master); and the datagrams each step emits: every
datagram the spec's step adds to net (hnet for HANDOVER) is emitted by the implementation in that
step, and every datagram the implementation emits maps (tracecheck's datagram mapping, the one the
whole-run check uses) to a datagram of the spec's net after the step.

What the replay tolerates, and why (nothing else):
  - the spec's clocks are abstract: a node's clock moves only when the spec's step needs it
    (a follower's on Tick, the timer of the step the spec takes), each driver has its own clock;
  - timers the spec abstracts into spontaneous steps run ahead: RequestRelay (the relay_retry
    period, and at once on entering PANIC), ShareMembers (on the RELAY_REQ an agent answers), a
    master's Heartbeat (leader_heartbeat), taken by the core before the spec takes them, change
    no compared variable (checked: the node's state must still match), and their datagrams are
    held back, not in flight, until the spec takes the step (then they are its datagrams) --
    never, if it does not (the network lost them);
  - datagrams System does not model are not delivered (the network lost them): PANIC (Fleet's
    broadcast on entering PANIC) and RELAY_ROUTE (System abstracts the route: the master reads
    the relay table). Any other datagram outside the spec is a mismatch;
  - a step the core takes ahead of the spec on the same input (BecomeMaster after HandleVote)
    is the spec's next step (the wrapper makes it so); until then that node is not compared.

A mismatch ends its trace (the rest is counted as not replayed); the other traces still run.
Mismatches are classified by (action, differing fields); the first of each class is printed with
the trace up to it.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from ev3conformance import driver as drv
from ev3conformance import tla, tracecheck, wire
from ev3conformance.replay import split_sent
from ev3conformance.sim_replay import Mismatch, SimFigures, SimReplay, SimTrace

SIM_MODULE = "MCSystemSim.tla"
SIM_CFG = "MCSystemSim.cfg"
PC = 1
LOSS = 100                      # the agents' heartbeat timeout (ms)
TICK = LOSS - 1                 # one spec Tick (T = 1): a follower's timer is due, not fired
AGENT_TIMERS = {"sync": 1000, "heartbeat": 10 ** 7, "loss": LOSS, "paused": 2 * LOSS, "relay_retry": 100,
                "backoff": 1000, "backoff_step": 10, "candidate": 500, "leader_heartbeat": 1000,
                "vouch": 0}  # vouch 0: the relay's timing rules, which the spec leaves out, off
MASTER_TIMERS = {"resend": 10 ** 7, "drop": 10 ** 7, "leader_heartbeat": 50, "candidate": 500}
MAX_WAKES = 60                  # deadlines a node's clock is advanced to for one spec step
FOLLOWERS = ("ACTIVE", "WORKING", "PAUSED")
# Actions that change no variable the replay compares (checked after every step): the core may take
# them before the spec does; their datagrams wait for the spec's step.
FREE = ("RequestRelay", "ShareMembers", "Heartbeat", "Tick")
NOT_MODELLED = ("PANIC", "RELAY_ROUTE")   # datagrams System has no counterpart of: not delivered
AGENT_FIELDS = ("life", "epoch", "votedFor", "votes", "leader", "following", "via", "relays", "offered",
                "prevotes", "members", "mepoch", "floor")
PC_FIELDS = ("life", "epoch", "votes", "members", "mepoch")


# --- datagrams -------------------------------------------------------------------------------------

def at(x, n):
    """x[n] of a TLA+ function as TLC prints it: a sequence when its domain is 1..N (Nodes), else a dict."""
    return x[n - 1] if isinstance(x, tuple) else x[n]


def _rec(**kv) -> tla.Rec:
    return tla.Rec(kv)


def spec_msg(t: str, src: int, dst: int, e: int, x: int = 0, k: int = 0, mem=frozenset()) -> tla.Rec:
    """Election.tla's datagram record (M, MK, MH)."""
    return _rec(t=t, src=src, dst=dst, e=e, x=x, k=k, mem=frozenset(mem))


def as_spec(data: bytes, agents: frozenset, score: dict) -> tuple[list, str | None]:
    """A datagram the implementation emitted as the spec datagrams it stands for (net elements; a
    HANDOVER: an hnet element), by tracecheck's mapping (the one of the whole-run check): [] for a
    type System does not model (NOT_MODELLED); an error text when it is outside the spec."""
    m = wire.decode(data)
    name = m.type_name or str(m.type)
    if name in NOT_MODELLED:
        return [], None
    if name == "HANDOVER":
        ps = list(m.params)
        mem = set()
        for p in ps[1:]:
            head = p.split(b":", 1)[0]
            if head.isdigit() and 2 <= int(head) <= 49999:
                mem.add(int(head))
        return [_rec(src=m.sender, dst=m.receiver, e=int(ps[0]), mem=frozenset(mem))], None
    d, _inner, members = tracecheck._el_msg(data.decode("latin-1"))
    t = d["t"]
    if t in ("NONE", "ROUTE", "RELAY", "CMD"):
        return [], f"{name} is not a datagram of System (no commands in MCSystemSim)"
    if t in ("RREQ", "ELECT") and d["sc"] != score[d["src"]]:
        return [], f"{name} from {d['src']} carries score {d['sc']}, the spec's Score is {score[d['src']]}"
    if t == "HB":
        mem = frozenset(members)
        if d["x"] == 0:   # a copy of a membership: to its receiver, or the PC's broadcast to every agent
            dsts = [d["dst"]] if d["dst"] else sorted(agents)
            return [spec_msg("HB", d["src"], a, d["e"], mem=mem) for a in dsts], None
        if d["x"] != d["src"] or d["dst"] != 0:
            return [], f"LEADER from {d['src']} to {d['dst']} names leader {d['x']}"
        return [spec_msg("HB", d["src"], 0, d["e"], mem=mem)], None
    if t == "VOTE":
        ps = list(m.params)
        cand = int(ps[1]) if len(ps) > 1 and ps[1].isdigit() else -1
        if cand != m.receiver:
            return [], f"VOTE to {m.receiver} names candidate {cand}"
        return [spec_msg("VOTE", d["src"], d["dst"], d["e"])], None
    if t in ("RREQ", "ELECT"):
        return [spec_msg(t, d["src"], 0, d["e"], k=d["k"])], None
    if t in ("ROFFER", "RACCEPT"):
        return [spec_msg(t, d["src"], d["dst"], d["e"], x=d["x"])], None
    return [spec_msg(t, d["src"], d["dst"], d["e"])], None     # STALE, RDROP, PREOK


def msg_text(m) -> str:
    if "t" not in m:
        return f"HANDOVER {m['src']}->{m['dst']} e{m['e']} {sorted(m['mem'])}"
    extra = (f" x{m['x']}" if m["x"] else "") + (f" k{m['k']}" if m["k"] else "") + \
            (f" {sorted(m['mem'])}" if m["mem"] else "")
    return f"{m['t']} {m['src']}->{m['dst'] or '*'} e{m['e']}{extra}"


def step_text(la: tuple) -> str:
    return " ".join(msg_text(x) if isinstance(x, dict) else str(x) for x in la)


def step_key(la: tuple) -> str:
    return str(la[0])


# --- figures and mismatches -----------------------------------------------------------------------

@dataclass
class SystemFigures(SimFigures):
    wakes: int = 0             # clock advances to a deadline for a timer's step
    held: int = 0              # datagrams held back (emitted ahead of the spec's step)
    held_used: int = 0         # ... later taken by the spec's step
    dropped: Counter = field(default_factory=Counter)   # not modelled datagrams (type -> count)
    elected: int = 0           # BecomeMaster of an agent, matched
    pc_elected: int = 0        # BecomeMaster of the PC (after a crash), matched
    handovers: int = 0         # MasterHandover matched (the PC took an elected agent's HANDOVER)
    handed: int = 0            # HANDOVERs sent (steps that add to hnet), matched
    late: int = 0              # deliveries of a datagram of an epoch older than the receiver's
    again: int = 0             # deliveries of a datagram the receiver got before (duplicates)

    def title(self) -> str:
        return (f"election (System): traces {self.traces} ({self.agents} agents + the PC; one driver "
                f"process per node, one per elected agent's Master core)")

    def details(self) -> list[str]:
        return [f"  agents elected {self.elected}, the PC elected again {self.pc_elected}, HANDOVERs sent "
                f"{self.handed}, taken by the PC {self.handovers} (copies included)",
                f"  deliveries of an older epoch than the receiver's {self.late}, of a datagram delivered "
                f"before {self.again}",
                f"  driver inputs {self.inputs}  clock wakes {self.wakes}  datagrams held back {self.held} "
                f"(used later {self.held_used})  not modelled, not delivered: "
                + (", ".join(f"{k} {n}" for k, n in sorted(self.dropped.items())) or "-")]


# --- one trace -------------------------------------------------------------------------------------

class _Trace(SimTrace):
    def __init__(self, rp: "SystemReplay", idx: int, path: Path | None, states: list[dict]) -> None:
        super().__init__(rp, idx, path, states)
        self.agents = sorted(states[0]["silence"].keys())
        self.aset = frozenset(self.agents)
        self.score = {PC: 0, **{a: a for a in self.agents}}
        self.ag: dict = {}            # agent -> driver
        self.core: dict = {}          # agent -> its Master core's driver (while elected)
        self.core_seen: dict = {}     # agent -> (sender, msgid) its Master core took (node.hpp's window)
        self.pc: drv.Driver | None = None
        self.el: dict = {}            # node -> the election state its driver reported last
        self.silence: dict = {}       # agent -> its vars.silence
        self.pc_saved: dict = {}      # the PC's state file (epoch, members, mepoch, next msgid, next id)
        self.pc_msgid = 1
        self.bytes: dict = {}         # spec datagram (net / hnet element) -> bytes that stand for it
        self.pool: dict = {}          # (node, action) -> [(spec datagrams, bytes)] emitted ahead
        self.ahead: dict = {}         # node -> [action] the core took ahead of the spec
        self.ahead_sent: dict = {}    # node -> the datagrams of the action it took ahead
        self.got_before: set = set()  # (receiver, datagram) delivered so far (SystemFigures.again)

    # -- drivers --
    def _pc_config(self, candidate: bool) -> None:
        s = self.pc_saved
        self._ask(self.pc, "PC", {"type": "config", "timers": MASTER_TIMERS, "next_id": s["next_id"],
                                  "next_msgid": s["msgid"],
                                  "election": {"enabled": True, "epoch": s["epoch"], "members": s["members"],
                                               "members_epoch": s["mepoch"], "candidate": candidate}})

    def start(self) -> None:
        init = self.states[0]
        for a in self.agents:
            d = self.ag[a] = self.rp.driver("agent")
            temp = 50000 + a
            mem = sorted(at(init["members"], a))
            self._ask(d, a, {"type": "config", "timers": AGENT_TIMERS, "temp_id": temp,
                             "first_msgid": 1000 * a + 1, "behaviours": [{"name": "wait", "devices": 0}],
                             "election": {"enabled": True, "score": a, "epoch": 1, "members": mem,
                                          "members_epoch": 1, "floor": 1}})
            # Before Init: the PC's MASTER gives the agent its id (Init: every agent follows the PC in
            # epoch 1); the agent's ACK is the setup's, not a datagram of the spec.
            sync = wire.encode(wire.Message(PC, a, 100 + a, 2, (str(temp).encode(),)))
            out = self._ask(d, a, {"type": "recv", "from": PC, "hex": sync.hex()})
            self._took(a, out)
        self.pc = self.rp.driver("master")
        mem0 = at(init["members"], PC)
        self.pc_saved = {"epoch": 1, "members": sorted(mem0), "mepoch": 1, "msgid": 1,
                         "next_id": max(self.agents) + 1}
        self._pc_config(False)
        out = self._ask(self.pc, "PC", {"type": "advance", "ms": 0})   # its first LEADER: before Init, lost
        self._took(PC, out)
        self.compare()

    def _took(self, node, out: dict) -> None:
        if "election" in out:
            self.el[node] = out["election"]
        if node != PC and isinstance(node, int) and "vars" in out:
            self.silence[node] = out["vars"].get("silence")
        if node == PC and "vars" in out:
            self.pc_msgid = out["vars"]["msgid"]

    # -- emitted datagrams --
    def _collect(self, node, out: dict, want: str | None, got: list, emitted: list, free_ok=True) -> list:
        """The actions of one driver output: stateful ones returned, free ones not asked for pooled,
        the datagrams of the others into @p emitted (as (node, bytes))."""
        acts = out.get("actions", [])
        per = split_sent(out) if acts else [[]]
        if not acts and out.get("sent"):
            per = [out["sent"]]
        stateful = []
        for i, a in enumerate(acts):
            name = a["action"]
            data = [bytes.fromhex(s["hex"]) for s in drv.sent_beyond_reports(per[i] if i < len(per) else [])]
            if name in FREE and name != want:
                if name == "Tick":
                    emitted += [(node, x) for x in data]
                    continue
                if data:
                    self.pool.setdefault((node, name), []).append(data)
                    self.rp.fig.held += len(data)
                continue
            got.append(name)
            stateful.append(name)
            emitted += [(node, x) for x in data]
        if not acts:
            emitted += [(node, bytes.fromhex(s["hex"])) for s in drv.sent_beyond_reports(out.get("sent", []))]
        return stateful

    def _from_pool(self, node, name: str, want) -> list | None:
        """Datagrams of a @p name the core took ahead of the spec whose spec datagrams include @p want."""
        for i, data in enumerate(self.pool.get((node, name), [])):
            specs = [m for x in data for m in self._map(x)[0]]
            if want is None or want in specs:
                self.pool[(node, name)].pop(i)
                self.rp.fig.held_used += len(data)
                return data
        return None

    def _map(self, data: bytes) -> tuple[list, str | None]:
        return as_spec(data, self.aset, self.score)

    def match_emitted(self, s0: dict, s1: dict, emitted: list) -> None:
        new = (set(s1["net"]) - set(s0["net"])) | (set(s1["hnet"]) - set(s0["hnet"]))
        now = set(s1["net"]) | set(s1["hnet"])
        seen, extra = set(), []
        for node, data in emitted:
            specs, err = self._map(data)
            if err:
                self.fail("a datagram outside the spec", ("emitted",), f"  {node} emitted {data!r}: {err}")
            if not specs:
                self.rp.fig.dropped[wire.decode(data).type_name] += 1
                continue
            for m in specs:
                if m not in now:
                    extra.append(f"{node}: {msg_text(m)}  ({data.decode('latin-1')})")
                    continue
                seen.add(m)
                self.bytes.setdefault(m, []).append(data)
        missing = new - seen
        if extra or missing:
            self.fail("emitted datagrams differ", ("emitted",),
                      "  spec emits, implementation did not: " + ("; ".join(msg_text(m) for m in missing) or "-") +
                      "\n  implementation emitted, not in the spec's net: " + ("; ".join(extra) or "-"))

    # -- inputs --
    def _deliver(self, node, m, emitted: list, want: str | None = None) -> list:
        """recv of @p m's bytes on @p node (the PC, or the agent and its Master core)."""
        if m not in self.bytes:
            self.fail("no bytes", ("internal",), f"  the spec delivers {msg_text(m)}, which no driver emitted")
        data = self.bytes[m][-1]
        src = m["src"]
        got: list = []
        if node == PC:
            out = self._ask(self.pc, "PC", {"type": "recv", "from": src, "hex": data.hex()})
            self._collect(PC, out, want, got, emitted)
            self._took(PC, out)
            return got
        out = self._ask(self.ag[node], node, {"type": "recv", "from": src, "hex": data.hex()})
        self._collect(node, out, want, got, emitted)
        self._took(node, out)
        core = self.core.get(node)
        if core is not None:
            key = (src, wire.decode(data).msgid)
            if key not in self.core_seen[node]:
                self.core_seen[node].add(key)
                cout = self._ask(core, f"{node}'s Master core", {"type": "recv", "from": src, "hex": data.hex()})
                cgot: list = []
                self._collect(("core", node), cout, None, cgot, emitted)
                self.el[("core", node)] = cout.get("election")
                got += [f"core:{x}" for x in cgot]
        return got

    def _wake(self, node, d: drv.Driver, want: str, emitted: list, label) -> list:
        """Advances @p node's clock to its next deadline until its core takes @p want."""
        got: list = []
        for _ in range(MAX_WAKES):
            out = self._ask(d, label, {"type": "advance", "ms": 0})
            if not out.get("actions"):
                dl = out.get("deadline")
                if dl is None:
                    break
                out = self._ask(d, label, {"type": "advance", "to": dl})
                self.rp.fig.wakes += 1
            self._collect(node, out, want, got, emitted)
            if node == PC:
                self._took(PC, out)
            elif isinstance(node, tuple):
                self.el[node] = out.get("election")
            else:
                self._took(node, out)
            if want in got:
                return got
            if got:
                break
        self.fail(f"the core did not take {want} (it took {got or 'nothing'} as its timers fired)",
                  ("action",), "")
        return got

    def _expect(self, got: list, want: list) -> None:
        if got != want:
            self.fail(f"action: spec {want}, implementation {got}", ("action",), "")

    def _start_core(self, a, emitted: list) -> None:
        el = self.el[a]
        d = self.core[a] = self.rp.driver("master")
        self.core_seen[a] = set()
        out = self._ask(d, f"{a}'s Master core", {
            "type": "config", "timers": MASTER_TIMERS,
            "election": {"enabled": True, "self_id": a, "epoch": el["master_epoch"], "members": el["members"]}})
        out = self._ask(d, f"{a}'s Master core", {"type": "advance", "ms": 0})   # its first LEADER: now
        got: list = []
        self._collect(("core", a), out, "Heartbeat", got, emitted)
        self.el[("core", a)] = out.get("election")
        self._expect(got, ["Heartbeat"])

    def _stop_cores(self) -> None:
        """node.hpp drops a Master core that stepped down once its agent is master no more."""
        for a in list(self.core):
            cel = self.el.get(("core", a)) or {}
            if cel.get("life") == "STEPPED_DOWN" and self.el[a]["life"] != "MASTER":
                self.rp.close(self.core.pop(a))
                self.el.pop(("core", a), None)

    # -- steps --
    def step(self) -> None:
        s0, s1 = self.states[self.k - 1], self.states[self.k]
        la = s1["lastAction"]
        n = la[0]
        emitted: list = []
        if n in ("Lose", "LoseHandover"):
            pass
        elif n == "Tick":
            for a in self.agents:
                if at(s0["life"], a) in FOLLOWERS:
                    if self.ahead.get(a):
                        self._owes(a)
                    out = self._ask(self.ag[a], a, {"type": "advance", "ms": TICK})
                    got: list = []
                    self._collect(a, out, None, got, emitted)
                    self._took(a, out)
                    if got:
                        self.fail(f"{a}: spec Tick, implementation {got}", ("action",), "")
        elif n == "Timeout":
            a = la[1]
            self._owes(a)
            out = self._ask(self.ag[a], a, {"type": "advance", "ms": 1})
            got = []
            self._collect(a, out, None, got, emitted)
            self._took(a, out)
            self._expect(got, ["HeartbeatLost"])
        elif n == "MasterHandover":
            h = la[1]
            if h not in self.bytes:
                self.fail("no bytes", ("internal",), f"  the spec delivers {msg_text(h)}, which no driver emitted")
            self._owes(PC)
            out = self._ask(self.pc, "PC", {"type": "recv", "from": h["src"], "hex": self.bytes[h][-1].hex()})
            got = []
            self._collect(PC, out, None, got, emitted)
            self._took(PC, out)
            self._expect(got, ["MasterHandover"])
            self.rp.fig.handovers += 1
        elif n in ("RequestRelay", "ShareMembers"):
            node = la[1]
            self._owes(node)
            want = next(iter(set(s1["net"]) - set(s0["net"])), None)
            data = self._from_pool(node, n, want)
            if data is not None:
                emitted += [(node, x) for x in data]
            elif n == "ShareMembers":
                got = self._deliver(node, la[2], emitted, "ShareMembers")
                self._expect(got, ["ShareMembers"])
            else:
                self._wake(node, self.ag[node], n, emitted, node)
        elif n == "Heartbeat":
            node = la[1]
            self._owes(node)
            want = next(iter(set(s1["net"]) - set(s0["net"])), None)
            key = PC if node == PC else ("core", node)
            data = self._from_pool(key, n, want)
            if data is not None:
                emitted += [(key, x) for x in data]
            elif node == PC:
                self._wake(PC, self.pc, n, emitted, "PC")
            else:
                if node not in self.core:
                    self.fail(f"{node} is master in the spec; no Master core runs for it", ("core",), "")
                self._wake(key, self.core[node], n, emitted, f"{node}'s Master core")
        elif n == "StartElection":
            node = la[1]
            self._owes(node)
            if node == PC:
                self._wake(PC, self.pc, n, emitted, "PC")
            else:
                self._wake(node, self.ag[node], n, emitted, node)
        elif n == "BecomeMaster":
            node = la[1]
            if self.ahead.get(node) != ["BecomeMaster"]:
                self.fail(f"spec BecomeMaster, the implementation took {self.ahead.get(node) or 'nothing'} "
                          f"ahead", ("action",), "")
            del self.ahead[node]
            emitted += self.ahead_sent.pop(node, [])
            if node == PC:
                self.rp.fig.pc_elected += 1
            else:
                self._start_core(node, emitted)
                self.rp.fig.elected += 1
        elif n == "Crash":
            node = la[1]
            if node != PC:
                self.fail("agent crashes are not replayed (MCSystemSim: Crashes = FALSE)", ("internal",), "")
            el = self.el[PC]
            self.pc_saved.update(epoch=el["epoch"], members=el["members"], mepoch=el["mepoch"],
                                 msgid=self.pc_msgid)
            self.rp.close(self.pc)
            self.pc = None
            self.el[PC] = {"life": "DOWN", "epoch": el["epoch"], "votes": [], "members": el["members"],
                           "mepoch": el["mepoch"], "want": el["want"]}
        elif n == "Restart":
            node = la[1]
            if node != PC:
                self.fail("agent restarts are not replayed", ("internal",), "")
            self.pc = self.rp.driver("master")
            self._pc_config(True)
            self.el[PC] = self.last_out["PC"]["election"]
        elif n == "Ignore":
            # a datagram no rule of System takes: no step, nothing sent
            node, m = la[1], la[2]
            self._owes(node)
            got = self._deliver(node, m, emitted)
            if [x for x in got if x not in ("Ignore", "core:Ignore")]:
                self.fail(f"action: spec none (no rule takes {m['t']}), implementation {got}", ("action",), "")
        elif n in ("Refresh", "HandleHeartbeat", "HandleElect", "HandleVote", "HandleStale", "OfferRelay",
                   "AcceptRelay", "HandleAccept", "RelayDropped", "GrantPreVote", "HandlePreVote",
                   "LearnMembers"):
            node, m = la[1], la[2]
            self._owes(node)
            got = self._deliver(node, m, emitted)
            self._check_delivery(n, node, s0, got, emitted)
        else:
            self.fail(f"step {n} is not replayed (outside MCSystemSim's bounds)", ("internal",), "")
        self._stop_cores()
        self.match_emitted(s0, s1, emitted)
        self.compare()

    def _check_delivery(self, n: str, node, s0: dict, got: list, emitted: list) -> None:
        want = {"Refresh": [], "HandleHeartbeat": ["HandleHeartbeat"]}.get(n, [n])
        core = [x for x in got if x.startswith("core:")]
        own = [x for x in got if not x.startswith("core:")]
        if node != PC and at(s0["life"], node) == "MASTER":
            # the master node's part of the same step (master.hpp: HandleElect, HandleHeartbeat,
            # LearnMembers, HandleStale of an elected agent's Master core); whether it stepped down
            # is compared after the step ("master core")
            if core not in ([], [f"core:{n}"]):
                self.fail(f"action of {node}'s Master core: spec {n}, implementation {core}", ("action",), "")
        elif core:
            self.fail(f"{node}'s Master core took {core}; the spec has no step of it here", ("action",), "")
        if n == "Refresh" and own in ([], ["HandleHeartbeat"]):
            return
        if own[:len(want)] != want:
            self.fail(f"action: spec {want}, implementation {own}", ("action",), "")
        rest = own[len(want):]
        if rest == ["BecomeMaster"]:
            # the core won on this VOTE; the spec's next step is BecomeMaster (MCSystemSim Eager), whose
            # datagrams are those of the core's BecomeMaster
            self.ahead[node] = rest
            cut = self._split_last(node)
            self.ahead_sent[node] = cut
            for c in cut:
                emitted.remove(c)
        elif rest:
            self.fail(f"action: spec {want}, implementation {own}", ("action",), "")

    def _split_last(self, node) -> list:
        """The datagrams of the last action of @p node's last output (BecomeMaster's)."""
        out = self.last_out["PC" if node == PC else str(node)]
        per = split_sent(out)
        return [(node, bytes.fromhex(s["hex"])) for s in (per[-1] if per else [])]

    def _owes(self, node) -> None:
        if self.ahead.get(node):
            self.fail(f"the implementation took {self.ahead[node]} at {node}; the spec has not",
                      ("implementation ahead",), "")

    # -- comparison --
    def spec_node(self, s: dict, n) -> dict:
        def f(v):
            return at(s[v], n)
        if n == PC:
            out = {"life": f("life"), "epoch": f("epoch"), "votes": sorted(f("votes")),
                   "members": sorted(f("members")), "mepoch": f("mepoch"), "want": sorted(s["want"])}
            if out["life"] != "CANDIDATE":
                del out["votes"]     # read only by a candidate (HandleVoteOk, BecomeMasterOk)
            return out
        out = {k: f(k) for k in ("life", "epoch", "votedFor", "leader", "following", "via", "mepoch", "floor")}
        for k in ("votes", "relays", "offered", "prevotes", "members"):
            out[k] = sorted(f(k))
        if out["life"] != "CANDIDATE":
            del out["votes"]     # read only by a candidate (HandleVoteOk, BecomeMasterOk)
        if out["life"] in FOLLOWERS:
            out["silence"] = f("silence") * TICK
        out["master core"] = out["life"] == "MASTER"
        return out

    def impl_node(self, n) -> dict:
        el = self.el.get(n) or {}
        if n == PC:
            out = {k: el.get(k) for k in PC_FIELDS}
            out["want"] = el.get("want")
            for k in ("votes", "members", "want"):
                out[k] = sorted(out[k] or [])
            return out
        out = {k: el.get(k) for k in AGENT_FIELDS}
        for k in ("votes", "relays", "offered", "prevotes", "members"):
            out[k] = sorted(out[k] or [])
        if el.get("life") in FOLLOWERS:
            out["silence"] = self.silence.get(n)
        out["master core"] = n in self.core
        return out

    def diffs(self, s: dict) -> dict:
        d = {}
        for n in [PC] + self.agents:
            if self.ahead.get(n):
                continue
            sv, iv = self.spec_node(s, n), self.impl_node(n)
            ks = [k for k in sv if sv[k] != iv.get(k)]
            if ks:
                d[n] = ks
        return d

    def compare(self) -> None:
        d = self.diffs(self.states[self.k])
        if d:
            flds = tuple(sorted({f"{'PC' if n == PC else 'agent'}.{k}" for n, ks in d.items() for k in ks}))
            self.fail("state differs", flds, "")

    # -- reports --
    def key(self, k: int) -> str:
        return step_key(self.states[k]["lastAction"])

    def text(self, k: int) -> str:
        return step_text(self.states[k]["lastAction"])

    def counted(self, k: int) -> None:
        s0, s1 = self.states[k - 1], self.states[k]
        fig = self.rp.fig
        fig.handed += len(set(s1["hnet"]) - set(s0["hnet"]))
        la = s1["lastAction"]
        if len(la) > 2 and isinstance(la[2], dict) and "e" in la[2]:
            fig.late += la[2]["e"] < at(s0["epoch"], la[1])
            fig.again += (la[1], la[2]) in self.got_before
            self.got_before.add((la[1], la[2]))
        elif la[0] == "MasterHandover":
            fig.again += (PC, la[1]) in self.got_before
            self.got_before.add((PC, la[1]))

    def fail(self, what: str, fields: tuple, detail: str) -> None:
        s = self.states[self.k]
        lines = [self.where(), f"  {what}"]
        if detail:
            lines.append(detail)
        for n in [PC] + self.agents:
            sv, iv = self.spec_node(s, n), self.impl_node(n)
            lines.append(f"  {'PC' if n == PC else 'agent ' + str(n)} (spec | implementation):")
            for k in sv:
                mark = "!!" if sv[k] != iv.get(k) else "  "
                lines.append(f"   {mark} {k:12} {str(sv[k]):28} | {iv.get(k)}")
        s0 = self.states[self.k - 1] if self.k else s
        new = (set(s["net"]) - set(s0["net"])) | (set(s["hnet"]) - set(s0["hnet"]))
        lines.append("  spec emits: " + ("; ".join(msg_text(m) for m in new) or "-"))
        for node, out in self.last_out.items():
            lines.append(f"  {node}'s last driver output: {json.dumps(out)[:900]}")
        raise Mismatch(what, fields, "\n".join(lines + self.history()))


# --- the runner --------------------------------------------------------------------------------------

class SystemReplay(SimReplay):
    """New driver processes for every trace: the PC's, one per agent, one per elected agent's Master
    core (while it runs)."""

    MODULE = SIM_MODULE
    PREFIX = "system-sim"
    Trace = _Trace
    Figures = SystemFigures


def replay_simulation(seed: int, num: int, depth: int, agent_argv: list[str], master_argv: list[str],
                      cfg: str = SIM_CFG) -> SystemFigures:
    """Simulates MCSystemSim and replays its traces (SimReplay.replay_simulation)."""
    return SystemReplay(agent_argv, master_argv).replay_simulation(seed, num, depth, cfg)
