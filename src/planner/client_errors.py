"""The exceptions of the Python client, :mod:`planner.client` (which exports each of them).

One tree under the library's :class:`~planner.exceptions.PlannerError`: a caller catches every
failure of the client (:class:`PlannerClientError`), every error answer of the server
(:class:`APIError`), or one status (e.g. :class:`NotFoundError`). The classes need no HTTP
library; which answer raises which class is decided where answers are read, in the client.

All carry a message; :class:`APIError` also the server's status and ``detail``::

    PlannerError                         (planner.exceptions)
    └── PlannerClientError               base of every error the client raises
        ├── TransportError               the server could not be reached
        │   └── RequestTimeoutError      no answer within the client's timeout
        ├── ProtocolError                the answer is not what the API promises
        └── APIError                     the server answered an error status
            ├── InvalidRequestError      422 (or rejected locally: status_code None)
            ├── AuthenticationError      401
            ├── NotFoundError            404
            ├── PayloadTooLargeError     413
            ├── DeadlineExceededError    504: the request's time budget ran out
            └── ServerError              other 5xx
                └── ServiceUnavailableError  503 after the retries ran out
"""

from __future__ import annotations

from typing import Any

from planner.exceptions import PlannerError

__all__ = [
    "APIError",
    "AuthenticationError",
    "DeadlineExceededError",
    "InvalidRequestError",
    "NotFoundError",
    "PayloadTooLargeError",
    "PlannerClientError",
    "ProtocolError",
    "RequestTimeoutError",
    "ServerError",
    "ServiceUnavailableError",
    "TransportError",
]


class PlannerClientError(PlannerError):
    """Base of every error raised by the client."""


class TransportError(PlannerClientError):
    """The server could not be reached (connection refused, reset, DNS...)."""


class RequestTimeoutError(TransportError):
    """No answer within the client's ``timeout``."""


class ProtocolError(PlannerClientError):
    """The server's answer does not parse as the model the API promises."""


class APIError(PlannerClientError):
    """The server answered an error status.

    Attributes
    ----------
    status_code : int or None
        HTTP status (None for a request rejected locally, before sending).
    detail : list of dict
        The server's ``detail`` items, each with ``loc``, ``msg`` and ``type``.
    message : str
        The items joined as ``"body.design.L1: Input should be ..."``.
    """

    def __init__(
        self, message: str, *, status_code: int | None, detail: list[dict[str, Any]] | None = None
    ) -> None:
        super().__init__(message)
        self.message = message
        self.status_code = status_code
        self.detail = detail or []

    def __str__(self) -> str:
        return self.message if self.status_code is None else f"{self.status_code}: {self.message}"


class InvalidRequestError(APIError):
    """422: a field breaks a rule (``detail[i]["loc"]`` names it)."""


class AuthenticationError(APIError):
    """401: the API key is missing or wrong."""


class NotFoundError(APIError):
    """404: no such route (an older server?)."""


class PayloadTooLargeError(APIError):
    """413: the request body is larger than the server accepts."""


class DeadlineExceededError(APIError):
    """504: the server's time budget for the request ran out."""


class ServerError(APIError):
    """A 5xx answer other than 504."""


class ServiceUnavailableError(ServerError):
    """503 after every retry: all workers stayed busy. ``retry_after`` is the server's last
    advice, s (None if it gave none)."""

    def __init__(
        self,
        message: str,
        *,
        status_code: int | None,
        detail: list[dict[str, Any]] | None = None,
        retry_after: float | None = None,
    ) -> None:
        super().__init__(message, status_code=status_code, detail=detail)
        self.retry_after = retry_after
