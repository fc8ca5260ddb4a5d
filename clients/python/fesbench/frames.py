"""The server's JSON as pandas DataFrames.

Column names are the API's, which carry their units (docs/ARCHITECTURE.md,
"Units and sign conventions"); ``DataFrame.attrs["units"]`` maps each
column that has one to its unit.
"""

from __future__ import annotations

import io
import json
import posixpath
import tarfile
import zipfile
from typing import Any, Dict, Iterable, Optional, Sequence

import numpy as np
import pandas as pd

# A set's curves (docs/MODEL.md "The parameter set"): section path, the
# abscissa key and unit, the ordinate key and unit.
_CURVES = (
    ("irc", ("irc",), "stim_ma", "mA", "activation", "1"),
    ("tau_pta", ("passive", "torque_angle"), "angle_deg", "deg", "torque_nm", "N.m"),
    ("tau_ptv", ("passive", "torque_velocity"), "velocity_deg_s", "deg/s", "torque_nm", "N.m"),
    ("f_ata", ("active", "torque_angle"), "angle_deg", "deg", "gain", "1"),
    ("f_atv", ("active", "torque_velocity"), "velocity_deg_s", "deg/s", "gain", "1"),
)

# The unit a column name ends with (docs/ARCHITECTURE.md).
_SUFFIX_UNITS = (
    ("_deg_s2", "deg/s^2"), ("_deg_s", "deg/s"), ("_deg", "deg"), ("_nm", "N.m"),
    ("_ma", "mA"), ("_m_s2", "m/s^2"), ("_mv", "mV"), ("_kgm2", "kg.m^2"),
    ("_per_s", "1/s"), ("_hz", "Hz"), ("_us", "us"), ("_s", "s"), ("_kg", "kg"), ("_cm", "cm"),
)


def unit_of(name: str) -> Optional[str]:
    """The unit a field name carries (``angle_deg`` → ``deg``), or None."""
    leaf = name.rsplit(".", 1)[-1]
    for suffix, unit in _SUFFIX_UNITS:
        if leaf.endswith(suffix):
            return unit
    return None


def records_frame(items: Sequence[dict], columns: Sequence[str]) -> pd.DataFrame:
    frame = pd.DataFrame.from_records(list(items), columns=list(columns))
    frame.attrs["units"] = {c: u for c in frame.columns if (u := unit_of(c))}
    return frame


def revisions_frame(items: Sequence[dict]) -> pd.DataFrame:
    rows = []
    for r in items:
        row = {k: r.get(k) for k in ("revision", "corrects_revision", "reason", "changed_by",
                                     "changed_at_utc")}
        for key, value in (r.get("details") or {}).items():
            row[f"details.{key}"] = value
        rows.append(row)
    return pd.DataFrame(rows)


def pulses_frame(trial: dict) -> pd.DataFrame:
    pulses = trial.get("pulses")
    if not pulses:
        raise ValueError(f"trial {trial.get('id')} has no delivered pulses (an imported recording)")
    frame = pd.DataFrame({"t_s": np.asarray(pulses["t_s"], dtype=float),
                          "stim_ma": np.asarray(pulses["stim_ma"], dtype=float)})
    frame.attrs.update({"trial_id": trial.get("id"), "pulse_rate_hz": pulses["pulse_rate_hz"],
                        "pulse_width_us": pulses["pulse_width_us"],
                        "units": {"t_s": "s", "stim_ma": "mA"}})
    return frame


def _flatten(prefix: str, value: Any, out: Dict[str, Any]) -> None:
    """Scalars of nested objects as ``a.b.c``; lists of scalars are skipped
    (curves), except short ones kept as tuples (ranges, trial ids)."""
    if isinstance(value, dict):
        for key, item in value.items():
            _flatten(f"{prefix}.{key}" if prefix else key, item, out)
    elif isinstance(value, list):
        if len(value) <= 8 and all(not isinstance(v, (dict, list)) for v in value):
            out[prefix] = tuple(value)
    else:
        out[prefix] = value


_SUMMARY = ("id", "subject_id", "leg_id", "version", "model", "irc_method", "passive_method",
            "active_method", "software_version", "supersedes_id", "created_at_utc", "approved")


def history_frame(items: Sequence[dict]) -> pd.DataFrame:
    """One row per set: the summary, then the parameters' scalars by path."""
    rows = []
    for s in items:
        row: Dict[str, Any] = {k: s.get(k) for k in _SUMMARY}
        approval = s.get("approval") or {}
        row["approved_by"] = approval.get("approved_by")
        row["approved_at_utc"] = approval.get("approved_at_utc")
        parameters = s.get("parameters")
        if isinstance(parameters, dict):
            _flatten("", {k: v for k, v in parameters.items() if k != "model"}, row)
        rows.append(row)
    frame = pd.DataFrame(rows, columns=None if rows else list(_SUMMARY))
    if "created_at_utc" in frame and len(frame):
        frame["created_at_utc"] = pd.to_datetime(frame["created_at_utc"], utc=True)
    frame.attrs["units"] = {c: u for c in frame.columns if (u := unit_of(c))}
    frame.attrs["sets"] = list(items)
    return frame


