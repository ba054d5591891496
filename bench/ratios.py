#!/usr/bin/env python3
"""The codec's targets as ratios, measured over several runs of bench_codec (docs/benchmarks.md).

    python3 bench/ratios.py [--runs N] [--repetitions R] [--bin build/bench/bin/bench_codec]

Each run is one invocation of bench_codec: every benchmark R times (--benchmark_min_time=0.1 each,
CPU time), the R x 25 measurements in a random order (--benchmark_enable_random_interleaving), so
that a slow minute of the shared VM falls on ours, the thesis-style decoder and the floor alike. A
run's figure for a benchmark is the median of its R measurements, and a ratio is only taken
between figures of the same run (ours against the thesis-style decoder and against the memchr
floor, same datagram). The table gives, per datagram, the median of the per-run figures and their
range. Target: decode more than 10x faster than the thesis-style decoder, 0 allocations.

The last table puts the PING decode next to the receive system call before it (recvfrom() of a
queued loopback datagram, CPU time, same run) and gives both as a share of one core at the master's
load with 10,000 agents: 10,000 agents x one PING at 10 Hz x 3 copies = 300,000 datagrams a second.
Exit status 0 whatever the figures: this measures, it does not judge (a timed test would flake).
"""
import argparse
import json
import statistics
import subprocess
import sys

DATAGRAMS = ["ping", "sensor_value", "behaviour_1k"]
PINGS_PER_SECOND = 10_000 * 10 * 3  # agents x Hz x copies


def one_run(binary, repetitions):
    """{(benchmark, datagram index): (cpu ns, allocs/op)} of one bench_codec invocation: per
    benchmark the median of its repetitions' CPU times, and the most allocations of any."""
    out = subprocess.run([binary, "--benchmark_min_time=0.1", "--benchmark_format=json",
                          "--benchmark_repetitions=%d" % repetitions,
                          "--benchmark_enable_random_interleaving=true"],
                         check=True, capture_output=True, text=True).stdout
    samples = {}
    for b in json.loads(out)["benchmarks"]:
        if b.get("run_type", "iteration") != "iteration":
            continue  # the library's own aggregates (mean, median, stddev): we take our own
        name, _, arg = b["run_name"].partition("/")
        # recvfrom: its own counter (the iteration's CPU time includes the sends that fill the queue)
        ns = b["recvfrom_cpu_ns"] if "recvfrom_cpu_ns" in b else b["cpu_time"]
        samples.setdefault((name, int(arg or 0)), []).append((ns, b.get("allocs/op", 0.0)))
    return {key: (statistics.median(t for t, _ in v), max(a for _, a in v)) for key, v in samples.items()}


