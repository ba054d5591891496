#!/usr/bin/env python3
"""Runner for the TLA+ spec of libev3proto (spec/tla/, docs/spec.md).

Subcommands:
  check --size small|full [--update]   SANY + TLC on each model of that size;
                                       figures compared with spec/tla/manifest.json;
                                       then the trace modules (spec/tla/trace) on their samples
  check --size quick                   make check's share: the small models marked "quick"
                                       in the manifest (one per spec module) and the thesis
                                       model; no trace modules
  refute                               every broken variant (every BUG switch of the
                                       spec) must be refuted on the property it
                                       breaks, by a model make spec runs, with that
                                       model's constants; fails on any other
  diagram [--check]                    docs/lifecycle.{dot,svg} from TLC's state graph
                                       of MCAgent; --check fails if they are stale
  mutate [--only ID..] [--all] [--list]
                                       the spec mutations of spec/tla/mutations.toml, each
                                       on a copy of spec/tla with the models make spec
                                       runs, until one kills it (docs/spec.md)
  scale MODEL AGENTS [--set NAME=VALUE] [--simulate N --depth D]
                                       one model of the manifest with other agents (AGENTS:
                                       a TLA+ set, "{2, 3, 4}"), invariants only, one worker:
                                       states, depth, time; or N random behaviours
  distributed MODEL [--workers N] [--threads T] [--host H] [--bug B]
                                       one model of the manifest by TLC's distributed mode:
                                       a TLCServer and N TLCWorker processes (on this machine,
                                       or workers started by hand on others); invariants only

Python 3 standard library only.  Uses the pinned jar .tools/tla2tools.jar; every
TLC run gets its own -metadir under build/spec/.
"""
import argparse
import contextlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SPEC = os.path.join(ROOT, "spec", "tla")   # check --spec DIR: that copy instead
SHIPPED_SPEC = SPEC
JAR = os.path.join(ROOT, ".tools", "tla2tools.jar")
BUILD = os.path.join(ROOT, "build", "spec")
MANIFEST = os.path.join(SPEC, "manifest.json")
DOCS = os.path.join(ROOT, "docs")
JAVA = ["java", "-XX:+UseParallelGC", "-Xss16m"]
# A run expected to take less than C1_SECONDS (the manifest's figure; a run with none: a refute
# variant or a spec mutation, which stop at the first violation) leaves out the JVM's optimising
# compiler (C2): on runs of seconds its compiler threads cost more CPU than they win back, about half
# of a run of a few seconds (docs/spec.md "Commands").
C1_SECONDS = 10
C1_ONLY = ["-XX:TieredStopAtLevel=1"]
# TLC runs at a time in check and refute (one JVM each; a model's own -workers as the manifest says).
JOBS = int(os.environ.get("SPEC_JOBS", "2"))
# Every run of check and refute is stopped, and fails naming its model, when it has run LIMIT_FACTOR
# times the seconds manifest.json gives for it (a variant: its own seconds, else its model's), and at
# least LIMIT_FLOOR seconds: a change that livelocks a model (counters growing without bound, TLC
# exploring for ever) fails within minutes instead of holding the suite until CI kills it.
LIMIT_FACTOR = float(os.environ.get("SPEC_LIMIT_FACTOR", "10"))
LIMIT_FLOOR = float(os.environ.get("SPEC_LIMIT_FLOOR", "60"))


def limit(seconds):
    """The most seconds a run expected to take @p seconds (None: unknown, 5) may take."""
    return max(LIMIT_FLOOR, LIMIT_FACTOR * (seconds if seconds is not None else 5.0))


def no_verdict(name, out, secs):
    """The failure line of a run stopped at its limit: where TLC was (depth, distinct states)."""
    prog = re.findall(r"Progress\((\d+)\) at [^:]*:\d+:\d+: ([\d,]+) states generated.*?([\d,]+) distinct", out)
    where = ("TLC's last progress report (one a minute): depth %s, %s distinct states" % (prog[-1][0], prog[-1][2])
             if prog else "TLC had not reported its progress yet")
    return ("FAIL %s: no verdict within %.0f s (%g times its time in manifest.json, at least %.0f s); %s: a "
            "livelock, whose counters grow without bound?" % (name, secs, LIMIT_FACTOR, LIMIT_FLOOR, where))


def load_manifest():
    with open(MANIFEST) as f:
        return json.load(f)


def run(cmd, timeout=None, cwd=None):
    """rc, output, seconds; rc None when the run took longer than timeout (it is killed)."""
    cwd = cwd or SPEC
    t0 = time.monotonic()
    try:
        p = subprocess.run(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True, timeout=timeout)
    except subprocess.TimeoutExpired as e:
        out = e.stdout.decode(errors="replace") if isinstance(e.stdout, bytes) else (e.stdout or "")
        return None, out, time.monotonic() - t0
    return p.returncode, p.stdout, time.monotonic() - t0


# Every TLC run of one `check` or `refute` goes into one pool of JOBS runs, the costliest first (the
# manifest's seconds times the model's workers), so that a long run does not end alone while the other
# core idles; the results are printed in the manifest's order.
_POOL = None
_STARTED = {}


def start_all(jobs):
    """jobs: [(key, fn, item, cost)]: fn(item) started in the pool, the costliest first; in_parallel
    takes the result of a started key instead of running it again."""
    global _POOL
    if _POOL is None:
        _POOL = ThreadPoolExecutor(max(1, JOBS))
    for key, fn, item, _ in sorted(jobs, key=lambda j: -j[3]):
        if key not in _STARTED:
            _STARTED[key] = _POOL.submit(fn, item)


def in_parallel(fn, items, key=None):
    """fn(item) for each item, JOBS at a time; the results in the order of items, each as soon as
    it and those before it are done. A run start_all started (its key(item)) is not run again."""
    keys = [key(it) if key else ("run", id(it)) for it in items]
    start_all([(k, fn, it, 0) for k, it in zip(keys, items)])
    for k in keys:
        yield _STARTED[k].result()


def cost(m):
    """The expected CPU seconds of a run of manifest model m (its measured seconds times workers)."""
    return m.get("measured", {}).get("seconds", 10.0) * m.get("workers", 1)


def metadir(name):
    os.makedirs(BUILD, exist_ok=True)
    d = tempfile.mkdtemp(prefix=name + "-", dir=BUILD)
    return d


def sany(module):
    tmp = metadir("sany-" + module)
    rc, out, _ = run(JAVA + ["-Djava.io.tmpdir=" + tmp, "-cp", JAR, "tla2sany.SANY", module + ".tla"])
    shutil.rmtree(tmp, ignore_errors=True)
    if rc != 0 or "*** Errors" in out or "Semantic errors" in out or "Parse Error" in out:
        print(out)
        raise SystemExit("SANY failed on %s" % module)


