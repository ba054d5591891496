"""ev3-master's record in SQLite (`--db FILE`, docs/record.md): robots, state changes, commands and
their answers, every report once with its number, drops; what survives a killed master; which files
it refuses."""

from __future__ import annotations

import sqlite3
import sys
import subprocess

import pytest

from ev3net import T, FakeAgent, free_ports, read_status, wait_until
from ev3conformance.wire import Message, encode


def db_rows(path, sql: str, *args) -> list[tuple]:
    c = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    try:
        return c.execute(sql, args).fetchall()
    finally:
        c.close()


def report(a: FakeAgent, m, seq: int, value: int, copies: int = 3) -> None:
    """REPORT(seq, first 1, SENSOR_VALUE in4 US-DIST-CM value) from agent @a."""
    inner = Message(a.id, 1, a.next_msgid(), T["SENSOR_VALUE"], (b"in4", b"US-DIST-CM", str(value).encode()))
    a.send(Message(a.id, 1, inner.msgid, T["REPORT"], (str(seq).encode(), b"1", encode(inner))), m.port, copies)


def registered(agents, m, n: int, devices: tuple[str, ...] = ()) -> list[FakeAgent]:
    out = []
    for i in range(n):
        a = FakeAgent(m.port, 50200 + i, devices=devices if i == 0 else ())
        agents.append(a)
        a.register()
        a.pinging = True
        out.append(a)
    wait_until(lambda: all(x["state"] == "ACTIVE" for x in (read_status(m.status) or {}).get("agents", [{}]))
               and len(read_status(m.status)["agents"]) == n, 3, "the agents ACTIVE")
    return out


def test_the_record_holds_robots_states_commands_and_each_report_once(start_master, agents, tmp_path):
    db = tmp_path / "mission.db"
    m = start_master("--db", str(db), "--state-file", str(tmp_path / "m.state"), control=True)
    a, b = registered(agents, m, 2, devices=("left motor", "right motor", "colour sensor"))
    m.write(f"behaviour {a.id} wait seconds=3")
    m.write(f"start {a.id}")
    # The robot pings ACTIVE, not WORKING, so the core sends BEHAVIOUR and START again itself
    # (reconcile): only the operator's two are rows, each with the answer to it.
    # (each command once: a copy the master resent before the agent's ACK reached it has its msgid)
    wait_until(lambda: a.command_types()[:2] == [T["BEHAVIOUR"], T["START"]], 3,
               "BEHAVIOUR and START")
    wait_until(lambda: len([x for x in a.commands if x.type == T["START"]]) >= 3, 3, "reconcile's own STARTs")
    for seq in (1, 2, 3):
        report(a, m, seq, 40 + seq)
    report(a, m, 2, 42)  # a resending of 2: recorded once
    report(b, m, 1, 7)
    wait_until(lambda: len(db_rows(db, "SELECT * FROM reports")) == 4, 3, "4 reports in the record")
    assert db_rows(db, "SELECT agent, seq, type, text FROM reports ORDER BY agent, seq") == sorted([
        (a.id, 1, "SENSOR_VALUE", "in4:US-DIST-CM:41"), (a.id, 2, "SENSOR_VALUE", "in4:US-DIST-CM:42"),
        (a.id, 3, "SENSOR_VALUE", "in4:US-DIST-CM:43"), (b.id, 1, "SENSOR_VALUE", "in4:US-DIST-CM:7")])
    assert db_rows(db, "SELECT agent, command, args, answer FROM commands ORDER BY row") == [
        (a.id, "BEHAVIOUR", "wait seconds=3", "acked"), (a.id, "START", "", "acked")]
    assert sorted(r[0] for r in db_rows(db, "SELECT id FROM robots")) == sorted([a.id, b.id])
    assert {(r[0], r[1]) for r in db_rows(db, "SELECT agent, state FROM states")} >= {
        (a.id, "SYNCED"), (a.id, "ACTIVE"), (b.id, "SYNCED"), (b.id, "ACTIVE")}
    # the model and the devices as each announced them in AGENT (b: the model alone)
    assert db_rows(db, "SELECT id, model, devices FROM robots ORDER BY id") == sorted([
        (a.id, "A", '["left motor","right motor","colour sensor"]'), (b.id, "A", "[]")])
    status = {x["id"]: x for x in read_status(m.status)["agents"]}
    assert status[a.id]["devices"] == ["left motor", "right motor", "colour sensor"]
    assert status[b.id]["devices"] == []
    assert db_rows(db, "PRAGMA user_version") == [(3,)]
    assert db_rows(db, "PRAGMA journal_mode") == [("wal",)]


