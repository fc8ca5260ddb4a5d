#!/usr/bin/env python3
"""How well can the thesis's model predict a leg's random-binary trials at all?

For every session of a `fesbench study` (or any session with two
prediction_random_binary trials and a rapid_parameterisation run), through
the analyst's tools only (`fesbench --json`, `fesbench-model identify
output_error`):

  rapid    the rapid set's knee-angle E_RMS on each random-binary trial
           (the study's clinician-chain figure, recomputed offline);
  sibling  the rapid set refined by output error on the *other*
           random-binary trial of the same leg (same amplitude, the same
           session, seconds apart: the best identification data the leg
           can give for that input), then its E_RMS on this trial.

The sibling column bounds what any identification of this model can reach
on these trials (docs/STUDY.md). Needs python3 only.

  scripts/rb-floor.py --server http://127.0.0.1:8080 --token-file admin.token \\
      --sessions 1-16 --out /tmp/rb-floor
"""
import argparse
import json
import os
import statistics
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def parse_sessions(text):
    ids = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        ids.extend(range(int(lo), int(hi or lo) + 1))
    return ids


class Tools:
    def __init__(self, args):
        self.cli = [args.fesbench, "--server", args.server, "--token-file", args.token_file]
        self.model = args.fesbench_model
        self.stops = args.stops
        self.out = args.out
        self.iterations = args.iterations

    def fesbench_json(self, *argv):
        done = subprocess.run(self.cli + ["--json", *argv], check=True, capture_output=True,
                              text=True)
        return json.loads(done.stdout)

    def fesbench(self, *argv):
        subprocess.run(self.cli + list(argv), check=True, capture_output=True, text=True)

    def output_error(self, params, trial, iterations, out):
        """fesbench-model identify output_error; returns the report's E_RMS, deg."""
        lo, hi = self.stops
        done = subprocess.run(
            [self.model, "identify", "output_error", "--trial", trial, "--params-in", params,
             "--option", f"iterations={iterations}", "--option", f"min_angle_deg={lo}",
             "--option", f"max_angle_deg={hi}", "--out", out],
            check=True, capture_output=True, text=True)
        return json.loads(done.stdout)["fit_rms"]["output_error_deg"]


def leg_row(tools, session):
    trials = tools.fesbench_json("trials", "list", "--session", str(session))
    rb = [t for t in trials if t["kind"] == "prediction_random_binary"]
    rapid_runs = sorted({t["run_id"] for t in trials if t["kind"].startswith("rapid_")})
    if len(rb) < 2 or not rapid_runs:
        return None
    rb = rb[:2]
    set_id = tools.fesbench_json("run", "show", str(rapid_runs[-1]))["parameter_set_id"]
    d = os.path.join(tools.out, f"session_{session}")
    os.makedirs(d, exist_ok=True)
    rapid = os.path.join(d, "rapid.json")
    tools.fesbench("params", "get", str(set_id), "--format", "json", "--out", rapid)
    paths = []
    for t in rb:
        paths.append(os.path.join(d, f"trial_{t['id']}.csv"))
        tools.fesbench("trials", "get", str(t["id"]), "--out", paths[-1])
    row = {"session": session, "set": set_id, "trials": [t["id"] for t in rb]}
    scratch = os.path.join(d, "scratch.json")
    row["rapid"] = [tools.output_error(rapid, p, 0, scratch) for p in paths]
    row["sibling"] = []
    for k, p in enumerate(paths):
        other = paths[1 - k]
        fitted = os.path.join(d, f"fitted_on_{os.path.basename(other)}.json")
        tools.output_error(rapid, other, tools.iterations, fitted)
        row["sibling"].append(tools.output_error(fitted, p, 0, scratch))
    return row



def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--server", required=True)
    ap.add_argument("--token-file", required=True)
    ap.add_argument("--sessions", default="1-16", help="e.g. 1-16 or 3,8,13")
    ap.add_argument("--stops", type=float, nargs=2, default=[10.0, 110.0],
                    help="the bench's range of motion, deg")
    ap.add_argument("--iterations", type=int, default=10,
                    help="output-error iterations of the sibling fit")
    ap.add_argument("--out", required=True, help="folder for the exported trials and sets")
    ap.add_argument("--fesbench", default=os.path.join(ROOT, "build/clients/cli/fesbench"))
    ap.add_argument("--fesbench-model",
                    default=os.path.join(ROOT, "build/clients/model_cli/fesbench-model"))
    args = ap.parse_args()
    tools = Tools(args)
    rows = []
    print("session,set,trial_a,trial_b,rapid_a_deg,rapid_b_deg,sibling_a_deg,sibling_b_deg")
    for s in parse_sessions(args.sessions):
        try:
            row = leg_row(tools, s)
        except subprocess.CalledProcessError as e:
            print(f"session {s}: {' '.join(e.cmd[:3])}: {e.stderr.strip()}", file=sys.stderr)
            continue
        if row is None:
            print(f"session {s}: no two random-binary trials and rapid run", file=sys.stderr)
            continue
        rows.append(row)
        print(",".join(str(v) for v in [s, row["set"], *row["trials"],
                                        *(f"{e:.2f}" for e in row["rapid"] + row["sibling"])]))
    if rows:
        for name in ("rapid", "sibling"):
            e = [x for r in rows for x in r[name]]
            print(f"# {name}: median {statistics.median(e):.2f}, worst {max(e):.2f} deg "
                  f"over {len(e)} trials, {sum(x > 3.0 for x in e)} above 3 deg")


if __name__ == "__main__":
    main()
