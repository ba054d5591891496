"""Signed mode (docs/protocol.md "Signed datagrams"): ev3-master and ev3-agent (native, and the
static armel build under qemu-arm) with one key, a man in the middle on their link (ev3net.Links)
that captures everything, and a stranger on the network. Every forged, altered, replayed, unsigned
and wrong-key datagram is refused and counted by reason; the agent never acts on one; a command
withheld and replayed after a newer one is not obeyed; the master stays in command throughout.
Bad key files stop both programs at start with an error naming the file."""

from __future__ import annotations

import os
import re
import shutil
import socket
import subprocess
import time
from pathlib import Path

import pytest

from ev3conformance.signing import counter, seal, unseal
from ev3net import Links, Program, assert_static_armel, drop_counters, free_ports, read_status, unsigned, wait_until

KEY = bytes(range(100, 132))
OTHER = bytes(range(32))


def key_file(path: Path, key: bytes, mode: int = 0o600) -> Path:
    path.write_text(key.hex() + "\n")
    os.chmod(path, mode)
    return path


def drops_of(log: str) -> dict[str, int]:
    """The auth: drop counters of a program's stop line."""
    return {k: v for k, v in drop_counters(log).items() if k.startswith("auth:")}


def agent_cmd(request) -> list[str]:
    if request.param == "native":
        return [os.environ.get("EV3_BIN", str(Path(__file__).resolve().parents[3] / "build" / "bin")) + "/ev3-agent"]
    d = os.environ.get("EV3_ARM_BIN")
    assert d, "EV3_ARM_BIN is not set: run this through `make test-blackbox` (it builds `make arm` first)"
    exe = Path(d) / "ev3-agent"
    assert exe.is_file(), f"{exe} is missing: build it with `make arm`"
    assert shutil.which("qemu-arm"), "qemu-arm is missing (make deps installs qemu-user)"
    assert_static_armel(exe)
    return [shutil.which("qemu-arm"), str(exe)]


@pytest.fixture(params=["native", "armel"])
def agent_argv(request):
    return agent_cmd(request)


