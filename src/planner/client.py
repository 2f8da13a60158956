"""Python client of the hybrid-planner service (``/v1``), sync and async, on httpx.

>>> with PlannerClient("http://127.0.0.1:8000") as client:          # doctest: +SKIP
...     postures = client.ik([0.3, 0.1, 0.2]).postures
...     verdict = client.check_design({"L0": 0.5, "L1": 0.2, "L2": 0.6})
...     regions = client.regions({"L0": 0.3, "L1": 0.3, "L2": 0.4}, resolution=128)
...     result = client.plan(start={"q": [0, 1, 2], "assembly_mode": "+"},
...                          goal={"p": [0.3, 0.1, 0.2], "working_mode": "any"})

Both clients take the same keyword-only options and return the shared wire models of
:mod:`planner.wire`; :class:`AsyncPlannerClient`'s methods are coroutines. Each endpoint
method is written once (a request builder in :class:`_BaseClient`) and turned into a sync or
an async method, so the two clients cannot drift apart.

Requests are validated locally before they are sent (a bad field raises
:class:`InvalidRequestError` without a round trip). A 503 (every worker busy) is retried
``max_retries`` times, waiting what the server's ``Retry-After`` asks, else an exponential
backoff, capped at ``max_backoff_s``.

Trajectories come as parallel arrays (``timing.format`` "arrays", the default) or as a
controller's points ("points"); :func:`to_points` and :func:`to_arrays` convert either way
(the same floats) and :func:`write_csv` writes either as CSV (``t,theta1,theta2,theta3,...``
under a line naming the units: :func:`planner.timing.export.write_csv`).

Exceptions: the tree of :mod:`planner.client_errors` (every class importable from here),
under :class:`planner.exceptions.PlannerError`; :class:`APIError` carries the server's status
and ``detail``, and each status the API answers has its own class (table ``_STATUS_ERRORS``).
"""

from __future__ import annotations

import asyncio
import email.utils
import inspect
import itertools
import time
from collections.abc import Awaitable, Callable, Mapping
from typing import Any, Concatenate, ParamSpec, TypeVar

import httpx
from pydantic import BaseModel, ValidationError

import planner
from planner.client_errors import (
    APIError,
    AuthenticationError,
    DeadlineExceededError,
    InvalidRequestError,
    NotFoundError,
    PayloadTooLargeError,
    PlannerClientError,
    ProtocolError,
    RequestTimeoutError,
    ServerError,
    ServiceUnavailableError,
    TransportError,
)
from planner.client_requests import M, Requests, _Call, _describe_item, none_as_absent
from planner.client_stream import AsyncStreamSession, StreamSession, first_message
from planner.wire import (
    TrajectoryModel,
    TrajectoryPointsModel,
    trajectory_arrays,
    trajectory_points,
)

__all__ = [
    "DEFAULT_BACKOFF_S",
    "DEFAULT_BASE_URL",
    "DEFAULT_MAX_BACKOFF_S",
    "DEFAULT_MAX_RETRIES",
    "DEFAULT_TIMEOUT_S",
    "APIError",
    "AsyncPlannerClient",
    "AuthenticationError",
    "DeadlineExceededError",
    "InvalidRequestError",
    "NotFoundError",
    "PayloadTooLargeError",
    "PlannerClient",
    "PlannerClientError",
    "ProtocolError",
    "RequestTimeoutError",
    "ServerError",
    "ServiceUnavailableError",
    "TransportError",
    "to_arrays",
    "to_points",
    "write_csv",
]

#: Where ``planner serve`` listens by default.
DEFAULT_BASE_URL = "http://127.0.0.1:8000"
#: Seconds to wait for one answer (planning may take the whole request budget of the server).
DEFAULT_TIMEOUT_S = 60.0
#: Retries of a request answered 503.
DEFAULT_MAX_RETRIES = 3
#: First backoff, s, doubled at each retry when the server sends no Retry-After.
DEFAULT_BACKOFF_S = 0.25
#: Longest single wait between retries, s.
DEFAULT_MAX_BACKOFF_S = 10.0


_STATUS_ERRORS: dict[int, type[APIError]] = {
    401: AuthenticationError,
    404: NotFoundError,
    413: PayloadTooLargeError,
    422: InvalidRequestError,
    503: ServiceUnavailableError,
    504: DeadlineExceededError,
}


def _retry_after(response: httpx.Response) -> float | None:
    """Seconds asked by a ``Retry-After`` header (delta-seconds or an HTTP date)."""
    value = response.headers.get("retry-after")
    if value is None:
        return None
    try:
        return max(0.0, float(value))
    except ValueError:
        pass
    try:
        when = email.utils.parsedate_to_datetime(value)
    except (TypeError, ValueError):
        return None
    return max(0.0, when.timestamp() - time.time())


