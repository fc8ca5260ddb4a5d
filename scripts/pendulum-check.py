#!/usr/bin/env python3
"""A real pendulum test through the API, as a lab would bring it (docs/MODEL.md,
"Passive-only identification"; the figures are in docs/VALIDATION.md).

Imports two OpenSim motion files of one leg's pendulum tests into a new
subject on a running fesbench-server (knee_angle_r mapped by its OpenSim
name, flexion negative; every other coordinate left out), identifies the
passive curves from the first with method passive, J identified from the
swing with the given m·g·l (J given instead when the server says the swing
does not determine it, or with --given-inertia), predicts
both from the release (the examiner holds the shank before it), and prints
J against the scaled model's and E_RMS over the whole swing and its first
2 s. Beside it, the
2-parameter pendulum of the pendulum-test literature,
    J·θ̈ = m·g·l·sin(θ_rest − θ) − B·θ̇ + T
(θ_rest the knee angle at which the shank hangs at rest in the recording,
so θ_rest − θ is the shank's angle from the vertical), with J and m·g·l from
the same anthropometrics and B, T fitted by output error
(scipy.optimize.least_squares) on the same trial, from the same start.

The recordings are not in the repository (their source states no licence):
docs/VALIDATION.md names them and how they were obtained.

  scripts/pendulum-check.py --url http://127.0.0.1:8080 --token-file T \\
      --inertia-kgm2 0.0552 --mgl-nm 1.94 FIT.mot HELD_OUT.mot
"""
import argparse
import sys
import time

import numpy as np
import requests
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares


def call(s, method, url, body=None, ok=(200, 201, 202)):
    r = s.request(method, url, json=body, timeout=120)
    if r.status_code not in ok:
        sys.exit(f"{method} {url}: {r.status_code} {r.text[:500]}")
    return r.json()


def wait(s, base, job_id, may_fail=False):
    while True:
        job = call(s, "GET", f"{base}/jobs/{job_id}")
        if job["state"] in ("done", "failed"):
            if job["state"] == "failed":
                if may_fail:
                    return job
                sys.exit(f"job {job_id} failed: {job.get('error')}")
            return job["result"]
        time.sleep(0.2)


def channel(trial, name):
    for ch in trial["channels"]:
        if ch["name"] == name:
            return np.asarray(ch["values"], dtype=float)
    sys.exit(f"trial has no {name} channel")


def rms(a, b):
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


