"""A deliberately broken driver: runs the real `ev3-agent --driver` (argv[1:], ending with
`--trace FILE`) and corrupts the trace it writes: the first record that changes `state` claims the
wrong state (ACTIVE <-> WORKING, others -> PAUSED). Its outputs are the real ones. Trace validation
must reject it."""
import json
import subprocess
import sys
from pathlib import Path

argv = sys.argv[1:]
k = argv.index("--trace")
target = Path(argv[k + 1])
real_trace = target.with_name(target.name + ".real")
argv[k + 1] = str(real_trace)
p = subprocess.run(argv, stdin=sys.stdin, check=False)
recs = [json.loads(x) for x in real_trace.read_text().splitlines() if x.strip()]
for r in recs:
    ch = r.get("changed", {})
    if "state" in ch:
        ch["state"] = {"ACTIVE": "WORKING", "WORKING": "ACTIVE"}.get(ch["state"], "PAUSED")
        break
target.write_text("".join(json.dumps(r) + "\n" for r in recs))
sys.exit(p.returncode)
