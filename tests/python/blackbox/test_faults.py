"""The transport's fault injection flags (--fault-*), seen from outside."""

from __future__ import annotations

import time
from collections import Counter

from ev3net import T, wait_until


def test_loss_100_sends_nothing(start_agent, tm):
    start_agent("--fault-loss", "100")
    time.sleep(0.5)
    assert tm.received() == []


def test_dup_100_doubles_every_copy(start_agent, tm):
    start_agent("--fault-dup", "100", "--fault-seed", "5")
    wait_until(lambda: len({m.msgid for _, m, _ in tm.received() if m.type == T["AGENT"]}) >= 3, 2, "3 AGENTs")
    time.sleep(0.1)
    per_msgid = Counter(m.msgid for _, m, _ in tm.received() if m.type == T["AGENT"])
    full = [c for c in per_msgid.values()][:2]
    assert all(c == 6 for c in full), per_msgid


def test_delay_delays_every_copy(start_agent, tm):
    t0 = time.monotonic()
    start_agent("--fault-delay-ms", "400", "--heartbeat-ms", "50")
    t, _, _ = tm.wait_for(lambda m: m.type == T["AGENT"], 3, "AGENT")
    assert t - t0 >= 0.4


def test_lossy_reordering_link_still_syncs_and_works(start_agent, tm):
    start_agent("--fault-loss", "30", "--fault-dup", "20", "--fault-reorder", "30", "--fault-delay-ms", "3",
                "--fault-seed", "9")
    tm.sync(2, timeout=5)
    tm.wait_state(2, "ACTIVE", 3)
    # Commands are resent with their msgid until answered, as a master does.
    for cmd, args in [("BEHAVIOUR", ("wait", "seconds=0.3")), ("START", ())]:
        mark = tm.mark()
        mid = tm.command(2, cmd, *args)
        for _ in range(20):
            try:
                assert tm.answer(2, mid, mark, timeout=0.2).type == T["ACK"]
                break
            except AssertionError:
                tm.command(2, cmd, *args, msgid=mid)
        else:
            raise AssertionError(f"{cmd} never answered")
    tm.wait_for(lambda m: m.type == T["ACTION_OK"], 3, "ACTION_OK")
