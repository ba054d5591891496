"""Mutation score of the conformance checks: seeded faults in the cores (libev3proto/include), each
applied to a COPY of the sources in build/mutate/src; ev3-agent / ev3-master are rebuilt there (one
ninja tree, -O0, so each mutant recompiles only what includes the patched header; for election mutants
also the transcript program, transcript_tests) and checked.

A mutant is found by structure, not by position: its site is a spec action (the handler X and its
guard XOk, wherever they are defined: the action's name is the rule, docs/core.md), a named function
("fn:name") or a state table ("table:kStays"); the site's text must contain the mutant's code exactly
once (compared with any whitespace between tokens). So a mutant follows its handler through a
restructuring (moved to another header, split into XOk / X, reformatted) and is reported "stale" only
when the code it breaks is gone from its site. The headers are the library's top level and its
election/ folder; agent and election mutants look in the agent side's (every header but master*.hpp
and election/master.hpp), master mutants in those.

Checks, stopping at the first that fails:
  agent mutants:    agent replay of MCAgent's state graph (stops at the first mismatch), one driver
                    trace (a fixed scenario, trace_script) validated by TLC, the election traces;
  election mutants: the election traces (election_scripts: driver runs with the election on, each
                    validated by TLC against AgentLogic composed with Election.tla's per-agent rules),
                    the fleet transcripts (tests/cpp/testdata/fleet_*.txt: several nodes over a
                    scripted network, where the environment one agent's trace cannot see is in
                    view, e.g. Election's HeartbeatOK), then the agent trace and the agent replay;
  master mutants:   master replay of MCMaster's state graph, strict (stops at the first mismatch).

A mutant is caught when a check fails naming what differs (a mismatch, a trace TLC rejects, a driver
that crashes or exits), survives when every check passes. A check that ends because the mutant did not
finish (the driver killed by its CPU limit, prlimit; a hung driver or transcript program) is no
verdict: the next check runs, and a mutant no check catches that timed out is reported as "timeout",
apart from the caught and the surviving, and counted against the score (not caught). One whose site
no longer holds its code exactly once is "stale" and not counted; one that leaves the binaries
byte-identical is "equivalent" and not counted.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

from ev3conformance import driver as drv
from ev3conformance import graph as gr
from ev3conformance import wire

INC = "libev3proto/include/ev3proto"


@dataclass(frozen=True)
class Mutant:
    name: str
    site: str      # a spec action ("RecvPause": its X and XOk), "fn:NAME" or "table:NAME"
    old: str       # code in the site, exactly once (tokens compared, whitespace between them free)
    new: str
    kind: str      # "agent", "election" or "master": which headers, which checks
    what: str


MUTANTS: tuple[Mutant, ...] = (
    # ---- agent core (AgentLogic)
    Mutant("A01-pause-from-active", "table:kTransitions",
           "{State::WORKING, State::PAUSED, Action::RecvPause},",
           "{State::WORKING, State::PAUSED, Action::RecvPause}, {State::ACTIVE, State::PAUSED, Action::RecvPause},",
           "agent", "a row added: PAUSE accepted in ACTIVE"),
    Mutant("A02-stop-wrong-next-state", "table:kTransitions", "{State::WORKING, State::ACTIVE, Action::RecvStop}",
           "{State::WORKING, State::PAUSED, Action::RecvStop}", "agent", "wrong next state: STOP -> PAUSED"),
    Mutant("A03-loss-timeout-off-by-one", "HeartbeatLost", "silence() >= cfg_.timers[t]",
           "silence() > cfg_.timers[t]", "agent", "off-by-one: heartbeat loss one tick late"),
    Mutant("A04-sync-timeout-off-by-one", "SyncTimeout", "silence() >= cfg_.timers[Timer::sync]",
           "silence() > cfg_.timers[Timer::sync]", "agent", "off-by-one: sync timeout one tick late"),
    Mutant("A05-no-dedupe", "fn:Fresh", "return !Seen(m) && !Stale(m);", "(void)m; return true;",
           "agent", "missing dedupe: every copy is fresh"),
    Mutant("A24-no-stale-check", "fn:Fresh", "return !Seen(m) && !Stale(m);", "return !Seen(m);",
           "agent", "a copy that outlived its window entry is fresh again (Stale left out)"),
    Mutant("A06-ack-wrong-msgid", "fn:Answer", "a.ref = m.msgid;", "a.ref = m.msgid + 1;", "agent",
           "wrong msgid in ACK/NOT (ref + 1)"),
    Mutant("A07-led-paused-green", "fn:led_of", "case State::PAUSED: return Led::ORANGE;",
           "case State::PAUSED: return Led::GREEN;", "agent", "wrong LED: PAUSED shows GREEN"),
    Mutant("A08-pong-ignored", "RecvPong", "{ hear(); }", "{}", "agent", "PONG ignored (silence not reset)"),
    Mutant("A09-refusal-reason", "RecvStart", "Refuse(m, Refusal::no_behaviour)", "Refuse(m, Refusal::wrong_state)",
           "agent", "wrong refusal reason: START without behaviour says wrong state"),
    Mutant("A10-unknown-behaviour-accepted", "RecvBehaviour", "b == nullptr || !BehaviourStore::fits(m)", "b == nullptr && !BehaviourStore::fits(m)",
           "agent", "dropped guard: unknown behaviour loaded when its args fit"),
    Mutant("A11-resume-motors-off", "RecvResume", "if (wait_ == Wait::NONE) motors_on(false);", "", "agent",
           "RESUME leaves the motors off"),
    Mutant("A12-heartbeat-period", "fn:Tick", "timers_.get(AgentTimer::periodic) + cfg_.timers[Timer::heartbeat]",
           "timers_.get(AgentTimer::periodic) + cfg_.timers[Timer::heartbeat] + 1", "agent",
           "off-by-one: heartbeat period one tick long"),
    Mutant("A13-loss-working-panics", "table:kTransitions", "{State::WORKING, State::PAUSED, Action::HeartbeatLost}",
           "{State::WORKING, State::PANIC, Action::HeartbeatLost}", "agent",
           "wrong next state: lost master in WORKING -> PANIC (not PAUSED)"),
    Mutant("A14-master-ref-unchecked", "RecvMaster", "ref_of(m) == id_ &&", "", "agent",
           "dropped guard: MASTER for another temporary id taken"),
    Mutant("A15-duplicate-not-answered", "RecvDuplicate", "if (a != nullptr) send_answer(*a);", "(void)a;", "agent",
           "duplicate command not answered again"),
    Mutant("A16-paused-timeout-is-loss", "fn:lifecycle_timer", "case State::PAUSED: t = Timer::paused;",
           "case State::PAUSED: t = Timer::loss;", "agent", "wrong timer: PAUSED uses the loss timeout"),
    Mutant("A17-continue-without-interruption", "table:kStays",
           "{State::WORKING, State::WORKING, Action::RecvContinue, only(Wait::CONTINUE)}",
           "{State::WORKING, State::WORKING, Action::RecvContinue}", "agent",
           "a row widened: CONTINUE without an interrupted action"),
    Mutant("A18-answer-keeps-silence", "fn:Answer", "hear();", "", "agent",
           "an answered command does not reset the silence"),
    Mutant("A19-failed-waits-continue", "ActionFailed", "wait_ = Wait::RESTART;", "wait_ = Wait::CONTINUE;", "agent",
           "wrong wait after ACTION_ERR (CONTINUE, not RESTART)"),
    Mutant("A20-action-ok-no-step", "ActionOk", "++step_;", "", "agent", "ACTION_OK does not advance the step"),
    Mutant("A21-missing-device-ignored", "RecvBehaviour", "!dev_ok() ||", "", "agent",
           "dropped half of a guard: the model's other devices are not required"),
    Mutant("A22-table-guard-dropped", "fn:ObeyCommand", "if (!next) return Refuse(m, Refusal::wrong_state);", "",
           "agent", "the state table no longer refuses: every command accepted in every state"),
    Mutant("A23-start-in-working-refused", "table:kStays", "{State::WORKING, State::WORKING, Action::RecvStart},", "",
           "agent", "a row dropped: START while WORKING refused (it restarts the behaviour)"),
    # ---- relay and election (Election.tla), agent side
    Mutant("E01-double-vote", "fn:ElectGrant", "voted_for == 0 || voted_for == candidate", "true", "election",
           "a second vote in one epoch (Election BUG DoubleVote)"),
    Mutant("E02-no-epoch-check", "fn:Take", "if (e != 0 && e < epoch) v.stale = true;", "", "election",
           "an older ELECT / LEADER taken as current (Election BUG NoEpochCheck)"),
    Mutant("E03-no-fencing", "fn:Obeys", "return leader == sender && following == e && e == epoch;",
           "(void)sender; (void)e; return true;", "election",
           "a command of any master applied (Election BUG NoFencing)"),
    Mutant("E04-minority-quorum", "BecomeMaster", "QuorumOf(votes, members, 0)", "votes.size() > 0",
           "election", "master with a minority of votes (Election BUG MinorityQuorum)"),
    Mutant("E05-no-pre-vote", "fn:PreVoteQuorum", "QuorumOf(prevotes, members, me)", "me != 0", "election",
           "stands without the pre-votes of a majority (Election PreVote = FALSE)"),
    Mutant("E06-keep-table-on-panic", "fn:unfollow", "drop_relays(n);", "", "election",
           "the relay table kept when the master is lost (Election BUG KeepTableOnPanic)"),
    Mutant("E07-offer-while-relayed", "fn:DirectFollower", "via == 0", "true", "election",
           "a relayed agent offers to relay (Election BUG OfferWhileRelayed)"),
    Mutant("E08-newer-epoch-keeps-vote", "fn:NewerEpoch", "voted_for = 0;", "", "election",
           "a newer epoch adopted with the old epoch's vote"),
    Mutant("E09-master-does-not-step-down", "fn:SteppedDown", "if (role != ElectionRole::none) become_masterless(me);", "",
           "election", "a master or candidate keeps its role in a newer epoch"),
    Mutant("E10-older-offer-accepted", "AcceptRelay", "*e >= epoch &&", "", "election",
           "a relay offer of an older epoch taken"),
    Mutant("E11-vote-counted-twice", "HandleVote", "!votes.contains(m.sender) &&", "", "election",
           "a copy of a VOTE counted again"),
    Mutant("E12-pre-vote-to-stronger", "GrantPreVote", "*sc <= me.score", "sc.has_value()", "election",
           "a pre-vote granted to a stronger asker"),
    Mutant("E13-pre-vote-counted-twice", "HandlePreVote", "!prevotes.contains(m.sender) &&", "", "election",
           "a copy of a PREVOTE_OK counted again"),
    Mutant("E14-relays-kept-on-master-change", "HandleHeartbeat", "drop_relays(n);", "", "election",
           "the relay table kept when the master changes"),
    Mutant("E15-newer-epoch-not-adopted", "fn:NewerEpoch", "epoch = e;", "(void)e;", "election",
           "a newer epoch not adopted (the agent steps down but stays in its epoch)"),
    Mutant("E16-relay-drop-from-anyone", "RelayDropped", "m.sender == via &&", "", "election",
           "a RELAY_DROP from an agent that is not our relay obeyed"),
    Mutant("E17-healthy-follower-votes", "HandleElect", "if (me.hears_master && m.sender != kMasterId) return false;",
           "", "election", "a follower that still hears its master votes (disrupts it)"),
    Mutant("E18-working-not-paused-on-newer-epoch", "fn:step_down",
           "Goto(next_state(state_, by).to); motors_pause();", "", "election",
           "a WORKING agent that learns a newer epoch keeps working"),
    Mutant("E19-candidate-accepts-relay", "AcceptRelay", "role == ElectionRole::none", "true", "election",
           "a candidate takes a relay offer"),
    Mutant("E20-forward-for-anyone", "Forward", "return relays.find(*target) != nullptr;", "return true;",
           "election", "a relay forwards to an agent it does not relay for"),
    # ---- master core (MasterLogic), as master.hpp has it on main: handler names, XOk when split
    Mutant("M01-no-resend", "MasterTick", "send_pending(e);", "", "master", "master not resending the pending datagram"),
    Mutant("M02-id-reused", "MasterSync", "nid = next_id_++;", "nid = next_id_;", "master", "master reusing agent ids"),
    Mutant("M03-msgid-reused", "fn:start_next", "e.mid = msgid_++;", "e.mid = msgid_;", "master",
           "master reusing msgids for commands"),
    Mutant("M04-answer-ref-unchecked", "MasterAnswer", "!e.pending || !ref || *ref != e.mid", "!e.pending || !ref",
           "master", "dropped guard: an ACK of any msgid answers"),
    Mutant("M05-pong-wrong-ref", "MasterPing", "decimal(m.msgid, num)", "decimal(m.msgid + 1, num)", "master",
           "wrong msgid in PONG's ref"),
    Mutant("M06-drop-off-by-one", "MasterTick", "now_ - e.heard >= cfg_.timers[Timer::drop]",
           "now_ - e.heard > cfg_.timers[Timer::drop]", "master", "off-by-one: drop one tick late"),
    Mutant("M07-max-resends-off-by-one", "MasterTick", "e.resends >= cfg_.max_resends", "e.resends > cfg_.max_resends",
           "master", "off-by-one: one resend too many"),
    Mutant("M08-ping-not-heard", "MasterPing", "e.heard = now_;", "", "master",
           "PING does not refresh the agent (dropped while pinging)"),
    Mutant("M09-not-answers-master", "MasterAnswer", "if (!e.synced && !ack) return;", "", "master",
           "dropped guard: a NOT answers MASTER"),
    Mutant("M10-panic-resync-unordered", "MasterSync", "s == e.id && msgid_newer(m.msgid, e.last_msgid)", "s == e.id", "master",
           "dropped guard: an old PANIC copy re-syncs a synced agent"),
)


# ---- finding a mutant's site by structure

_QUALIFIERS = re.compile(r"\s*(?:(?:const|noexcept|override|final)\b\s*)*(?:->\s*[\w:<>,\s]+?)?\{")


def _skip_literal(text: str, i: int) -> int:
    """Index after the string / char literal or comment starting at i (else i)."""
    if text.startswith("//", i):
        j = text.find("\n", i)
        return len(text) if j < 0 else j
    if text.startswith("/*", i):
        j = text.find("*/", i + 2)
        return len(text) if j < 0 else j + 2
    if text[i] in "\"'":
        q, j = text[i], i + 1
        while j < len(text) and text[j] != q:
            j += 2 if text[j] == "\\" else 1
        return j + 1
    return i


def _matching(text: str, i: int, open_: str, close: str) -> int:
    """Index of the bracket closing the one at i (literals and comments skipped); -1 if none."""
    depth = 0
    while i < len(text):
        j = _skip_literal(text, i)
        if j != i:
            i = j
            continue
        if text[i] == open_:
            depth += 1
        elif text[i] == close:
            depth -= 1
            if depth == 0:
                return i
        i += 1
    return -1


def definitions(text: str, name: str) -> list[tuple[int, int]]:
    """(start, end) of each definition of function @name in @text: `name(...) [qualifiers] { ... }`
    (calls are followed by something else than a body)."""
    out = []
    for m in re.finditer(r"(?<![\w.>])" + re.escape(name) + r"\s*\(", text):
        close = _matching(text, m.end() - 1, "(", ")")
        if close < 0:
            continue
        q = _QUALIFIERS.match(text, close + 1)
        if not q:
            continue
        end = _matching(text, q.end() - 1, "{", "}")
        if end > 0:
            out.append((m.start(), end + 1))
    return out


def table(text: str, name: str) -> list[tuple[int, int]]:
    """(start, end) of the array initializer `name[] = { ... }`."""
    out = []
    for m in re.finditer(re.escape(name) + r"\s*\[\s*\]\s*=\s*\{", text):
        end = _matching(text, m.end() - 1, "{", "}")
        if end > 0:
            out.append((m.start(), end + 1))
    return out


def site_ranges(texts: dict[str, str], site: str) -> list[tuple[str, int, int, str]]:
    """Every (header, start, end, label) of @site in the headers @texts."""
    out = []
    if site.startswith("table:"):
        names, finder = [site[6:]], table
    elif site.startswith("fn:"):
        names, finder = [site[3:]], definitions
    else:  # a spec action: its handler and its guard
        names, finder = [site, site + "Ok"], definitions
    for f, text in sorted(texts.items()):
        for n in names:
            out += [(f, a, b, n) for a, b in finder(text, n)]
    return out


def _pattern(code: str) -> re.Pattern:
    return re.compile(r"\s*".join(re.escape(t) for t in code.split()))


def locate(texts: dict[str, str], m: Mutant) -> tuple[str, int, int, str] | str:
    """(header, start, end, where) of the one occurrence of m.old in its site; else why not."""
    ranges = site_ranges(texts, m.site)
    if not ranges:
        return f"site {m.site} not found"
    pat = _pattern(m.old)
    hits = []
    for f, a, b, n in ranges:
        hits += [(f, a + h.start(), a + h.end(), f"{n} in {f}") for h in pat.finditer(texts[f][a:b])]
    if len(hits) != 1:
        return f"{m.old!r} found {len(hits)} times in {m.site} ({', '.join(sorted({r[3] for r in ranges}))})"
    return hits[0]


def library_headers(inc: Path) -> dict[str, str]:
    """The headers mutants are sited in (the library's top level and election/), by their path under
    @p inc (libev3proto/include/ev3proto)."""
    return {p.relative_to(inc).as_posix(): p.read_text() for p in [*inc.glob("*.hpp"), *inc.glob("election/*.hpp")]}


def headers_for(kind: str, headers: dict[str, str]) -> dict[str, str]:
    master = {f: t for f, t in headers.items() if f.rsplit("/", 1)[-1].startswith("master")}
    return master if kind == "master" else {f: t for f, t in headers.items() if f not in master}


# The fixed scenario of the validated trace (agent mutants): timers and constants for tracecheck.
TRACE_TIMERS = {"sync": 5, "heartbeat": 2, "loss": 3, "paused": 6}
TRACE_CONSTS = {"TSync": 5, "TPing": 2, "TLoss": 3, "TPaused": 6}


def _m(mid: int, type_: str, ref: int = 0, args: tuple = (), dst: int = 7, src: int = 1) -> dict:
    m = {"src": src, "dst": dst, "msgid": mid, "type": type_, "ref": ref, "args": args}
    return {"type": "recv", "from": 100 + src, "text": drv.spec_to_wire(m).decode("latin-1")}


def trace_script() -> list[dict]:
    ev = lambda e, **kw: dict({"type": "event", "event": e}, **kw)  # noqa: E731
    adv = lambda ms: {"type": "advance", "ms": ms}  # noqa: E731
    return [
        # Two devices (mask 3); "wait" needs device 1 only: unplugging device 2 must still refuse
        # BEHAVIOUR (devOk: every device of the model), which MCAgent (one device) cannot show.
        {"type": "config", "timers": TRACE_TIMERS, "behaviours": [{"name": "wait", "devices": 1}],
         "devices": 3, "temp_id": 50001},
        adv(1), _m(1, "MASTER", 50001, dst=7), _m(1, "MASTER", 50001, dst=7), adv(2), _m(2, "PONG", 3),
        _m(3, "START"), _m(4, "BEHAVIOUR", args=("dance",)), _m(5, "BEHAVIOUR", args=("wait",)),
        _m(6, "START"), _m(6, "START"), adv(1), ev("action_ok"), ev("sensor_report", port="1", mode="m", values=["4"]),
        _m(7, "PAUSE"), _m(8, "PAUSE"), _m(9, "RESUME"), ev("action_interrupted", warning="OBSTACLE_DETECTED"),
        _m(10, "CONTINUE"), _m(11, "CONTINUE"), ev("action_failed"), _m(12, "RESTART"), adv(2),
        _m(13, "PONG", 4), _m(14, "STANDBY"), _m(15, "STOP"), _m(16, "START"), _m(17, "STOP"),
        ev("robot_event", name="OBSTACLE_DETECTED", port="in1"),
        ev("device_unplugged", devices=2, port="in4"), ev("robot_event", name="DEVICE_DISCONNECTED", port="in2"),
        _m(18, "BEHAVIOUR", args=("wait",)), _m(19, "START"),
        ev("device_plugged", devices=2, port="in4"), ev("robot_event", name="DEVICE_CONNECTED", port="in2"),
        _m(20, "BEHAVIOUR", args=("wait",)), _m(21, "START"),
        ev("battery_low"), adv(3), adv(2), _m(22, "RESUME"), adv(5), adv(2), adv(3),
        _m(23, "MASTER", 7, dst=8), _m(24, "START", dst=8), _m(25, "BEHAVIOUR", args=("wait",), dst=8),
        _m(26, "START", dst=8), adv(1), _m(27, "PAUSE", dst=8), adv(6), adv(1), adv(10),
    ]


# ---- the election scenarios (election mutants): driver runs with the election on, validated by TLC

# vouch 0: the relay's timing rules off (the spec has no clock for them); leader_heartbeat as the
# scenarios were written with.
ELECTION_TIMERS = {"sync": 1000, "heartbeat": 100, "loss": 300, "paused": 600, "relay_retry": 100,
                   "backoff": 300, "backoff_step": 10, "candidate": 200, "leader_heartbeat": 1000, "vouch": 0}
ELECTION_CONSTS = {"TSync": 1000, "TPing": 100, "TLoss": 300, "TPaused": 600, "Score": 5, "Epoch": 1,
                   "VotedFor": 0}

_DGRAM = re.compile(r"\s*(\d+)->(\d+)\s+(\w+)\s+#(\d+)")


def datagram(text: str) -> bytes:
    """The bytes of a datagram written as the transcripts write it: `1->7 EPOCH_CMD #3 3 [1->7 START #3]`
    (sender->receiver TYPE #msgid params; a datagram inside a param in brackets)."""
    pos = 0

    def one() -> bytes:
        nonlocal pos
        m = _DGRAM.match(text, pos)
        if not m:
            raise ValueError(f"not a datagram at {text[pos:]!r}")
        pos = m.end()
        params = []
        while True:
            while pos < len(text) and text[pos] == " ":
                pos += 1
            if pos >= len(text) or text[pos] == "]":
                break
            if text[pos] == "[":
                pos += 1
                params.append(one())
                pos += 1  # ]
            else:
                end = pos
                while end < len(text) and text[end] not in " ]":
                    end += 1
                params.append(text[pos:end].encode())
                pos = end
        return wire.encode(wire.Message(int(m[1]), int(m[2]), int(m[4]), wire.TYPES_BY_NAME[m[3]].number,
                                        tuple(params)))

    return one()


def election_scripts() -> dict[str, list[dict]]:
    """Scenarios of one agent (score 5, temporary id 50001) among the PC (peer 1) and agents 8, 9,
    10 (peers of the same number). Each is validated alone (a trace starts at Init)."""
    def rx(text: str) -> dict:
        return {"type": "recv", "from": int(text.split("->")[0]), "text": datagram(text).decode("latin-1")}

    def via(peer: int, text: str) -> dict:  # a datagram forwarded by relay @peer
        return {"type": "recv", "from": peer, "text": datagram(text).decode("latin-1")}

    adv = lambda ms: {"type": "advance", "ms": ms}  # noqa: E731
    cfg = {"type": "config", "timers": ELECTION_TIMERS, "behaviours": [{"name": "wait", "devices": 0}],
           "temp_id": 50001, "election": {"enabled": True, "score": 5}}
    synced = [cfg, adv(100), rx("1->7 MASTER #20 50001"), rx("1->0 LEADER #21 1 1 7 8 9")]
    return {
        # A relay, the master lost, pre-votes, elected, stepped down by a newer ELECT, one vote per
        # epoch, a new master followed, fenced and stale commands, a newer epoch while WORKING.
        "relay-elect-fence": synced + [
            rx("9->0 RELAY_REQ #5 1 30"), rx("9->7 RELAY_ACCEPT #6 1 1"),
            rx("1->7 RELAY #30 9 [1->9 PONG #31 5]"), rx("1->7 RELAY #32 8 [1->8 PONG #33 4]"),
            rx("9->7 RELAY #7 1 [9->1 PING #7 ACTIVE]"), rx("9->7 RELAY #8 1 [8->1 PING #8 ACTIVE]"),
            rx("8->0 ELECT #3 2 1 0"), rx("8->0 RELAY_REQ #4 2 1"),
            adv(300),                                      # PANIC: RELAY_DROP to 9, RELAY_REQ
            rx("9->0 RELAY_REQ #9 1 30"), rx("8->0 RELAY_REQ #5 1 3"),
            rx("8->7 PREVOTE_OK #6 1"), rx("8->7 PREVOTE_OK #6 1"),
            adv(400),                                      # stands in epoch 2
            rx("9->7 VOTE #10 2 7"), rx("8->7 VOTE #7 2 7"), rx("9->0 ELECT #11 2 9 0"), adv(50),
            rx("8->0 ELECT #8 3 4 0"), rx("9->0 ELECT #12 3 2 0"),
            rx("8->0 LEADER #9 3 8 7 8 9"), rx("1->0 LEADER #40 1 1 7 8 9"),
            rx("8->7 EPOCH_CMD #10 3 [8->7 START #10]"), rx("8->7 EPOCH_CMD #11 3 [8->7 BEHAVIOUR #11 wait]"),
            rx("8->7 EPOCH_CMD #12 3 [8->7 START #12]"), rx("9->7 EPOCH_CMD #13 3 [9->7 STOP #13]"),
            rx("1->7 STOP #41"), rx("1->7 EPOCH_CMD #42 2 [1->7 STOP #42]"),
            rx("8->7 EPOCH_CMD #12 3 [8->7 START #12]"), adv(50),
            rx("9->7 EPOCH_STALE #14 5"), rx("9->0 LEADER #15 5 9 7 8 9"),
            rx("9->7 EPOCH_CMD #16 5 [9->7 RESUME #16]"), adv(100),
        ],
        # Relayed: an older offer refused, a newer one taken; commands through the relay; no offer
        # while relayed; a RELAY_DROP from a stranger ignored, from the relay obeyed; relayed again,
        # then the master heard directly.
        "relayed": synced + [
            adv(400), rx("9->7 EPOCH_STALE #1 2"), rx("8->7 RELAY_OFFER #3 1 1"), rx("8->7 RELAY_OFFER #4 2 9"),
            adv(100), via(8, "9->7 PONG #20 9"), via(8, "9->7 EPOCH_CMD #21 2 [9->7 BEHAVIOUR #21 wait]"),
            rx("10->0 RELAY_REQ #2 2 30"), rx("9->7 RELAY_DROP #22 2"), rx("8->7 RELAY_DROP #6 2"),
            rx("8->7 RELAY_OFFER #7 2 9"), rx("9->0 LEADER #23 2 9 7 8 9"), adv(100),
            adv(900),                                      # PANIC without pre-votes: must not stand
        ],
        # The master changes (same epoch) while WORKING with a relay table: paused, table dropped.
        "master-change": synced + [
            rx("9->0 RELAY_REQ #5 1 30"), rx("9->7 RELAY_ACCEPT #6 1 1"),
            rx("1->7 BEHAVIOUR #22 wait"), rx("1->7 START #23"), rx("8->0 LEADER #5 1 8 7 8 9"), adv(100),
        ],
        # A candidate among five: a second PREVOTE_OK of a peer (another msgid, so no copy window can
        # hide it) is not counted, a VOTE copy and a stranger's VOTE do not count, a relay offer is
        # not for a candidate; the third vote wins.
        "candidate": [cfg, adv(100), rx("1->7 MASTER #20 50001"), rx("1->0 LEADER #21 1 1 7 8 9 10 11"),
                      adv(300), rx("8->7 PREVOTE_OK #2 1"), rx("8->7 PREVOTE_OK #4 1"),
                      rx("9->7 PREVOTE_OK #2 1"), adv(400),
                      rx("8->7 VOTE #3 2 7"), rx("8->7 VOTE #3 2 7"), rx("12->7 VOTE #1 2 7"),
                      rx("10->7 RELAY_OFFER #3 2 9"), rx("9->7 VOTE #3 2 7"), adv(100)],
    }


@dataclass
class Outcome:
    mutant: Mutant
    status: str  # caught / survived / timeout / stale / equivalent / build-failed
    by: str = ""
    seconds: float = 0.0
    detail: str = ""


class Workspace:
    """A copy of the sources (build/mutate/src) and one ninja tree (build/mutate/build): the library,
    cmake/, behaviours/ (the built-in behaviours cmake embeds) and every top-level directory the top
    CMakeLists.txt adds (so a new program directory does not break the copy); ev3-agent and
    ev3-master are built, and the transcript program for election mutants."""

    BASE_DIRS = ("behaviours", "cmake", "libev3proto")

    def __init__(self, root: Path, base: Path) -> None:
        self.root, self.base = root, base
        self.src, self.bld = base / "src", base / "build"
        self.bin = self.bld / "bin"

    def prepare(self) -> None:
        for d in (self.src, self.bld):  # a fresh tree: copied mtimes must not fool ninja
            if d.exists():
                shutil.rmtree(d)
        self.src.mkdir(parents=True)
        top = (self.root / "CMakeLists.txt").read_text()
        added = {a.split("/")[0] for a in re.findall(r"add_subdirectory\(\s*([\w./-]+)", top)}
        for d in sorted(set(self.BASE_DIRS) | added):
            if (self.root / d).is_dir():  # symlinks as links: the ev3dev test trees loop
                shutil.copytree(self.root / d, self.src / d, symlinks=True)
        # A mutant may leave a parameter unused: warnings stay on, but not as errors, in the copy.
        (self.src / "CMakeLists.txt").write_text(top.replace(" -Werror", ""))
        inc = self.src / INC
        self.pristine = library_headers(inc)
        cmd = ["cmake", "-S", str(self.src), "-B", str(self.bld), "-G", "Ninja", "-DEV3_TESTS=ON",
               "-DCMAKE_BUILD_TYPE=Debug", "-DCMAKE_CXX_FLAGS_DEBUG=-O0",
               f"-DCMAKE_RUNTIME_OUTPUT_DIRECTORY={self.bin}"]
        p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        if p.returncode:
            raise RuntimeError(f"cmake failed:\n{p.stdout[-3000:]}")

    def restore(self) -> None:
        for name, text in self.pristine.items():
            f = self.src / INC / name
            if f.read_text() != text:
                f.write_text(text)

    def apply(self, m: Mutant) -> str:
        """Patches the copy; returns where (a function or table and its header), or why not ("stale: ...")."""
        self.restore()
        at = locate(headers_for(m.kind, self.pristine), m)
        if isinstance(at, str):
            return "stale: " + at
        f, a, b, where = at
        text = self.pristine[f]
        (self.src / INC / f).write_text(text[:a] + m.new + text[b:])
        return where

    PROGRAMS = ("ev3-agent", "ev3-master")
    TRANSCRIPTS = "transcript_tests"

    def build(self, jobs: int, kinds: set[str]) -> tuple[bool, str]:
        """ev3-agent, ev3-master and, when an election mutant is among @kinds, the transcripts."""
        extra = [self.TRANSCRIPTS] if "election" in kinds else []
        p = subprocess.run(["ninja", "-C", str(self.bld), f"-j{jobs}", *self.PROGRAMS, *extra],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        return p.returncode == 0, p.stdout[-3000:]

    def digest(self) -> dict:
        return {n: hashlib.sha256((self.bin / n).read_bytes()).hexdigest() for n in self.PROGRAMS}


class Checks:
    """The checks, with the state graphs dumped by TLC once."""

    def __init__(self, bin_dir: Path, limit: float, sample: int = 1) -> None:
        self.bin, self.limit, self.sample = bin_dir, limit, sample
        self.ag = self.ms = None
        self.ag_cache: dict = {}
        self.ms_cache: dict = {}

    def load(self, kinds: set[str]) -> dict:
        figs = {}
        if "agent" in kinds:
            self.ag, f = gr.dump_graph("MCAgent.tla", "MCAgent.cfg", "mutate-agent")
            self.agc = gr.cfg_constants("MCAgent.tla", "MCAgent.cfg")
            figs["agent"] = f
        if "master" in kinds:
            self.ms, f = gr.dump_graph("MCMaster.tla", "MCMaster.cfg", "mutate-master")
            self.msc = gr.cfg_constants("MCMaster.tla", "MCMaster.cfg")
            figs["master"] = f
        return figs

    def argv(self, prog: str) -> list[str]:
        # A looping mutant is killed by the CPU limit (prlimit execs the driver: same process, so
        # the replay's kill reaches the driver itself): its EOF is no verdict (drv.DriverKilled).
        return ["prlimit", f"--cpu={int(self.limit)}", str(self.bin / prog), "--driver"]

    # Each check returns (verdict, what): True passed, False failed (the mutant caught), None no
    # verdict (timed out).
    def agent_replay(self) -> tuple[bool | None, str]:
        from ev3conformance import replay
        try:
            f = replay.AgentReplay(self.ag, self.agc, self.argv("ev3-agent"), cache=self.ag_cache,
                                   sample=self.sample).run()
        except replay.Mismatch as m:
            return False, m.report.splitlines()[0]
        except drv.DriverKilled as e:
            return None, f"driver killed (CPU limit): {str(e).splitlines()[0]}"
        except drv.DriverError as e:
            return False, f"driver failed: {str(e).splitlines()[0]}"
        return True, f"{f.replayed} edges matched"

    def master_replay(self) -> tuple[bool | None, str]:
        from ev3conformance import master_replay as mr
        try:
            f = mr.MasterReplay(self.ms, self.msc, self.argv("ev3-master"), (),
                                stop_first=True, cache=self.ms_cache).run()
        except drv.DriverKilled as e:
            return None, f"driver killed (CPU limit): {str(e).splitlines()[0]}"
        except (drv.DriverError, RuntimeError) as e:
            return False, f"driver failed: {str(e).splitlines()[0]}"
        if f.classes:
            (act, flds), (n, _) = next(iter(f.classes.items()))
            return False, f"MISMATCH (master): {act} differs in [{', '.join(flds)}]"
        return True, f"{f.matched} edges matched"

    def agent_trace(self, work: Path) -> tuple[bool | None, str]:
        from ev3conformance import tracecheck
        work.mkdir(parents=True, exist_ok=True)
        trace = work / "agent.ndjson"
        trace.unlink(missing_ok=True)
        inp = "\n".join(json.dumps(i) for i in trace_script()) + "\n"
        try:
            p = subprocess.run(self.argv("ev3-agent") + ["--trace", str(trace)], input=inp, text=True,
                               capture_output=True, timeout=10 * self.limit)
        except subprocess.TimeoutExpired:
            return None, "driver hung on the trace scenario"
        if p.returncode in drv.KILLED:
            return None, f"driver killed (signal {-p.returncode}: CPU limit) on the trace scenario"
        if p.returncode != 0 or not trace.exists():
            return False, f"driver exit {p.returncode} on the trace scenario"
        r = tracecheck.validate(trace, TRACE_CONSTS, workdir=work)
        return r.ok, r.message.splitlines()[0]


    def election_traces(self, work: Path) -> tuple[bool | None, str]:
        """Each election scenario through the driver (--trace), each trace validated by TLC."""
        from ev3conformance import tracecheck
        work.mkdir(parents=True, exist_ok=True)
        n = 0
        for name, script in election_scripts().items():
            trace = work / f"{name}.ndjson"
            trace.unlink(missing_ok=True)
            inp = "\n".join(json.dumps(i) for i in script) + "\n"
            try:
                p = subprocess.run(self.argv("ev3-agent") + ["--trace", str(trace)], input=inp, text=True,
                                   capture_output=True, timeout=10 * self.limit)
            except subprocess.TimeoutExpired:
                return None, f"driver hung on the election scenario {name}"
            if p.returncode in drv.KILLED:
                return None, f"driver killed (signal {-p.returncode}: CPU limit) on the election scenario {name}"
            if p.returncode != 0 or not trace.exists():
                return False, f"driver exit {p.returncode} on the election scenario {name}"
            r = tracecheck.validate(trace, ELECTION_CONSTS, workdir=work)
            if not r.ok:
                return False, f"{name}: {r.message.splitlines()[0]}"
            n += r.records
        return True, f"{len(election_scripts())} election traces, {n} records matched"

    def fleet_transcripts(self) -> tuple[bool | None, str]:
        """The fleet transcripts (tests/cpp/testdata/fleet_*.txt) of the mutant's transcript program:
        several nodes (node.hpp: the agent core and its Master core) and the PC over a scripted
        network, each datagram and action compared with the file."""
        env = {k: v for k, v in os.environ.items() if k != "EV3_REWRITE"}  # check, never rewrite
        try:
            p = subprocess.run(["prlimit", f"--cpu={int(self.limit)}", str(self.bin / Workspace.TRANSCRIPTS),
                                "--gtest_filter=*FleetTranscript*", "--gtest_brief=1"], env=env, text=True,
                               capture_output=True, timeout=10 * self.limit)
        except subprocess.TimeoutExpired:
            return None, "the fleet transcripts hung"
        if p.returncode in drv.KILLED:
            return None, f"the fleet transcripts killed (signal {-p.returncode}: CPU limit)"
        if p.returncode != 0:
            failed = sorted(set(re.findall(r"\[  FAILED  \] \S*FleetTranscript\.Matches/(\w+)", p.stdout)))
            case = re.search(r"(fleet_\w+\.txt:\d+)", p.stdout)
            return False, (f"{', '.join(failed) or 'exit ' + str(p.returncode)} differs"
                           + (f" (the case at {case[1]})" if case else ""))
        n = re.search(r"\[  PASSED  \] (\d+) test", p.stdout)
        if not n or int(n[1]) < 1:
            return False, "no fleet transcript ran"
        return True, f"{n[1]} fleet transcripts matched"

    def for_kind(self, kind: str, work: Path) -> list[tuple[str, object]]:
        """The checks of a mutant of @kind, the likeliest to fail first."""
        replay = ("agent replay", self.agent_replay)
        trace = ("agent trace", lambda: self.agent_trace(work / "trace"))
        election = ("election traces", lambda: self.election_traces(work / "election"))
        fleet = ("fleet transcripts", self.fleet_transcripts)
        if kind == "agent":
            return [replay, trace, election]
        if kind == "election":
            return [election, fleet, trace, replay]
        return [("master replay", self.master_replay)]


def run(root: Path, names: list[str] | None = None, jobs: int = 2, limit: float = 120.0,
        log=print, sample: int = 1) -> list[Outcome]:
    base = gr.BUILD.parent / "mutate"
    ws = Workspace(root, base)
    chosen = [m for m in MUTANTS if not names or any(m.name.startswith(n) for n in names)]
    t0 = time.monotonic()
    ws.prepare()
    kinds = {m.kind for m in chosen}
    ok, out = ws.build(jobs, kinds)
    if not ok:
        raise RuntimeError(f"the unmutated copy does not build (retry when the tree builds):\n{out}")
    base_digest = ws.digest()
    log(f"mutate: workspace {base} built in {time.monotonic() - t0:.0f}s")
    ck = Checks(ws.bin, limit, sample)
    t1 = time.monotonic()
    figs = ck.load({"agent" if k == "election" else k for k in kinds})
    log(f"mutate: state graphs dumped in {time.monotonic() - t1:.0f}s "
        + " ".join(f"{k}: {v.get('distinct')} states" for k, v in figs.items()))
    # The unmutated build must pass every check it is used for (else a "caught" means nothing).
    t2 = time.monotonic()
    base_checks = {}
    for k in sorted(kinds):
        base_checks.update(dict(ck.for_kind(k, base)))
    for label, fn in base_checks.items():
        good, msg = fn()
        if not good:
            raise RuntimeError(f"the unmutated build fails the {label}: {msg}")
        log(f"mutate: baseline {label}: {msg}")
    log(f"mutate: baseline checks {time.monotonic() - t2:.0f}s")
    res: list[Outcome] = []
    try:
        for m in chosen:
            s = time.monotonic()
            where = ws.apply(m)
            if where.startswith("stale: "):
                res.append(Outcome(m, "stale", detail=where[7:]))
                log(f"  {m.name:36} STALE ({where[7:]})")
                continue
            ok, out = ws.build(jobs, {m.kind})
            if not ok:
                res.append(Outcome(m, "build-failed", detail=out[-500:], seconds=time.monotonic() - s))
                log(f"  {m.name:36} BUILD FAILED")
                continue
            if ws.digest() == base_digest:
                res.append(Outcome(m, "equivalent", detail="binary unchanged", seconds=time.monotonic() - s))
                log(f"  {m.name:36} EQUIVALENT (binaries unchanged)")
                continue
            tb = time.monotonic() - s
            checks = ck.for_kind(m.kind, base)
            o = Outcome(m, "survived")
            for label, fn in checks:
                good, msg = fn()
                if good is False:
                    o.status, o.by, o.detail = "caught", label, msg
                    break
                if good is None:  # no verdict: the next check may still name what differs
                    o.status, o.by = "timeout", label
                o.detail = (o.detail + "; " if o.detail else "") + f"{label}: {msg}"
            o.seconds = time.monotonic() - s
            res.append(o)
            log(f"  {m.name:36} {o.status.upper():8} {o.seconds:5.0f}s (build {tb:.0f}s, {where})  {o.by}: "
                f"{o.detail[:160]}")
    finally:
        ws.restore()
    return res


def score(res: list[Outcome]) -> tuple[int, int]:
    counted = [o for o in res if o.status in ("caught", "survived", "timeout")]
    return sum(o.status == "caught" for o in counted), len(counted)
