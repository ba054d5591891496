"""`make demo`'s run, in `make test`: tools/demo.py (a master and three agents over loopback UDP: sync,
a behaviour, the master killed, an election with a relay, the elected agent's commands, the PC taking
the fleet back) must complete every phase, and every trace it leaves (three agents, the master's two
runs, the elected agent's Master core) must be validated by TLC as conforming (docs/spec.md
"Election traces", "Election master traces"), and so must the whole run, all of them merged ("Whole-run
traces": System.tla's and Election.tla's invariants, the agents' timeout the demo's).
The demo also checks its mission record (the master's --db) against the agents' traces: every report
each agent made is in it once; and it starts the web view (ev3-fleet serve), prints its address, and
checks that its map draws both exploring robots from their pose reports. The demo exits 1 on a failed phase, a record that differs or a trace
that does not conform; its output names which."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]


def test_demo_runs_and_its_traces_conform(agent_exe: Path, tmp_path: Path):
    demo = subprocess.run([sys.executable, str(REPO / "tools" / "demo.py"), "--bin", str(agent_exe.parent),
                           "--dir", str(tmp_path / "demo")],
                          capture_output=True, text=True, timeout=600)
    out = demo.stdout + demo.stderr
    assert demo.returncode == 0, out[-6000:]
    verdicts = [line for line in out.splitlines() if ": conforms: " in line or "DOES NOT CONFORM" in line]
    # three agents, the master's runs before and after the kill, the elected agent's Master core
    assert len(verdicts) >= 6, out[-6000:]
    assert all(": conforms: " in line for line in verdicts), "\n".join(verdicts)
    assert any(line.lstrip().startswith("the whole run (5 traces merged): conforms: ") for line in verdicts), \
        "\n".join(verdicts)
    assert "DEMO FAILED" not in out
    record = [line for line in out.splitlines() if "reports; the record holds" in line]
    assert len(record) == 3 and all(line.endswith("every one, once") for line in record), "\n".join(record)
    assert any("started the web view (ev3-fleet serve" in line and "open http://127.0.0.1:" in line
               for line in out.splitlines()), out[-6000:]
    assert any("the web view's map" in line and "draws the paths of agents" in line for line in out.splitlines())
