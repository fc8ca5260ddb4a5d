"""The fesbench HTTP/JSON API (docs/API.md) for analysts, in Python.

Every method maps onto one resource of docs/API.md and keeps the server's
field names (units in the keys: ``angle_deg``, ``torque_nm``, ``stim_ma``),
so the vocabulary is the one of api/ and the server. Tabular data come back
as pandas DataFrames whose column names carry their units; the units are
also in ``DataFrame.attrs["units"]``.
"""

from __future__ import annotations

import io
import json
import os
import re
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Callable, Dict, Iterator, List, Optional, Sequence, Tuple, Union

import pandas as pd
import requests

from . import frames
from .errors import ApiError, ConnectionFailed, FesbenchError, JobFailed

API_PREFIX = "/api/v1"

# A subject by id or pseudonymous code.
_Id = Union[int, str]


class Job:
    """A job of the server's pool (docs/API.md, "Jobs"): an identification,
    prediction or comparison. :meth:`wait` follows it to ``done`` (its
    ``result``) or ``failed`` (:class:`JobFailed`)."""

    def __init__(self, client: "Client", job: dict):
        self._client = client
        self.record = job

    @property
    def id(self) -> int:
        return int(self.record["id"])

    @property
    def kind(self) -> str:
        return str(self.record["kind"])

    @property
    def state(self) -> str:
        return str(self.record["state"])

    def refresh(self) -> dict:
        self.record = self._client._get(f"/jobs/{self.id}")
        return self.record

    def wait(self, timeout_s: float = 600.0, progress: Union[bool, Callable[[dict], None]] = False,
             poll_s: float = 0.02, max_poll_s: float = 0.25) -> Any:
        """Polls ``GET /jobs/{id}`` until the job ends; returns its ``result``.

        ``progress``: True prints each state change and the time waited on
        standard error; a callable is called with the job record after each
        poll. Raises :class:`JobFailed` for a failed job, ``TimeoutError``
        after ``timeout_s``.
        """
        start = time.monotonic()
        last_state = None
        delay = poll_s
        while True:
            job = self.record
            if callable(progress):
                progress(job)
            elif progress and job["state"] != last_state:
                print(f"job {self.id} ({self.kind}): {job['state']} after "
                      f"{time.monotonic() - start:.2f} s", file=sys.stderr)
            last_state = job["state"]
            if job["state"] == "done":
                return job.get("result")
            if job["state"] == "failed":
                raise JobFailed(job)
            if time.monotonic() - start > timeout_s:
                raise TimeoutError(f"job {self.id} still {job['state']} after {timeout_s} s")
            time.sleep(delay)
            delay = min(delay * 2.0, max_poll_s)
            self.refresh()

    def __repr__(self) -> str:
        return f"Job(id={self.id}, kind={self.kind!r}, state={self.state!r})"


