"""The trace modules of spec/tla/trace/ checked themselves, as `make spec` does (tools/spec.py
check): SANY on every module, each trace check (ev3conformance.tracecheck) on its sample trace and
the whole-run check (ev3conformance.merged) on a sample run, each also on the same trace with a
fault in it, which it must reject."""

from __future__ import annotations

import json
import shutil
import subprocess
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from ev3conformance import graph as gr
from ev3conformance import merged, tracecheck


def _sany(modules: list[str], cwd: Path) -> str | None:
    """SANY on @p modules in @p cwd: None, or its report of the first module with errors."""
    md = tempfile.mkdtemp(prefix="sany-", dir=cwd)
    try:
        p = subprocess.run(gr.JAVA + gr.C1_ONLY + [f"-Djava.io.tmpdir={md}", "-cp", str(gr.JAR), "tla2sany.SANY"] + modules,
                           cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    finally:
        shutil.rmtree(md, ignore_errors=True)
    out = p.stdout
    if p.returncode != 0 or "*** Errors" in out or "Semantic errors" in out or "Parse Error" in out:
        return out
    return None


def check_modules(say=print, jobs: int = 2) -> bool:
    """What make spec checks of spec/tla/trace/: SANY on every module (the MC*Trace ones are parsed by
    TLC with their sample's data), and each check on its sample trace (samples/samples.json): the
    sample must conform, and the same trace with one record changed must be rejected naming that
    record. A sample with "run" (MCMergedTrace) is a directory of one run's traces, checked whole
    (ev3conformance.merged): it must conform, and each of its "plants" planted in it must be rejected
    naming the file and record, and failing the one invariant it is planted for (merged.PLANT_INVARIANT).
    Every MC*Trace module must have a sample. Prints one line per check;
    True when all pass."""
    wd = gr.BUILD / "trace-modules"
    wd.mkdir(parents=True, exist_ok=True)
    d = Path(tempfile.mkdtemp(prefix="sany-", dir=wd))
    for f in sorted(gr.SPEC.glob("*.tla")) + sorted(tracecheck.TRACE_SPEC.glob("*.tla")):
        shutil.copy(f, d / f.name)
    mods = sorted(f.name for f in tracecheck.TRACE_SPEC.glob("*.tla"))
    err = _sany([m for m in mods if not m.startswith("MC")], d)
    shutil.rmtree(d, ignore_errors=True)
    if err:
        say(err)
        say("FAIL trace modules: SANY found errors (above)")
        return False
    say(f"trace modules: SANY ok on {', '.join(m for m in mods if not m.startswith('MC'))}")
    spec = json.loads((tracecheck.SAMPLES / "samples.json").read_text())["samples"]
    missing = sorted({m[:-4] for m in mods if m.startswith("MC")} - {s["module"] for s in spec})
    runs = [s for s in spec if "run" in s]  # whole runs (MCMergedTrace): a directory of traces
    spec = [s for s in spec if "run" not in s]
    if missing:
        say(f"FAIL trace modules: no sample trace checks {', '.join(missing)} (samples/samples.json)")
        return False

    def run(job):
        s, bad = job
        path = tracecheck.SAMPLES / s["trace"]
        k = 0
        if bad:
            recs = [json.loads(x) for x in path.read_text().splitlines() if x.strip()]
            k = s["corrupt"]["record"]
            recs[k - 1] = dict(recs[k - 1], changed=dict(recs[k - 1].get("changed", {}), **s["corrupt"]["changed"]))
            path = Path(tempfile.mkdtemp(prefix="bad-", dir=wd)) / s["trace"]
            path.write_text("".join(json.dumps(r) + "\n" for r in recs))
        r = (tracecheck.validate_master(path, s["consts"], workdir=wd) if s.get("master")
             else tracecheck.validate(path, s["consts"], workdir=wd))
        if bad:
            shutil.rmtree(path.parent, ignore_errors=True)
            ok = not r.ok and f"record {k} of {r.records} could not be matched" in r.message
            return ok, f"{s['module']} on {s['trace']} with record {k} changed: " + \
                       (f"rejected, record {k} named" if ok else f"NOT REJECTED AS IT SHOULD BE: {r.message}")
        return r.ok, f"{s['module']} on {s['trace']}: {r.message}"

    def run_merged(job):
        # the run must conform; each planted fault must be rejected, naming the file it was planted in
        s, fault = job
        path = tracecheck.SAMPLES / s["run"]
        if fault is None:
            r = merged.validate([path], workdir=wd, loss=s["consts"]["TLoss"])
            return r.ok, f"{s['module']} on {s['run']}/ ({r.seconds:.0f} s): {r.message.splitlines()[0]}"
        out = Path(tempfile.mkdtemp(prefix="plant-", dir=wd))
        where = merged.plant([path], out, fault, s["consts"]["TLoss"])
        r = merged.validate([out], workdir=wd, loss=s["consts"]["TLoss"])
        shutil.rmtree(out, ignore_errors=True)
        inv = merged.PLANT_INVARIANT[fault]
        head = r.message.splitlines()[0] if r.message else ""
        ok = (not r.ok and where.split(" (")[0] in r.message and "cannot merge" not in r.message
              and (f"({inv}" in head or f"{inv} is violated" in head))
        return ok, (f"{s['module']} on {s['run']}/ with {fault} planted at {where}: " +
                    (f"rejected: {r.message.splitlines()[0]}" if ok else f"NOT REJECTED AS IT SHOULD BE: {r.message}"))

    with ThreadPoolExecutor(max_workers=max(1, jobs)) as ex:
        results = list(ex.map(run, [(s, bad) for s in spec for bad in (False, True)]))
        results += list(ex.map(run_merged, [(s, f) for s in runs for f in [None] + s["plants"]]))
    for ok, line in results:
        say(f"{'ok  ' if ok else 'FAIL'} {line}")
    return all(ok for ok, _ in results)
