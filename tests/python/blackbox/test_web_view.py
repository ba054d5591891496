"""The web view (`ev3-fleet serve`, docs/record.md "The web view") in a real browser: two ev3-agent
run model A on ev3-sim robots under ev3-master with --db and --control; headless Chromium (Debian's
package, driven by Selenium through chromedriver) opens the page while the robots work, sees every
robot in its state with its LED colour, the event log, a sensor plot and the map, presses pause on
one robot and sees it PAUSED with the robot's answer, and saves a screenshot as
build/web/fleet-view.png. Then the view's refusals without a browser: control actions without the
token it was given, a command it does not know, and bad flags at start."""

from __future__ import annotations

import http.client
import json
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from ev3net import Program, free_ports, read_status, sim_agent, start_custom_all, wait_until
from ev3sim_proc import ev3_sim_path

REPO = Path(__file__).resolve().parents[3]
WORLD = "bounds 0 0 400 300\nbox 180 130 40 40\nfloor red rect 150 215 100 50\nstart 60 60 0\n"
POSES = [("robot1", "60,60,0"), ("robot2", "60,240,0")]
# Drives a square for good (turning early when something is ahead), reporting the distance ahead every 200 ms (and its pose every 500 ms:
# --pose-ms).
ROAM = ("behaviour roam\nreport distance every 200ms\non DEVICE_ERROR -> end\non OBSTACLE_DETECTED, PROXIMITY_ALERT -> b\n"
        "state a = drive 20cm speed=300 -> b\nstate b = turn 90 speed=200 -> a\n")
SHOT = REPO / "build" / "web" / "fleet-view.png"


def serve(tmp_path: Path, programs: list, db: Path, sock: Path, *extra: str, name: str = "view") -> tuple[Program, int]:
    port = free_ports(1)[0]
    p = Program(Path(sys.executable), ["-m", "ev3fleet.cli", "serve", "--db", str(db), "--control", str(sock),
                                       "--bind", f"127.0.0.1:{port}", *extra], tmp_path, name)
    programs.append(p)
    wait_until(lambda: "the fleet's view at" in p.stdout(), 10, "the view to say its address")
    return p, port


def post(port: int, body: dict, token: str | None = None, content_type: str = "application/json"):
    headers = {"Content-Type": content_type}
    if token:
        headers["X-Ev3fleet-Token"] = token
    req = urllib.request.Request(f"http://127.0.0.1:{port}/api/command", data=json.dumps(body).encode(),
                                 headers=headers, method="POST")
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


@pytest.fixture
def mission(master_exe, agent_exe, programs, sim_factory, tmp_path):
    """Two robots WORKING a reporting behaviour under a master with --db and --control."""
    sim = sim_factory(WORLD, robots=POSES)
    mport = free_ports(1)[0]
    status, db, sock = tmp_path / "master.json", tmp_path / "mission.db", tmp_path / "master.sock"
    (tmp_path / "roam.bhv").write_text(ROAM)
    (tmp_path / "world.txt").write_text(WORLD)
    m = Program(master_exe, ["--port", str(mport), "--bind", "127.0.0.1", "--status-json", str(status),
                             "--state-file", str(tmp_path / "master.state"), "--db", str(db), "--control", str(sock),
                             "--agent-timeout-ms", "3000", "--resend-ms", "150", "--log-level", "3",
                             f"--trace={tmp_path / 'master.nd'}"], tmp_path, "master", stdin=subprocess.PIPE)
    programs.append(m)
    for i, (name, pose) in enumerate(POSES):
        programs.append(sim_agent(agent_exe, sim.root(name), tmp_path, i + 1, mport, 2000, 4000, "--pose", pose, "--pose-ms", "500"))
    start_custom_all(m, status, tmp_path / "roam.bhv", len(POSES))
    ids = sorted(a["id"] for a in read_status(status)["agents"])
    return {"status": status, "db": db, "sock": sock, "ids": ids, "world": tmp_path / "world.txt"}


def browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    opts = webdriver.ChromeOptions()
    opts.binary_location = "/usr/bin/chromium"
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--window-size=1400,1300"):
        opts.add_argument(a)
    return webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=opts)