def tlc(module, cfg, workers=2, extra=(), name=None, cwd=None, timeout=None, seconds=None):
    """TLC on module (a .tla in cwd, the spec directory unless a mutant's copy) with cfg; seconds:
    how long the run is expected to take, if known (C1_SECONDS)."""
    md = metadir(name or module)
    # Its own java.io.tmpdir too: TLC extracts the standard modules there, and parallel runs sharing
    # /tmp race on those files (tlaplus/tlaplus#378).
    jvm = JAVA + (C1_ONLY if seconds is None or seconds < C1_SECONDS else [])
    cmd = jvm + ["-Djava.io.tmpdir=" + md, "-cp", JAR, "tlc2.TLC", "-workers", str(workers), "-metadir", md,
                  "-config", cfg] + list(extra) + [module + ".tla"]
    rc, out, secs = run(cmd, timeout=timeout, cwd=cwd)
    shutil.rmtree(md, ignore_errors=True)
    return rc, out, secs


def figures(out):
    g = re.search(r"([\d,]+) states generated, ([\d,]+) distinct states found, (\d+) states left", out)
    d = re.search(r"The depth of the complete state graph search is (\d+)", out)
    if not g:
        return None
    return {"generated": int(g.group(1).replace(",", "")),
            "distinct": int(g.group(2).replace(",", "")),
            "depth": int(d.group(1)) if d else None}


def violation(out):
    """Name of the violated property, or a description, or None."""
    m = re.search(r"Invariant (\w+) is violated", out)
    if m:
        return m.group(1)
    m = re.search(r"Action property (\w+) of the temporal formula", out) or \
        re.search(r"Action property (\w+) is violated", out)
    if m:
        return m.group(1)
    if "Temporal properties were violated" in out:
        return "temporal"
    if "Deadlock reached" in out:
        return "deadlock"
    if re.search(r"^Error:", out, re.M):
        return "error"
    return None


def counterexample(out):
    i = out.find("Error:")
    return out[i:] if i >= 0 else out[-4000:]


def check_tsv():
    """The spec's TypeNum must match docs/messages.tsv."""
    tsv = {}
    with open(os.path.join(DOCS, "messages.tsv")) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            cols = line.rstrip("\n").split("\t")
            tsv[cols[1]] = int(cols[0])
    with open(os.path.join(SPEC, "Messages.tla")) as f:
        text = f.read()
    body = text[text.index("TypeNum =="):text.index("TypeNames")]
    spec = {k: int(v) for k, v in re.findall(r"(\w+) \|-> (\d+)", body)}
    if spec != tsv:
        raise SystemExit("Messages.tla TypeNum differs from docs/messages.tsv:\n  spec %s\n  tsv  %s"
                         % (sorted(spec.items()), sorted(tsv.items())))
    print("types: Messages.tla TypeNum matches docs/messages.tsv (%d types)" % len(tsv))


def check_model(m):
    """TLC on a model of the manifest. "dump": NAME also dumps its state graph where `ev3-conformance
    replay` takes it (build/conformance/NAME-graph.dot, recorded with the spec's digest): make
    conformance then replays the graph of this run instead of running TLC on the model again."""
    secs = m.get("measured", {}).get("seconds")
    if not m.get("dump") or SPEC != SHIPPED_SPEC:  # a copy's graph is not the shipped spec's
        return tlc(m["module"], m["cfg"], workers=m.get("workers", 1), name=m["name"], seconds=secs,
                   timeout=limit(secs))
    sys.path.insert(0, os.path.join(ROOT, "conformance"))
    from ev3conformance import graph
    rc, out, secs = tlc(m["module"], m["cfg"], workers=m.get("workers", 1), name=m["name"],
                        extra=graph.dump_args(m["dump"]), seconds=secs, timeout=limit(secs))
    if rc == 0 and "Model checking completed. No error has been found." in out:
        graph.record_dump(m["module"], m["cfg"], m["dump"], out)
    return rc, out, secs


def of_size(m, size):
    """Whether manifest entry m is run by `check --size size`: quick is a subset of small."""
    if size == "quick":
        return m["size"] == "small" and m.get("quick", False)
    return m["size"] == size


def chosen(m, args):
    """Whether `check` runs manifest model m: of its --size, and named by --only if given."""
    return of_size(m, args.size) and (not getattr(args, "only", None) or m["name"] in args.only)


def cmd_check(args):
    man = load_manifest()
    check_tsv()
    failed = False
    models = [m for m in man["models"] if chosen(m, args)]
    for mod in sorted({m["module"] for m in models}):
        sany(mod)
    # One worker: TLC's reported depth is only exact with a single worker.
    runs = in_parallel(check_model, models, key=lambda m: ("check", m["name"]))
    for m, (rc, out, secs) in zip(models, runs):
        if rc is None:
            print(no_verdict(m["name"], out, secs))
            failed = True
            continue
        fig = figures(out)
        v = violation(out)
        if v or fig is None or "Model checking completed. No error has been found." not in out:
            print("FAIL %s: %s" % (m["name"], v or "TLC did not complete"))
            print(counterexample(out))
            failed = True
            continue
        line = "%-14s states %9d  distinct %8d  depth %3d  time %6.1fs" % (
            m["name"], fig["generated"], fig["distinct"], fig["depth"], secs)
        if args.update:
            m["distinct"], m["depth"] = fig["distinct"], fig["depth"]
            m["measured"] = {"generated": fig["generated"], "seconds": round(secs, 1)}
            print(line + "  (manifest updated)")
        elif fig["distinct"] != m.get("distinct") or fig["depth"] != m.get("depth"):
            print(line + "  MISMATCH: manifest says distinct %s depth %s"
                  % (m.get("distinct"), m.get("depth")))
            failed = True
        else:
            print(line + "  ok")
    if args.update:
        with open(MANIFEST, "w") as f:
            json.dump(man, f, indent=2)
            f.write("\n")
    if failed:
        raise SystemExit(1)


def is_liveness(p):
    """A temporal (liveness) property: not an invariant nor an action property."""
    return not (p.endswith("Inv") or p.endswith("Prop") or p == "TypeOK")


def variant_cfg(base, bug, props, name=None, sets=None, src=None, dest=BUILD):
    """The base cfg (in src) with BUG = bug (bug None: BUG as it is) and the constants in sets
    changed, and only the given properties checked (props None: the base cfg's own properties);
    written to dest, its path returned."""
    with open(os.path.join(src or SPEC, base)) as f:
        lines = f.read().splitlines()
    sets = dict(sets or {})
    outl, skip = [], False
    for ln in lines:
        s = ln.strip()
        if s.startswith("BUG") and bug is not None:
            outl.append('    BUG = "%s"' % bug)
            continue
        key = s.split("=")[0].strip() if "=" in s else None
        if key in sets:
            outl.append("    %s = %s" % (key, sets.pop(key)))
            continue
        if props is None:
            outl.append(ln)
            continue
        if s in ("INVARIANTS", "INVARIANT", "PROPERTIES", "PROPERTY"):
            skip = True
            continue
        if skip and (ln.startswith(" ") or ln.startswith("\t")):
            continue
        skip = False
        if s == "SPECIFICATION FairSpec" and not any(is_liveness(p) for p in props):
            ln = "SPECIFICATION Spec"  # safety only; a liveness variant keeps FairSpec
        outl.append(ln)
    if sets:
        raise SystemExit("variant %s: %s not constants of %s" % (bug, sorted(sets), base))
    for p in props or ():
        outl.append(("INVARIANT %s" if p.endswith("Inv") or p == "TypeOK" else "PROPERTY %s") % p)
    os.makedirs(dest, exist_ok=True)
    path = os.path.join(dest, "refute-%s.cfg" % (name or bug))
    with open(path, "w") as f:
        f.write("\n".join(outl) + "\n")
    return path


