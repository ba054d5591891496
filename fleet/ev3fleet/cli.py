"""ev3-fleet: questions to a mission record (ev3-master --db FILE, docs/record.md).

    ev3-fleet summary DB
    ev3-fleet export DB --table reports --format csv|parquet [--out FILE]
    ev3-fleet plot DB --robot ID --sensor PORT [--out FILE.png|FILE.svg]
    ev3-fleet serve --db DB --control PATH [--bind HOST:PORT] [--world FILE [--sim PATH]] [--token-file FILE]
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

from .record import TABLES, NotARecord, open_record


def unplugged(db, rid: int) -> str:
    """"; unplugged: in4": the ports robot @rid told unplugged (DEVICE_DISCONNECTED) and not back since
    (DEVICE_CONNECTED of that port, docs/protocol.md), or ""."""
    ports: list[str] = []
    for (text,) in db.execute("SELECT text FROM reports WHERE agent = ? AND type = 'EVENT' AND text LIKE 'DEVICE!_%' "
                              "ESCAPE '!' ORDER BY row", (rid,)):
        event, _, port = text.partition(":")
        if event == "DEVICE_CONNECTED" and port in ports:
            ports.remove(port)
        elif event == "DEVICE_DISCONNECTED" and port not in ports:
            ports.append(port)
    return f"; unplugged: {', '.join(ports)}" if ports else ""


def summary(db) -> str:
    """Per robot: reports and their numbers, what is missing, states, commands and answers."""
    out = []
    robots = db.execute("SELECT id, model, address FROM robots ORDER BY id").fetchall()
    span = db.execute("SELECT min(t_ms), max(t_ms) FROM (SELECT t_ms FROM states UNION ALL SELECT t_ms FROM reports)"
                      ).fetchone()
    seconds = (span[1] - span[0]) / 1000 if span[0] is not None else 0.0
    total = db.execute("SELECT count(*) FROM reports").fetchone()[0]
    out.append(f"{len(robots)} robots, {total} reports, {seconds:.1f} s of mission")
    out.append("robot  model  address               reports  numbers   missing            last state  commands (answered)")
    for rid, model, address in robots:
        n, lo, hi = db.execute("SELECT count(seq), min(seq), max(seq) FROM reports WHERE agent = ?", (rid,)).fetchone()
        unnumbered = db.execute("SELECT count(*) FROM reports WHERE agent = ? AND seq IS NULL", (rid,)).fetchone()[0]
        miss = db.execute("SELECT kind, sum(last - first + 1) FROM reports_missing WHERE agent = ? GROUP BY kind",
                          (rid,)).fetchall()
        gone = ", ".join(f"{c} {k}" for k, c in miss) or "-"
        # A hole: a number up to the highest recorded that is neither a report nor missing.
        covered = n + sum(c for _, c in miss if c)
        if hi is not None and covered < hi:
            gone += f", {hi - covered} not yet"
        state = db.execute("SELECT state FROM states WHERE agent = ? ORDER BY row DESC LIMIT 1", (rid,)).fetchone()
        cmds, answered = db.execute("SELECT count(*), count(answer) FROM commands WHERE agent = ?", (rid,)).fetchone()
        numbers = f"{lo}-{hi}" if hi is not None else "-"
        reports = f"{n + unnumbered}"
        out.append(f"{rid:<6} {model or '-':<6} {address:<21} {reports:>7}  {numbers:<9} {gone:<18} "
                   f"{state[0] if state else '-':<11} "
                   f"{cmds} ({answered})")
    for rid, devices in db.execute("SELECT id, devices FROM robots WHERE devices IS NOT NULL ORDER BY id").fetchall():
        out.append(f"robot {rid} devices: {', '.join(json.loads(devices)) or 'none'}{unplugged(db, rid)}")
    epochs = db.execute("SELECT epoch, role FROM epochs ORDER BY row").fetchall()
    if epochs:
        out.append("epochs: " + ", ".join(f"{e} {r}" for e, r in epochs))
    return "\n".join(out)


def export(db, table: str, fmt: str, out: Path | None) -> Path:
    cur = db.execute(f"SELECT * FROM {table} ORDER BY rowid")  # table checked against TABLES
    names = [d[0] for d in cur.description]
    rows = cur.fetchall()
    target = out or Path(f"{table}.{fmt}")
    if fmt == "csv":
        with open(target, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(names)
            w.writerows(rows)
    else:
        import pyarrow as pa
        import pyarrow.parquet as pq
        columns = {n: [r[i] for r in rows] for i, n in enumerate(names)}
        pq.write_table(pa.table(columns), target)
    return target


def sensor_figure(db, robot: int, sensor: str):
    """A matplotlib figure of robot @robot's SENSOR_VALUE reports of port @sensor over time."""
    rows = db.execute("SELECT t_ms, text FROM reports WHERE agent = ? AND type = 'SENSOR_VALUE' ORDER BY t_ms",
                      (robot,)).fetchall()
    points: dict[str, list[tuple[float, float]]] = {}
    t0 = rows[0][0] if rows else 0
    for t, text in rows:
        f = text.split(":")  # port, mode, value...
        if len(f) < 3 or f[0] != sensor:
            continue
        try:
            points.setdefault(f[1], []).append(((t - t0) / 1000, float(f[2])))
        except ValueError:
            continue
    if not points:
        ports = sorted({r[1].split(":")[0] for r in rows})
        raise NotARecord(f"robot {robot} has no SENSOR_VALUE of {sensor} in the record"
                         + (f" (it reported {', '.join(ports)})" if ports else " (no sensor reports at all)"))
    from matplotlib.figure import Figure  # the object API: no global state, safe in a worker thread
    fig = Figure(figsize=(8, 3.5))
    ax = fig.subplots()
    for mode, pts in sorted(points.items()):
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker=".", linewidth=1, label=mode)
    ax.set_xlabel("time since its first sensor report (s)")
    ax.set_ylabel(sensor)
    ax.set_title(f"robot {robot}, {sensor}")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def plot(db, robot: int, sensor: str, out: Path | None) -> Path:
    fig = sensor_figure(db, robot, sensor)
    target = out or Path(f"robot{robot}-{sensor}.png")
    fig.savefig(target)
    return target


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="ev3-fleet", description="Questions to a mission record (ev3-master --db).")
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("summary", help="robots, reports, what is missing, states, commands")
    s.add_argument("db")
    e = sub.add_parser("export", help="one table as CSV or Parquet")
    e.add_argument("db")
    e.add_argument("--table", required=True, choices=TABLES)
    e.add_argument("--format", required=True, choices=("csv", "parquet"))
    e.add_argument("--out", type=Path, help="the file to write (default: TABLE.FORMAT)")
    p = sub.add_parser("plot", help="a robot's sensor values over time, as PNG or SVG")
    p.add_argument("db")
    p.add_argument("--robot", type=int, required=True)
    p.add_argument("--sensor", required=True, help="its port, e.g. in4")
    p.add_argument("--out", type=Path, help="FILE.png or FILE.svg (default: robotID-PORT.png)")
    v = sub.add_parser("serve", help="a live web view of the fleet: table, map, plots, log, buttons")
    v.add_argument("--db", required=True, type=Path, help="the master's --db record")
    v.add_argument("--control", required=True, help="the master's --control socket")
    v.add_argument("--bind", default="127.0.0.1:8080", help="HOST:PORT to serve on (default 127.0.0.1:8080)")
    v.add_argument("--world", type=Path,
                   help="the world drawn under the robots' paths: an ev3-sim world file, or the JSON "
                        "`ev3-sim world FILE` prints")
    v.add_argument("--sim", help="the ev3-sim that reads a --world file (default: ev3-sim on PATH)")
    v.add_argument("--token-file", type=Path,
                   help="the token control actions need (default: none on loopback, a new one elsewhere)")
    a = ap.parse_args(argv)
    if a.cmd == "serve":
        from .serve import serve
        from .world import WorldError
        try:
            return serve(a.db, a.control, a.bind, a.token_file, a.world, a.sim)
        except (ValueError, WorldError) as err:
            print(f"ev3-fleet: {err}", file=sys.stderr)
            return 2
        except OSError as err:
            print(f"ev3-fleet: cannot serve on {a.bind}: {err.strerror}", file=sys.stderr)
            return 2
    if a.cmd == "plot" and a.out is not None and a.out.suffix not in (".png", ".svg"):
        ap.error(f"--out {a.out}: a plot is written as .png or .svg")
    try:
        db = open_record(a.db)
        try:
            if a.cmd == "summary":
                print(summary(db))
            elif a.cmd == "export":
                print(export(db, a.table, a.format, a.out))
            else:
                print(plot(db, a.robot, a.sensor, a.out))
        finally:
            db.close()
    except NotARecord as err:
        print(f"ev3-fleet: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