def test_the_page_shows_the_fleet_and_pauses_a_robot(mission, programs, tmp_path):
    from selenium.webdriver.common.by import By
    view, port = serve(tmp_path, programs, mission["db"], mission["sock"], "--world", str(mission["world"]),
                       "--sim", str(ev3_sim_path()))
    a, b = mission["ids"]
    drv = browser()
    try:
        drv.get(f"http://127.0.0.1:{port}/")

        def state(robot: int) -> str:
            cells = drv.find_elements(By.CSS_SELECTOR, f'tr[data-robot="{robot}"] td.state')
            return cells[0].text if cells else ""

        def led(robot: int) -> str:
            spans = drv.find_elements(By.CSS_SELECTOR, f'tr[data-robot="{robot}"] td.state span.led')
            return spans[0].get_attribute("class") if spans else ""

        wait_until(lambda: state(a) == "WORKING" and state(b) == "WORKING", 10, "both robots WORKING on the page")
        assert "GREEN" in led(a).split() and "GREEN" in led(b).split()
        assert drv.find_element(By.CSS_SELECTOR, f'tr[data-robot="{a}"] td.behaviour').text == "custom"
        assert drv.find_element(By.CSS_SELECTOR, f'tr[data-robot="{a}"] td.id').get_attribute("title") == (
            "model A: left motor, right motor, ultrasonic sensor, touch sensor, colour sensor")
        drv.find_element(By.CSS_SELECTOR, f'tr[data-robot="{a}"] button[data-command="pause"]').click()
        wait_until(lambda: state(a) == "PAUSED", 10, f"robot {a} PAUSED on the page")
        assert "ORANGE" in led(a).split()
        wait_until(lambda: drv.find_element(By.CSS_SELECTOR, f'tr[data-robot="{a}"] td.answer').text
                   == f"PAUSE: {a} acked", 5, "the robot's answer in its row")
        assert state(b) == "WORKING", "the other robot goes on"
        # The event log has the states and the commands from the record; a sensor plot is drawn.
        wait_until(lambda: "PAUSED" in drv.find_element(By.ID, "log").text, 5, "PAUSED in the event log")
        log = drv.find_element(By.ID, "log").text
        assert f"robot {a} command: PAUSE" in log and f"robot {b} state: WORKING" in log, log[-2000:]
        plot = f"plot-{b}-in4"
        wait_until(lambda: drv.execute_script(
            f"const i = document.getElementById('{plot}'); return i != null && i.complete && i.naturalWidth > 0"),
                   10, "robot b's distance plot drawn")
        assert drv.execute_script("const i = document.getElementById('map'); return i.complete && i.naturalWidth > 0")
        # The map draws both robots' paths from their pose reports (odometry).
        wait_until(lambda: all(f"robot {r}" in urllib.request.urlopen(f"http://127.0.0.1:{port}/map.svg",
                                                                      timeout=10).read().decode()
                               for r in (a, b)), 10, "both robots on the map")
        SHOT.parent.mkdir(parents=True, exist_ok=True)
        drv.save_screenshot(str(SHOT))
    finally:
        drv.quit()
    assert SHOT.stat().st_size > 10_000
    assert "Traceback" not in view.stderr(), view.stderr()


def test_control_needs_the_token_and_a_known_command(mission, programs, tmp_path):
    token_file = tmp_path / "token"
    token_file.write_text("s3cret-token-of-the-lab-fleet\n")
    _, port = serve(tmp_path, programs, mission["db"], mission["sock"], "--token-file", str(token_file))
    a = mission["ids"][0]
    code, body = post(port, {"robot": a, "command": "pause"})
    assert code == 403 and "token" in body["error"]
    code, body = post(port, {"robot": a, "command": "pause"}, token="wrong-token-wrong-token")
    assert code == 403
    code, body = post(port, {"robot": a, "command": "fly"}, token="s3cret-token-of-the-lab-fleet")
    assert code == 400 and "unknown command 'fly'" in body["error"]
    code, body = post(port, {"robot": "two", "command": "stop"}, token="s3cret-token-of-the-lab-fleet")
    assert code == 400 and "bad robot 'two'" in body["error"]
    code, body = post(port, {"robot": a, "command": "pause"}, token="s3cret-token-of-the-lab-fleet",
                      content_type="text/plain")
    assert code == 415
    code, body = post(port, {"robot": a, "command": "pause"}, token="s3cret-token-of-the-lab-fleet")
    assert code == 200 and body["ok"] and body["answers"] == [{"agent": a, "answer": "acked"}], body
    code, body = post(port, {"robot": 999, "command": "resume"}, token="s3cret-token-of-the-lab-fleet")
    assert code == 200 and not body["ok"] and body["answers"] == [{"agent": 999, "answer": "unknown_agent"}], body
    with urllib.request.urlopen(f"http://127.0.0.1:{port}/map.svg", timeout=10) as r:
        assert r.headers["Content-Type"].startswith("image/svg+xml")


