"""A barrage of generated malformed and misaddressed datagrams (a few thousand each) leaves
ev3-agent and ev3-master answering, and their drop counters count them by reason (the expected
counts come from the reference codec)."""

from __future__ import annotations

import random
import subprocess
import time
from collections import Counter

from ev3conformance.wire import DecodeError, Message, decode, encode

from ev3net import T, FakeAgent, Program, drop_counters, free_ports, read_status, wait_until

N = 3000


def generate(seed: int, n: int, me: int, senders: list[int]) -> list[bytes]:
    rnd = random.Random(seed)
    valid = [b"1:2:3:5:ACTIVE", b"7:1:12:5:WORKING", b"1:2:9:7:wait:seconds=1", b"2:1:4:20:EVENT:x",
             b"1:0:5:19", b"50001:0:1:1:A"]
    out = []
    msgid = 1_000_000
    for i in range(n):
        k = rnd.randrange(6)
        if k == 0:
            d = bytes(rnd.randrange(256) for _ in range(rnd.randrange(0, 40)))
        elif k == 1:
            v = bytearray(rnd.choice(valid))
            for _ in range(rnd.randrange(1, 4)):
                v[rnd.randrange(len(v))] = rnd.choice(b":%0123456789AZaz\x00\xff- ")
            d = bytes(v)
        elif k == 2:
            d = rnd.choice([b"", b"1", b"1:2", b"1:2:3", b"1:2:3:0", b"1:2:3:300", b"01:2:3:5:IDLE",
                            b"1:2:3:5:SLEEPING", b"1:2:3:99", b"1:2:3:8:x", b"1:2:3:7:a%41",
                            b"1:2:3:7:%3a", b"70000:1:1:5:IDLE", b"1:2:3:5"])
        elif k == 3:
            d = b"1:2:3:7:" + b"a" * rnd.randrange(4090, 5000)
        else:
            # Valid but not for the receiver under test: another receiver, or a foreign sender.
            msgid += 1
            if k == 4:
                d = encode(Message(1, rnd.choice([4242, 3, 49999]), msgid, T["STOP"]))
            else:
                d = encode(Message(rnd.choice(senders), me, msgid, T["MASTER"], (b"12",)))
        out.append(d)
    return out


MASTER_HANDLES = {T[n] for n in ("AGENT", "PANIC", "PING", "ACK", "NOT", "ACTION_OK", "ACTION_INTERR", "REPORT", "REPORT_DROPPED",
                                   "ACTION_ERR", "SENSOR_VALUE", "EVENT")}


def harmless(datagrams: list[bytes], me: int, master: bool) -> list[bytes]:
    """Keeps what the receiver must drop: undecodable, misaddressed, from a foreign sender (agent),
    of a type the master does not take (master); each valid (sender, msgid) once."""
    out, seen = [], set()
    for d in datagrams:
        try:
            m = decode(d)
        except DecodeError:
            out.append(d)
            continue
        if (m.sender, m.msgid) in seen:
            continue
        if m.receiver in (me, 0):
            if master and m.type in MASTER_HANDLES:
                continue
            if not master and m.sender == 1:
                continue
        seen.add((m.sender, m.msgid))
        out.append(d)
    return out


def expected(datagrams: list[bytes], me: int, master: bool) -> Counter:
    c = Counter()
    for d in datagrams:
        try:
            m = decode(d)
        except DecodeError as e:
            c["decode:" + e.reason.replace(" ", "_")] += 1
            continue
        if m.receiver not in (me, 0):
            c["misaddressed"] += 1
        elif master:
            c["unexpected_type"] += 1
        elif m.sender != 1:
            c["foreign_sender"] += 1
        else:
            raise AssertionError(f"generated a valid message for the receiver: {d!r}")
    return c


def blast(sock_node, datagrams: list[bytes], port: int) -> None:
    for i, d in enumerate(datagrams):
        sock_node.send_raw(d, port)
        if i % 100 == 99:
            time.sleep(0.01)  # pace: loopback drops datagrams when the receive buffer overflows


def test_agent_survives_barrage_and_counts_by_reason(start_agent, tm, tmp_path):
    p = start_agent()
    tm.sync(2)
    tm.wait_state(2, "ACTIVE")
    data = harmless(generate(11, N, 2, [3, 5, 9]), 2, master=False)
    blast(tm, data, tm.agent_port)
    # Still alive and answering: PINGs go on, a command is answered.
    tm.wait_state(2, "ACTIVE")
    tm.ack(2, "BEHAVIOUR", "wait", "seconds=1")
    assert p.stop() == 0
    log = (tmp_path / "agent.log").read_text()
    drops = Counter(drop_counters(log))
    want = expected(data, 2, master=False)
    assert sum(want.values()) == len(data) and len(data) > 2500
    for k, v in want.items():
        assert drops[k] == v, f"{k}: counted {drops[k]}, sent {v} (all: {dict(drops)})"
    assert "drop (decode:" in log  # the verbose log names each drop


def test_master_survives_barrage_and_counts_by_reason(master_exe, programs, tmp_path):
    port = free_ports(1)[0]
    status = tmp_path / "m.json"
    m = Program(master_exe, ["--port", str(port), "--bind", "127.0.0.1", "--status-json", str(status),
                             "--agent-timeout-ms", "5000"], tmp_path, "master")
    programs.append(m)
    a = FakeAgent(port, 50070)
    try:
        a.register()
        data = harmless(generate(12, N, 1, [40000, 3]), 1, master=True)
        blast(a, data, port)
        mark = a.mark()
        mid = a.send_master("PING", "ACTIVE")
        _, pong, _ = a.wait_for(lambda x: x.type == T["PONG"], 2, "PONG after the barrage", mark)
        assert pong.params == (str(mid).encode(),)
        want = expected(data, 1, master=True)

        def counted():
            s = read_status(status)
            return s if s and all(s["drops"].get(k, 0) >= v for k, v in want.items()) else None
        try:
            s = wait_until(counted, 3, "the drop counters")
        finally:
            last = read_status(status)
        for k, v in want.items():
            assert s["drops"][k] == v, f"{k}: counted {s['drops'][k]}, sent {v}; status {last['drops']}"
    finally:
        a.close()
