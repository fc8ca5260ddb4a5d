"""A real fesbench-server for the Python tests and the notebook, as
tests/server/http/server_process.h starts one: 127.0.0.1, --port 0 (the port
read from its "listening on" line), a temporary data folder, --time-scale 0
(the simulated bench as fast as it computes), --dds-transport off. The admin
token is the one the server writes to <data-dir>/admin.token.

Also the recordings the tests need, made through the API the way a clinician
makes them (docs/API.md): a subject whose anthropometrics are the simulated
leg's, a session with its limits, and protocol runs heart-beaten to their end.
"""

from __future__ import annotations

import atexit
import ctypes
import json
import os
import re
import shutil
import signal
import subprocess
import tempfile
import threading
import time
import urllib.request
from typing import List, Optional


def _die_with_parent() -> None:
    """In the child: SIGTERM when the test process dies, however it dies
    (Linux prctl PR_SET_PDEATHSIG), so no server outlives its test."""
    ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)


class Server:
    def __init__(self, binary: str, extra_args: Optional[List[str]] = None, timeout_s: float = 20):
        self.dir = tempfile.mkdtemp(prefix="fesbench-py-")
        data = os.path.join(self.dir, "data")
        args = [binary, "--bind", "127.0.0.1", "--port", "0", "--db", os.path.join(data, "fesbench.db"),
                "--data-dir", data, "--time-scale", "0", "--dds-transport", "off"]
        self.stderr = open(os.path.join(self.dir, "stderr.log"), "wb")
        self.process = subprocess.Popen(args + (extra_args or []), stdout=subprocess.PIPE,
                                        stderr=self.stderr, text=True,
                                        preexec_fn=_die_with_parent)
        atexit.register(self._kill_if_running)
        self.port = 0
        deadline = time.monotonic() + timeout_s
        lines = []
        while time.monotonic() < deadline:
            line = self.process.stdout.readline()
            if not line:
                break
            lines.append(line)
            m = re.search(r"listening on \S*:(\d+)", line)
            if m:
                self.port = int(m.group(1))
                break
        if not self.port:
            self.stop()
            raise RuntimeError("fesbench-server did not start:\n" + "".join(lines))
        # Keep reading stdout so the server never blocks on a full pipe.
        threading.Thread(target=self.process.stdout.read, daemon=True).start()
        with open(os.path.join(data, "admin.token"), encoding="utf-8") as f:
            self.admin_token = f.read().strip()
        self.admin_token_file = os.path.join(data, "admin.token")
        self.url = f"http://127.0.0.1:{self.port}"

    def stop(self) -> int:
        code = -1
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            try:
                code = self.process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        else:
            code = self.process.returncode
        self.stderr.close()
        shutil.rmtree(self.dir, ignore_errors=True)
        return code

    def _kill_if_running(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()
            shutil.rmtree(self.dir, ignore_errors=True)

    # --- raw API calls (the tests' own, independent of the client) -----------

    def call(self, method: str, path: str, body=None, token: Optional[str] = None):
        data = json.dumps(body).encode() if body is not None else None
        request = urllib.request.Request(self.url + "/api/v1" + path, data=data, method=method)
        request.add_header("Authorization", f"Bearer {token or self.admin_token}")
        if data is not None:
            request.add_header("Content-Type", "application/json")
        with urllib.request.urlopen(request, timeout=30) as response:
            return json.loads(response.read() or b"null")

    def user_token(self, name: str, role: str) -> str:
        user = self.call("POST", "/users", {"name": name, "role": role})
        return self.call("POST", "/tokens", {"user_id": user["id"]})["token"]

    def run(self, session_id: int, protocol: str, parameters: Optional[dict] = None) -> dict:
        """Starts a protocol and heart-beats it to its end; the final run."""
        body = {"protocol": protocol}
        if parameters:
            body["parameters"] = parameters
        run = self.call("POST", f"/sessions/{session_id}/runs", body)
        run_id = run["run_id"]
        deadline = time.monotonic() + 120
        while run["state"] in ("queued", "running"):
            if time.monotonic() > deadline:
                raise RuntimeError(f"run {run_id} did not end")
            try:
                self.call("POST", f"/runs/{run_id}/heartbeat")
            except urllib.error.HTTPError:
                pass  # the run ended between the two calls
            time.sleep(0.05)
            run = self.call("GET", f"/runs/{run_id}")
        if run["state"] != "done":
            raise RuntimeError(f"run {run_id} ({protocol}) ended {run['state']}: {run['reason']}")
        return run

    def leg_with_recordings(self, code: str, rapid_runs: int = 2,
                            fresh: tuple = ("prediction_random_binary",)) -> dict:
        """A subject (right leg) with one session, `rapid_runs` rapid
        parameterisations (one set each) and the `fresh` prediction runs
        (trials no set was fitted on). Ids of everything made."""
        truth = self.call("GET", "/bench/virtual-subject")
        anthropometrics = truth["anthropometrics"]
        subject = self.call("POST", "/subjects", {
            "code": code, "legs": ["right"],
            "details": {"weight_kg": anthropometrics["body_mass_kg"],
                        "shank_length_cm": anthropometrics["shank_length_m"] * 100.0}})
        session = self.call("POST", f"/subjects/{subject['id']}/sessions", {
            "leg": "right", "date": "2026-11-21", "threshold_ma": truth["threshold_ma"],
            "max_tolerated_ma": truth["max_tolerated_ma"]})
        sets, fresh_trials = [], []
        for _ in range(rapid_runs):
            sets.append(self.run(session["id"], "rapid_parameterisation")["parameter_set_id"])
        for protocol in fresh:
            fresh_trials.extend(self.run(session["id"], protocol)["trial_ids"])
        return {"subject_id": subject["id"], "code": code, "session_id": session["id"],
                "set_ids": sets, "fresh_trial_ids": fresh_trials}
