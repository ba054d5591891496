"""ev3-fleet serve: a live web view of a fleet (docs/record.md "The web view").

The view reads two things the master offers and writes nothing of its own: the master's status
through its control socket (`list`, twice a second) and the mission record (`--db`) for what
happened (state changes, commands and their answers, reports, poses). The page gets both as
server-sent events the moment they change; its buttons send console commands through the control
socket and show each robot's answer. Pictures (the map, the sensor plots) are drawn in worker
threads and kept until the reports they show change, so no page waits on another's picture.
"""

from __future__ import annotations

import asyncio
import hmac
import io
import ipaddress
import json
import re
import secrets
import signal
import sqlite3
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import quote

from aiohttp import web

from . import control
from .record import NotARecord, open_record
from .world import World

WEB = Path(__file__).parent / "web"
COMMANDS = ("start", "pause", "resume", "stop")
POLL_S = 0.5
LOG_BACKLOG = 200  # log lines a page gets when it opens
POSE_PORT = "pose"  # SENSOR_VALUE(pose, ODOM, x_mm, y_mm, heading_deg): a robot's odometry
ROBOT_ID = re.compile(r"[0-9]{1,5}")
CLOSE = ("close", None)  # the queue item that ends a page's event stream (the server stops)


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
    record_error: str | None = None
    log: list[dict] = field(default_factory=list)
    sensors: dict[str, dict[str, int]] = field(default_factory=dict)  # robot -> port -> reports
    poses: int = 0
    queues: set[asyncio.Queue] = field(default_factory=set)
    last_row: dict[str, int] = field(default_factory=dict)
    counted: int = 0          # the reports' rowid up to which sensors and poses are counted
    answered_ms: int = 0      # the latest command answer in the log
    record_id: tuple | None = None  # (inode, application_id): a record replaced starts over

    def publish(self, event: str, data) -> None:
        for q in self.queues:
            if q.qsize() < 1000:  # a page that reads nothing is not fed forever
                q.put_nowait((event, data))

    def snapshot(self) -> list[tuple[str, object]]:
        return [("fleet", self.fleet_doc()), ("backlog", self.log[-LOG_BACKLOG:]),
                ("sensors", self.sensors), ("map", self.poses)]

    def fleet_doc(self) -> dict:
        return {"status": self.status, "error": self.master_error, "record_error": self.record_error}

    # -- the master's status ---------------------------------------------------------------------
    async def poll_status(self) -> None:
        try:
            answer = await control.ask(self.control_path, "list", timeout=5.0)
            if not isinstance(answer, dict) or not isinstance(answer.get("status", {}), dict):
                raise control.ControlError("the master's answer to list is not its status")
            status, error = answer.get("status"), None if answer.get("ok") else answer.get("error")
        except control.ControlError as e:
            status, error = self.status, str(e)  # keep the last table; the page marks it as old
        if status != self.status or error != self.master_error:
            self.status, self.master_error = status, error
            self.publish("fleet", self.fleet_doc())

    # -- the record --------------------------------------------------------------------------------
    def read_record(self) -> tuple[list[dict], dict | None, int | None, str | None]:
        """New log lines, the sensor counts and pose count when they changed, and what is wrong with
        the record (None: it reads). Runs in a worker thread."""
        try:
            db = open_record(self.db_path)
        except NotARecord as e:
            return [], None, None, str(e)
        try:
            ident = (self.db_path.stat().st_ino, db.execute("PRAGMA application_id").fetchone()[0])
            if ident != self.record_id:  # a new record: read it from its start
                self.record_id, self.last_row, self.counted, self.answered_ms = ident, {}, 0, 0
                self.sensors, self.poses = {}, 0
            lines = self.new_rows(db)
            sensors, poses = self.count(db)
        except (sqlite3.Error, OSError) as e:
            return [], None, None, f"{self.db_path}: {e}"
        finally:
            db.close()
        return lines, sensors, poses, None

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
        for t, agent, cmd, answer, reason in db.execute(
                "SELECT answered_ms, agent, command, answer, reason FROM commands WHERE answered_ms > ? "
                "ORDER BY answered_ms", (self.answered_ms,)).fetchall():
            self.answered_ms = max(self.answered_ms, t)
            lines.append({"t_ms": t, "agent": agent, "kind": "answer",
                          "text": f"{cmd} {answer}" + (f" ({reason})" if reason else "")})
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

    def count(self, db) -> tuple[dict | None, int | None]:
        """Sensor reports per robot and port, and pose reports, counted on from the last call."""
        sensors = {r: dict(p) for r, p in self.sensors.items()}
        poses, top = self.poses, self.counted
        for agent, port, n, last in db.execute(
                "SELECT agent, substr(text, 1, instr(text, ':') - 1) AS port, count(*), max(rowid) FROM reports "
                "WHERE rowid > ? AND type = 'SENSOR_VALUE' GROUP BY agent, port", (self.counted,)):
            top = max(top, last)
            if port == POSE_PORT:
                poses += n
            else:
                sensors.setdefault(str(agent), {})[port] = sensors.get(str(agent), {}).get(port, 0) + n
        self.counted = top
        return (sensors if sensors != self.sensors else None), (poses if poses != self.poses else None)

    async def run(self, pool: ThreadPoolExecutor) -> None:
        loop = asyncio.get_running_loop()
        while True:
            try:
                await self.poll_status()
                lines, sensors, poses, error = await loop.run_in_executor(pool, self.read_record)
                if error != self.record_error:
                    self.record_error = error
                    self.publish("fleet", self.fleet_doc())
                if lines:
                    self.log.extend(lines)
                    del self.log[:-LOG_BACKLOG]
                    self.publish("log", lines)
                if sensors is not None:
                    self.sensors = sensors
                    self.publish("sensors", sensors)
                if poses is not None:
                    self.poses = poses
                    self.publish("map", poses)
            except asyncio.CancelledError:
                raise
            except Exception as e:  # noqa: BLE001 (one bad turn must not stop the view)
                print(f"ev3-fleet serve: {type(e).__name__}: {e}", file=sys.stderr, flush=True)
            await asyncio.sleep(POLL_S)