def print_floors(runs, med):
    """The decode floors side by side: (b) a memchr() per ':', (c) one plain loop over the bytes (copy,
    note each ':', classify), (d) the copy and range check of ours (detail::copy_printable) alone. The
    (a)/X columns are the most any decoder doing at least that work could reach against the
    thesis-style decoder (per-run ratios): the target is more than 10x."""
    print("\nDecode floors, median over %d runs (range of the runs); (a)/X = the most a decoder doing at least"
          " X's work could reach:" % len(runs))
    print("| datagram | ours ns/op | (b) memchr ns/op | (c) one plain pass ns/op | (d) copy+check ns/op "
          "| (a)/ours | (a)/(b) | (a)/(c) | (a)/((b)+(d)) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")

    def ns(r, name, k):
        return r[(name, k)][0]

    for k, dg in enumerate(DATAGRAMS):
        cols = [med([ns(r, n, k) for r in runs]) for n in (
            "BM_Decode_Ours", "BM_Decode_MemchrFloor", "BM_Decode_ScalarPassFloor", "BM_Decode_CopyCheckFloor")]
        thesis = [ns(r, "BM_Decode_Thesis", k) for r in runs]
        ratios = [med([t / x for t, x in zip(thesis, xs)], "x") for xs in (
            [ns(r, "BM_Decode_Ours", k) for r in runs],
            [ns(r, "BM_Decode_MemchrFloor", k) for r in runs],
            [ns(r, "BM_Decode_ScalarPassFloor", k) for r in runs],
            [ns(r, "BM_Decode_MemchrFloor", k) + ns(r, "BM_Decode_CopyCheckFloor", k) for r in runs])]
        print("| %s | %s |" % (dg, " | ".join(cols + ratios)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=9, help="bench_codec invocations (default 9)")
    ap.add_argument("--repetitions", type=int, default=5,
                    help="measurements of each benchmark per run, interleaved (default 5)")
    ap.add_argument("--bin", default="build/bench/bin/bench_codec")
    args = ap.parse_args()
    if args.runs < 1 or args.repetitions < 1:
        sys.exit("ratios.py: --runs and --repetitions must be at least 1")
    runs = []
    for i in range(args.runs):
        runs.append(one_run(args.bin, args.repetitions))
        print("run %d of %d done" % (i + 1, args.runs), file=sys.stderr)

    def med(values, unit=""):
        return "%.1f%s (%.1f-%.1f)" % (statistics.median(values), unit, min(values), max(values))

    for op, thesis, floor in (("Decode", "BM_Decode_Thesis", "BM_Decode_MemchrFloor"),
                              ("Encode", "BM_Encode_Thesis", "BM_Encode_MemcpyFloor")):
        print("\n%s, median over %d runs of %d interleaved repetitions each (range of the runs):" % (op, args.runs, args.repetitions))
        print("| datagram | ours ns/op | (a) thesis ns/op | (b) floor ns/op | (a)/ours | ours/(b) | allocs ours / (a) |")
        print("|---|---:|---:|---:|---:|---:|---:|")
        for k, dg in enumerate(DATAGRAMS):
            ours = [r[("BM_%s_Ours" % op, k)][0] for r in runs]
            a = [r[(thesis, k)][0] for r in runs]
            b = [r[(floor, k)][0] for r in runs]
            speedup = [r[(thesis, k)][0] / r[("BM_%s_Ours" % op, k)][0] for r in runs]
            to_floor = [r[("BM_%s_Ours" % op, k)][0] / r[(floor, k)][0] for r in runs]
            allocs = (max(r[("BM_%s_Ours" % op, k)][1] for r in runs), max(r[(thesis, k)][1] for r in runs))
            print("| %s | %s | %s | %s | %s | %s | %.0f / %.0f |" % (
                dg, med(ours), med(a), med(b), med(speedup, "x"), med(to_floor, "x"), allocs[0], allocs[1]))

    if ("BM_Decode_ScalarPassFloor", 0) in runs[0]:
        print_floors(runs, med)

    if ("BM_Recvfrom_Loopback", 0) not in runs[0]:
        return  # a bench_codec without it (an older build given with --bin)
    decode = [r[("BM_Decode_Ours", 0)][0] for r in runs]
    recv = [r[("BM_Recvfrom_Loopback", 0)][0] for r in runs]
    print("\nPING decode and the receive system call, median over %d runs (range of the runs); share of one"
          " core at %d datagrams/s (10,000 agents x PING at 10 Hz x 3 copies):" % (args.runs, PINGS_PER_SECOND))
    print("| | ns per PING | share of one core | recvfrom / decode |")
    print("|---|---:|---:|---:|")
    print("| decode (ours) | %s | %s | |" % (med(decode), med([PINGS_PER_SECOND * t / 1e7 for t in decode], " %")))
    print("| recvfrom() on loopback | %s | %s | %s |" % (
        med(recv), med([PINGS_PER_SECOND * t / 1e7 for t in recv], " %"),
        med([r[("BM_Recvfrom_Loopback", 0)][0] / r[("BM_Decode_Ours", 0)][0] for r in runs], "x")))
    for name, label in (("BM_Auth_Open", "check of a signed PING (signed mode)"), ("BM_Auth_Seal", "its trailer, sealed")):
        if (name, 0) in runs[0]:
            t = [r[(name, 0)][0] for r in runs]
            print("| %s | %s | %s | %s |" % (label, med(t), med([PINGS_PER_SECOND * x / 1e7 for x in t], " %"),
                                            med([r[(name, 0)][0] / r[("BM_Decode_Ours", 0)][0] for r in runs], "x")))


if __name__ == "__main__":
    main()