class Client:
    """A client of one fesbench server.

    ``Client("http://127.0.0.1:8080", token="fsb_…")`` or
    ``Client(url, token_file="analyst.token")`` (white space around the
    token is dropped, as the CLI does). ``ca_file`` names the CA PEM of a
    lab's self-signed certificate (``https://`` servers); ``timeout_s`` is
    the connect and read timeout of each request; a 503 (overload) or 429
    (too many failed tokens) is retried ``retries`` times after the
    server's ``Retry-After`` (at most ``max_retry_wait_s``; docs/API.md
    error table); a GET whose connection the server had closed (idle
    keep-alive connections close after 5 s) is sent once more on a new one.
    ``compress=False`` (the default) asks for answers uncompressed: the
    server compresses a 340 kB trial in about 0.6 s, far longer than a lab
    network takes to carry it whole. ``parallel``: how many
    requests at once fetch many sets or trials (``with_parameters``,
    :meth:`trial_frames`): on a 2-core server one at a time is fastest
    (benchmarks/python/fetch_bench.py), a server with more cores may gain.
    """

    def __init__(self, url: str, token: Optional[str] = None, token_file: Optional[str] = None,
                 ca_file: Optional[str] = None, timeout_s: float = 30.0, retries: int = 3,
                 max_retry_wait_s: float = 10.0, compress: bool = False, parallel: int = 1):
        if not isinstance(url, str) or not url.startswith(("http://", "https://")):
            raise ValueError(f"url must start with http:// or https://, got {url!r}")
        if (token is None) == (token_file is None):
            raise ValueError("give exactly one of token= and token_file=")
        if token_file is not None:
            with open(token_file, encoding="utf-8") as f:
                token = f.read()
        token = (token or "").strip()
        if not token or any(c.isspace() for c in token):
            raise ValueError("the token is empty or has white space inside it"
                             + (f" ({token_file})" if token_file else ""))
        if ca_file is not None and not os.path.isfile(ca_file):
            raise ValueError(f"ca_file {ca_file!r} is not a file")
        if retries < 0:
            raise ValueError("retries must be ≥ 0")
        self.url = url.rstrip("/")
        self.timeout_s = float(timeout_s)
        self.retries = int(retries)
        self.max_retry_wait_s = float(max_retry_wait_s)
        self._headers = {"Authorization": f"Bearer {token}"}
        if not compress:
            self._headers["Accept-Encoding"] = "identity"
        # One keep-alive session per thread (requests' sessions are not
        # thread-safe); the fetches of many sets or trials use a few threads.
        self._local = threading.local()
        self._sessions: List[requests.Session] = []
        self._sessions_lock = threading.Lock()
        self.parallel = max(1, int(parallel))
        # The environment (proxies, REQUESTS_CA_BUNDLE / CURL_CA_BUNDLE) is
        # read once here, as requests would read it, and not again for each
        # request (about 1 ms each); a CA file given here wins over it.
        self._proxies = requests.utils.get_environ_proxies(url)
        self._verify: Union[str, bool] = (
            ca_file if ca_file is not None else
            os.environ.get("REQUESTS_CA_BUNDLE") or os.environ.get("CURL_CA_BUNDLE") or True)
        self._trial_kinds: Optional[List[dict]] = None  # GET /trial-kinds, read once

    # --- transport ---------------------------------------------------------

    def _session(self) -> requests.Session:
        session = getattr(self._local, "session", None)
        if session is None:
            session = requests.Session()
            session.trust_env = False
            session.proxies.update(self._proxies)
            session.headers.update(self._headers)
            self._local.session = session
            with self._sessions_lock:
                self._sessions.append(session)
        return session

    def _map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> List[Any]:
        """fn over items on up to `parallel` threads, results in order."""
        if len(items) < 2 or self.parallel < 2:
            return [fn(item) for item in items]
        with ThreadPoolExecutor(max_workers=min(self.parallel, len(items))) as pool:
            return list(pool.map(fn, items))

    def close(self) -> None:
        with self._sessions_lock:
            for session in self._sessions:
                session.close()
            self._sessions.clear()

    def __del__(self) -> None:
        if hasattr(self, "_sessions_lock"):
            self.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _request(self, method: str, path: str, params: Optional[dict] = None,
                 body: Any = None, stream: bool = False,
                 timeout_s: Optional[float] = None) -> requests.Response:
        url = self.url + API_PREFIX + path
        params = {k: v for k, v in (params or {}).items() if v is not None}
        data = None
        headers = {}
        if body is not None:
            data = json.dumps(body)
            headers["Content-Type"] = "application/json"
        timeout = timeout_s if timeout_s is not None else self.timeout_s
        resent = False
        attempt = 0
        while True:
            try:
                response = self._session().request(method, url, params=params, data=data,
                                                   headers=headers, stream=stream,
                                                   verify=self._verify,
                                                   timeout=(self.timeout_s, timeout))
            except requests.exceptions.SSLError as e:
                raise ConnectionFailed(f"TLS with {self.url} failed: {e}") from e
            except requests.exceptions.Timeout as e:
                raise ConnectionFailed(f"{method} {path}: no answer within {timeout} s") from e
            except requests.exceptions.ConnectionError as e:
                if method == "GET" and not resent:
                    resent = True
                    continue
                raise ConnectionFailed(f"cannot reach {self.url}: {e}") from e
            if response.status_code < 400:
                return response
            retry_after = _retry_after_s(response)
            if response.status_code in (429, 503) and attempt < self.retries:
                attempt += 1
                response.close()
                time.sleep(min(retry_after if retry_after is not None else 1.0,
                               self.max_retry_wait_s))
                continue
            try:
                payload = response.json()
            except ValueError:
                payload = None
            raise ApiError.from_response(response.status_code, payload, retry_after)

    def _get(self, path: str, **params) -> Any:
        return self._request("GET", path, params=params).json()

    def _post(self, path: str, body: Any) -> Any:
        return self._request("POST", path, body=body).json()

    def _pages(self, path: str, paged: bool = True, **params) -> List[dict]:
        """Every item of a list (docs/API.md "Lists"): a paged one 500 a
        page, following ``next_cursor``; ``paged=False`` for the lists that
        take no ``limit`` (revisions, trial kinds)."""
        items: List[dict] = []
        cursor = None
        while True:
            if paged:
                page = self._get(path, limit=500, cursor=cursor, **params)
            else:
                page = self._get(path, **params)
            items.extend(page["items"])
            cursor = page.get("next_cursor")
            if not cursor:
                return items

    # --- the server and the token -------------------------------------------

    def health(self) -> dict:
        """``GET /health``: status, version, schema_version, time_utc."""
        return self._get("/health")

    def openapi(self) -> dict:
        """``GET /openapi.json``: the OpenAPI 3 document of the server."""
        return self._get("/openapi.json")

    def me(self) -> dict:
        """``GET /me``: the token's user (id, name, role)."""
        return self._get("/me")

    # --- subjects and sessions -------------------------------------------------

    def subjects(self, code: Optional[str] = None) -> List[dict]:
        """Every subject (``GET /subjects``; ``code`` an exact code)."""
        return self._pages("/subjects", code=code)

    def subject(self, subject: _Id) -> dict:
        """One subject by id or pseudonymous code, with its legs."""
        return self._get(f"/subjects/{self.subject_id(subject)}")

    def subject_id(self, subject: _Id) -> int:
        if isinstance(subject, int) or (isinstance(subject, str) and subject.isdigit()):
            return _positive(subject, "subject")
        found = self.subjects(code=str(subject))
        if not found:
            raise ApiError(404, "not_found", f"no subject with code {subject}", "code")
        return int(found[0]["id"])

    def subject_revisions(self, subject: _Id) -> pd.DataFrame:
        """The subject's revisions, oldest first: who changed what, when, why."""
        return frames.revisions_frame(
            self._pages(f"/subjects/{self.subject_id(subject)}/revisions", paged=False))

    def sessions(self, subject: _Id, date_from: Optional[str] = None,
                 date_to: Optional[str] = None) -> List[dict]:
        """A subject's sessions (``?from=``/``?to=`` dates, YYYY-MM-DD)."""
        return self._pages(f"/subjects/{self.subject_id(subject)}/sessions",
                           **{"from": date_from, "to": date_to})

    def session(self, session_id: int) -> dict:
        return self._get(f"/sessions/{_positive(session_id, 'session')}")

    def session_revisions(self, session_id: int) -> pd.DataFrame:
        return frames.revisions_frame(
            self._pages(f"/sessions/{_positive(session_id, 'session')}/revisions", paged=False))

    def runs(self, session_id: int) -> List[dict]:
        """A session's runs (the run object of docs/API.md "Runs")."""
        return self._pages(f"/sessions/{_positive(session_id, 'session')}/runs")

    def run(self, run_id: int) -> dict:
        return self._get(f"/runs/{_positive(run_id, 'run')}")

    # --- trials ---------------------------------------------------------------

    def trials(self, session_id: int) -> pd.DataFrame:
        """A session's trial summaries, one row per trial (``id``, ``run_id``,
        ``name``, ``kind``, ``num_samples``, ``sample_rate_hz``, ``duration_s``,
        ``created_at_utc``)."""
        items = self._pages(f"/sessions/{_positive(session_id, 'session')}/trials")
        return frames.records_frame(items, ["id", "run_id", "name", "kind", "num_samples",
                                            "sample_rate_hz", "duration_s", "created_at_utc"])

    def trial_json(self, trial_id: int) -> dict:
        """A trial in its JSON form: channels with units, EMG, pulses."""
        return self._get(f"/trials/{_positive(trial_id, 'trial')}")

    def trial(self, trial_id: int, group: str = "main") -> pd.DataFrame:
        """A trial's channels as columns (``t_s``, ``angle_deg``, ``stim_ma``, …);
        ``group="emg"`` the 1 kHz EMG. ``attrs``: ``trial_id``, ``name``,
        ``kind`` (the name when it is a trial kind, docs/API.md
        ``GET /trial-kinds``), ``sample_rate_hz`` (from ``t_s``), ``units``
        (channel → unit, from the names).

        Read from the trial's CSV, a third of its JSON's size (no EMG or
        pulses besides), whose numbers are the shortest text of each double,
        parsed back exactly (``float_precision="round_trip"``); the JSON with
        everything is :meth:`trial_json`."""
        if group not in ("main", "emg"):
            raise ValueError(f"group must be 'main' or 'emg', got {group!r}")
        trial_id = _positive(trial_id, "trial")
        response = self._request("GET", f"/trials/{trial_id}",
                                 params={"format": "csv", "group": group})
        frame = pd.read_csv(io.BytesIO(response.content), float_precision="round_trip",
                            dtype=float)
        name = _attachment_name(response.headers.get("Content-Disposition", ""), trial_id, group)
        t = frame["t_s"].to_numpy() if "t_s" in frame else None
        rate = ((len(t) - 1) / (t[-1] - t[0])) if t is not None and len(t) > 1 else None
        frame.attrs.update({
            "trial_id": trial_id, "name": name,
            "kind": name if name in self._trial_kind_names() else None, "group": group,
            "sample_rate_hz": rate,
            "units": {c: u for c in frame.columns if (u := frames.unit_of(c))},
        })
        return frame

    def trial_frames(self, trial_ids: Sequence[int], group: str = "main") -> Dict[int, pd.DataFrame]:
        """Many trials as :meth:`trial` DataFrames, by id, fetched on a few
        threads at once."""
        ids = [_positive(t, "trial") for t in trial_ids]
        return dict(zip(ids, self._map(lambda t: self.trial(t, group), ids)))

    def pulses(self, trial_id: int) -> pd.DataFrame:
        """The delivered stimulation pulses of a recorded trial (``t_s``, ``stim_ma``)."""
        return frames.pulses_frame(self.trial_json(trial_id))

    def trial_kinds(self) -> List[dict]:
        return self._pages("/trial-kinds", paged=False)

    # --- parameter sets --------------------------------------------------------

    def parameter_sets(self, subject: Optional[_Id] = None, leg: Optional[str] = None,
                       method: Optional[str] = None, date_from: Optional[str] = None,
                       date_to: Optional[str] = None,
                       with_parameters: bool = False) -> pd.DataFrame:
        """Parameter-set history (``GET /parameter-sets``), one row per set:
        its summary (methods, version, approval). ``with_parameters`` also
        reads each set (``GET /parameter-sets/{id}``) and adds every scalar
        parameter and provenance field as a column named by its path
        (``contraction.pole_per_s``, ``passive.inertia_kgm2``).
        ``attrs["sets"]``: the sets as sent."""
        if leg is not None and leg not in ("left", "right"):
            raise ValueError(f"leg must be 'left' or 'right', got {leg!r}")
        subject_id = self.subject_id(subject) if subject is not None else None
        items = self._pages("/parameter-sets", subject_id=subject_id, leg=leg, method=method,
                            **{"from": date_from, "to": date_to})
        if with_parameters:
            items = self._map(lambda item: self.parameter_set(item["id"]), items)
        return frames.history_frame(items)

    def parameter_set(self, set_id: int) -> dict:
        """One set: summary, ``parameters`` (docs/MODEL.md), ``trial_ids``, approval."""
        return self._get(f"/parameter-sets/{_positive(set_id, 'parameter set')}")

    def approved_parameter_set(self, subject: _Id, leg: str) -> dict:
        """The leg's clinician-approved set, the one that gates stimulation."""
        if leg not in ("left", "right"):
            raise ValueError(f"leg must be 'left' or 'right', got {leg!r}")
        return self._get(f"/subjects/{self.subject_id(subject)}/legs/{leg}/approved-parameter-set")

    def curves(self, parameter_set: Union[int, dict]) -> pd.DataFrame:
        """A set's curves at their breakpoints, long and tidy: ``curve``
        (``irc``, ``tau_pta``, ``tau_ptv``, ``f_ata``, ``f_atv``), ``x``,
        ``x_unit``, ``y``, ``y_unit`` and ``parameter_set_id``."""
        s = parameter_set if isinstance(parameter_set, dict) else self.parameter_set(parameter_set)
        return frames.curves_frame(s)

    def provenance(self, parameter_set: Union[int, dict]) -> dict:
        """How a set was fitted: methods, trial ids, fit RMS, warnings, ranges."""
        s = parameter_set if isinstance(parameter_set, dict) else self.parameter_set(parameter_set)
        return dict(s["parameters"].get("provenance", {}))

    def held_out_trials(self, parameter_set: Union[int, dict],
                        exclude_sets: Sequence[Union[int, dict]] = ()) -> List[int]:
        """The free-swing trials of the set's leg (every session of its
        subject) that it — and every set of ``exclude_sets`` — was not fitted
        on: honest validation, as ``fesbench predict`` and ``compare`` do."""
        s = parameter_set if isinstance(parameter_set, dict) else self.parameter_set(parameter_set)
        training = set(s.get("trial_ids") or [])
        for other in exclude_sets:
            o = other if isinstance(other, dict) else self.parameter_set(other)
            training |= set(o.get("trial_ids") or [])
        free_swing = self._free_swing()
        held_out = []
        for session in self.sessions(s["subject_id"]):
            if session["leg_id"] != s["leg_id"]:
                continue
            for trial in self._pages(f"/sessions/{session['id']}/trials"):
                if trial.get("kind") in free_swing and trial["id"] not in training:
                    held_out.append(int(trial["id"]))
        return held_out

    def _kinds(self) -> List[dict]:
        if self._trial_kinds is None:
            self._trial_kinds = self.trial_kinds()
        return self._trial_kinds

    def _trial_kind_names(self) -> set:
        return {k["name"] for k in self._kinds()}

    def _free_swing(self) -> set:
        return {k["name"] for k in self._kinds() if k.get("free_swing")}

    def parameter_set_events(self, timeout_s: int = 300) -> "EventStream":
        """``GET /events/parameter-sets``, opened now: iterate it for one dict
        per set stored from now on (``parameter_set_id``, ``subject_id``,
        ``leg_id``, ``seq``) until the server ends the stream after
        ``timeout_s`` (1–3600) seconds; ``close()`` leaves earlier."""
        if not isinstance(timeout_s, int) or not 1 <= timeout_s <= 3600:
            raise ValueError(f"timeout_s must be an integer 1–3600, got {timeout_s!r}")
        response = self._request("GET", "/events/parameter-sets", params={"timeout_s": timeout_s},
                                 stream=True, timeout_s=timeout_s + 10)
        return EventStream(response)

    # --- predictions, identifications, comparisons -----------------------------

    def predictions_of(self, set_id: int) -> List[dict]:
        """The stored predictions of a set."""
        return self._pages(f"/parameter-sets/{_positive(set_id, 'parameter set')}/predictions")

    def prediction(self, prediction_id: int) -> dict:
        """A stored prediction with its input and output."""
        return self._get(f"/predictions/{_positive(prediction_id, 'prediction')}")

    def jobs(self, limit: int = 50) -> List[dict]:
        return self._get("/jobs", limit=limit)["items"]

    def job(self, job_id: int) -> Job:
        return Job(self, self._get(f"/jobs/{_positive(job_id, 'job')}"))

    def submit_identification(self, session_id: Optional[int] = None,
                              trial_ids: Optional[Sequence[int]] = None, method: str = "thesis",
                              **options) -> Job:
        """``POST /identifications`` (analyst, admin): exactly one of
        ``session_id`` and ``trial_ids``; ``options`` the request's other
        fields by their API names (``irc_method``, ``passive_method``,
        ``contraction_order``, ``pole_method``, ``models``, ``breakpoints``,
        ``inertia_kgm2``, ``torque_angle_parameter_set_id``), sent as given
        (the server refuses what it does not take)."""
        if (session_id is None) == (trial_ids is None):
            raise ValueError("give exactly one of session_id and trial_ids")
        body: Dict[str, Any] = {"method": method, **options}
        if session_id is not None:
            body["session_id"] = session_id
        else:
            body["trial_ids"] = list(trial_ids)
        return Job(self, self._post("/identifications", body))

    def identify(self, *args, progress: Union[bool, Callable] = False,
                 timeout_s: float = 600.0, **kwargs) -> dict:
        """:meth:`submit_identification` and wait: the job's result
        (``parameter_sets``, ``report``)."""
        return self.submit_identification(*args, **kwargs).wait(timeout_s, progress)

    def submit_prediction(self, parameter_set_id: int, trial_id: Optional[int] = None,
                          stimulus: Optional[dict] = None, **options) -> Job:
        """``POST /predictions``: a set on a stored trial or a stimulus
        (``{"generator", "params"}``); ``options``: ``mode``,
        ``initial_angle_deg``, ``initial_velocity_deg_s``, ``duration_s``,
        ``fit_scale``."""
        if (trial_id is None) == (stimulus is None):
            raise ValueError("give exactly one of trial_id and stimulus")
        body: Dict[str, Any] = {"parameter_set_id": parameter_set_id, **options}
        if trial_id is not None:
            body["trial_id"] = trial_id
        else:
            body["stimulus"] = stimulus
        return Job(self, self._post("/predictions", body))

    def predict(self, parameter_set_id: int, trial_id: Optional[int] = None,
                stimulus: Optional[dict] = None, progress: Union[bool, Callable] = False,
                timeout_s: float = 600.0, **options) -> pd.DataFrame:
        """A prediction as a DataFrame of its columns (``t_s``, ``stim_ma``,
        ``angle_deg``, ``velocity_deg_s``, ``torque_nm``, ``activation``);
        ``attrs``: ``errors`` (E_RMS … against the trial, or None),
        ``prediction_id``, ``trial_id``, ``mode``, ``result`` (the rest)."""
        job = self.submit_prediction(parameter_set_id, trial_id, stimulus, **options)
        return frames.prediction_frame(job.wait(timeout_s, progress))

    def predict_held_out(self, parameter_set_id: int, progress: Union[bool, Callable] = False,
                         timeout_s: float = 600.0) -> pd.DataFrame:
        """The set on each free-swing trial of its leg it was not fitted on,
        one row per trial: ``trial_id``, ``prediction_id``, ``channel``,
        ``unit``, ``e_rms``, ``e_abs``, ``normalised_rms``, ``e_ave``."""
        trials = self.held_out_trials(parameter_set_id)
        if not trials:
            raise FesbenchError(f"parameter set {parameter_set_id} has no free-swing trial of its "
                                f"leg that it was not fitted on")
        jobs = [self.submit_prediction(parameter_set_id, trial_id=t) for t in trials]
        return frames.errors_frame([job.wait(timeout_s, progress) for job in jobs])

    def submit_comparison(self, pairs: Sequence[Union[dict, Tuple[int, int, Sequence[int]]]],
                          metric: str = "e_rms", confidence: float = 0.95) -> Job:
        """``POST /comparisons``: ``pairs`` as dicts of the API or
        ``(a_set, b_set, trial_ids)`` tuples."""
        wire = []
        for p in pairs:
            if isinstance(p, dict):
                wire.append(p)
            else:
                a, b, trials = p
                wire.append({"a_parameter_set_id": a, "b_parameter_set_id": b,
                             "trial_ids": list(trials)})
        return Job(self, self._post("/comparisons", {"pairs": wire, "metric": metric,
                                                     "confidence": confidence}))

    def compare(self, a: int, b: int, trial_ids: Optional[Sequence[int]] = None,
                metric: str = "e_rms", confidence: float = 0.95,
                progress: Union[bool, Callable] = False, timeout_s: float = 600.0) -> "Comparison":
        """Two sets of one leg over its trials: one pair per trial, so the
        paired t-test (Eq. 6.3) runs over the trials; by default the leg's
        free-swing trials neither set was fitted on. With one trial (or
        equal differences) there is no test: ``t_test`` is None and
        ``t_test_note`` says why (docs/API.md, Jobs)."""
        trials = (list(dict.fromkeys(_positive(t, "trial") for t in trial_ids))
                  if trial_ids is not None else self.held_out_trials(a, [b]))
        if not trials:
            raise FesbenchError(f"parameter sets {a} and {b} have no free-swing trial of their leg "
                                f"that neither was fitted on; name trial_ids")
        job = self.submit_comparison([(a, b, [t]) for t in trials], metric, confidence)
        return Comparison(job.wait(timeout_s, progress))

    # --- data out ---------------------------------------------------------------

    def export(self, session_id: int, fmt: str = "zip") -> bytes:
        """The session archive (docs/API.md "Session archives") as bytes."""
        if fmt not in ("zip", "tar.gz"):
            raise ValueError(f"fmt must be 'zip' or 'tar.gz', got {fmt!r}")
        return self._request("GET", f"/sessions/{_positive(session_id, 'session')}/export",
                             params={"format": fmt}).content

    def load_export(self, session_id: int, fmt: str = "zip") -> Dict[str, Any]:
        """The session archive read into memory: every ``.tsv`` as a
        DataFrame (a ``*_motion.tsv`` or ``*_emg.tsv``, which has no header
        row in BIDS, named by its ``*_channels.tsv``), every ``.json`` as a
        dict, ``README.md`` as text; keys are the paths inside the root
        folder (``sub-S01/ses-1/motion/…_motion.tsv``)."""
        return frames.load_archive(self.export(session_id, fmt), fmt)

    def report(self, session_id: int) -> str:
        """The session report, one self-contained HTML page."""
        return self._request("GET", f"/sessions/{_positive(session_id, 'session')}/report").text


