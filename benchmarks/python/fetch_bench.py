#!/usr/bin/python3
"""Fetching as DataFrames: the fesbench Python client against the same done
by hand with requests + pandas. Not a pass/fail test: it prints min, median
and max wall time over --repeats runs of each way.

Starts its own fesbench-server (tests/python/server.py: 127.0.0.1, port 0, a
temporary data folder, --time-scale 0), records --runs rapid
parameterisations on one leg (about 7 trials each; the first --trials are
fetched) and identifies from them until the leg has --sets parameter sets.

    benchmarks/python/fetch_bench.py --server build/server/fesbench-server
"""

from __future__ import annotations

import argparse
import io
import os
import statistics
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))
sys.path[:0] = [os.path.join(ROOT, "clients", "python"), os.path.join(ROOT, "tests", "python")]

import pandas as pd  # noqa: E402
import requests  # noqa: E402

from fesbench import Client  # noqa: E402
from server import Server  # noqa: E402


def timed(fn, repeats):
    times = []
    result = None
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return times, result


def identity_session():
    """A session that asks for answers uncompressed, as the client does."""
    session = requests.Session()
    session.headers["Accept-Encoding"] = "identity"
    return session


def by_hand_sets(url, token, subject_id, session=None):
    """What an analyst writes without the client: page the list, GET each
    set, flatten with json_normalize."""
    get = (session or requests).get
    headers = {"Authorization": f"Bearer {token}"}
    items, cursor = [], None
    while True:
        params = {"subject_id": subject_id, "limit": 500}
        if cursor:
            params["cursor"] = cursor
        page = get(f"{url}/api/v1/parameter-sets", params=params, headers=headers).json()
        items += page["items"]
        cursor = page["next_cursor"]
        if not cursor:
            break
    sets = [get(f"{url}/api/v1/parameter-sets/{s['id']}", headers=headers).json() for s in items]
    return pd.json_normalize(sets)


def by_hand_trials(url, token, trial_ids, session=None, csv=False, exact=False):
    get = (session or requests).get
    headers = {"Authorization": f"Bearer {token}"}
    frames = []
    for t in trial_ids:
        if csv:
            text = get(f"{url}/api/v1/trials/{t}", params={"format": "csv"}, headers=headers).text
            # Pandas' default float parser is not exact: float_precision=
            # "round_trip" reads back the doubles the server stored.
            frames.append(pd.read_csv(io.StringIO(text),
                                      float_precision="round_trip" if exact else None))
        else:
            trial = get(f"{url}/api/v1/trials/{t}", headers=headers).json()
            frames.append(pd.DataFrame({c["name"]: c["values"] for c in trial["channels"]}))
    return frames


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--server", default=os.path.join(ROOT, "build", "server", "fesbench-server"),
                        help="the fesbench-server binary")
    parser.add_argument("--sets", type=int, default=1000, help="parameter sets to fetch")
    parser.add_argument("--trials", type=int, default=100, help="trials to fetch")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs of each way")
    parser.add_argument("--skip-gzip", action="store_true",
                        help="leave out the by-hand ways that accept gzip (minutes at 1,000 sets)")
    args = parser.parse_args()

    server = Server(args.server)
    try:
        runs = -(-args.trials // 7)
        start = time.perf_counter()
        leg = server.leg_with_recordings("BENCH", rapid_runs=runs, fresh=())
        trials = [t["id"] for t in server.call("GET", f"/sessions/{leg['session_id']}/trials?limit=500")["items"]]
        trials = trials[: args.trials]
        if len(trials) < args.trials:
            raise SystemExit(f"only {len(trials)} trials recorded")
        token = server.user_token("bench", "analyst")
        fb = Client(server.url, token=token)
        two_at_a_time = Client(server.url, token=token, parallel=2)
        have = len(leg["set_ids"])
        models = ["full", "single_segment", "parametric"]
        while have < args.sets:
            result = fb.identify(session_id=leg["session_id"], method="rapid",
                                 models=models[: min(3, args.sets - have)])
            have += len(result["parameter_sets"])
        print(f"server with {len(trials)} trials and {have} parameter sets in "
              f"{time.perf_counter() - start:.1f} s", file=sys.stderr)

        url, subject = server.url, leg["subject_id"]
        ways = [
            ("sets: client parameter_sets(with_parameters=True)",
             lambda: fb.parameter_sets(subject=subject, with_parameters=True)),
            ("sets: client, parallel=2",
             lambda: two_at_a_time.parameter_sets(subject=subject, with_parameters=True)),
            ("sets: by hand, requests.get + json_normalize",
             lambda: by_hand_sets(url, token, subject)),
            ("sets: by hand, requests.Session + json_normalize",
             lambda: by_hand_sets(url, token, subject, requests.Session())),
            ("sets: by hand, requests.Session, no gzip + json_normalize",
             lambda: by_hand_sets(url, token, subject, identity_session())),
            ("sets: client parameter_sets() (summaries only)",
             lambda: fb.parameter_sets(subject=subject)),
            ("trials: client trial_frames(), parallel=2",
             lambda: two_at_a_time.trial_frames(trials)),
            ("trials: client trial() one after another",
             lambda: [fb.trial(t) for t in trials]),
            ("trials: by hand, requests.get JSON + DataFrame",
             lambda: by_hand_trials(url, token, trials)),
            ("trials: by hand, requests.Session JSON + DataFrame",
             lambda: by_hand_trials(url, token, trials, requests.Session())),
            ("trials: by hand, requests.Session, no gzip, JSON + DataFrame",
             lambda: by_hand_trials(url, token, trials, identity_session())),
            ("trials: by hand, requests.Session CSV + read_csv",
             lambda: by_hand_trials(url, token, trials, requests.Session(), csv=True)),
            ("trials: by hand, requests.Session, no gzip, CSV + read_csv",
             lambda: by_hand_trials(url, token, trials, identity_session(), csv=True)),
            ("trials: by hand, Session, no gzip, CSV + read_csv round_trip",
             lambda: by_hand_trials(url, token, trials, identity_session(), csv=True, exact=True)),
        ]
        if args.skip_gzip:
            ways = [w for w in ways if "no gzip" in w[0] or "client" in w[0]]
        print(f"{'what':62s} {'n':>5s} {'min s':>8s} {'median s':>9s} {'max s':>8s}")
        for name, fn in ways:
            times, result = timed(fn, args.repeats)
            n = len(result)
            print(f"{name:62s} {n:5d} {min(times):8.3f} {statistics.median(times):9.3f} "
                  f"{max(times):8.3f}", flush=True)
    finally:
        server.stop()


if __name__ == "__main__":
    main()