# Every broken variant is a BUG switch of the spec (or a protocol switch turned off, "set"), checked
# with the constants of a model that `make spec` runs on the shipped spec (size small): a variant
# refuted only by a model of its own would show nothing about the CI models.
BUG_RE = re.compile(r'\bBUG\s*(?:=|#)\s*"(\w+)"')


def spec_switches():
    """Every BUG value the spec modules test, with the module naming it."""
    found = {}
    for fn in sorted(os.listdir(SPEC)):
        if fn.endswith(".tla") and not fn.startswith("MC"):
            with open(os.path.join(SPEC, fn)) as f:
                for b in BUG_RE.findall(f.read()):
                    if b.lower() != "none":
                        found.setdefault(b, fn)
    return found


def variants_declared():
    """Fails unless every BUG switch of the spec is refuted by a CI (small) model in the manifest,
    and no variant has a configuration of its own (MC*Bug*.cfg)."""
    man = load_manifest()
    small = {m["name"] for m in man["models"] if m["size"] == "small"}
    el = man["election"]
    small_el = {m["name"] for m in el["models"] + el.get("live", []) if m["size"] == "small"}
    problems = []
    refuted = set()
    for v in man["refute"]:
        if v["model"] not in small:
            problems.append("BUG=%s is refuted by %s, not a model make spec runs" % (v["bug"], v["model"]))
        refuted.add(v["bug"])
    for v in el["refute"]:
        if v.get("model") not in small_el:
            problems.append("BUG=%s is refuted by %s, not a model make spec runs"
                            % (v["bug"], v.get("model", v.get("cfg"))))
        refuted.add(v["bug"])
    for b, fn in sorted(spec_switches().items()):
        if b not in refuted:
            problems.append("BUG=%s (%s) is refuted by no model make spec runs" % (b, fn))
    own = sorted(fn for fn in os.listdir(SPEC) if re.match(r"MC\w*Bug\w*\.cfg$", fn))
    if own:
        problems.append("variants with configurations of their own (not the CI models' constants): %s"
                        % ", ".join(own))
    for p in problems:
        print("FAIL " + p)
    if problems:
        raise SystemExit(1)
    print("variants: %d BUG switches, each refuted by a model make spec runs" % len(refuted))


def refute_base(v):
    """The make-spec model a lifecycle variant v is refuted on."""
    return next(m for m in load_manifest()["models"] if m["name"] == v["model"] and m["size"] == "small")


def refute_run(v):
    man = load_manifest()
    base = refute_base(v)
    cfg = variant_cfg(base["cfg"], v["bug"], v["all"] if "all" in v else man["refute_props"][base["module"]],
                      name="%s-%s" % (v["bug"], v["model"]))
    return tlc(base["module"], cfg, workers=1, name="refute-" + v["bug"], seconds=v.get("seconds"),
               timeout=limit(refute_seconds(v, base)))


def refute_seconds(v, base):
    """What a variant's run is expected to take: its own seconds, else its model's."""
    return v.get("seconds", base.get("measured", {}).get("seconds"))


def refute_key(v):
    return ("refute", v["bug"], v["model"])


def cmd_refute(args):
    variants_declared()
    man = load_manifest()
    failed = False
    for v, (rc, out, secs) in zip(man["refute"], in_parallel(refute_run, man["refute"], key=refute_key)):
        if rc is None:
            print(no_verdict("BUG=%s on %s" % (v["bug"], v["model"]), out, secs))
            failed = True
            continue
        got = violation(out)
        live = [p for p in v.get("all", []) if is_liveness(p)]
        if got == "temporal" and len(live) == 1:
            got = live[0]  # TLC 2.18 does not name the violated temporal property
        ok = got == v["property"]
        print("%-4s BUG=%-18s %-12s expect %-28s got %-28s %5.1fs" % (
            "ok" if ok else "FAIL", v["bug"], v["model"], v["property"], got, secs))
        if not ok:
            print(counterexample(out)[:3000])
            failed = True
    if failed:
        raise SystemExit(1)


# ------------------------------------------------------------------ spec mutations
# spec/tla/mutations.toml: textual mutations of the shipped spec, each applied to a copy of
# spec/tla/ and checked with the models `make spec` runs (docs/spec.md "Spec mutations").  Not the
# BUG variants above: a mutation changes the text of a rule, nothing in the spec switches it.
MUTATIONS = os.path.join(SPEC, "mutations.toml")
MUTATION_FIELDS = {"id", "module", "class", "from", "to", "breaks", "models", "expect"}
MUTATION_OPTIONAL = {"only", "why", "timeout"}
# The guard classes (each needs at least one mutation), and the other kinds of rule.
GUARD_CLASSES = {"sender", "epoch", "vote", "relay", "timeout", "dedupe"}
OTHER_CLASSES = {"state", "registry", "bound", "reconcile"}
MUTATION_TIMEOUT = 300   # seconds per TLC run unless the mutation says otherwise


def mutation_models():
    """Every model `make spec` runs (size small), by name: [module, cfg]."""
    man = load_manifest()
    el = man["election"]
    return {m["name"]: m for m in man["models"] + el["models"] + el.get("live", [])
            if m["size"] == "small"}