class EventStream:
    """An open Server-Sent Events stream of parameter sets (docs/API.md,
    ``GET /events/parameter-sets``): an iterator of the events' data."""

    def __init__(self, response: requests.Response):
        self._response = response
        self._events = _server_sent_events(response)

    def __iter__(self) -> "EventStream":
        return self

    def __next__(self) -> dict:
        for event, data in self._events:
            if event == "parameter_set":
                return data
        self.close()
        raise StopIteration

    def close(self) -> None:
        self._response.close()

    def __enter__(self) -> "EventStream":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class Comparison:
    """The result of a comparison job: ``metric``, ``unit``, ``t_test`` (or
    None), ``t_test_note``, ``pairs`` and ``frame`` (one row per pair and
    trial: ``a_parameter_set_id``, ``b_parameter_set_id``, ``trial_id``,
    ``a_error``, ``b_error``, ``difference``)."""

    def __init__(self, result: dict):
        self.result = result
        self.metric: str = result["metric"]
        self.unit: str = result["unit"]
        self.t_test: Optional[dict] = result.get("t_test")
        self.t_test_note: Optional[str] = result.get("t_test_note")
        self.pairs: List[dict] = result["pairs"]
        self.frame = frames.comparison_frame(result)

    def __repr__(self) -> str:
        if self.t_test:
            t = self.t_test
            test = (f"t = {t['t']:.3f}, df = {t['df']:g}, p = {t['p_value']:.4f}, "
                    f"significant = {t['significant']}")
        else:
            test = self.t_test_note
        return f"Comparison({self.metric} [{self.unit}], {len(self.pairs)} pairs; {test})"


