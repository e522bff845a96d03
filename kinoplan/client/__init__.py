"""The Python client of the kinoplan service: ``from kinoplan.client import Client``.

A separate, light program that talks to a running service over HTTP (httpx), numpy arrays
in and out; it imports none of the service's code to do so. A tour: docs/client.md.

    with Client("http://127.0.0.1:8000") as c:
        T = c.fk("glt_palletizer", np.zeros(6))            # (4, 4)
        job = c.submit("workspace", {"robot": "glt_palletizer", "samples": 20_000})
        job.wait()
        report = job.result()
"""

from .client import DEFAULT_URL as DEFAULT_URL
from .client import Client as Client
from .errors import ApiError as ApiError
from .errors import ConflictError as ConflictError
from .errors import ForbiddenError as ForbiddenError
from .errors import InvalidError as InvalidError
from .errors import NotFoundError as NotFoundError
from .errors import QueueFullError as QueueFullError
from .errors import TooLargeError as TooLargeError
from .errors import UnauthorizedError as UnauthorizedError
from .errors import UnavailableError as UnavailableError
from .jobs import Job as Job

__all__ = [
    "Client", "DEFAULT_URL", "Job", "ApiError", "UnauthorizedError", "ForbiddenError",
    "NotFoundError", "ConflictError", "TooLargeError", "InvalidError", "QueueFullError",
    "UnavailableError",
]