def load_mutations(path=MUTATIONS):
    """The catalogue, checked: fields, ids, modules, models, and every mutation point found
    exactly once in its module (a point that moved or was edited fails here, loudly)."""
    import tomllib
    with open(path, "rb") as f:
        cat = tomllib.load(f)
    muts = cat.get("mutation", [])
    models = mutation_models()
    problems, seen = [], set()
    for i, mu in enumerate(muts):
        name = mu.get("id", "#%d" % (i + 1))
        missing = MUTATION_FIELDS - set(mu)
        extra = set(mu) - MUTATION_FIELDS - MUTATION_OPTIONAL
        if missing or extra:
            problems.append("%s: missing %s, unknown %s" % (name, sorted(missing), sorted(extra)))
            continue
        if not re.fullmatch(r"[A-Z]\d\d", name):
            problems.append("%s: an id is a capital letter and two digits" % name)
        if name in seen:
            problems.append("%s: id used twice" % name)
        seen.add(name)
        if mu["class"] not in GUARD_CLASSES | OTHER_CLASSES:
            problems.append("%s: class %r is none of %s" % (name, mu["class"],
                                                           sorted(GUARD_CLASSES | OTHER_CLASSES)))
        mod = os.path.join(SPEC, mu["module"])
        if not (mu["module"].endswith(".tla") and not mu["module"].startswith("MC")
                and os.path.exists(mod)):
            problems.append("%s: %s is not a spec module of spec/tla" % (name, mu["module"]))
            continue
        with open(mod) as f:
            n = f.read().count(mu["from"])
        if n != 1:
            problems.append("%s: the text to replace occurs %d times in %s (must be once): %r"
                            % (name, n, mu["module"], mu["from"]))
        if mu["from"] == mu["to"]:
            problems.append("%s: the replacement is the text itself" % name)
        for m in mu["models"]:
            if m not in models:
                problems.append("%s: %s is not a model make spec runs" % (name, m))
        only = mu.get("only", {})
        if not isinstance(only, dict) or not all(
                k in mu["models"] and isinstance(v, list) and v and all(isinstance(p, str) for p in v)
                for k, v in only.items()):
            problems.append("%s: only must map models of models to lists of properties" % name)
        exp = mu["expect"]
        if exp == "survives":
            if not mu.get("why"):
                problems.append("%s: a mutation expected to survive needs why (equivalent)" % name)
        else:
            model, _, prop = exp.partition(":")
            if model not in mu["models"] or not prop:
                problems.append("%s: expect %r is not model:Property with a model of models" % (name, exp))
    for c in sorted(GUARD_CLASSES - {mu.get("class") for mu in muts}):
        problems.append("no mutation of guard class %s" % c)
    if problems:
        raise SystemExit("spec/tla/mutations.toml:\n  " + "\n  ".join(problems))
    return muts


def mutant_dir(mu):
    """A copy of spec/tla (modules and cfgs) with the mutation applied."""
    d = os.path.join(BUILD, "mutant-" + mu["id"])
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    for fn in os.listdir(SPEC):
        if fn.endswith((".tla", ".cfg")):
            shutil.copy(os.path.join(SPEC, fn), d)
    path = os.path.join(d, mu["module"])
    with open(path) as f:
        text = f.read()
    with open(path, "w") as f:
        f.write(text.replace(mu["from"], mu["to"], 1))
    return d


def kill_verdict(rc, out, only):
    """What killed a mutant: (property, exit code), or None if the model passed."""
    if rc == 0 and "Model checking completed. No error has been found." in out:
        return None
    if rc in (11, 12, 13):
        got = violation(out)
        if got == "temporal" and only and len(only) == 1:
            got = only[0]   # TLC 2.18 does not name the violated temporal property
        return got, rc
    raise SystemExit("TLC failed (exit %s), not a verdict:\n%s" % (rc, counterexample(out)[:3000]))


def run_mutant(mu, models):
    """Each model of mu in order (one worker, a timeout each) until one kills it.
    Returns (model, property, exit, seconds in all, runs)."""
    d = mutant_dir(mu)
    runs, total = [], 0.0
    try:
        for name in mu["models"]:
            m = models[name]
            cfg = m["cfg"]
            only = mu.get("only", {}).get(name)
            if only:
                cfg = variant_cfg(m["cfg"], None, only, name="mutant-" + mu["id"], src=d, dest=d)
            rc, out, secs = tlc(m["module"], cfg, workers=1, name="mutant-" + mu["id"], cwd=d,
                                timeout=mu.get("timeout", MUTATION_TIMEOUT))
            total += secs
            if rc is None:
                runs.append((name, "timeout", None, secs))
                continue
            v = kill_verdict(rc, out, only)
            runs.append((name, v[0] if v else "passed", rc, secs))
            if v:
                return name, v[0], rc, total, runs
        return None, None, None, total, runs
    finally:
        shutil.rmtree(d, ignore_errors=True)


def cmd_mutate(args):
    muts = load_mutations()
    models = mutation_models()
    if args.list:
        for mu in muts:
            print("%-6s %-16s %-9s %s" % (mu["id"], mu["module"], mu["class"], mu["expect"]))
        return
    todo = [mu for mu in muts if (not args.only or any(mu["id"].startswith(o) for o in args.only))
            and (args.all or args.only or mu["expect"] != "survives")]
    t0 = time.monotonic()
    failed = []
    print("%-6s %-9s %-20s %-30s %4s %7s  %s" % ("id", "class", "killed by", "property", "exit",
                                                "seconds", "expected"))
    timeouts = []
    for mu in todo:
        model, prop, rc, secs, runs = run_mutant(mu, models)
        # a run stopped at its timeout is no verdict: neither a kill nor a survival
        timed_out = [r[0] for r in runs if r[1] == "timeout"]
        got = "%s:%s" % (model, prop) if model else ("timeout" if timed_out else "survives")
        if got == "timeout":
            timeouts.append(mu["id"])
            model, prop = ",".join(timed_out), "(no verdict: timed out)"
        ok = got == mu["expect"]
        passed = ", ".join("%s %s %.0fs" % (r[0], r[1], r[3]) for r in runs if r[1] in ("passed", "timeout")
                           ) if len(runs) > 1 or not model else ""
        print("%-6s %-9s %-20s %-30s %4s %7.1f  %s%s%s" % (
            mu["id"], mu["class"], model or "-", prop or "(survived)", rc if rc is not None else "-",
            secs, mu["expect"], "" if ok else "  FAIL", "  (tried: %s)" % passed if passed else ""))
        if not ok:
            failed.append(mu["id"])
        sys.stdout.flush()
    skipped = len([mu for mu in muts if mu["expect"] == "survives" and mu not in todo]) if not args.only else 0
    print("mutations: %d run, %d as expected%s%s, %.0f s in all%s" % (
        len(todo), len(todo) - len(failed),
        "" if not skipped else ", %d equivalent ones not run (--all runs them)" % skipped,
        "" if not timeouts else ", %d without a verdict (timed out, counted neither killed nor surviving: %s)"
        % (len(timeouts), " ".join(timeouts)),
        time.monotonic() - t0, "" if not failed else "; FAILED: " + " ".join(failed)))
    if failed:
        raise SystemExit(1)


STATE_RE = re.compile(r'state \|-> \\"(\w+)\\"')
ACTION_RE = re.compile(r'lastAction = \[\s*name \|-> \\"(\w+)\\"')
COLOURS = {"IDLE": "gold", "ACTIVE": "palegreen", "WORKING": "green3",
           "PAUSED": "orange", "PANIC": "red", "OFF": "grey70"}