def curves_frame(parameter_set: dict) -> pd.DataFrame:
    parameters = parameter_set["parameters"]
    parts = []
    for name, path, x_key, x_unit, y_key, y_unit in _CURVES:
        section: Any = parameters
        for key in path:
            section = section.get(key) if isinstance(section, dict) else None
        if not isinstance(section, dict) or x_key not in section:
            continue
        x = np.asarray(section[x_key], dtype=float)
        parts.append(pd.DataFrame({"curve": name, "x": x, "x_unit": x_unit,
                                   "y": np.asarray(section[y_key], dtype=float),
                                   "y_unit": y_unit}))
    frame = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(
        columns=["curve", "x", "x_unit", "y", "y_unit"])
    frame["parameter_set_id"] = parameter_set.get("id")
    frame.attrs["model"] = parameters.get("model")
    frame.attrs["identified_range_deg"] = parameters.get("provenance", {}).get("identified_range_deg")
    frame.attrs["identified_range_deg_s"] = parameters.get("provenance", {}).get(
        "identified_range_deg_s")
    return frame


def prediction_frame(result: dict) -> pd.DataFrame:
    columns = result.get("columns") or {}
    frame = pd.DataFrame({k: np.asarray(v, dtype=float) for k, v in columns.items()}, copy=False)
    frame.attrs.update({
        "prediction_id": result.get("prediction_id"), "trial_id": result.get("trial_id"),
        "parameter_set_id": result.get("parameter_set_id"), "mode": result.get("mode"),
        "errors": result.get("errors"),
        "result": {k: v for k, v in result.items() if k != "columns"},
        "units": {c: u for c in frame.columns if (u := unit_of(c))},
    })
    return frame


def errors_frame(results: Iterable[dict]) -> pd.DataFrame:
    rows = []
    for r in results:
        e = r.get("errors") or {}
        rows.append({"parameter_set_id": r.get("parameter_set_id"), "trial_id": r.get("trial_id"),
                     "prediction_id": r.get("prediction_id"), "mode": r.get("mode"),
                     "channel": e.get("channel"), "unit": e.get("unit"),
                     "samples": e.get("samples"), "e_rms": e.get("e_rms"),
                     "e_abs": e.get("e_abs"), "max_abs": e.get("max_abs"),
                     "normalised_rms": e.get("normalised_rms"), "e_ave": e.get("e_ave"),
                     "share_outside_identified_ranges":
                         r.get("share_outside_identified_ranges")})
    return pd.DataFrame(rows)


def comparison_frame(result: dict) -> pd.DataFrame:
    rows = []
    for i, p in enumerate(result["pairs"]):
        for t in p["trials"]:
            rows.append({"pair": i, "a_parameter_set_id": p["a_parameter_set_id"],
                         "b_parameter_set_id": p["b_parameter_set_id"],
                         "subject_id": p["subject_id"], "trial_id": t["trial_id"],
                         "a_error": t["a_error"], "b_error": t["b_error"],
                         "difference": t["a_error"] - t["b_error"]})
    frame = pd.DataFrame(rows)
    frame.attrs["units"] = {c: result["unit"] for c in ("a_error", "b_error", "difference")}
    frame.attrs["metric"] = result["metric"]
    return frame


def _read_entries(blob: bytes, fmt: str) -> Dict[str, bytes]:
    entries: Dict[str, bytes] = {}
    if fmt == "zip":
        with zipfile.ZipFile(io.BytesIO(blob)) as archive:
            for info in archive.infolist():
                if not info.is_dir():
                    entries[info.filename] = archive.read(info)
    else:
        with tarfile.open(fileobj=io.BytesIO(blob), mode="r:gz") as archive:
            for member in archive.getmembers():
                if member.isfile():
                    entries[member.name] = archive.extractfile(member).read()
    return entries


def load_archive(blob: bytes, fmt: str) -> Dict[str, Any]:
    """docs/API.md "Session archives" into memory (see Client.load_export)."""
    raw = _read_entries(blob, fmt)
    # Paths inside the one root folder fesbench-session-<id>/.
    entries = {name.split("/", 1)[1]: data for name, data in raw.items() if "/" in name}
    out: Dict[str, Any] = {}
    for name, data in sorted(entries.items()):
        if name.endswith(".json"):
            out[name] = json.loads(data)
        elif name.endswith(".md"):
            out[name] = data.decode("utf-8")
        elif name.endswith(".tsv"):
            headerless = name.endswith("_motion.tsv") or name.endswith("_emg.tsv")
            if headerless:
                stem = name[: name.rfind("_")]
                channels = pd.read_csv(io.BytesIO(entries[stem + "_channels.tsv"]), sep="\t")
                frame = pd.read_csv(io.BytesIO(data), sep="\t", header=None,
                                    names=list(channels["name"]))
                frame.attrs["units"] = dict(zip(channels["name"], channels["units"]))
            else:
                frame = pd.read_csv(io.BytesIO(data), sep="\t")
            out[name] = frame
    return out


def motion(export: Dict[str, Any]) -> Dict[str, pd.DataFrame]:
    """The motion tables of a loaded export, by trial id (its ``run-`` label)."""
    tables = {}
    for name, value in export.items():
        if name.endswith("_motion.tsv"):
            label = [p for p in posixpath.basename(name).split("_") if p.startswith("run-")]
            tables[int(label[0][4:]) if label else name] = value
    return tables