class Pictures:
    """The map and the sensor plots as SVG, drawn in worker threads with matplotlib's object API
    (no pyplot: it is not thread-safe), each kept until the count of reports it shows changes."""

    def __init__(self, hub: Hub, pool: ThreadPoolExecutor) -> None:
        self.hub, self.pool = hub, pool
        self.cache: dict[tuple, tuple[int, bytes]] = {}  # key -> (the count it shows, its SVG)

    async def get(self, key: tuple, count: int, draw) -> bytes:
        hit = self.cache.get(key)
        if hit is not None and hit[0] == count:
            return hit[1]
        svg = await asyncio.get_running_loop().run_in_executor(self.pool, draw)
        self.cache[key] = (count, svg)
        return svg

    def draw_plot(self, robot: int, port: str) -> bytes:
        from .cli import sensor_figure
        db = open_record(self.hub.db_path)
        try:
            return svg_bytes(sensor_figure(db, robot, port))
        finally:
            db.close()

    def draw_map(self) -> bytes:
        from .mapview import map_figure
        try:
            db = open_record(self.hub.db_path)
        except NotARecord:
            db = None
        try:
            return svg_bytes(map_figure(db, self.hub.world))
        finally:
            if db is not None:
                db.close()


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def make_app(hub: Hub, pool: ThreadPoolExecutor) -> web.Application:
    pictures = Pictures(hub, pool)

    @web.middleware
    async def guard(req, handler):
        # Without a token the view trusts whoever reaches it on loopback, so it answers only a
        # request addressed to a loopback name (a page of another site that rebinds its own name
        # to 127.0.0.1 sends that name in Host), and no page may frame it.
        if hub.token is None and not is_loopback(req.url.host or ""):
            return web.json_response({"ok": False, "error": f"this view answers only at a loopback address, "
                                                            f"not '{req.host}'"}, status=403)
        resp = await handler(req)
        resp.headers["X-Frame-Options"] = "DENY"
        resp.headers["Content-Security-Policy"] = "frame-ancestors 'none'"
        return resp

    app = web.Application(middlewares=[guard])

    async def index(_req):
        return web.FileResponse(WEB / "index.html")

    async def events(req):
        resp = web.StreamResponse(headers={"Content-Type": "text/event-stream", "Cache-Control": "no-cache"})
        await resp.prepare(req)
        q: asyncio.Queue = asyncio.Queue()
        for event, data in hub.snapshot():
            q.put_nowait((event, data))
        hub.queues.add(q)
        try:
            while True:
                try:
                    event, data = await asyncio.wait_for(q.get(), 15.0)
                except asyncio.TimeoutError:
                    await resp.write(b": keep-alive\n\n")
                    continue
                if (event, data) == CLOSE:
                    break
                await resp.write(f"event: {event}\ndata: {json.dumps(data)}\n\n".encode())
        except (ConnectionResetError, ConnectionError):
            pass
        finally:
            hub.queues.discard(q)
        return resp

    async def command(req):
        if hub.token is not None:
            given = req.headers.get("X-Ev3fleet-Token", "").encode("utf-8", "replace")
            if not hmac.compare_digest(given, hub.token.encode()):
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
        if robot != "all" and not (ROBOT_ID.fullmatch(robot) and 0 < int(robot) < 65536):
            return web.json_response({"ok": False, "error": f"bad robot '{robot}' (an id or all)"}, status=400)
        try:
            answer = await control.ask(hub.control_path, f"{cmd} {robot}")
        except control.ControlError as e:
            return web.json_response({"ok": False, "error": str(e)}, status=502)
        return web.json_response(answer)

    async def plot_svg(req):
        robot, port = req.match_info["robot"], req.match_info["port"]
        if not ROBOT_ID.fullmatch(robot):
            raise web.HTTPNotFound(text=f"no robot {robot}")
        count = hub.sensors.get(robot, {}).get(port)
        if count is None:
            raise web.HTTPNotFound(text=f"robot {robot} has no SENSOR_VALUE of {port} in the record")
        try:
            svg = await pictures.get(("plot", robot, port), count, lambda: pictures.draw_plot(int(robot), port))
        except (NotARecord, sqlite3.Error) as e:
            raise web.HTTPNotFound(text=str(e))
        return web.Response(body=svg, content_type="image/svg+xml")

    async def map_svg(_req):
        try:
            svg = await pictures.get(("map",), hub.poses, pictures.draw_map)
        except sqlite3.Error as e:
            raise web.HTTPServiceUnavailable(text=str(e))
        return web.Response(body=svg, content_type="image/svg+xml")

    app.router.add_get("/", index)
    app.router.add_get("/events", events)
    app.router.add_post("/api/command", command)
    app.router.add_get(r"/plot/{robot:\d+}/{port:[A-Za-z0-9]+}.svg", plot_svg)
    app.router.add_get("/map.svg", map_svg)
    app.router.add_static("/static", WEB)

    async def start_hub(app_):
        app_["hub"] = asyncio.create_task(hub.run(pool))

    async def close_streams(_app):
        for q in hub.queues:
            q.put_nowait(CLOSE)

    async def stop_hub(app_):
        app_["hub"].cancel()

    app.on_startup.append(start_hub)
    app.on_shutdown.append(close_streams)
    app.on_cleanup.append(stop_hub)
    return app