def lifecycle_dot():
    man = load_manifest()
    base = next(m for m in man["models"] if m["name"] == man["diagram_model"])
    # The graph `check` dumped for the conformance replay when the spec is unchanged since (the
    # model's "dump" name), else a fresh TLC run.
    sys.path.insert(0, os.path.join(ROOT, "conformance"))
    from ev3conformance import graph
    try:
        path, _ = graph.dump_file(base["module"], base["cfg"], base.get("dump") or base["name"])
    except RuntimeError as e:
        print(e)
        raise SystemExit("TLC failed while dumping the state graph")
    # Edge labels of -dump carry the TLA+ action name only for actions without
    # parameters (others show as "Next"), so the handler name is taken from
    # lastAction of the target state, as the conformance replay does.
    node_state, node_action, edges = {}, {}, set()
    with open(path) as f:
        for ln in f:
            m = re.match(r'\s*(-?\d+) -> (-?\d+) \[label=', ln)
            if m:
                edges.add((m.group(1), m.group(2)))
                continue
            m = re.match(r'\s*(-?\d+) \[label="(.*)"', ln)
            if m:
                s = STATE_RE.search(m.group(2))
                n = ACTION_RE.search(m.group(2))
                if s:
                    node_state[m.group(1)] = s.group(1)
                if n:
                    node_action[m.group(1)] = n.group(1)
    trans = {}
    for (a, b) in edges:
        sa, sb = node_state.get(a), node_state.get(b)
        if sa is None or sb is None or sa == sb:
            continue
        trans.setdefault((sa, sb), set()).add(node_action[b])
    order = ["IDLE", "ACTIVE", "WORKING", "PAUSED", "PANIC", "OFF"]
    leds = {"IDLE": "blinking yellow", "ACTIVE": "blinking green", "WORKING": "solid green",
            "PAUSED": "solid orange", "PANIC": "blinking red", "OFF": "dark (shut down)"}
    lines = ["// Generated by tools/spec.py diagram from TLC's state graph of %s." % base["cfg"],
             "// %d states of the one-agent model collapsed to the agent's state. Do not edit."
             % len(node_state),
             "digraph lifecycle {", '  rankdir=LR;',
             '  node [shape=box, style="rounded,filled", fontname="Helvetica"];',
             '  edge [fontname="Helvetica", fontsize=10];']
    for s in order:
        if s in node_state.values():
            lines.append('  %s [label="%s\\n%s", fillcolor=%s];' % (s, s, leds[s], COLOURS[s]))
    for (sa, sb) in sorted(trans, key=lambda t: (order.index(t[0]), order.index(t[1]))):
        lines.append('  %s -> %s [label="%s"];' % (sa, sb, "\\n".join(sorted(trans[(sa, sb)]))))
    lines.append("}")
    return "\n".join(lines) + "\n"


def render(dot_text):
    p = subprocess.run(["dot", "-Tsvg"], input=dot_text, stdout=subprocess.PIPE, text=True, check=True)
    return p.stdout


def cmd_diagram(args):
    dot_text = lifecycle_dot()
    svg = render(dot_text)
    dot_path, svg_path = os.path.join(DOCS, "lifecycle.dot"), os.path.join(DOCS, "lifecycle.svg")
    if args.check:
        stale = []
        for path, text in ((dot_path, dot_text), (svg_path, svg)):
            if not os.path.exists(path) or open(path).read() != text:
                stale.append(os.path.relpath(path, ROOT))
        if stale:
            raise SystemExit("stale: %s (run: python3 tools/spec.py diagram)" % ", ".join(stale))
        print("diagram: docs/lifecycle.svg up to date")
        return
    with open(dot_path, "w") as f:
        f.write(dot_text)
    with open(svg_path, "w") as f:
        f.write(svg)
    print("diagram: wrote docs/lifecycle.dot, docs/lifecycle.svg")


# ------------------------------------------------------------------ relay and election
# docs/election.md.  Figures and expectations in the "election" key of spec/tla/manifest.json:
#   thesis     MCThesisElection must FAIL (exit 12) on its invariant (the thesis' split brain);
#   models     exhaustive runs (size small: make spec; full: make spec-full), distinct/depth checked;
#   live       temporal properties (stabilisation variant), run with the models of its size;
#   simulate   the 5-agent random simulation (size full);
#   refute     every variant: the constants of the make-spec model it names ("model", size small)
#              with its BUG switch (and the protocol switches of "set", e.g. PreVote = FALSE)
#              must FAIL on its named invariant (exit 12) or a temporal property (exit 13);
#   chart      docs/thesis-split-brain.svg, drawn by tools/seqchart.py from a fresh thesis trace.
# Election cfgs say CHECK_DEADLOCK FALSE themselves (bounded models stop).

def election_tlc(entry, name, extra=(), seconds=None):
    workers = entry.get("workers", 2)
    secs = seconds if seconds is not None else entry.get("measured", {}).get("seconds")
    return tlc(entry["module"], entry["cfg"], workers=workers, name=name, extra=list(extra),
               seconds=secs, timeout=limit(secs))


def thesis_run(th):
    return election_tlc(th, "thesis", seconds=5)


def election_model(m):
    return election_tlc(m, m["name"])


def election_thesis(el):
    th = el["thesis"]
    rc, out, secs = next(in_parallel(thesis_run, [th], key=lambda th: ("thesis",)))
    if rc is None:
        print(no_verdict("thesis", out, secs))
        return False, out
    got = violation(out)
    ok = rc == 12 and got == th["property"]
    print("%-4s thesis         expect exit 12 on %s: got exit %d on %s  %5.1fs" % (
        "ok" if ok else "FAIL", th["property"], rc, got, secs))
    if not ok:
        print(counterexample(out)[:3000])
    return ok, out


def election_check(args):
    man = load_manifest()
    el = man["election"]
    failed = False
    for mod in ("MCElection", "MCElectionLive", "MCThesisElection", "MCSystem"):
        sany(mod)
    if args.size in ("small", "quick") and not args.only:
        failed |= not election_thesis(el)[0]
    models = [m for m in el["models"] + el.get("live", []) if chosen(m, args)]
    for m, (rc, out, secs) in zip(models, in_parallel(election_model, models, key=lambda m: ("el", m["name"]))):
        if rc is None:
            print(no_verdict(m["name"], out, secs))
            failed = True
            continue
        fig = figures(out)
        v = violation(out)
        if rc != 0 or v or fig is None or "Model checking completed. No error has been found." not in out:
            print("FAIL %s: exit %d, %s" % (m["name"], rc, v or "TLC did not complete"))
            print(counterexample(out)[:4000])
            failed = True
            continue
        line = "%-14s states %9d  distinct %8d  depth %3d  time %6.1fs (%d workers)" % (
            m["name"], fig["generated"], fig["distinct"], fig["depth"], secs, m.get("workers", 2))
        if args.update:
            m["distinct"], m["depth"] = fig["distinct"], fig["depth"]
            m["measured"] = {"generated": fig["generated"], "seconds": round(secs, 1)}
            print(line + "  (manifest updated)")
        elif fig["distinct"] != m.get("distinct") or (
                m.get("workers", 2) == 1 and fig["depth"] != m.get("depth")):
            # distinct is exact whatever the workers; the depth only with one worker
            print(line + "  MISMATCH: manifest says distinct %s depth %s"
                  % (m.get("distinct"), m.get("depth")))
            failed = True
        else:
            print(line + "  ok")
    sim = el.get("simulate")
    if sim and sim["size"] == args.size and not args.only:
        extra = ["-simulate", "num=%d" % sim["num"], "-depth", str(sim["depth"]),
                 "-seed", str(sim["seed"])]
        rc, out, secs = election_tlc(sim, "election-sim", extra)
        if rc is None:
            print(no_verdict("election-sim", out, secs))
            return False
        v = violation(out)
        # TLC 2.18 -simulate prints only "Progress: N states checked." and stops after
        # num behaviours (traces); it reports no count of them, so completion is
        # exit 0 + "Finished" + no violation.
        g = re.findall(r"Progress: ([\d,]+) states checked", out)
        states = int(g[-1].replace(",", "")) if g else None
        behaviours = sim["num"] * sim.get("workers", 2)  # TLC 2.18: num is per worker
        ok = rc == 0 and v is None and states is not None and "Finished in" in out
        print("%-4s election-sim   %s behaviours, %s states, depth <= %d, seed %d  %6.1fs" % (
            "ok" if ok else "FAIL", behaviours, states, sim["depth"], sim["seed"], secs))
        if not ok:
            print("exit %d, %s" % (rc, v))
            print(counterexample(out)[:4000])
            failed = True
        elif args.update:
            sim["measured"] = {"behaviours": behaviours, "states": states, "seconds": round(secs, 1)}
    if args.update:
        with open(MANIFEST) as f:
            cur = json.load(f)
        cur["election"] = el   # only the election key: the rest may have changed meanwhile
        with open(MANIFEST, "w") as f:
            json.dump(cur, f, indent=2)
            f.write("\n")
    return not failed


