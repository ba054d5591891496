"""A deliberately broken driver: runs the real `ev3-agent --driver` and corrupts its output
(after RecvMaster the state reads WORKING). Replay must fail against it."""
import json
import subprocess
import sys

real = subprocess.Popen(sys.argv[1:], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1)
for line in sys.stdin:
    real.stdin.write(line)
    real.stdin.flush()
    out = json.loads(real.stdout.readline())
    for a in out.get("actions", []):
        if a["action"] == "RecvMaster":
            a["vars"]["state"] = "WORKING"
    print(json.dumps(out), flush=True)
