#!/usr/bin/env python3
"""Compares Google Benchmark runs with their committed baselines.

Each RUN is the JSON a benchmark program writes with
--benchmark_format=json (aggregates of repetitions: the medians are
compared); its baseline is benchmarks/baseline/<program>.json, a run of the same
program kept in the repository with the machine it was measured on (its
"context"). Prints one row per figure in both, and names every figure more
than --threshold (default 25 %) slower than its baseline. A shared machine
is too noisy to fail on: exit 0 unless --strict.

    benchmarks/compare_baseline.py RUN.json... [--threshold 0.25] [--strict]
"""

import argparse
import json
import os
import sys

UNIT_NS = {"ns": 1.0, "us": 1e3, "ms": 1e6, "s": 1e9}


def figures(path):
    """{benchmark name: (nanoseconds, which time)} of a run's medians (or
    its plain iterations when it has no aggregates), and its context."""
    with open(path, encoding="utf-8") as f:
        run = json.load(f)
    out = {}
    for b in run.get("benchmarks", []):
        if b.get("run_type") == "aggregate" and b.get("aggregate_name") != "median":
            continue
        name = b.get("run_name", b["name"])
        # Manual and real-time benchmarks (DDS, I/O) are judged on wall time.
        which = "real_time" if ("manual_time" in name or "real_time" in name) else "cpu_time"
        out[name] = (b[which] * UNIT_NS[b.get("time_unit", "ns")], which)
    return out, run.get("context", {})


def machine(context):
    return "{} ({} CPUs at {} MHz, {})".format(
        context.get("host_name", "?"), context.get("num_cpus", "?"),
        context.get("mhz_per_cpu", "?"), context.get("date", "?"))


def show(ns):
    for unit, scale in (("s", 1e9), ("ms", 1e6), ("us", 1e3)):
        if ns >= scale:
            return "{:.3g} {}".format(ns / scale, unit)
    return "{:.3g} ns".format(ns)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", help="JSON of a benchmark run, named <program>.json")
    parser.add_argument("--baseline-dir",
                        default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "baseline"))
    parser.add_argument("--threshold", type=float, default=0.25)
    parser.add_argument("--strict", action="store_true", help="exit 1 if a figure slipped")
    args = parser.parse_args()

    slipped = []
    for path in args.runs:
        program = os.path.splitext(os.path.basename(path))[0]
        base_path = os.path.join(args.baseline_dir, program + ".json")
        if not os.path.exists(base_path):
            print(f"{program}: no baseline ({base_path}); nothing to compare")
            continue
        now, now_context = figures(path)
        base, base_context = figures(base_path)
        print(f"{program}: baseline on {machine(base_context)}; this run on {machine(now_context)}")
        print(f"  {'benchmark':<52} {'baseline':>10} {'now':>10} {'ratio':>6}")
        for name in sorted(base.keys() & now.keys()):
            before, after = base[name][0], now[name][0]
            ratio = after / before if before > 0 else float("inf")
            mark = ""
            if ratio > 1.0 + args.threshold:
                mark = f"  SLOWER by {100 * (ratio - 1):.0f} %"
                slipped.append(f"{program} {name}")
            print(f"  {name:<52} {show(before):>10} {show(after):>10} {ratio:6.2f}{mark}")
        for name in sorted(base.keys() - now.keys()):
            print(f"  {name:<52} (in the baseline, not run)")
        for name in sorted(now.keys() - base.keys()):
            print(f"  {name:<52} (new: {show(now[name][0])}, no baseline)")
    if slipped:
        print(f"{len(slipped)} figure(s) more than {100 * args.threshold:.0f} % slower than "
              "their baseline: " + ", ".join(slipped))
    else:
        print(f"no figure more than {100 * args.threshold:.0f} % slower than its baseline")
    return 1 if (slipped and args.strict) else 0


if __name__ == "__main__":
    sys.exit(main())
