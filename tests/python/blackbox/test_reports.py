"""Reliable reports end to end (docs/reports.md): two ev3-agent run model A on ev3-sim robots under
ev3-master with --record; the master is killed (SIGKILL) in the middle of a mission that reports
every 100 ms and comes back from its --state-file and --record a second later. The agents keep
working meanwhile (a long --master-timeout-ms), so reports are made while no master runs; the
restarted master takes them when the agents reach it again. The second robot's agent keeps at most
8 reports (--report-buffer 8), so its bound drops some while the master is gone. Afterwards each
record holds every number each agent made (the `made` of its own trace) exactly once, in order: the
first robot's all as reports, the second's as reports and, where its bound dropped them, as dropped,
and the status JSON counts them so (no gap). A record file that is not one is refused at start,
naming its line.

The agents' traces are checked against the spec at teardown like every other agent's (conftest.py);
with this test they hold TakeAck records, and the master's PCTake records."""

from __future__ import annotations

import re
import subprocess
import time
from pathlib import Path

from ev3net import Program, free_ports, made, read_status, sim_agent, start_custom_all, wait_until

WORLD = "bounds 0 0 800 600\nstart 100 150 0\n"
POSES = [("robot1", "100,150,0"), ("robot2", "100,450,0")]
# A mission that reports: distance and touch every 100 ms while the robot waits, 1 s at a time
# (one ACTION_OK each), for good.
BEAT = "behaviour beat\nreport distance, touch every 100ms\non DEVICE_ERROR -> end\nstate a = wait 1s -> a\n"
LOSS_MS = 4000  # the agents keep WORKING this long without their master


def agent_id(tmp: Path, i: int) -> int:
    """Agent #i's id, from its log ("state ACTIVE (id N)")."""
    log = tmp / f"agent{i}.log"
    m = wait_until(lambda: log.exists() and re.search(r"state ACTIVE \(id (\d+)\)", log.read_text(errors="replace")),
                   3, f"agent #{i}'s id")
    return int(m.group(1))


def record(path: Path) -> dict[int, list[tuple[int, int, str]]]:
    """The record file's entries per agent: (first, last, kind)."""
    out: dict[int, list[tuple[int, int, str]]] = {}
    for line in path.read_text().splitlines():
        if line and not line.startswith("#"):
            f = line.split("\t")
            out.setdefault(int(f[0]), []).append((int(f[1]), int(f[2]), f[3]))
    return out


