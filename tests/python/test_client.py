"""The fesbench Python client (clients/python) against a real fesbench-server
(tests/python/server.py): every method, its errors, the parameter-set event
stream, a token file, retries on 429/503, timeouts and TLS with a CA file.

Run by ctest (tests/python/CMakeLists.txt) with FESBENCH_SERVER_BINARY set.
"""

from __future__ import annotations

import http.server
import math
import os
import re
import shutil
import subprocess
import tempfile
import threading
import time
import unittest

import numpy as np
import pandas as pd

import fesbench
from fesbench import ApiError, Client, ConnectionFailed, JobFailed
from server import Server

BINARY = os.environ.get("FESBENCH_SERVER_BINARY", "")
SERVER: Server = None  # type: ignore[assignment]
LEG: dict = {}
ANALYST = ""


# Every (method, path) the client sent during the tests; tearDownModule
# checks each against the server's OpenAPI document (one vocabulary).
SENT = set()
_request = fesbench.client.Client._request


def _recording_request(self, method, path, *args, **kwargs):
    SENT.add((method, path, self.url))
    return _request(self, method, path, *args, **kwargs)


def setUpModule():
    global SERVER, LEG, ANALYST
    if not os.path.exists(BINARY):
        raise RuntimeError("FESBENCH_SERVER_BINARY must name the fesbench-server binary")
    fesbench.client.Client._request = _recording_request
    SERVER = Server(BINARY)
    try:
        LEG = SERVER.leg_with_recordings("PY-A", rapid_runs=2,
                                         fresh=("prediction_random_binary", "prediction_step"))
        ANALYST = SERVER.user_token("ana", "analyst")
    except BaseException:
        SERVER.stop()  # tearDownModule does not run after a failed setUpModule
        raise


def tearDownModule():
    fesbench.client.Client._request = _request
    if SERVER is not None:
        doc = SERVER.call("GET", "/openapi.json")
        routes = [(m.upper(), re.compile("^" + re.sub(r"\{[^}]+\}", "[^/]+", p) + "$"))
                  for p, ops in doc["paths"].items() for m in ops]
        sent = {(m, p) for m, p, url in SENT if url == SERVER.url}
        unknown = [(m, p) for m, p in sent
                   if not any(m == rm and rx.match("/api/v1" + p) for rm, rx in routes)]
        if unknown or len(sent) < 25:
            SERVER.stop()
            raise AssertionError(f"the client used routes the OpenAPI document lacks: {unknown} "
                                 f"(of {len(sent)} sent)")
        code = SERVER.stop()
        if code != 0:
            raise RuntimeError(f"fesbench-server exited {code}")


def analyst() -> Client:
    return Client(SERVER.url, token=ANALYST)