def _error_from(response: httpx.Response) -> APIError:
    """The typed exception of an error answer, carrying the server's message."""
    try:
        detail = response.json().get("detail")
    except (ValueError, AttributeError):
        detail = None
    if isinstance(detail, str):
        detail = [{"loc": [], "msg": detail, "type": "http_error"}]
    if not isinstance(detail, list):
        detail = [
            {"loc": [], "msg": response.text[:500] or response.reason_phrase, "type": "http_error"}
        ]
    message = "; ".join(_describe_item(item) for item in detail) or response.reason_phrase
    status = response.status_code
    cls = _STATUS_ERRORS.get(status, ServerError if status >= 500 else APIError)
    if cls is ServiceUnavailableError:
        return ServiceUnavailableError(
            message, status_code=status, detail=detail, retry_after=_retry_after(response)
        )
    return cls(message, status_code=status, detail=detail)


# ---------------------------------------------------------------------------- trajectories
_Trajectory = TrajectoryModel | TrajectoryPointsModel


def to_points(trajectory: _Trajectory) -> TrajectoryPointsModel:
    """A trajectory of an answer in the points form (``duration``, ``joint_names``,
    ``points``), whichever form it came in; the same samples."""
    return trajectory_points(trajectory)


def to_arrays(trajectory: _Trajectory) -> TrajectoryModel:
    """A trajectory of an answer as parallel arrays (``t``, ``q``, ``qd``, ``qdd``),
    whichever form it came in; the same samples."""
    return trajectory_arrays(trajectory)


def write_csv(trajectory: _Trajectory, target: Any) -> None:
    """Write a trajectory of an answer (either form) as CSV to ``target`` (a path or a text
    file): a comment line naming the units, the header
    ``t,theta1,theta2,theta3,dtheta1,...,ddtheta3`` (and ``dddtheta1..3`` with ruckig's
    jerks, ``tau1..3`` with torques), one row per sample with 17 significant digits
    (:func:`planner.timing.export.read_csv` gives back the same numbers)."""
    from planner.timing.export import write_csv as write

    a = to_arrays(trajectory)
    write(target, a.t, a.q, a.qd, a.qdd, jerk=a.jerk, tau=a.tau)


class _BaseClient(Requests):
    """Configuration, request building, error translation and retry policy shared by
    :class:`PlannerClient` and :class:`AsyncPlannerClient`."""

    def __init__(
        self,
        base_url: str = DEFAULT_BASE_URL,
        *,
        timeout: float = DEFAULT_TIMEOUT_S,
        api_key: str | None = None,
        max_retries: int = DEFAULT_MAX_RETRIES,
        backoff_s: float = DEFAULT_BACKOFF_S,
        max_backoff_s: float = DEFAULT_MAX_BACKOFF_S,
        headers: Mapping[str, str] | None = None,
    ) -> None:
        if max_retries < 0 or backoff_s < 0 or max_backoff_s < 0 or not timeout > 0:
            raise ValueError("timeout must be > 0; max_retries, backoff_s, max_backoff_s >= 0")
        self.base_url = base_url.rstrip("/")
        self.timeout = timeout
        self.max_retries = max_retries
        self.backoff_s = backoff_s
        self.max_backoff_s = max_backoff_s
        self._headers = {
            "user-agent": f"hybrid-planner-client/{planner.__version__}",
            **(headers or {}),
        }
        if api_key is not None:
            self._headers["x-api-key"] = api_key

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.base_url!r})"

    def _client_options(self) -> dict[str, Any]:
        return {"base_url": self.base_url, "timeout": self.timeout, "headers": self._headers}

    # -- policy
    def _retry_delay(
        self, call: _Call[Any], attempt: int, response: httpx.Response
    ) -> float | None:
        """Seconds to wait before retrying, or None to stop and answer."""
        if response.status_code != 503 or not call.retry or attempt >= self.max_retries:
            return None
        asked = _retry_after(response)
        delay = asked if asked is not None else self.backoff_s * 2**attempt
        return min(delay, self.max_backoff_s)

    @staticmethod
    def _parse(call: _Call[M], response: httpx.Response) -> M:
        if response.status_code not in call.ok_statuses:
            raise _error_from(response)
        if not issubclass(call.model, BaseModel):  # bytes: the body as it is
            return response.content  # type: ignore[return-value]
        try:
            return call.model.model_validate_json(response.content)
        except ValidationError as exc:
            raise ProtocolError(
                f"{call.method} {call.path}: the answer is not a {call.model.__name__}: {exc}"
            ) from exc

    @staticmethod
    def _request_args(call: _Call[Any]) -> dict[str, Any]:
        args: dict[str, Any] = {"method": call.method, "url": call.path}
        if call.params:
            args["params"] = dict(call.params)
        if call.body is not None:
            args["content"] = call.body.model_dump_json(exclude_unset=True).encode()
            args["headers"] = {"content-type": "application/json"}
        return args

    @staticmethod
    def _transport_error(call: _Call[Any], exc: httpx.HTTPError) -> PlannerClientError:
        where = f"{call.method} {call.path}"
        if isinstance(exc, httpx.TimeoutException):
            return RequestTimeoutError(f"{where}: no answer in time ({exc})")
        return TransportError(f"{where}: {type(exc).__name__}: {exc}")


