"""A deliberately broken election node: runs the real driver (the rest of the command line) and
changes what it does, as a faulty implementation would, by FAULT (the first argument):

  double-vote    an agent that already voted for another candidate in an ELECT's epoch grants it a
                 second VOTE (and reports the vote moved): two votes in one epoch
  ignore-epoch   an agent answers no EPOCH_STALE to an ELECT of an older epoch (it does not fence
                 a stale candidate)
  no-handover    an elected agent's Master core sends no HANDOVER when it steps down

The election replay must catch each of them."""
import json
import subprocess
import sys

fault, argv = sys.argv[1], sys.argv[2:]
real = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1)
state = {}


def decode(hexs: str) -> list[str]:
    return bytes.fromhex(hexs).decode("latin-1").split(":")


for line in sys.stdin:
    real.stdin.write(line)
    real.stdin.flush()
    out = json.loads(real.stdout.readline())
    inp = json.loads(line)
    el_before = state.get("el")
    if inp.get("type") == "recv" and "election" in out:
        f = decode(inp["hex"])
        sender, typ, params = int(f[0]), int(f[3]), f[4:]
        if fault == "double-vote" and typ == 27 and el_before:
            e = int(params[0])
            voted = el_before["votedFor"]
            if e == el_before["epoch"] and voted not in (0, sender) and not out["sent"]:
                me = out["vars"]["id"]
                text = f"{me}:{sender}:{out['vars'].get('msgid', 9000)}:28:{e}:{sender}"
                out["sent"].append({"to": "peer", "peer": sender, "text": text, "hex": text.encode().hex()})
                out["election"]["votedFor"] = sender
        if fault == "ignore-epoch" and typ == 27 and el_before and int(params[0]) < el_before["epoch"]:
            out["sent"] = [s for s in out["sent"] if decode(s["hex"])[3] != "30"]
    if fault == "no-handover":
        out["sent"] = [s for s in out.get("sent", []) if decode(s["hex"])[3] != "32"]
    if "election" in out:
        state["el"] = out["election"]
    print(json.dumps(out), flush=True)