def pendulum(t, theta0, omega0, rest, j, mgl, b, tb):
    """The 2-parameter pendulum from theta0 (deg), omega0 (deg/s), shank
    vertical at rest (deg), sampled at t (s)."""
    hang = np.radians(rest)
    def rhs(_, y):
        th, w = y
        return [w, (mgl * np.sin(hang - th) - b * w + tb) / j]
    sol = solve_ivp(rhs, (t[0], t[-1]), [np.radians(theta0), np.radians(omega0)], t_eval=t,
                    rtol=1e-8, atol=1e-10)
    out = np.full(len(t), np.nan)
    out[: sol.y.shape[1]] = np.degrees(sol.y[0])
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--url", default="http://127.0.0.1:8080")
    ap.add_argument("--token-file", required=True)
    ap.add_argument("--inertia-kgm2", type=float, required=True)
    ap.add_argument("--mgl-nm", type=float, required=True)
    ap.add_argument("--given-inertia", action="store_true",
                    help="identify with --inertia-kgm2 fixed instead of J from the swing")
    ap.add_argument("--source", default="pendulum test, OpenSim IK")
    ap.add_argument("files", nargs=2, metavar="MOT")
    a = ap.parse_args()
    base = a.url.rstrip("/") + "/api/v1"
    s = requests.Session()
    s.headers["Authorization"] = "Bearer " + open(a.token_file).read().strip()

    code = "PENDULUM-" + time.strftime("%Y%m%d%H%M%S")
    subject = call(s, "POST", f"{base}/subjects",
                   {"code": code, "details": {}, "legs": ["right"]})
    session = call(s, "POST", f"{base}/subjects/{subject['id']}/sessions",
                   {"leg": "right", "date": time.strftime("%Y-%m-%d")})
    spec = {"kind": "free_swing_passive", "format": "sto",
            "columns": [{"column": "knee_angle_r"}], "unmapped": "ignore", "source": a.source}
    ids = []
    for path in a.files:
        with open(path) as f:
            imported = call(s, "POST", f"{base}/sessions/{session['id']}/trials",
                            {"spec": spec, "data": f.read()})
        ids.append(imported["trials"][0]["id"])
    # J from the swing with m·g·l given; when the swing does not determine
    # it the server refuses naming the figures, and J is given instead.
    result = None
    if not a.given_inertia:
        fit = call(s, "POST", f"{base}/identifications",
                   {"trial_ids": [ids[0]], "method": "passive", "gravity_moment_nm": a.mgl_nm})
        result = wait(s, base, fit["id"], may_fail=True)
        if result.get("state") == "failed":
            print(f"J from the swing refused: {result['error']['message']}")
            result = None
    if result is None:
        fit = call(s, "POST", f"{base}/identifications",
                   {"trial_ids": [ids[0]], "method": "passive", "inertia_kgm2": a.inertia_kgm2})
        result = wait(s, base, fit["id"])
    set_id = result["parameter_sets"][0]["id"]
    print(f"subject {code}: trials {ids[0]} (fit) and {ids[1]} (held out); parameter set {set_id}")
    params = call(s, "GET", f"{base}/parameter-sets/{set_id}")["parameters"]
    j = params["passive"]["inertia_kgm2"]
    print(f"J {j:.4f} kg·m² ({params['provenance']['inertia_method']}), "
          f"{100.0 * (j / a.inertia_kgm2 - 1.0):+.1f} % against {a.inertia_kgm2} kg·m²")

    # Each trial from its release (the server predicts a held pendulum test
    # from there: released_at_s), times from the release.
    measured, predicted, start_velocity = [], [], []
    for tid in ids:
        trial = call(s, "GET", f"{base}/trials/{tid}")
        t = channel(trial, "t_s")
        angle = channel(trial, "angle_deg")
        job = call(s, "POST", f"{base}/predictions", {"parameter_set_id": set_id, "trial_id": tid})
        result = wait(s, base, job["id"])
        released = result.get("released_at_s") or 0.0
        keep = t - t[0] >= released - 1e-9
        t_rel = t[keep] - t[keep][0]
        measured.append((t_rel, angle[keep]))
        start_velocity.append(result["initial_velocity_deg_s"])
        pred = call(s, "GET", f"{base}/predictions/{result['prediction_id']}")
        cols = pred.get("columns") or pred.get("output", {}).get("columns")
        predicted.append(np.interp(t_rel, cols["t_s"], cols["angle_deg"]))
        print(f"trial {tid}: released at {released:.2f} s, E_RMS from the server "
              f"{result['errors']['e_rms']:.2f}°")

    # The 2-parameter pendulum, B and T fitted on the first trial; each trial's
    # rest angle is the mean of its last second.
    rest = [float(np.mean(th[tt >= tt[-1] - 1.0])) for tt, th in measured]
    t0, th0 = measured[0]
    def resid(p):
        r = pendulum(t0, th0[0], start_velocity[0], rest[0], a.inertia_kgm2, a.mgl_nm,
                     p[0], p[1]) - th0
        return np.nan_to_num(r, nan=1e3)
    bt = least_squares(resid, [0.05, 0.0], bounds=([0.0, -5.0], [5.0, 5.0])).x
    print(f"2-parameter pendulum: B = {bt[0]:.4f} N·m·s/rad, T = {bt[1]:.4f} N·m "
          f"(J = {a.inertia_kgm2} kg·m², m·g·l = {a.mgl_nm} N·m, rest "
          f"{rest[0]:.1f}° / {rest[1]:.1f}°)")

    print("trial        | fesbench E_RMS whole / first 2 s | pendulum E_RMS whole / first 2 s")
    for k, name in enumerate(["fit", "held out"]):
        t, th = measured[k]
        pend = pendulum(t, th[0], start_velocity[k], rest[k], a.inertia_kgm2, a.mgl_nm,
                        bt[0], bt[1])
        first = t <= 2.0
        print(f"{name:12} | {rms(predicted[k], th):6.2f}° / {rms(predicted[k][first], th[first]):6.2f}°"
              f"             | {rms(pend, th):6.2f}° / {rms(pend[first], th[first]):6.2f}°")


if __name__ == "__main__":
    main()