def svg_bytes(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="svg")
    return buf.getvalue()


def read_token(token_file: Path) -> str:
    try:
        token = token_file.read_text().strip()
    except (OSError, UnicodeDecodeError) as e:
        raise ValueError(f"--token-file {token_file}: {getattr(e, 'strerror', None) or e}") from None
    if len(token) < 16 or not token.isascii() or not token.isprintable() or " " in token:
        raise ValueError(f"--token-file {token_file}: a token of at least 16 printable ASCII characters, no spaces")
    return token


def serve(db: Path, control_path: str, bind: str, token_file: Path | None, world_file: Path | None,
          sim: str | None = None) -> int:
    host, _, port_text = bind.rpartition(":")
    if not host or not port_text.isdigit() or not 0 < int(port_text) < 65536:
        raise ValueError(f"--bind {bind}: expected HOST:PORT, e.g. 127.0.0.1:8080")
    if "\0" in control_path:
        raise ValueError("--control: a path holds no NUL")
    token = read_token(token_file) if token_file is not None else None
    generated = token is None and not is_loopback(host)
    if generated:
        token = secrets.token_urlsafe(24)
    world = World.read(world_file, sim) if world_file is not None else None
    hub = Hub(Path(db), control_path, token, world)
    return asyncio.run(_serve(hub, host.strip("[]"), int(port_text), generated))


async def _serve(hub: Hub, host: str, port: int, generated: bool) -> int:
    import matplotlib
    matplotlib.rcParams["svg.fonttype"] = "none"  # text as text: smaller, and a page can find it
    with ThreadPoolExecutor(max_workers=2, thread_name_prefix="draw") as pool:
        runner = web.AppRunner(make_app(hub, pool), handle_signals=False, shutdown_timeout=2.0)
        await runner.setup()
        try:
            await web.TCPSite(runner, host, port).start()
        except OSError as e:
            await runner.cleanup()
            raise OSError(e.errno, e.strerror) from None
        shown = f"[{host}]" if ":" in host else host
        url = f"http://{shown}:{port}/" + (f"?token={quote(hub.token, safe='')}" if generated else "")
        print(f"ev3-fleet serve: the fleet's view at {url}", flush=True)
        if generated:
            print("ev3-fleet serve: control actions need the token in that address", flush=True)
        elif hub.token is not None:
            print("ev3-fleet serve: control actions need the token of --token-file: open the address with "
                  "?token=... added", flush=True)
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(sig, stop.set)
        await stop.wait()
        await runner.cleanup()
    return 0