def test_the_record_has_every_report_once_after_the_master_was_killed(master_exe, agent_exe, programs, sim_factory,
                                                                     tmp_path):
    sim = sim_factory(WORLD, robots=POSES)
    mport = free_ports(1)[0]
    rec, status = tmp_path / "record.tsv", tmp_path / "master.json"
    (tmp_path / "beat.bhv").write_text(BEAT)

    def master(name: str) -> Program:
        m = Program(master_exe, ["--port", str(mport), "--bind", "127.0.0.1", "--status-json", str(status),
                                 "--state-file", str(tmp_path / "master.state"), "--record", str(rec),
                                 "--agent-timeout-ms", "6000", "--resend-ms", "150", "--log-level", "3",
                                 f"--trace={tmp_path / f'{name}.nd'}"], tmp_path, name, stdin=subprocess.PIPE)
        programs.append(m)
        return m

    m1 = master("master1")
    for i, (name, _) in enumerate(POSES):
        programs.append(sim_agent(agent_exe, sim.root(name), tmp_path, i + 1, mport, LOSS_MS, 8000,
                                  *(["--report-buffer", "8"] if i == 1 else [])))
    start_custom_all(m1, status, tmp_path / "beat.bhv", len(POSES))
    wait_until(lambda: all(r.get("last", 0) >= 10 for r in (read_status(status) or {}).get("reports", {}).values())
               and len((read_status(status) or {}).get("reports", {})) == 2, 5, "ten reports of each agent recorded")
    m1.proc.kill()  # SIGKILL: whatever the master held but had not appended is gone with it
    m1.proc.wait()
    m1.close()
    programs.remove(m1)
    killed = {a: max(e[1] for e in es) for a, es in record(rec).items()}
    trace_of = {agent_id(tmp_path, i + 1): tmp_path / f"agent{i + 1}.nd" for i in range(len(POSES))}
    assert sorted(trace_of) == sorted(killed)
    small = agent_id(tmp_path, 2)  # --report-buffer 8
    time.sleep(1.0)  # the agents go on working and reporting: nobody acknowledges
    made_then = {a: made(t) for a, t in trace_of.items()}
    m2 = master("master2")
    wait_until(lambda: "record " + str(rec) + ": " in m2.stdout(), 3, "the restarted master to read its record")
    ids = sorted(killed)
    # The agents reach it again (their REPORTs and PINGs; it syncs them anew when they PANIC, or
    # takes their reports at once); then the mission is stopped and the record must catch up.
    wait_until(lambda: (s := read_status(status)) and all(
        r["last"] > killed[int(a)] for a, r in s.get("reports", {}).items()) and len(s.get("reports", {})) == 2,
               LOSS_MS / 1000 + 10, "reports made while the master was gone recorded by the restarted one")
    wait_until(lambda: (s := read_status(status)) and sum(a["state"] in ("ACTIVE", "WORKING") for a in s["agents"]) == 2,
               LOSS_MS / 1000 + 12, "both agents synced with the restarted master")
    m2.write("stop all")
    wait_until(lambda: (s := read_status(status)) and sum(a["state"] == "ACTIVE" for a in s["agents"]) == 2, 5,
               "both agents stopped (ACTIVE)")
    want = {a: made(trace_of[a]) for a in ids}
    wait_until(lambda: {int(a): r["last"] for a, r in (read_status(status) or {}).get("reports", {}).items()} == want,
               5, f"the record to reach every report made ({want})")
    s = read_status(status)
    entries = record(rec)
    for a in ids:
        es = entries[a]
        # 1, 2, 3, ... each once, in order: each entry starts where the previous one ended
        assert es[0][0] == 1 and es[-1][1] == want[a], es[:20]
        assert all(x[1] + 1 == y[0] for x, y in zip(es, es[1:])), es
        assert all(e[2] == "report" and e[0] == e[1] or e[2] == "dropped" for e in es), es
        dropped = sum(e[1] - e[0] + 1 for e in es if e[2] == "dropped")
        assert s["reports"][str(a)] == {"first": 1, "last": want[a], "recorded": want[a] - dropped,
                                        "dropped": dropped, "skipped": 0, "gap": None}
        # the first robot's bound dropped nothing; the second's (8 reports) did, while no master ran
        assert (dropped > 0) == (a == small), (a, dropped)
        # reports were made while no master ran, and reached the restarted one
        assert want[a] > made_then[a] > killed[a], (a, killed[a], made_then[a], want[a])
    print(f"\nrecorded before the kill {killed}, made by then {made_then}, in the end {want}; dropped by agent "
          f"{small}'s bound: {s['reports'][str(small)]['dropped']}")
    for p in programs:
        assert p.stop() == 0, p.name


def test_a_damaged_record_is_refused_naming_its_line(master_exe, tmp_path):
    rec = tmp_path / "record.tsv"
    rec.write_text("# ev3-master record of reports\n2\t1\t1\treport\tACTION_OK\t0\n2\t3\t3\treport\tACTION_OK\t1\n")
    p = subprocess.run([str(master_exe), "--port", str(free_ports(1)[0]), "--bind", "127.0.0.1", "--record", str(rec)],
                       capture_output=True, text=True, timeout=10, stdin=subprocess.DEVNULL)
    assert p.returncode == 2, p.stdout + p.stderr
    assert f"--record {rec}: line 3: agent 2's entry starts at 3, expected 2" in p.stderr, p.stderr
    assert rec.read_text().count("\n") == 3  # left as it was