P = ParamSpec("P")
R = TypeVar("R", bound=BaseModel | bytes)


def _adopt(method: Callable[..., Any], build: Callable[..., Any], owner: str) -> None:
    """Give ``method`` the public name, docstring and signature of its builder, the return
    annotation being the model (``FKResponse``), not the ``_Call[FKResponse]`` built."""
    name = build.__name__.lstrip("_")
    method.__name__ = name
    method.__qualname__ = f"{owner}.{name}"
    method.__doc__ = build.__doc__
    sig = inspect.signature(build)
    returns = str(sig.return_annotation).removeprefix("_Call[").removesuffix("]")
    method.__signature__ = sig.replace(return_annotation=returns)  # type: ignore[attr-defined]


def _sync(
    build: Callable[Concatenate[_BaseClient, P], _Call[R]],
) -> Callable[Concatenate[PlannerClient, P], R]:
    call = none_as_absent(build)

    def method(self: PlannerClient, /, *args: P.args, **kwargs: P.kwargs) -> R:
        return self._execute(call(self, *args, **kwargs))

    _adopt(method, build, "PlannerClient")
    return method


def _async(
    build: Callable[Concatenate[_BaseClient, P], _Call[R]],
) -> Callable[Concatenate[AsyncPlannerClient, P], Awaitable[R]]:
    call = none_as_absent(build)

    async def method(self: AsyncPlannerClient, /, *args: P.args, **kwargs: P.kwargs) -> R:
        return await self._execute(call(self, *args, **kwargs))

    _adopt(method, build, "AsyncPlannerClient")
    return method


class PlannerClient(_BaseClient):
    """Blocking client. Use as a context manager (or call :meth:`close`).

    Parameters
    ----------
    base_url : str
        Root of the service, e.g. ``"http://127.0.0.1:8000"``.
    timeout : float, keyword-only
        Seconds to wait for one answer.
    api_key : str, optional, keyword-only
        Sent as ``X-API-Key`` when the server requires one.
    max_retries, backoff_s, max_backoff_s : keyword-only
        Retry policy for 503 answers (see the module docstring).
    headers : mapping, optional
        Extra headers sent with every request.
    transport : httpx.BaseTransport, optional
        For tests (e.g. ``httpx.MockTransport``).
    """

    def __init__(
        self,
        base_url: str = DEFAULT_BASE_URL,
        *,
        transport: httpx.BaseTransport | None = None,
        **options: Any,
    ) -> None:
        super().__init__(base_url, **options)
        self._http = httpx.Client(transport=transport, **self._client_options())

    def stream(
        self,
        request: Any,
        *,
        kind: str | None = "plan",
        rate_hz: float | None = 1000.0,
        lookahead_s: float | None = 0.05,
        auto_ack: bool | None = True,
    ) -> StreamSession:
        """Stream the answer of a plan (or ``kind="sequence"``) request as setpoints over
        ``/v1/stream`` (a WebSocket): a :class:`planner.client_stream.StreamSession` to
        iterate (``setpoints``, ``switched``, ``done`` messages), with ``ack(t)``,
        ``replace(request)`` and ``stop()``; an ``error`` message raises
        :class:`InvalidRequestError` naming the field."""
        first = first_message(kind, request, rate_hz, lookahead_s)
        return StreamSession(self.base_url, self._headers, first, auto_ack=auto_ack is not False)

    def _execute(self, call: _Call[M]) -> M:
        for attempt in itertools.count():
            try:
                response = self._http.request(**self._request_args(call))
            except httpx.HTTPError as exc:
                raise self._transport_error(call, exc) from exc
            delay = self._retry_delay(call, attempt, response)
            if delay is None:
                return self._parse(call, response)
            time.sleep(delay)
        raise AssertionError("unreachable")  # pragma: no cover

    def close(self) -> None:
        """Close the connections."""
        self._http.close()

    def __enter__(self) -> PlannerClient:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    health = _sync(_BaseClient._health)
    ready = _sync(_BaseClient._ready)
    version = _sync(_BaseClient._version)
    designs = _sync(_BaseClient._designs)
    fk = _sync(_BaseClient._fk)
    ik = _sync(_BaseClient._ik)
    analyze = _sync(_BaseClient._analyze)
    check_design = _sync(_BaseClient._check_design)
    plan = _sync(_BaseClient._plan)
    cartesian = _sync(_BaseClient._cartesian)
    plan_batch = _sync(_BaseClient._plan_batch)
    sequence = _sync(_BaseClient._sequence)
    workspace = _sync(_BaseClient._workspace)
    figure = _sync(_BaseClient._figure)
    timing = _sync(_BaseClient._timing)
    stop = _sync(_BaseClient._stop)
    dynamics = _sync(_BaseClient._dynamics)
    calibrate = _sync(_BaseClient._calibrate)
    calibration_poses = _sync(_BaseClient._calibration_poses)
    identify = _sync(_BaseClient._identify)
    simulate = _sync(_BaseClient._simulate)
    simulate_bag = _sync(_BaseClient._simulate_bag)
    design_mjcf = _sync(_BaseClient._design_mjcf)
    optimize_design = _sync(_BaseClient._optimize_design)
    regions = _sync(_BaseClient._regions)
    submit_job = _sync(_BaseClient._submit_job)
    job = _sync(_BaseClient._job)
    jobs = _sync(_BaseClient._jobs)
    cancel_job = _sync(_BaseClient._cancel_job)
    put_scene = _sync(_BaseClient._put_scene)
    scene = _sync(_BaseClient._scene)
    delete_scene = _sync(_BaseClient._delete_scene)
    scenes = _sync(_BaseClient._scenes)