def election_refute_base(v):
    """The make-spec model an election variant v is refuted on."""
    el = load_manifest()["election"]
    return next(m for m in el["models"] + el.get("live", []) if m["name"] == v["model"] and m["size"] == "small")


def election_refute_run(v):
    base = election_refute_base(v)
    # "only": the variant is checked on these properties alone (another property the bug
    # also breaks would be found first and hide whether this one is reached)
    cfg = variant_cfg(base["cfg"], v["bug"], v.get("only"), name="el-%s-%s%s" % (
        v["bug"], v["model"], "".join("-" + p for p in v.get("only", ()))), sets=v.get("set"))
    return election_tlc(dict(base, cfg=cfg), "refute-" + v["bug"], seconds=v.get("seconds"))


def election_refute_key(v):
    return ("el-refute", v["bug"], v["model"], tuple(v.get("only", ())))


def election_refute(args):
    """Each variant: the constants of the CI model it names, with its BUG switch (and the protocol
    switches in "set" turned off), all the model's properties (or those of "only"); it must fail on
    the one named."""
    el = load_manifest()["election"]
    failed = False
    for v, (rc, out, secs) in zip(el["refute"], in_parallel(election_refute_run, el["refute"],
                                                            key=election_refute_key)):
        if rc is None:
            print(no_verdict("BUG=%s on %s" % (v["bug"], v["model"]), out, secs))
            failed = True
            continue
        got = violation(out)
        # exit 12: an invariant is violated; 13: a temporal property (the Live variant)
        ok = rc == v.get("exit", 12) and got == v["property"]
        fig = re.findall(r"([\d,]+) distinct states found", out)   # the last: TLC's final count
        print("%-4s BUG=%-18s %-20s expect %-28s got %-28s %8s distinct %5.1fs" % (
            "ok" if ok else "FAIL", v["bug"], v["model"], v["property"], "%s (exit %d)" % (got, rc),
            fig[-1] if fig else "?", secs))
        if not ok:
            print(counterexample(out)[:3000])
            failed = True
    return not failed


def election_chart():
    """The SVG text of the thesis' split brain, drawn from a fresh TLC trace."""
    el = load_manifest()["election"]
    ok, out = election_thesis(el)
    if not ok:
        raise SystemExit("the thesis model did not produce its counterexample")
    ch = el["chart"]
    os.makedirs(BUILD, exist_ok=True)
    trace = os.path.join(BUILD, "thesis.out")
    svg = os.path.join(BUILD, "thesis-split-brain.svg")
    with open(trace, "w") as f:
        f.write(out)
    subprocess.run([sys.executable, os.path.join(ROOT, "tools", "seqchart.py"), trace, svg]
                   + ch["args"], check=True)
    with open(svg) as f:
        return f.read()


def election_diagram(args):
    text = election_chart()
    path = os.path.join(DOCS, "thesis-split-brain.svg")
    if args.check:
        if not os.path.exists(path) or open(path).read() != text:
            raise SystemExit("stale: docs/thesis-split-brain.svg (run: python3 tools/spec.py diagram)")
        print("diagram: docs/thesis-split-brain.svg up to date")
        return True
    with open(path, "w") as f:
        f.write(text)
    print("diagram: wrote docs/thesis-split-brain.svg")
    return True


def election_main(args):
    ok = {"check": election_check, "refute": election_refute, "diagram": election_diagram}[args.cmd](args)
    if not ok:
        raise SystemExit(1)


def trace_modules():
    """spec/tla/trace/, the trace checks of `ev3-conformance validate` (docs/spec.md "Implementation ->
    spec"): SANY on every module, and each check on its sample trace (must conform; one record changed
    must be rejected, naming it), the whole-run check (MCMergedTrace) on a black-box run (must
    conform; each planted fault rejected, naming its record): ev3conformance.tracemodules.check_modules
    (standard library only)."""
    sys.path.insert(0, os.path.join(ROOT, "conformance"))
    from ev3conformance import tracemodules
    t0 = time.monotonic()
    ok = tracemodules.check_modules()
    print("trace modules: %s (%.1fs)" % ("ok" if ok else "FAILED", time.monotonic() - t0))
    if not ok:
        raise SystemExit(1)


def all_jobs(args):
    """Every TLC run of `check` (lifecycle and election models, the thesis) or of `refute` (every
    variant), for start_all: one pool for both parts."""
    man = load_manifest()
    el = man["election"]
    if args.cmd == "check":
        jobs = [(("check", m["name"]), check_model, m, cost(m)) for m in man["models"] if chosen(m, args)]
        if args.size in ("small", "quick") and not args.only:
            jobs.append((("thesis",), thesis_run, el["thesis"], 5))
        return jobs + [(("el", m["name"]), election_model, m, cost(m))
                       for m in el["models"] + el.get("live", []) if chosen(m, args)]
    if args.cmd == "refute":
        return ([(refute_key(v), refute_run, v, v.get("seconds", 5)) for v in man["refute"]]
                + [(election_refute_key(v), election_refute_run, v, v.get("seconds", 5) * election_refute_base(v).get("workers", 2))
                   for v in el["refute"]])
    return []


def check_args(args):
    """--spec: the directory checked from here on; --only: every name a model of the manifest."""
    global SPEC
    if args.spec:
        if not os.path.isfile(os.path.join(args.spec, "MCFleet.tla")):
            raise SystemExit("--spec %s: not a copy of spec/tla (no MCFleet.tla there)" % args.spec)
        SPEC = os.path.abspath(args.spec)
    if args.only:
        man = load_manifest()
        known = {m["name"] for m in man["models"] + man["election"]["models"] + man["election"].get("live", [])}
        unknown = sorted(set(args.only) - known)
        if unknown:
            raise SystemExit("--only: %s: no such model in manifest.json (models: %s)"
                             % (", ".join(unknown), ", ".join(sorted(known))))
        if args.update:
            raise SystemExit("--only and --update: the manifest is updated by a run of every model")


