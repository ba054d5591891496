"""A flood of a million datagrams from four senders at once, half at ev3-master and half at an
ev3-agent it commands, while a second agent (Python) pings the master: none of them decodes, so
nothing may change; the master answers every PING it gets within one heartbeat, the agent never
loses its master (default timeout, heartbeat 200 ms), the registry is what it was, both count the flood by reason and exit 0."""

from __future__ import annotations

import multiprocessing
import re
import socket
import time

from ev3net import T, FakeAgent, Program, free_ports, read_status, wait_until

FLOOD = 1_000_000
SENDERS = 4
# Each refused by the codec (docs/protocol.md "Rejection"): empty, too few fields, a header that is
# not a number, bytes outside the alphabet, over 4096 bytes, an unknown type.
GARBAGE = [b"", b"1:2", b"x" * 50, b"\xff\x00abc", b"1:2:3:7:" + b"a" * 4100, b"7:1:5:250"]
REASONS = {"decode:empty", "decode:too_few_fields", "decode:bad_number", "decode:too_long",
           "decode:unknown_type"}


def _flood(ports: list[int], n: int, first: int) -> int:
    """Sends @p n datagrams, GARBAGE in turn, each round of it to the next of @p ports; returns how
    many the kernel took."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sent = 0
    try:
        for i in range(first, first + n):
            try:
                s.sendto(GARBAGE[i % len(GARBAGE)], ("127.0.0.1", ports[i // len(GARBAGE) % len(ports)]))
                sent += 1
            except OSError:
                pass  # a full buffer refuses it: the flood is only that much smaller
    finally:
        s.close()
    return sent


def test_a_flood_changes_nothing_and_the_fleet_keeps_answering(master_exe, agent_exe, programs, tmp_path):
    mport, aport = free_ports(2)
    status = tmp_path / "status.json"
    m = Program(master_exe, ["--port", str(mport), "--bind", "127.0.0.1", "--broadcast", f"127.0.0.1:{aport}",
                             "--status-json", str(status), "--agent-timeout-ms", "3000"], tmp_path, "master")
    programs.append(m)
    a = Program(agent_exe, ["--port", str(aport), "--bind", "127.0.0.1", "--broadcast", f"127.0.0.1:{mport}",
                            "--heartbeat-ms", "200"], tmp_path, "agent")
    programs.append(a)
    fake = FakeAgent(mport, 50077)
    try:
        fake.register()
        fake.pinging = True  # a PING every 50 ms

        def fleet():
            xs = (read_status(status) or {}).get("agents", [])
            return {x["id"]: x["state"] for x in xs}
        wait_until(lambda: len(fleet()) == 2 and "IDLE" not in fleet().values(), 10, "both agents synced")
        before = fleet()
        mark = fake.mark()
        t0 = time.monotonic()
        per = FLOOD // SENDERS
        with multiprocessing.get_context("fork").Pool(SENDERS) as pool:
            sent = sum(pool.starmap(_flood, [([mport, aport], per, k * per) for k in range(SENDERS)]))
        t1 = time.monotonic()
        time.sleep(0.3)
        # The PONGs the Python agent got while the flood ran: never more than one heartbeat (the
        # agent's default, 1 s) apart.
        pongs = [t for t, x, _ in fake.received(mark) if x.type == T["PONG"] and t0 <= t <= t1 + 0.3]
        assert pongs, "no PONG during the flood"
        gaps = [b - a_ for a_, b in zip([t0] + pongs, pongs + [t1])]
        assert max(gaps) <= 1.0, f"the master was silent {max(gaps):.2f} s during the flood ({t1 - t0:.1f} s)"
        assert fleet() == before
    finally:
        fake.close()
    assert sent >= FLOOD * 0.9, f"only {sent} of {FLOOD} datagrams left the senders"
    assert a.stop() == 0 and m.stop() == 0
    drops = (read_status(status) or {}).get("drops", {})  # written once more at exit
    # The agent never lost its master: it stayed ACTIVE from its sync to its stop.
    states = re.findall(r"state (\w+)", a.stderr())
    assert "ACTIVE" in states and not {"PANIC", "PAUSED", "IDLE"} & set(states[states.index("ACTIVE"):]), states
    for who, counted in (("master", drops),
                         ("agent", dict(re.findall(r"(\S+)=(\d+)", re.findall(r"drops: (.*)", a.stderr())[-1])))):
        counted = {k: int(v) for k, v in counted.items() if k.startswith("decode:")}
        assert set(counted) == REASONS, (who, counted)
        assert sum(counted.values()) <= sent, (who, counted, sent)  # what overflows the socket, the kernel drops