def _positive(value: Any, what: str) -> int:
    try:
        number = int(value)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a positive integer id, got {value!r}") from None
    if number <= 0 or (isinstance(value, float) and value != number):
        raise ValueError(f"{what} must be a positive integer id, got {value!r}")
    return number


def _attachment_name(disposition: str, trial_id: int, group: str) -> Optional[str]:
    """The trial's name from ``attachment; filename="trial-12-<name>[-emg].csv"``."""
    m = re.search(r'filename="trial-\d+-(.*)\.csv"', disposition)
    if not m:
        return None
    name = m.group(1)
    return name[: -len("-emg")] if group == "emg" and name.endswith("-emg") else name


def _retry_after_s(response: requests.Response) -> Optional[float]:
    value = response.headers.get("Retry-After")
    if value is None:
        return None
    try:
        return max(0.0, float(value))
    except ValueError:
        return None


def _server_sent_events(response: requests.Response) -> Iterator[Tuple[str, Any]]:
    """(event, data) of a text/event-stream; comments (keep-alive) skipped."""
    event, data = "message", []
    for raw in response.iter_lines(decode_unicode=True):
        if raw is None:
            continue
        line = raw.rstrip("\r")
        if not line:
            if data:
                yield event, json.loads("\n".join(data))
            event, data = "message", []
            continue
        if line.startswith(":"):
            continue
        key, _, value = line.partition(":")
        value = value[1:] if value.startswith(" ") else value
        if key == "event":
            event = value
        elif key == "data":
            data.append(value)
    if data:
        yield event, json.loads("\n".join(data))