@pytest.mark.empty_trace  # the restarted master hears nobody: its trace has no record
def test_a_killed_master_loses_no_committed_row_and_continues_the_file(start_master, agents, programs, tmp_path):
    db, state = tmp_path / "mission.db", tmp_path / "m.state"
    m = start_master("--db", str(db), "--state-file", str(state))
    a, = registered(agents, m, 1)
    for seq in range(1, 6):
        report(a, m, seq, seq)
    wait_until(lambda: len(db_rows(db, "SELECT * FROM reports")) == 5, 3, "5 reports in the record")
    m.proc.kill()  # SIGKILL: no chance to close the file
    m.proc.wait()
    m.close()
    programs.remove(m)
    assert len(db_rows(db, "SELECT * FROM reports")) == 5
    m2 = start_master("--db", str(db), "--state-file", str(state), name="again")
    wait_until(lambda: "continued (schema 3, 5 reports)" in m2.stdout(), 3, "the record continued")


@pytest.mark.empty_trace  # refused at start: no record in the trace
def test_files_that_are_not_a_record_are_refused(master_exe, tmp_path):
    def run(db, *extra):
        return subprocess.run([str(master_exe), "--port", str(free_ports(1)[0]), "--bind", "127.0.0.1",
                               "--db", str(db), *extra], capture_output=True, text=True, timeout=5,
                              stdin=subprocess.DEVNULL)
    state = ("--state-file", str(tmp_path / "m.state"))
    garbage = tmp_path / "garbage.db"
    garbage.write_bytes(b"this is not a database at all\n" * 200)
    r = run(garbage, *state)
    assert r.returncode == 2 and f"--db: {garbage} is not a record" in r.stderr
    assert garbage.read_bytes().startswith(b"this is not")
    foreign = tmp_path / "foreign.db"
    c = sqlite3.connect(foreign)
    c.execute("CREATE TABLE t (x)")
    c.commit()
    c.close()
    r = run(foreign, *state)
    assert r.returncode == 2 and "another program's SQLite database" in r.stderr
    newer = tmp_path / "newer.db"
    c = sqlite3.connect(newer)
    c.execute("CREATE TABLE t (x)")
    c.execute(f"PRAGMA application_id = {0x45563352}")
    c.execute("PRAGMA user_version = 99")
    c.commit()
    c.close()
    r = run(newer, *state)
    assert r.returncode == 2 and "has schema 99, newer than this ev3-master's 3" in r.stderr
    r = run(tmp_path / "fine.db")
    assert r.returncode == 2 and "--db needs --state-file" in r.stderr


@pytest.mark.empty_trace  # the second master hears nobody
def test_a_record_of_schema_1_is_migrated_keeping_its_rows(start_master, agents, programs, tmp_path):
    db, state = tmp_path / "mission.db", tmp_path / "m.state"
    m = start_master("--db", str(db), "--state-file", str(state))
    a, = registered(agents, m, 1)
    report(a, m, 1, 42)
    wait_until(lambda: len(db_rows(db, "SELECT * FROM reports")) == 1, 3, "the report in the record")
    assert m.stop() == 0
    programs.remove(m)
    m.close()
    c = sqlite3.connect(db)  # what a master of schema 1 left: no model or devices column
    c.execute("ALTER TABLE robots DROP COLUMN devices")
    c.execute("ALTER TABLE robots DROP COLUMN model")
    c.execute("PRAGMA user_version = 1")
    c.commit()
    c.close()
    m2 = start_master("--db", str(db), "--state-file", str(state), name="master2")
    wait_until(lambda: "migrated from schema 1 to 3" in m2.stdout(), 3, "the record migrated")
    assert db_rows(db, "PRAGMA user_version") == [(3,)]
    assert db_rows(db, "SELECT id, model, devices FROM robots") == [(a.id, None, None)]  # kept; not known
    assert db_rows(db, "SELECT seq, text FROM reports") == [(1, "in4:US-DIST-CM:42")]


