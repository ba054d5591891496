"""ev3-fleet serve: a live web view of a fleet (docs/record.md "The web view").

The view reads two things the master offers and writes nothing of its own: the master's status
through its control socket (`list`, twice a second) and the mission record (`--db`) for what
happened (state changes, commands and answers, reports, poses). The page gets both as server-sent
events the moment they change; its buttons send console commands through the control socket and
show each robot's answer.
"""

from __future__ import annotations

import asyncio
import hmac
import io
import ipaddress
import json
import secrets
import sqlite3
from dataclasses import dataclass, field
from pathlib import Path

from aiohttp import web

from . import control
from .record import NotARecord, open_record
from .world import World

WEB = Path(__file__).parent / "web"
COMMANDS = ("start", "pause", "resume", "stop")
POLL_S = 0.5
LOG_BACKLOG = 200  # log lines a page gets when it opens
POSE_PORT = "pose"  # SENSOR_VALUE(pose, ODOM, x_mm, y_mm, heading_deg): a robot's odometry


@dataclass
class Hub:
    """What the pages see: the latest status, the log, the sensor and pose counts; and the pages'
    event queues, each fed every change."""
    db_path: Path
    control_path: str
    token: str | None
    world: World | None
    status: dict | None = None
    master_error: str | None = None
    log: list[dict] = field(default_factory=list)
    sensors: dict[str, dict[str, int]] = field(default_factory=dict)  # robot -> port -> reports
    poses: int = 0
    queues: set[asyncio.Queue] = field(default_factory=set)
    last_row: dict[str, int] = field(default_factory=dict)

    def publish(self, event: str, data) -> None:
        for q in self.queues:
            if q.qsize() < 1000:  # a page that reads nothing is not fed forever
                q.put_nowait((event, data))

    def snapshot(self) -> list[tuple[str, object]]:
        return [("fleet", self.fleet_doc()), ("log", self.log[-LOG_BACKLOG:]),
                ("sensors", self.sensors), ("map", self.poses)]

    def fleet_doc(self) -> dict:
        return {"status": self.status, "error": self.master_error}

    # -- the master's status ---------------------------------------------------------------------
    async def poll_status(self) -> None:
        try:
            answer = await control.ask(self.control_path, "list", timeout=5.0)
            status, error = answer.get("status"), None if answer.get("ok") else answer.get("error")
        except control.ControlError as e:
            status, error = None, str(e)
        if status != self.status or error != self.master_error:
            self.status, self.master_error = status, error
            self.publish("fleet", self.fleet_doc())

    # -- the record --------------------------------------------------------------------------------
    def read_record(self) -> None:
        try:
            db = open_record(self.db_path)
        except NotARecord:
            return  # the master has not created it yet
        try:
            lines = self.new_rows(db)
            sensors, poses = self.counts(db)
        except sqlite3.Error:
            return
        finally:
            db.close()
        if lines:
            self.log.extend(lines)
            del self.log[:-LOG_BACKLOG]
            self.publish("log", lines)
        if sensors != self.sensors:
            self.sensors = sensors
            self.publish("sensors", sensors)
        if poses != self.poses:
            self.poses = poses
            self.publish("map", poses)

    def rows(self, db, table: str, sql: str) -> list[tuple]:
        """The rows of @table after the last one read (@sql selects rowid first, `WHERE rowid > ?`)."""
        out = db.execute(sql, (self.last_row.get(table, 0),)).fetchall()
        if out:
            self.last_row[table] = out[-1][0]
        return out

    def new_rows(self, db) -> list[dict]:
        lines = []
        for _r, t, agent, state in self.rows(db, "states", "SELECT rowid, t_ms, agent, state FROM states "
                                                           "WHERE rowid > ? ORDER BY rowid"):
            lines.append({"t_ms": t, "agent": agent, "kind": "state", "text": state})
        for _r, t, agent, cmd, args in self.rows(db, "commands", "SELECT rowid, sent_ms, agent, command, args "
                                                               "FROM commands WHERE rowid > ? ORDER BY rowid"):
            lines.append({"t_ms": t, "agent": agent, "kind": "command", "text": f"{cmd} {args or ''}".strip()})
        for _r, t, agent, typ, text in self.rows(db, "reports", "SELECT rowid, t_ms, agent, type, text FROM reports "
                                                               "WHERE rowid > ? AND type != 'SENSOR_VALUE' "
                                                               "ORDER BY rowid"):
            lines.append({"t_ms": t, "agent": agent, "kind": "report", "text": f"{typ} {text}"})
        for _r, t, agent, first, last, kind in self.rows(db, "reports_missing",
                                                         "SELECT rowid, t_ms, agent, first, last, kind FROM "
                                                         "reports_missing WHERE rowid > ? ORDER BY rowid"):
            lines.append({"t_ms": t, "agent": agent, "kind": "missing", "text": f"reports {first}-{last} {kind}"})
        for _r, t, epoch, role, members in self.rows(db, "epochs", "SELECT rowid, t_ms, epoch, role, members "
                                                                 "FROM epochs WHERE rowid > ? ORDER BY rowid"):
            lines.append({"t_ms": t, "agent": None, "kind": "epoch",
                          "text": f"the PC is {role} of epoch {epoch} (members {members or 'none'})"})
        lines.sort(key=lambda line: line["t_ms"])
        return lines

    @staticmethod
    def counts(db) -> tuple[dict[str, dict[str, int]], int]:
        sensors: dict[str, dict[str, int]] = {}
        poses = 0
        for agent, port, n in db.execute(
                "SELECT agent, substr(text, 1, instr(text, ':') - 1) AS port, count(*) FROM reports "
                "WHERE type = 'SENSOR_VALUE' GROUP BY agent, port"):
            if port == POSE_PORT:
                poses += n
            else:
                sensors.setdefault(str(agent), {})[port] = n
        return sensors, poses

    async def run(self) -> None:
        while True:
            await self.poll_status()
            self.read_record()
            await asyncio.sleep(POLL_S)


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def make_app(hub: Hub) -> web.Application:
    app = web.Application()

    async def index(_req):
        return web.FileResponse(WEB / "index.html")

    async def events(req):
        resp = web.StreamResponse(headers={"Content-Type": "text/event-stream", "Cache-Control": "no-cache"})
        await resp.prepare(req)
        q: asyncio.Queue = asyncio.Queue()
        hub.queues.add(q)
        try:
            for event, data in hub.snapshot():
                q.put_nowait((event, data))
            while True:
                try:
                    event, data = await asyncio.wait_for(q.get(), 15.0)
                    await resp.write(f"event: {event}\ndata: {json.dumps(data)}\n\n".encode())
                except asyncio.TimeoutError:
                    await resp.write(b": keep-alive\n\n")
        except (ConnectionResetError, asyncio.CancelledError):
            pass
        finally:
            hub.queues.discard(q)
        return resp

    async def command(req):
        if hub.token is not None and not hmac.compare_digest(req.headers.get("X-Ev3fleet-Token", ""), hub.token):
            return web.json_response({"ok": False, "error": "this view needs its token for control actions"},
                                     status=403)
        # A JSON body only: a page of another site cannot send one here without a CORS preflight,
        # which this server does not grant.
        if req.content_type != "application/json":
            return web.json_response({"ok": False, "error": "a command is sent as application/json"}, status=415)
        try:
            body = await req.json()
            robot, cmd = str(body["robot"]), str(body["command"])
        except (ValueError, KeyError, TypeError):
            return web.json_response({"ok": False, "error": 'expected {"robot": ID or "all", "command": ...}'},
                                     status=400)
        if cmd not in COMMANDS:
            return web.json_response({"ok": False, "error": f"unknown command '{cmd}' (one of {', '.join(COMMANDS)})"},
                                     status=400)
        if robot != "all" and not (robot.isdigit() and 0 < int(robot) < 65536):
            return web.json_response({"ok": False, "error": f"bad robot '{robot}' (an id or all)"}, status=400)
        try:
            answer = await control.ask(hub.control_path, f"{cmd} {robot}")
        except control.ControlError as e:
            return web.json_response({"ok": False, "error": str(e)}, status=502)
        return web.json_response(answer)

    async def plot_svg(req):
        from .cli import sensor_figure
        try:
            db = open_record(hub.db_path)
        except NotARecord as e:
            raise web.HTTPNotFound(text=str(e))
        try:
            fig = sensor_figure(db, int(req.match_info["robot"]), req.match_info["port"])
        except NotARecord as e:
            raise web.HTTPNotFound(text=str(e))
        finally:
            db.close()
        return web.Response(body=svg_bytes(fig), content_type="image/svg+xml")

    async def map_svg(_req):
        from .mapview import map_figure
        try:
            db = open_record(hub.db_path)
        except NotARecord:
            db = None
        try:
            fig = map_figure(db, hub.world)
        finally:
            if db is not None:
                db.close()
        return web.Response(body=svg_bytes(fig), content_type="image/svg+xml")

    app.router.add_get("/", index)
    app.router.add_get("/events", events)
    app.router.add_post("/api/command", command)
    app.router.add_get(r"/plot/{robot:\d+}/{port:[A-Za-z0-9]+}.svg", plot_svg)
    app.router.add_get("/map.svg", map_svg)
    app.router.add_static("/static", WEB)

    async def start_hub(app_):
        app_["hub"] = asyncio.create_task(hub.run())

    async def stop_hub(app_):
        app_["hub"].cancel()

    app.on_startup.append(start_hub)
    app.on_cleanup.append(stop_hub)
    return app


