"""Errors of the fesbench client.

The server answers every error as ``{"error": {"code", "message", "field"}}``
(docs/API.md, "HTTP conventions"); :class:`ApiError` carries those three and
the HTTP status. A failed job's ``error`` is the same object, raised as
:class:`JobFailed`.
"""

from __future__ import annotations

from typing import Any, Optional


class FesbenchError(Exception):
    """Base class of every error this package raises."""


class ApiError(FesbenchError):
    """An error answer of the server: ``status``, ``code``, ``message``, ``field``."""

    def __init__(self, status: int, code: str, message: str, field: Optional[str] = None,
                 retry_after_s: Optional[float] = None):
        self.status = status
        self.code = code
        self.message = message
        self.field = field
        self.retry_after_s = retry_after_s
        text = f"{message} (field {field})" if field else message
        super().__init__(f"[HTTP {status} {code}] {text}")

    @classmethod
    def from_response(cls, status: int, body: Any, retry_after_s: Optional[float] = None) -> "ApiError":
        error = body.get("error") if isinstance(body, dict) else None
        if not isinstance(error, dict):
            return cls(status, "unknown", f"the server answered HTTP {status} without an error object",
                       None, retry_after_s)
        return cls(status, str(error.get("code", "unknown")), str(error.get("message", "")),
                   error.get("field"), retry_after_s)


class JobFailed(FesbenchError):
    """A job that ended ``failed``: its id, kind and the server's error object."""

    def __init__(self, job: dict):
        self.job = job
        error = job.get("error") or {}
        self.job_id = job.get("id")
        self.code = error.get("code", "unknown")
        self.message = error.get("message", "")
        self.field = error.get("field")
        text = f"{self.message} (field {self.field})" if self.field else self.message
        super().__init__(f"job {self.job_id} ({job.get('kind')}) failed: [{self.code}] {text}")


class ConnectionFailed(FesbenchError):
    """No answer from the server (refused, unreachable, timed out, TLS)."""