def manifest_model(name):
    """The manifest's model @p name (the lifecycle's or the election's): (module, cfg, entry)."""
    man = load_manifest()
    for m in man["models"] + man["election"]["models"]:
        if m["name"] == name:
            return m["module"], m["cfg"], m
    names = sorted({m["name"] for m in man["models"] + man["election"]["models"]})
    raise SystemExit("distributed: %s: no such model in manifest.json (models: %s)" % (name, ", ".join(names)))


def free_port():
    import socket
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


CFG_SECTIONS = ("CONSTANTS", "CONSTANT", "INVARIANTS", "INVARIANT", "PROPERTIES", "PROPERTY", "SPECIFICATION",
                "INIT", "NEXT", "SYMMETRY", "CONSTRAINT", "CONSTRAINTS", "ACTION_CONSTRAINT", "VIEW",
                "CHECK_DEADLOCK")


def set_constant(text, name, value):
    """A cfg's text with constant @p name set to @p value (`name = value`); ValueError when the cfg
    sets no such constant."""
    pat = r"(?m)^(\s*%s\s*=).*$" % re.escape(name)
    if not re.search(pat, text):
        raise ValueError("no %s constant" % name)
    return re.sub(pat, lambda m: m.group(1) + " " + value, text)


@contextlib.contextmanager
def cfg_beside_model(kind, cfg, text):
    """A derived cfg written in the spec directory (TLC, its distributed server and its workers read
    a cfg there by its name alone) as spec/tla/KIND-PID-CFG; its name while the block runs, removed
    after it."""
    path = os.path.join(SPEC, "%s-%d-%s" % (kind, os.getpid(), cfg))
    try:
        with open(path, "w") as f:
            f.write(text)
        yield os.path.basename(path)
    finally:
        if os.path.exists(path):
            os.remove(path)


def safety_cfg(text, bug=None):
    """A cfg's text without its PROPERTIES / PROPERTY sections (TLC's distributed server checks no
    temporal property), with BUG = @p bug when given. Returns (text, whether properties were left
    out); ValueError when @p bug is given and the cfg has no BUG constant."""
    kept, dropping = [], False
    for line in text.splitlines():
        head = line.split("\\*")[0].strip()
        word = head.split()[0] if head else ""
        if word in ("PROPERTIES", "PROPERTY"):
            dropping = True
            continue
        if word in CFG_SECTIONS:
            dropping = False
        if not dropping:
            kept.append(line)
    left_out = len(kept) != len(text.splitlines())
    out = "\n".join(kept) + "\n"
    return (set_constant(out, "BUG", '"%s"' % bug) if bug else out), left_out


def cmd_scale(args):
    """A manifest model with the agents @p args.agents instead of its own (its cfg's `Agents =`),
    its invariants only (PROPERTIES left out), one worker: what the state space and the time become
    (docs/spec.md "Cost with the number of agents"); with --simulate N, N random behaviours of at
    most --depth states (TLC -simulate, seed 1) instead of the whole state space."""
    module, cfg, entry = manifest_model(args.model)
    text, _ = safety_cfg(open(os.path.join(SPEC, cfg)).read())
    if not re.fullmatch(r"\{[\w\s,]*\}", args.agents.strip()):
        raise SystemExit("scale: AGENTS must be a TLA+ set of agents, e.g. \"{2, 3, 4}\" (got %r)" % args.agents)
    try:
        text = set_constant(text, "Agents", args.agents.strip())
        for kv in args.set or ():
            k, _, v = kv.partition("=")
            if not v or not re.fullmatch(r"\w+", k.strip()):
                raise ValueError("--set %s: give NAME=VALUE" % kv)
            text = set_constant(text, k.strip(), v.strip())
    except ValueError as e:
        raise SystemExit("scale: %s: %s" % (cfg, e))
    extra = ["-simulate", "num=%d" % args.simulate, "-depth", str(args.depth), "-seed", "1"] if args.simulate else []
    with cfg_beside_model("scale", cfg, text) as scfg:
        rc, out, secs = tlc(module, scfg, workers=1, extra=extra, name="scale-" + args.model, seconds=1000,
                            timeout=args.timeout)
    if rc is None:
        raise SystemExit("scale: %s %s: no verdict within %d s (--timeout)" % (args.model, args.agents, args.timeout))
    v = violation(out)
    if rc != 0 or v:
        print(counterexample(out)[:4000])
        raise SystemExit("scale: %s %s: TLC failed (exit %s%s)" % (args.model, args.agents, rc, ", " + v if v else ""))
    if args.simulate:
        g = re.findall(r"Progress: ([\d,]+) states checked", out)
        print("scale: %s with Agents = %s: %d behaviours of depth <= %d, %s states checked, %.1f s"
              % (args.model, args.agents, args.simulate, args.depth, g[-1] if g else "?", secs))
        return
    fig = figures(out)
    print("scale: %s with Agents = %s: %s states generated, %s distinct, depth %s, %.1f s (1 worker)"
          % (args.model, args.agents, format(fig["generated"], ","), format(fig["distinct"], ","), fig["depth"], secs))