def test_only_the_keyholder_commands_a_signed_fleet(agent_argv, master_exe, programs, tmp_path):
    key = key_file(tmp_path / "fleet.key", KEY)
    mport, aport = free_ports(2)
    links = Links(1)
    links.connect(aport, [mport])  # the agent is Links' X: what goes towards it can be withheld
    status = tmp_path / "status.json"
    m = Program(master_exe, ["--port", str(mport), "--bind", "127.0.0.1", "--broadcast",
                             f"127.0.0.1:{links.to_x(mport)}", "--status-json", str(status),
                             "--agent-timeout-ms", "3000", "--resend-ms", "300", "--key-file", str(key),
                             "--log-level", "3"], tmp_path, "master", stdin=subprocess.PIPE)
    programs.append(m)
    a = Program(Path(agent_argv[0]), agent_argv[1:] + [
        "--port", str(aport), "--bind", "127.0.0.1", "--broadcast", f"127.0.0.1:{links.to_peer(mport)}",
        "--heartbeat-ms", "100", "--master-timeout-ms", "1500", "--key-file", str(key), "--log-level", "3"],
        tmp_path, "agent")
    programs.append(a)
    stranger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        def agent_state():
            xs = (read_status(status) or {}).get("agents", [])
            return xs[0]["state"] if xs else None
        wait_until(lambda: agent_state() == "ACTIVE", 15, "the agent ACTIVE in the master's status")
        aid = read_status(status)["agents"][0]["id"]
        m.write(f"behaviour {aid} wait seconds=60")
        m.write(f"start {aid}")
        wait_until(lambda: agent_state() == "WORKING", 10, "the agent WORKING")
        sent = {"auth:unsigned": 0, "auth:wrong_key": 0, "auth:bad_mac": 0, "auth:replay": 0}

        def attack(data: bytes, why: str, port: int = aport):
            stranger.sendto(data, ("127.0.0.1", port))
            sent[why] += 1

        # A stranger's STOP as docs/protocol.md spells it, with a msgid that would make every later
        # command of the master look stale; the same signed with another key.
        attack(f"1:{aid}:4000000000:9".encode(), "auth:unsigned")
        attack(seal(f"1:{aid}:4000000001:9".encode(), OTHER, counter(int(time.time() * 1000) + 10**6)),
               "auth:wrong_key")
        # Captured copies of the master's, altered: a msgid digit, the type (PONG -> STOP), the tag.
        captured = [d for towards_agent, d in links.passed if towards_agent]
        assert captured, "the man in the middle saw nothing from the master"
        pong = next(d for d in captured if unsigned(d).split(b":")[3] == b"6")
        d = unseal(pong)[0]
        fields = d.split(b":")
        msgid = fields[2][:-1] + (b"1" if fields[2][-1:] != b"1" else b"2")
        attack(b":".join(fields[:2] + [msgid] + fields[3:]) + pong[len(d):], "auth:bad_mac")
        attack(b":".join(fields[:3] + [b"9"]) + pong[len(d):], "auth:bad_mac")
        attack(pong[:-1] + (b"0" if pong[-1:] != b"0" else b"1"), "auth:bad_mac")
        # Every copy the master sent so far, again.
        for c in captured:
            attack(c, "auth:replay")
        # A stranger's PING to the master as the agent.
        attack(f"{aid}:1:999:5:PANIC".encode(), "auth:unsigned", port=mport)

        # A PAUSE withheld by the man in the middle (every copy of every resend) ...
        links.drop = {"PAUSE"}
        m.write(f"pause {aid}")
        wait_until(lambda: links.dropped.get("PAUSE", 0) >= 6, 5, "two sends of the PAUSE withheld")
        links.drop = set()
        # ... goes through on a later resend, then the master resumes the agent.
        wait_until(lambda: agent_state() == "PAUSED", 5, "the agent PAUSED by the master")
        m.write(f"resume {aid}")
        wait_until(lambda: agent_state() == "WORKING", 5, "the agent WORKING again")
        resumed = len(a.stderr())
        # The withheld copies replayed now: none is obeyed. The window refuses those 64 or more
        # copies behind the master's newest (auth:replay); the rest are copies of a PAUSE the agent
        # took, answered again and not acted on.
        for c in links.withheld:
            stranger.sendto(c, ("127.0.0.1", aport))
        time.sleep(1.2)  # the agent's PINGs (100 ms) and the status file (500 ms) catch up
        assert agent_state() == "WORKING"
        assert "state PAUSED" not in a.stderr()[resumed:], "a withheld PAUSE was obeyed"
        # The master is still in command.
        m.write(f"pause {aid}")
        wait_until(lambda: agent_state() == "PAUSED", 5, "the agent PAUSED by the master after the attacks")
        drops_master = (read_status(status) or {}).get("drops", {})
        assert drops_master.get("auth:unsigned") == 1, drops_master
    finally:
        stranger.close()
    assert a.stop() == 0
    got = drops_of(a.stderr())
    want = {k: v for k, v in sent.items() if v and k != "auth:unsigned"}
    want["auth:unsigned"] = sent["auth:unsigned"] - 1  # one went to the master
    # Replays: every captured copy sent again, and those of the withheld copies the window refuses.
    assert want["auth:replay"] <= got.get("auth:replay", 0) <= want["auth:replay"] + len(links.withheld), (got, want)
    want.pop("auth:replay")
    assert {k: got.get(k, 0) for k in want} == want, (got, want)
    # Nothing of the stranger's reached the agent's core (it logs every datagram it takes).
    assert "4000000000" not in a.stderr() and "4000000001" not in a.stderr()
    assert re.search(rf"recv 1:{aid}:\d+:10 ", a.stderr()), "the master's PAUSE in the agent's log"
    assert re.search(r"signed mode: key id [0-9A-F]{8}, boot \d+", a.stderr())
    assert KEY.hex() not in a.stderr() and KEY.hex().upper() not in a.stderr()
    assert KEY.hex() not in m.stderr() and KEY.hex() not in m.stdout()
    links.close()


@pytest.mark.parametrize("prog", ["ev3-master", "ev3-agent"])
@pytest.mark.parametrize("case", ["mode", "length", "digit", "missing"])
def test_a_bad_key_file_stops_the_program_naming_it(prog, case, tmp_path):
    exe = Path(os.environ.get("EV3_BIN", Path(__file__).resolve().parents[3] / "build" / "bin")) / prog
    f = tmp_path / "fleet.key"
    if case == "mode":
        key_file(f, KEY, 0o644)
    elif case == "length":
        f.write_text(KEY.hex()[:-2] + "\n")
        os.chmod(f, 0o600)
    elif case == "digit":
        f.write_text(KEY.hex()[:-1] + "g\n")
        os.chmod(f, 0o600)
    r = subprocess.run([str(exe), "--port", "0", "--bind", "127.0.0.1", "--key-file", str(f)],
                       capture_output=True, text=True, timeout=10)
    assert r.returncode == 2, r
    want = {"mode": "readable by group or others (mode 0644): chmod 600 it",
            "length": "is not 64 hex digits (a 32-byte key)",
            "digit": "holds a character that is not a hex digit",
            "missing": "cannot be read: No such file or directory"}[case]
    assert f"{prog}: bad value for --key-file: {f}: {want}" in r.stderr, r.stderr
    assert KEY.hex()[:20] not in r.stderr