class ConnectionTest(unittest.TestCase):
    def test_health_openapi_and_me(self):
        with analyst() as fb:
            self.assertEqual(fb.health()["status"], "ok")
            doc = fb.openapi()
            self.assertIn("/api/v1/comparisons", doc["paths"])
            me = fb.me()
            self.assertEqual((me["name"], me["role"]), ("ana", "analyst"))

    def test_token_file(self):
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "analyst.token")
            with open(path, "w") as f:
                f.write(f"  {ANALYST}\n")  # white space around it is dropped
            self.assertEqual(Client(SERVER.url, token_file=path).me()["role"], "analyst")
            self.assertEqual(Client(SERVER.url, token_file=SERVER.admin_token_file).me()["role"],
                             "admin")
            open(path, "w").close()
            with self.assertRaisesRegex(ValueError, "empty"):
                Client(SERVER.url, token_file=path)
            with self.assertRaises(FileNotFoundError):
                Client(SERVER.url, token_file=os.path.join(d, "missing"))
        with self.assertRaisesRegex(ValueError, "exactly one"):
            Client(SERVER.url, token=ANALYST, token_file="x")
        with self.assertRaisesRegex(ValueError, "exactly one"):
            Client(SERVER.url)
        with self.assertRaisesRegex(ValueError, "http"):
            Client("ftp://x", token=ANALYST)
        with self.assertRaisesRegex(ValueError, "ca_file"):
            Client("https://127.0.0.1:1", token=ANALYST, ca_file="/nonexistent/ca.pem")

    def test_the_readme_calls_only_methods_that_exist(self):
        root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
        with open(os.path.join(root, "README.md"), encoding="utf-8") as f:
            block = f.read().split("```python", 1)[1].split("```", 1)[0]
        names = set(re.findall(r"\bfb\.(\w+)\(", block))
        self.assertGreater(len(names), 8, block)
        for name in names:
            self.assertTrue(callable(getattr(Client, name, None)), f"README calls fb.{name}")
        for name in re.findall(r"^from fesbench import (.*)$", block, re.M)[0].split(", "):
            self.assertTrue(hasattr(fesbench, name), name)

    def test_errors_carry_the_servers_code_message_and_field(self):
        with analyst() as fb:
            with self.assertRaises(ApiError) as e:
                fb.parameter_set(999)
            self.assertEqual((e.exception.status, e.exception.code), (404, "not_found"))
            self.assertIn("parameter set 999", e.exception.message)
            with self.assertRaises(ApiError) as e:
                fb.submit_comparison([(LEG["set_ids"][0], LEG["set_ids"][1], [LEG["fresh_trial_ids"][0]])],
                                     metric="e_bogus")
            self.assertEqual((e.exception.status, e.exception.field), (400, "metric"))
            with self.assertRaises(ApiError) as e:
                fb.submit_prediction(LEG["set_ids"][0], trial_id=LEG["fresh_trial_ids"][0],
                                     modes="free_swing")
            self.assertEqual(e.exception.field, "modes", "unknown fields are refused by name")
            with self.assertRaisesRegex(ValueError, "positive integer id"):
                fb.trial(-3)
            with self.assertRaisesRegex(ValueError, "leg"):
                fb.parameter_sets(leg="up")
        with self.assertRaises(ApiError) as e:
            Client(SERVER.url, token="fsb_not_a_token", retries=0).me()
        self.assertEqual((e.exception.status, e.exception.code), (401, "unauthenticated"))
        with self.assertRaises(ConnectionFailed):
            Client("http://127.0.0.1:1", token=ANALYST).health()

    def test_a_job_waited_for_too_briefly_times_out_and_can_be_waited_for_again(self):
        with analyst() as fb:
            job = fb.submit_comparison(
                [{"a_parameter_set_id": LEG["set_ids"][0], "b_parameter_set_id": LEG["set_ids"][1],
                  "trial_ids": LEG["fresh_trial_ids"]}])
            self.assertEqual(job.kind, "comparison")
            # As answered before a worker took it (the answer may already
            # say running or done): a zero wait gives up at once.
            queued = fesbench.Job(fb, dict(job.record, state="queued"))
            with self.assertRaisesRegex(TimeoutError, f"job {job.id} still queued"):
                queued.wait(timeout_s=0)
            result = queued.wait()
            self.assertEqual(len(result["pairs"][0]["trials"]), len(LEG["fresh_trial_ids"]))
            self.assertIsNone(result["t_test"])

    def test_a_failed_job_raises_with_its_error(self):
        with Client(SERVER.url, token=ANALYST) as fb:
            job = fb.submit_prediction(LEG["set_ids"][0], trial_id=987654)
            with self.assertRaises(JobFailed) as e:
                job.wait()
            self.assertEqual(e.exception.code, "not_found")
            self.assertEqual(fb.job(job.id).state, "failed")
            self.assertIn(job.id, [j["id"] for j in fb.jobs()])