def cmd_distributed(args):
    """TLC's distributed mode (tlc2.tool.distributed): the server holds the state queue and the
    fingerprint set, each worker (its own JVM, --threads threads) computes successors and checks the
    invariants of the states it is given. TLC 2.18's server checks no temporal property, honours no
    CHECK_DEADLOCK line and, on a violation, prints the trace without naming the invariant and exits
    0: this runner leaves the model's PROPERTIES out (saying so), passes -deadlock for CHECK_DEADLOCK
    FALSE, fails on any "Error:" or when every local worker stops, and compares the distinct states
    with the manifest's (the depth it reports is not the one-machine run's BFS depth)."""
    module, cfg, entry = manifest_model(args.model)
    if args.workers < 0 or args.threads < 1:
        raise SystemExit("distributed: --workers must be 0 or more, --threads 1 or more")
    md = metadir("distributed-" + args.model)
    try:
        text, left_out = safety_cfg(open(os.path.join(SPEC, cfg)).read(), args.bug)
    except ValueError as e:
        raise SystemExit("distributed: %s: %s" % (cfg, e))
    port = args.port or free_port()
    props = ["-Dtlc2.tool.distributed.TLCServer.port=%d" % port]
    # The server honours no CHECK_DEADLOCK line: -deadlock turns its deadlock check off.
    no_deadlock = ["-deadlock"] if re.search(r"(?m)^\s*CHECK_DEADLOCK\s+FALSE", text) else []
    # A worker is called back by the server at the address it advertises: its own (here, loopback).
    worker_cmd = JAVA + props + ["-Djava.rmi.server.hostname=127.0.0.1",
                                 "-Dtlc2.tool.distributed.TLCWorker.threadCount=%d" % args.threads,
                                 "-Djava.io.tmpdir=" + md, "-cp", JAR, "tlc2.tool.distributed.TLCWorker", args.host]
    print("distributed: %s (%s %s) on %s:%d, %d local worker(s) of %d thread(s)%s"
          % (args.model, module, cfg, args.host, port, args.workers, args.threads,
             "; its PROPERTIES left out (the run checks the invariants)" if left_out else ""), flush=True)
    log = os.path.join(md, "server.log")
    t0 = time.monotonic()
    workers, server, rc = [], None, None
    old_term = signal.signal(signal.SIGTERM, lambda *_: sys.exit("distributed: stopped (SIGTERM)"))
    with cfg_beside_model("distributed", cfg, text) as dcfg:
        try:
            server_cmd = JAVA + props + ["-Djava.rmi.server.hostname=" + args.host, "-Djava.io.tmpdir=" + md, "-cp", JAR,
                                         "tlc2.tool.distributed.TLCServer", "-metadir", os.path.join(md, "states")] + \
                no_deadlock + ["-config", dcfg, module + ".tla"]
            with open(log, "w") as out:
                server = subprocess.Popen(server_cmd, cwd=SPEC, stdout=out, stderr=subprocess.STDOUT, text=True)
            deadline = time.monotonic() + 300
            while "is ready" not in open(log).read():
                if server.poll() is not None or time.monotonic() > deadline:
                    print(open(log).read()[-3000:])
                    raise SystemExit("distributed: the TLC server did not start (above)")
                time.sleep(0.1)
            if args.workers == 0:
                print("distributed: server ready; on each worker machine: java -cp tla2tools.jar %s "
                      "-Djava.rmi.server.hostname=THAT_MACHINES_ADDRESS tlc2.tool.distributed.TLCWorker %s"
                      % (" ".join(props), args.host), flush=True)
            for i in range(args.workers):
                workers.append(subprocess.Popen(worker_cmd, cwd=md, stdout=open(os.path.join(md, "worker%d.log" % i), "w"),
                                                stderr=subprocess.STDOUT))
            end = time.monotonic() + args.timeout
            while server.poll() is None:
                if time.monotonic() > end:
                    print("distributed: FAIL: no verdict within %d s (--timeout); the server's log: %s" % (args.timeout, log))
                    raise SystemExit(1)
                if workers and all(w.poll() is not None for w in workers):
                    time.sleep(2)  # the server may be writing its verdict
                    if server.poll() is None:
                        raise SystemExit("distributed: FAIL: every worker stopped with no verdict from the server "
                                         "(their logs: %s/worker*.log)" % md)
                time.sleep(0.2)
            rc = server.returncode
        finally:
            signal.signal(signal.SIGTERM, old_term)
            for p in ([server] if server else []) + workers:
                if p.poll() is None:
                    try:
                        p.wait(timeout=10 if p is not server else 0.1)
                    except subprocess.TimeoutExpired:
                        p.kill()
                        p.wait()
    secs = time.monotonic() - t0
    text = open(log).read()
    fig = figures(text)
    registered = len(re.findall(r"^Registration for worker", text, re.M))
    ok = rc == 0 and "No error has been found" in text and not re.search(r"^Error:", text, re.M)
    if fig:
        print("distributed: %s states generated, %s distinct, depth %s, %.1f s, %d worker thread(s) registered"
              % (format(fig["generated"], ","), format(fig["distinct"], ","), fig["depth"], secs, registered))
    if not ok:
        print(counterexample(text)[:4000])
        raise SystemExit("distributed: FAIL: %s (the server's log: %s)" % (
            "TLC reports an error (above; for a violation TLC's server does not name the property, a "
            "one-machine run of the model does)" if re.search(r"^Error:", text, re.M) else "exit status %s" % rc, log))
    if fig and entry.get("distinct") not in (None, fig["distinct"]):
        raise SystemExit("distributed: FAIL: %d distinct states, the manifest says %d" % (fig["distinct"], entry["distinct"]))
    shutil.rmtree(md, ignore_errors=True)
    print("distributed: ok, the manifest's %s distinct states" % format(fig["distinct"], ","))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("check")
    c.add_argument("--size", choices=["small", "full", "quick"], default="small")
    c.add_argument("--update", action="store_true", help="record the figures in the manifest")
    c.add_argument("--only", nargs="+", metavar="MODEL",
                   help="these models of manifest.json alone (no thesis, trace modules or simulation)")
    c.add_argument("--spec", metavar="DIR", help="a copy of spec/tla to check instead (a change tried out)")
    sub.add_parser("refute")
    d = sub.add_parser("diagram")
    d.add_argument("--check", action="store_true")
    mu = sub.add_parser("mutate", help="the spec mutations of spec/tla/mutations.toml")
    mu.add_argument("--only", nargs="*", help="mutation ids (prefixes)")
    mu.add_argument("--all", action="store_true", help="also those expected to survive")
    mu.add_argument("--list", action="store_true", help="the catalogue, checked, nothing run")
    sc = sub.add_parser("scale", help="a model with other agents: states, depth, time (or a simulation)")
    sc.add_argument("model", help="a model name of manifest.json (e.g. system)")
    sc.add_argument("agents", help='the agents, a TLA+ set: "{2, 3, 4}" (model values as the cfg spells them)')
    sc.add_argument("--simulate", type=int, default=0, metavar="N", help="N random behaviours instead (TLC -simulate)")
    sc.add_argument("--depth", type=int, default=60, help="--simulate: states per behaviour at most (default 60)")
    sc.add_argument("--timeout", type=int, default=3600, help="seconds a run may take, then it is stopped (default 3600)")
    sc.add_argument("--set", action="append", metavar="NAME=VALUE", help="another constant of the cfg, e.g. "
                    '"CmdAgents={3}" (repeatable)')
    di = sub.add_parser("distributed", help="one model by TLC's distributed mode (TLCServer, TLCWorker)")
    di.add_argument("model", help="a model name of manifest.json (e.g. reports_three)")
    di.add_argument("--workers", type=int, default=2, help="TLCWorker processes started here (default 2; 0: "
                    "none, start them by hand)")
    di.add_argument("--threads", type=int, default=1, help="threads per worker (default 1)")
    di.add_argument("--host", default="127.0.0.1", help="the address the server is reached at (default 127.0.0.1)")
    di.add_argument("--port", type=int, default=0, help="the server's RMI port (default: a free one)")
    di.add_argument("--timeout", type=int, default=3600, help="seconds a run may take, then it is stopped (default 3600)")
    di.add_argument("--bug", help="a broken variant of the spec (its BUG constant), which must fail")
    args = ap.parse_args()
    if args.cmd == "distributed":
        cmd_distributed(args)
        return
    if args.cmd == "scale":
        cmd_scale(args)
        return
    if args.cmd == "check":
        check_args(args)
    if args.cmd == "mutate":
        cmd_mutate(args)
        return
    start_all(all_jobs(args))
    {"check": cmd_check, "refute": cmd_refute, "diagram": cmd_diagram}[args.cmd](args)
    if args.cmd == "check" and args.size != "quick" and not args.only:
        trace_modules()
    election_main(args)  # relay and election, after the lifecycle models


if __name__ == "__main__":
    main()
