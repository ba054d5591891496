#!/usr/bin/env python3
"""Runs make targets one after another and prints how long each took.

    tools/suite.py NAME TARGET [TARGET ...]

Each TARGET runs as `make --no-print-directory TARGET` with its output passed through. At the end
(or at the first target that fails) a table gives each target's wall time and the total, so a reader
of a CI log sees where the time of `make test` or `make check` went. Exits 1 if a target failed,
after printing the table; the targets after it are not run. Python 3 standard library only.
"""
import os
import subprocess
import sys
import time


def fmt(seconds):
    m, s = divmod(int(round(seconds)), 60)
    return "%d min %02d s" % (m, s) if m else "%d s" % s


def table(name, rows, failed):
    width = max([len(t) for t, _, _ in rows] + [len("total")])
    print("\n%s: time per part" % name)
    for target, seconds, rc in rows:
        mark = "" if rc == 0 else "  FAILED (exit %d)" % rc
        print("  %-*s  %10s%s" % (width, target, fmt(seconds), mark))
    print("  %-*s  %10s" % (width, "total", fmt(sum(s for _, s, _ in rows))))
    if failed:
        print("%s: FAILED in %s" % (name, failed))
    else:
        print("%s: all %d parts passed" % (name, len(rows)))


def main(argv):
    if len(argv) < 3:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    name, targets = argv[1], argv[2:]
    make = os.environ.get("MAKE", "make")
    rows = []
    for target in targets:
        t0 = time.monotonic()
        rc = subprocess.call([make, "--no-print-directory", target])
        rows.append((target, time.monotonic() - t0, rc))
        if rc != 0:
            sys.stdout.flush()
            table(name, rows, target)
            return 1
    sys.stdout.flush()
    table(name, rows, None)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