class RecordsTest(unittest.TestCase):
    def test_subjects_sessions_and_revisions(self):
        SERVER.call("PATCH", f"/subjects/{LEG['subject_id']}",
                    {"reason": "measured", "details": {"age_years": 41}})
        with analyst() as fb:
            codes = [s["code"] for s in fb.subjects()]
            self.assertIn("PY-A", codes)
            subject = fb.subject("PY-A")
            self.assertEqual(subject["id"], LEG["subject_id"])
            self.assertEqual(fb.subject(LEG["subject_id"])["code"], "PY-A")
            revisions = fb.subject_revisions("PY-A")
            self.assertEqual(list(revisions["revision"]), [1, 2])
            self.assertEqual(revisions["reason"].iloc[-1], "measured")
            self.assertEqual(revisions["details.age_years"].iloc[-1], 41)
            sessions = fb.sessions("PY-A")
            self.assertEqual([s["id"] for s in sessions], [LEG["session_id"]])
            self.assertEqual(fb.sessions("PY-A", date_from="2027-01-01"), [])
            session = fb.session(LEG["session_id"])
            self.assertEqual(session["leg"], "right")
            self.assertEqual(list(fb.session_revisions(LEG["session_id"])["revision"]), [1])
            runs = fb.runs(LEG["session_id"])
            self.assertEqual(len(runs), 4)
            self.assertEqual(fb.run(runs[0]["run_id"])["protocol"], "rapid_parameterisation")
            with self.assertRaises(ApiError) as e:
                fb.subject("NOBODY")
            self.assertEqual(e.exception.status, 404)

    def test_trials_as_data_frames(self):
        with analyst() as fb:
            trials = fb.trials(LEG["session_id"])
            self.assertIn("num_samples", trials.columns)
            self.assertEqual(trials.attrs["units"]["sample_rate_hz"], "Hz")
            fresh = LEG["fresh_trial_ids"][0]
            row = trials.set_index("id").loc[fresh]
            frame = fb.trial(fresh)
            self.assertEqual(len(frame), row["num_samples"])
            for column in ("t_s", "angle_deg", "stim_ma", "torque_nm"):
                self.assertIn(column, frame.columns)
            self.assertEqual(frame.attrs["units"]["angle_deg"], "deg")
            self.assertAlmostEqual(frame.attrs["sample_rate_hz"], 200.0, places=6)
            self.assertEqual(frame.attrs["kind"], row["kind"])
            self.assertEqual(frame.attrs["name"], row["name"])
            # The same numbers as the trial's JSON, bit for bit.
            stored = fb.trial_json(fresh)
            self.assertEqual(list(frame.columns), [c["name"] for c in stored["channels"]])
            for channel in stored["channels"]:
                np.testing.assert_array_equal(frame[channel["name"]].to_numpy(),
                                              np.asarray(channel["values"]))
            if stored.get("emg"):
                emg = fb.trial(fresh, group="emg")
                self.assertEqual(len(emg), len(stored["emg"]["channels"][0]["values"]))
                self.assertEqual(emg.attrs["name"], row["name"])
                self.assertAlmostEqual(emg.attrs["sample_rate_hz"], 1000.0, places=6)
            else:
                with self.assertRaises(ApiError) as e:
                    fb.trial(fresh, group="emg")
                self.assertEqual(e.exception.field, "group")
            many = fb.trial_frames(list(trials["id"]))
            self.assertEqual(list(many), list(trials["id"]))
            pd.testing.assert_frame_equal(many[fresh], frame)
            self.assertEqual([len(f) for f in many.values()], list(trials["num_samples"]))
            pulses = fb.pulses(fresh)
            self.assertGreater(len(pulses), 10)
            self.assertEqual(pulses.attrs["units"]["stim_ma"], "mA")
            with self.assertRaisesRegex(ValueError, "group"):
                fb.trial(fresh, group="aux")
            kinds = {k["name"]: k for k in fb.trial_kinds()}
            self.assertTrue(kinds["prediction_random_binary"]["free_swing"])

    def test_export_loads_as_data_frames(self):
        with analyst() as fb:
            export = fb.load_export(LEG["session_id"])
            participants = export["participants.tsv"]
            self.assertEqual(list(participants["participant_id"]), ["sub-PYA"])
            tables = fesbench.motion(export)
            fresh = LEG["fresh_trial_ids"][0]
            self.assertIn(fresh, tables)
            np.testing.assert_array_equal(tables[fresh]["angle_deg"].to_numpy(),
                                          fb.trial(fresh)["angle_deg"].to_numpy())
            self.assertEqual(tables[fresh].attrs["units"]["angle_deg"], "deg")
            self.assertIn("derivatives/fesbench/session.json", export)
            as_tar = fb.load_export(LEG["session_id"], fmt="tar.gz")
            self.assertEqual(sorted(as_tar), sorted(export))
            with self.assertRaisesRegex(ValueError, "fmt"):
                fb.export(LEG["session_id"], fmt="rar")
            self.assertIn("<html", fb.report(LEG["session_id"]).lower())