def svg_bytes(fig) -> bytes:
    import matplotlib
    import matplotlib.pyplot as plt
    matplotlib.rcParams["svg.fonttype"] = "none"  # text as text: smaller, and a page can find it
    buf = io.BytesIO()
    fig.savefig(buf, format="svg")
    plt.close(fig)
    return buf.getvalue()


def serve(db: Path, control_path: str, bind: str, token_file: Path | None, world_file: Path | None) -> int:
    host, _, port_text = bind.rpartition(":")
    if not host or not port_text.isdigit() or not 0 < int(port_text) < 65536:
        raise ValueError(f"--bind {bind}: expected HOST:PORT, e.g. 127.0.0.1:8080")
    token = None
    if token_file is not None:
        try:
            token = token_file.read_text().strip()
        except OSError as e:
            raise ValueError(f"--token-file {token_file}: {e.strerror}") from None
        if len(token) < 16:
            raise ValueError(f"--token-file {token_file}: a token of at least 16 characters")
    elif not is_loopback(host):
        token = secrets.token_urlsafe(24)
    world = World.read(world_file) if world_file is not None else None
    hub = Hub(Path(db), control_path, token, world)
    url = f"http://{host}:{port_text}/" + (f"?token={token}" if token is not None else "")
    print(f"ev3-fleet serve: the fleet's view at {url}", flush=True)
    if token is not None:
        print("ev3-fleet serve: control actions need the token in that address", flush=True)
    web.run_app(make_app(hub), host=host, port=int(port_text), print=None, handle_signals=True)
    return 0