class AsyncPlannerClient(_BaseClient):
    """Asynchronous client (every endpoint method is a coroutine). Use with ``async with``
    (or await :meth:`aclose`). Parameters as :class:`PlannerClient`, ``transport`` an
    ``httpx.AsyncBaseTransport``."""

    def __init__(
        self,
        base_url: str = DEFAULT_BASE_URL,
        *,
        transport: httpx.AsyncBaseTransport | None = None,
        **options: Any,
    ) -> None:
        super().__init__(base_url, **options)
        self._http = httpx.AsyncClient(transport=transport, **self._client_options())

    def stream(
        self,
        request: Any,
        *,
        kind: str | None = "plan",
        rate_hz: float | None = 1000.0,
        lookahead_s: float | None = 0.05,
        auto_ack: bool | None = True,
    ) -> AsyncStreamSession:
        """:meth:`PlannerClient.stream` for asyncio: ``async with client.stream(...) as s``,
        ``async for message in s``, ``await s.ack(t)``."""
        first = first_message(kind, request, rate_hz, lookahead_s)
        return AsyncStreamSession(
            self.base_url, self._headers, first, auto_ack=auto_ack is not False
        )

    async def _execute(self, call: _Call[M]) -> M:
        for attempt in itertools.count():
            try:
                response = await self._http.request(**self._request_args(call))
            except httpx.HTTPError as exc:
                raise self._transport_error(call, exc) from exc
            delay = self._retry_delay(call, attempt, response)
            if delay is None:
                return self._parse(call, response)
            await asyncio.sleep(delay)
        raise AssertionError("unreachable")  # pragma: no cover

    async def aclose(self) -> None:
        """Close the connections."""
        await self._http.aclose()

    async def __aenter__(self) -> AsyncPlannerClient:
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        await self.aclose()

    health = _async(_BaseClient._health)
    ready = _async(_BaseClient._ready)
    version = _async(_BaseClient._version)
    designs = _async(_BaseClient._designs)
    fk = _async(_BaseClient._fk)
    ik = _async(_BaseClient._ik)
    analyze = _async(_BaseClient._analyze)
    check_design = _async(_BaseClient._check_design)
    plan = _async(_BaseClient._plan)
    cartesian = _async(_BaseClient._cartesian)
    plan_batch = _async(_BaseClient._plan_batch)
    sequence = _async(_BaseClient._sequence)
    workspace = _async(_BaseClient._workspace)
    figure = _async(_BaseClient._figure)
    timing = _async(_BaseClient._timing)
    stop = _async(_BaseClient._stop)
    dynamics = _async(_BaseClient._dynamics)
    calibrate = _async(_BaseClient._calibrate)
    calibration_poses = _async(_BaseClient._calibration_poses)
    identify = _async(_BaseClient._identify)
    simulate = _async(_BaseClient._simulate)
    simulate_bag = _async(_BaseClient._simulate_bag)
    design_mjcf = _async(_BaseClient._design_mjcf)
    optimize_design = _async(_BaseClient._optimize_design)
    regions = _async(_BaseClient._regions)
    submit_job = _async(_BaseClient._submit_job)
    job = _async(_BaseClient._job)
    jobs = _async(_BaseClient._jobs)
    cancel_job = _async(_BaseClient._cancel_job)
    put_scene = _async(_BaseClient._put_scene)
    scene = _async(_BaseClient._scene)
    delete_scene = _async(_BaseClient._delete_scene)
    scenes = _async(_BaseClient._scenes)