class ParameterSetsTest(unittest.TestCase):
    def test_history_curves_and_provenance(self):
        a, b = LEG["set_ids"]
        with analyst() as fb:
            history = fb.parameter_sets(subject="PY-A", leg="right")
            # (Other tests add sets by identification after these two.)
            self.assertEqual(list(history["id"][:2]), [a, b])
            self.assertEqual(list(history["version"][:2]), [1, 2])
            self.assertEqual(list(history["approved"][:2]), [False, True])
            self.assertEqual(history["approved_by"].iloc[0], "admin")
            full = fb.parameter_sets(subject=LEG["subject_id"], with_parameters=True)
            pole = fb.parameter_set(a)["parameters"]["contraction"]["pole_per_s"]
            self.assertEqual(full["contraction.pole_per_s"].iloc[0], pole)
            self.assertEqual(full.attrs["units"]["passive.inertia_kgm2"], "kg.m^2")
            self.assertEqual(len(fb.parameter_sets(subject="PY-A", date_from="2030-01-01")), 0)

            curves = fb.curves(a)
            self.assertEqual(sorted(curves["curve"].unique()),
                             ["f_ata", "f_atv", "irc", "tau_pta", "tau_ptv"])
            s = fb.parameter_set(a)
            pta = curves[curves["curve"] == "tau_pta"]
            self.assertEqual(list(pta["x"]), s["parameters"]["passive"]["torque_angle"]["angle_deg"])
            self.assertEqual(list(pta["y"]), s["parameters"]["passive"]["torque_angle"]["torque_nm"])
            self.assertEqual(set(pta["y_unit"]), {"N.m"})
            for _, c in curves.groupby("curve"):
                self.assertTrue(np.all(np.diff(c["x"].to_numpy()) > 0))
            self.assertEqual(set(fb.curves(s)["parameter_set_id"]), {a})

            provenance = fb.provenance(a)
            self.assertEqual(provenance["trial_ids"], s["trial_ids"])
            self.assertIn("fit_rms", provenance)
            held_out = fb.held_out_trials(a)
            self.assertFalse(set(held_out) & set(s["trial_ids"]))
            self.assertTrue(set(LEG["fresh_trial_ids"]) <= set(held_out))
            self.assertEqual(fb.approved_parameter_set("PY-A", "right")["id"], b)
            with self.assertRaises(ApiError) as e:
                fb.approved_parameter_set("PY-A", "left")
            self.assertEqual(e.exception.status, 404)


