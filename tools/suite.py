#!/usr/bin/env python3
"""Runs make targets one after another and prints how long each took.

    tools/suite.py NAME TARGET [TARGET ...]
    tools/suite.py --together NAME TARGET [TARGET ...]

Each TARGET runs as `make --no-print-directory TARGET` with its output passed through. At the end
(or at the first target that fails) a table gives each target's wall time, the CPU time (user +
system) of all its processes, and the totals, so a reader of a CI log sees where the time of
`make test` or `make check` went, and which parts wait rather than compute. Exits 1 if a target failed,
after printing the table; the targets after it are not run.

--together runs the targets at the same time (for parts that each keep one core busy, on a machine
with two or more): each one's output is held and printed whole, in the order given, once it is done;
the table gives each one's wall time and the time of them all. Exits 1 if any failed.
Python 3 standard library only.
"""
import os
import resource
import subprocess
import sys
import time


def fmt(seconds):
    m, s = divmod(int(round(seconds)), 60)
    return "%d min %02d s" % (m, s) if m else "%d s" % s


def cpu_seconds():
    """User + system time of every child process waited for so far."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def table(name, rows, failed):
    width = max([len(t) for t, _, _, _ in rows] + [len("total")])
    print("\n%s: time per part (wall, and CPU of all its processes)" % name)
    for target, seconds, cpu, rc in rows:
        mark = "" if rc == 0 else "  FAILED (exit %d)" % rc
        print("  %-*s  %10s  cpu %10s%s" % (width, target, fmt(seconds), fmt(cpu), mark))
    print("  %-*s  %10s  cpu %10s" % (width, "total", fmt(sum(r[1] for r in rows)),
                                      fmt(sum(r[2] for r in rows))))
    if failed:
        print("%s: FAILED in %s" % (name, failed))
    else:
        print("%s: all %d parts passed" % (name, len(rows)))


def together(name, targets, make):
    t0 = time.monotonic()
    procs = [(t, subprocess.Popen([make, "--no-print-directory", t], stdout=subprocess.PIPE,
                                  stderr=subprocess.STDOUT)) for t in targets]
    rows = []
    for target, p in procs:
        out, _ = p.communicate()
        rows.append((target, time.monotonic() - t0, p.returncode))
        sys.stdout.write(out.decode(errors="replace"))
        sys.stdout.flush()
    failed = [t for t, _, rc in rows if rc != 0]
    width = max(len(t) for t in targets + ["all, at the same time"])
    print("\n%s: time per part (run at the same time; each ends at the time shown)" % name)
    for target, seconds, rc in rows:
        print("  %-*s  %10s%s" % (width, target, fmt(seconds), "" if rc == 0 else "  FAILED (exit %d)" % rc))
    print("  %-*s  %10s" % (width, "all, at the same time", fmt(time.monotonic() - t0)))
    if failed:
        print("%s: FAILED in %s" % (name, ", ".join(failed)))
        return 1
    return 0


def main(argv):
    if len(argv) >= 2 and argv[1] == "--together":
        if len(argv) < 4:
            print(__doc__.strip(), file=sys.stderr)
            return 2
        return together(argv[2], argv[3:], os.environ.get("MAKE", "make"))
    if len(argv) < 3:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    name, targets = argv[1], argv[2:]
    make = os.environ.get("MAKE", "make")
    rows = []
    for target in targets:
        t0, c0 = time.monotonic(), cpu_seconds()
        rc = subprocess.call([make, "--no-print-directory", target])
        rows.append((target, time.monotonic() - t0, cpu_seconds() - c0, rc))
        if rc != 0:
            sys.stdout.flush()
            table(name, rows, target)
            return 1
    sys.stdout.flush()
    table(name, rows, None)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
