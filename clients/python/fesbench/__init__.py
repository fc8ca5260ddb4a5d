"""fesbench: the Python client of a fesbench server's HTTP/JSON API (docs/API.md).

    from fesbench import Client
    fb = Client("http://127.0.0.1:8080", token_file="analyst.token")
    history = fb.parameter_sets(subject="S01", leg="right")   # a DataFrame
"""

from .client import API_PREFIX, Client, Comparison, EventStream, Job
from .errors import ApiError, ConnectionFailed, FesbenchError, JobFailed
from .frames import motion, unit_of

__all__ = ["API_PREFIX", "ApiError", "Client", "Comparison", "ConnectionFailed",
           "EventStream", "FesbenchError", "Job", "JobFailed", "motion", "unit_of"]
__version__ = "0.1.0"