class AnalysisTest(unittest.TestCase):
    def test_predict_a_trial_a_stimulus_and_the_held_out_trials(self):
        a = LEG["set_ids"][0]
        fresh = LEG["fresh_trial_ids"][0]
        seen = []
        with analyst() as fb:
            prediction = fb.predict(a, trial_id=fresh, progress=seen.append)
            self.assertEqual(seen[-1]["state"], "done")
            self.assertEqual(len(prediction), len(fb.trial(fresh)))
            errors = prediction.attrs["errors"]
            self.assertEqual((errors["channel"], errors["unit"]), ("angle_deg", "deg"))
            self.assertGreater(errors["e_rms"], 0.0)
            self.assertLessEqual(errors["e_abs"], errors["e_rms"] + 1e-9)
            stored = fb.prediction(prediction.attrs["prediction_id"])
            self.assertEqual(stored["id"], prediction.attrs["prediction_id"])
            self.assertIn(stored["id"], [p["id"] for p in fb.predictions_of(a)])

            step = fb.predict(a, stimulus={"generator": "prediction_step", "params": {}})
            self.assertIsNone(step.attrs["errors"])
            self.assertIn("angle_deg", step.columns)
            with self.assertRaisesRegex(ValueError, "exactly one"):
                fb.predict(a)

            table = fb.predict_held_out(a)
            self.assertEqual(sorted(table["trial_id"]), sorted(fb.held_out_trials(a)))
            self.assertTrue((table["e_rms"] > 0).all())

    def test_compare_two_sets_over_many_trials_and_over_one(self):
        a, b = LEG["set_ids"]
        with analyst() as fb:
            many = fb.compare(a, b)
            trials = fb.held_out_trials(a, [b])
            self.assertGreaterEqual(len(trials), 2)
            self.assertEqual(sorted(many.frame["trial_id"]), sorted(trials))
            self.assertEqual(many.t_test["n"], len(trials))
            self.assertIsNone(many.t_test_note)
            d = many.frame["difference"].to_numpy()
            self.assertAlmostEqual(many.t_test["mean_difference"], d.mean(), places=9)
            self.assertAlmostEqual(many.t_test["t"],
                                   d.mean() / (d.std(ddof=1) / math.sqrt(len(d))), places=6)
            self.assertIn("p =", repr(many))

            one = fb.compare(a, b, trial_ids=[LEG["fresh_trial_ids"][0]])
            self.assertIsNone(one.t_test)
            self.assertIn("at least 2 pairs, got 1", one.t_test_note)
            self.assertEqual(len(one.frame), 1)
            self.assertGreater(one.frame["a_error"].iloc[0], 0.0)
            self.assertIn("at least 2 pairs", repr(one))

    def test_identify_and_the_approved_set(self):
        approved = SERVER.call("GET", f"/subjects/{LEG['subject_id']}/legs/right/approved-parameter-set")
        with analyst() as fb:
            result = fb.identify(session_id=LEG["session_id"], method="rapid")
            new_set = result["parameter_sets"][0]
            self.assertGreater(new_set["id"], max(LEG["set_ids"]))
            # A re-identification is a candidate: the approved set stays
            # (docs/API.md "Parameter-set approval").
            self.assertEqual(fb.approved_parameter_set("PY-A", "right")["id"], approved["id"])
            self.assertFalse(fb.parameter_set(new_set["id"])["approved"])
            # Every option reaches the request: rapid refuses thesis methods.
            with self.assertRaises(ApiError) as e:
                fb.identify(session_id=LEG["session_id"], method="rapid",
                            passive_method="simultaneous")
            self.assertEqual((e.exception.status, e.exception.field), (400, "passive_method"))
            with self.assertRaisesRegex(ValueError, "exactly one"):
                fb.submit_identification()

    def test_the_parameter_set_stream(self):
        with analyst() as fb:
            with fb.parameter_set_events(timeout_s=20) as events:
                job = fb.submit_identification(session_id=LEG["session_id"], method="rapid")
                result = job.wait()
                event = next(events)
            self.assertEqual(event["parameter_set_id"], result["parameter_sets"][0]["id"])
            self.assertEqual(event["subject_id"], LEG["subject_id"])
            with self.assertRaisesRegex(ValueError, "timeout_s"):
                fb.parameter_set_events(timeout_s=0)
            # A stream that ends on its own stops the iteration.
            with fb.parameter_set_events(timeout_s=1) as quiet:
                self.assertEqual(list(quiet), [])


class _Scripted(http.server.BaseHTTPRequestHandler):
    """Answers each GET with the next of `script`: (status, headers, delay_s)."""

    script: list = []
    seen: list = []

    def do_GET(self):  # noqa: N802 (http.server's name)
        status, headers, delay = self.script.pop(0) if self.script else (200, {}, 0)
        self.seen.append(time.monotonic())
        time.sleep(delay)
        body = (b'{"status": "ok"}' if status == 200 else
                b'{"error": {"code": "unavailable", "message": "busy"}}')
        self.send_response(status)
        for k, v in headers.items():
            self.send_header(k, v)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, *args):
        pass