@pytest.mark.empty_trace
def test_bad_flags_are_refused_at_start(tmp_path):
    (tmp_path / "short").write_text("abc\n")
    (tmp_path / "bad-world.txt").write_text("bounds 0 0 100 100\nbxo 1 2 3 4\n")

    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "ev3fleet.cli", "serve", "--db", str(tmp_path / "m.db"),
                               "--control", str(tmp_path / "m.sock"), *args], capture_output=True, text=True,
                              timeout=30)
    r = run("--bind", "localhost")
    assert r.returncode == 2 and "expected HOST:PORT" in r.stderr, r.stderr
    r = run("--token-file", str(tmp_path / "short"))
    assert r.returncode == 2 and "at least 16 printable ASCII characters" in r.stderr, r.stderr
    r = run("--token-file", str(tmp_path / "none"))
    assert r.returncode == 2 and "No such file" in r.stderr, r.stderr
    # A world file is read by ev3-sim, whose error names the line; without an ev3-sim to read it,
    # the view says what it needs.
    r = run("--world", str(tmp_path / "bad-world.txt"), "--sim", str(ev3_sim_path()))
    assert r.returncode == 2 and "bad-world.txt line 2" in r.stderr and "bxo" in r.stderr, r.stderr
    r = run("--world", str(tmp_path / "bad-world.txt"), "--sim", str(tmp_path / "no-sim"))
    assert r.returncode == 2 and "reading it needs ev3-sim" in r.stderr, r.stderr
    (tmp_path / "bad.json").write_text('{"bounds": [0, 0]}')
    r = run("--world", str(tmp_path / "bad.json"))
    assert r.returncode == 2 and "not the JSON of `ev3-sim world`" in r.stderr, r.stderr


@pytest.mark.empty_trace
def test_the_view_alone_guards_itself_and_stops_at_once(programs, tmp_path):
    """No master, no record yet: the page still loads, says why it has nothing, refuses a request
    addressed to another host name (DNS rebinding) and any framing; an unknown picture is a 404;
    SIGTERM with a page's event stream open ends the view within a second or two; a port in use is
    refused at start, before any address is printed."""
    view, port = serve(tmp_path, programs, tmp_path / "none.db", tmp_path / "none.sock")

    def get(path: str, host: str | None = None):
        c = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
        c.request("GET", path, headers={"Host": host} if host else {})
        try:
            r = c.getresponse()
            return r.status, dict(r.getheaders()), r.read()
        finally:
            c.close()
    status, headers, body = get("/")
    assert status == 200 and b"ev3 fleet" in body
    assert headers["X-Frame-Options"] == "DENY" and "frame-ancestors 'none'" in headers["Content-Security-Policy"]
    status, _, body = get("/", host=f"rebound.example:{port}")
    assert status == 403 and b"only at a loopback address" in body
    assert get("/plot/99999999999999999999/in4.svg")[0] == 404
    assert get("/plot/2/in4.svg")[0] == 404
    assert get("/map.svg")[0] == 200
    stream = socket.create_connection(("127.0.0.1", port), timeout=10)
    stream.sendall(f"GET /events HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode())
    seen = b""
    while b"event: fleet" not in seen:
        seen += stream.recv(4096)
    assert b"none.db: no such file" in seen or b"no such file" in seen  # the record's trouble, on the page
    t = time.monotonic()
    view.proc.send_signal(signal.SIGTERM)
    assert view.proc.wait(10) == 0
    assert time.monotonic() - t < 3, "the view took long to stop with a page open"
    stream.close()
    programs.remove(view)
    view.close()
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        r = subprocess.run([sys.executable, "-m", "ev3fleet.cli", "serve", "--db", str(tmp_path / "m.db"),
                            "--control", str(tmp_path / "m.sock"), "--bind", f"127.0.0.1:{busy.getsockname()[1]}"],
                           capture_output=True, text=True, timeout=30)
    assert r.returncode == 2 and "cannot serve on" in r.stderr and "the fleet's view at" not in r.stdout, r