def test_ev3_fleet_answers_questions_of_a_record(start_master, agents, tmp_path):
    db = tmp_path / "mission.db"
    m = start_master("--db", str(db), "--state-file", str(tmp_path / "m.state"))
    a, b = registered(agents, m, 2, devices=("left motor", "colour sensor"))
    for seq in range(1, 21):
        report(a, m, seq, 100 - 3 * seq)
    # Two devices gone, one back: the summary names the other one's port.
    for seq, (name, port) in enumerate([(b"DEVICE_DISCONNECTED", b"in3"), (b"DEVICE_DISCONNECTED", b"outC"),
                                        (b"DEVICE_CONNECTED", b"in3")], 21):
        event = Message(a.id, 1, a.next_msgid(), T["EVENT"], (name, port))
        a.send(Message(a.id, 1, event.msgid, T["REPORT"], (str(seq).encode(), b"1", encode(event))), m.port, 3)
    b.send_master("REPORT_DROPPED", "1", "2")
    report(b, m, 3, 5)
    wait_until(lambda: len(db_rows(db, "SELECT * FROM reports")) == 24
               and db_rows(db, "SELECT count(*) FROM reports_missing") == [(1,)], 3, "the reports in the record")

    def fleet(*args):
        return subprocess.run([sys.executable, "-m", "ev3fleet.cli", *args], capture_output=True, text=True,
                              timeout=60, cwd=tmp_path)
    r = fleet("summary", str(db))
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0].startswith("2 robots, 24 reports")
    row_a = next(x for x in lines[2:] if x.split()[0] == str(a.id))
    row_b = next(x for x in lines[2:] if x.split()[0] == str(b.id))
    assert " 23  1-23 " in row_a and " 1  3-3 " in row_b and "2 dropped" in row_b
    assert f"robot {a.id} devices: left motor, colour sensor; unplugged: outC" in lines
    assert f"robot {b.id} devices: none" in lines
    r = fleet("export", str(db), "--table", "reports", "--format", "csv", "--out", "r.csv")
    assert r.returncode == 0, r.stderr
    rows = (tmp_path / "r.csv").read_text().splitlines()
    assert rows[0] == "row,t_ms,agent,seq,type,text" and len(rows) == 25
    r = fleet("export", str(db), "--table", "reports", "--format", "parquet")
    assert r.returncode == 0, r.stderr
    import pyarrow.parquet as pq
    t = pq.read_table(tmp_path / "reports.parquet")
    assert t.num_rows == 24 and sorted(t.column("seq").to_pylist()) == sorted([*range(1, 24), 3])
    for out in ("a.png", "a.svg"):
        r = fleet("plot", str(db), "--robot", str(a.id), "--sensor", "in4", "--out", out)
        assert r.returncode == 0, r.stderr
    assert (tmp_path / "a.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert b"<svg" in (tmp_path / "a.svg").read_bytes()[:400]
    r = fleet("plot", str(db), "--robot", str(a.id), "--sensor", "in1")
    assert r.returncode == 2 and "no SENSOR_VALUE of in1" in r.stderr and "in4" in r.stderr
    (tmp_path / "junk.db").write_text("junk\n" * 100)
    r = fleet("summary", str(tmp_path / "junk.db"))
    assert r.returncode == 2 and "is not a record" in r.stderr