class TransportTest(unittest.TestCase):
    """Retries and timeouts, against a scripted server (the real one is
    never overloaded on purpose) and, for 429, the real one."""

    def setUp(self):
        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Scripted)
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}"
        _Scripted.seen = []

    def tearDown(self):
        self.httpd.shutdown()
        self.httpd.server_close()

    def test_503_is_retried_after_retry_after(self):
        _Scripted.script = [(503, {"Retry-After": "0.3"}, 0), (503, {"Retry-After": "0"}, 0)]
        self.assertEqual(Client(self.url, token="fsb_x", retries=2).health()["status"], "ok")
        self.assertEqual(len(_Scripted.seen), 3)
        self.assertGreaterEqual(_Scripted.seen[1] - _Scripted.seen[0], 0.28)
        _Scripted.script = [(503, {"Retry-After": "0"}, 0)] * 2
        with self.assertRaises(ApiError) as e:
            Client(self.url, token="fsb_x", retries=1).health()
        self.assertEqual((e.exception.status, e.exception.code), (503, "unavailable"))
        self.assertEqual(e.exception.retry_after_s, 0.0)

    def test_timeout(self):
        _Scripted.script = [(200, {}, 1.0)]
        start = time.monotonic()
        with self.assertRaisesRegex(ConnectionFailed, "no answer within"):
            Client(self.url, token="fsb_x", timeout_s=0.2).health()
        self.assertLess(time.monotonic() - start, 0.9)

    def test_429_from_the_real_server_is_retried(self):
        server = Server(BINARY, ["--auth-failure-burst", "1", "--auth-failure-refill-per-s", "1"])
        try:
            bad = Client(server.url, token="fsb_wrong", retries=0)
            with self.assertRaises(ApiError) as e:
                bad.me()  # spends the burst
            self.assertEqual(e.exception.status, 401)
            with self.assertRaises(ApiError) as e:
                bad.me()
            self.assertEqual(e.exception.status, 429)
            self.assertIsNotNone(e.exception.retry_after_s)
            # Retried after Retry-After, the wrong token is judged again: 401.
            start = time.monotonic()
            with self.assertRaises(ApiError) as e:
                Client(server.url, token="fsb_wrong", retries=3).me()
            self.assertEqual(e.exception.status, 401)
            self.assertGreater(time.monotonic() - start, 0.2)
        finally:
            self.assertEqual(server.stop(), 0)


@unittest.skipUnless(shutil.which("openssl"), "needs the openssl tool")
class TlsTest(unittest.TestCase):
    def test_https_with_a_ca_file(self):
        with tempfile.TemporaryDirectory() as d:
            def run(*args):
                subprocess.run(["openssl", *args], cwd=d, check=True, capture_output=True)
            key = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
            run("req", "-x509", *key, "-keyout", "ca.key", "-out", "ca.pem", "-days", "1",
                "-subj", "/CN=fesbench python test CA")
            run("req", *key, "-keyout", "server.key", "-out", "server.csr", "-subj", "/CN=127.0.0.1")
            with open(os.path.join(d, "server.ext"), "w") as f:
                f.write("basicConstraints=critical,CA:FALSE\nkeyUsage=critical,digitalSignature\n"
                        "extendedKeyUsage=serverAuth\nsubjectAltName=IP:127.0.0.1\n")
            run("x509", "-req", "-in", "server.csr", "-CA", "ca.pem", "-CAkey", "ca.key",
                "-CAcreateserial", "-days", "1", "-extfile", "server.ext", "-out", "server.pem")
            server = Server(BINARY, ["--tls-cert", os.path.join(d, "server.pem"),
                                     "--tls-key", os.path.join(d, "server.key")])
            try:
                url = server.url.replace("http://", "https://")
                fb = Client(url, token=server.admin_token, ca_file=os.path.join(d, "ca.pem"))
                self.assertEqual(fb.me()["role"], "admin")
                with self.assertRaisesRegex(ConnectionFailed, "TLS"):
                    Client(url, token=server.admin_token).me()
            finally:
                self.assertEqual(server.stop(), 0)


if __name__ == "__main__":
    unittest.main()
