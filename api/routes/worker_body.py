"""Large request bodies are parsed in a worker, never on the event loop.

Why: parsing is CPU work that holds the GIL. A 6 MB plan (a 200,000-point cloud) takes the
event loop ~0.1-0.2 s of ``json.loads`` and validation; sixteen clients sending such bodies
kept ``/v1/health`` waiting 1.9-4.7 s, and starved the pool's watchdog thread (which needs the
GIL to kill an overrunning job). A thread would not help: ``json.loads`` and pydantic's
validation hold the GIL throughout. So a route marked :func:`parsed_in_worker` reads its body
as bytes (cheap: the chunks are joined), and when it is larger than
``PLANNER_INLINE_PARSE_BYTES`` it hands the bytes to a worker (a copy down a pipe), which
parses them exactly as FastAPI does (``json.loads``, then the model's validation in Python
mode: the same rules, the same 422 locations under ``body``), applies the route's own checks
(:attr:`BodySpec.prepare`, the service's size limits), completes the design and runs the job
in the same call. A smaller body takes FastAPI's path as before (parsing it costs less than
the hand-over).

One case comes back to the event loop: a body that names a scene (the store is the server's,
not the workers'): the worker returns the parsed request, the route resolves the scene and
runs the job as any route does (the model then crosses the pipe twice).
"""

from __future__ import annotations

import json
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Any, Protocol

from fastapi import Request, Response
from fastapi.exceptions import RequestValidationError
from fastapi.routing import APIRoute
from pydantic import BaseModel, ValidationError

from planner.endpoints import Job, JobBudget, answer_sample_limit
from planner.wire import DesignModel
from planner_api.deps import ClientWatch, get_deadline, get_pool
from planner_api.logging import REQUEST_ID
from planner_api.metrics import record_job, run_measured
from planner_api.routes._common import json_response, run_job, with_design_defaults

__all__ = [
    "BodyInvalidError",
    "BodySpec",
    "Limits",
    "RouteLimits",
    "WorkerBody",
    "WorkerBodyRoute",
    "answer_of_worker_body",
    "checked_here",
    "cross_to_worker",
    "load_json",
    "parse_body",
    "parsed_in_worker",
    "run_worker_body",
    "unchanged",
    "validate_data",
    "worker_body",
]


class RouteLimits(Protocol):
    """The service's size limits a route's checks read (:class:`planner_api.settings.Settings`
    has them; :class:`Limits` carries them to a worker). Read-only: a frozen :class:`Limits`
    is one."""

    @property
    def max_obstacles(self) -> int: ...
    @property
    def max_sequence_targets(self) -> int: ...
    @property
    def max_batch(self) -> int: ...
    @property
    def request_timeout_s(self) -> float: ...


@dataclass(frozen=True, slots=True)
class Limits:
    """The settings a route's checks need, picklable (the settings object is not sent)."""

    max_obstacles: int
    max_sequence_targets: int
    max_batch: int
    request_timeout_s: float

    @classmethod
    def of(cls, settings: RouteLimits) -> Limits:
        return cls(
            settings.max_obstacles,
            settings.max_sequence_targets,
            settings.max_batch,
            settings.request_timeout_s,
        )


@dataclass(frozen=True, slots=True)
class BodySpec:
    """How a route's body is parsed and checked wherever that happens.

    Attributes
    ----------
    model : the request model (the route's ``body`` parameter).
    prepare : ``prepare(body, limits) -> body``, module-level: the route's own checks
        (:class:`planner_api.exceptions.LimitExceededError` at the field), run by the route on
        FastAPI's path and by the worker on this one.
    job : the route's job for a request (a dependency a test may override is resolved here).
    resolve_scene : for a request that may name a scene, the route's resolution of it
        (:func:`planner_api.routes.scenes.resolve_scene`); None: the model has no scene.
    handle : a route whose large body is not a job's request (a scene to store) handles the
        bytes itself, ``await handle(request, raw)``, with :func:`parse_body` in a worker;
        ``prepare`` and ``job`` then play no part.
    """

    model: type[BaseModel]
    prepare: Callable[[Any, RouteLimits], Any]
    job: Callable[[Request], Job | None]
    resolve_scene: Callable[[Request, Any], Awaitable[Any]] | None = None
    handle: Callable[[Request, bytes], Awaitable[Response]] | None = None


@dataclass(frozen=True, slots=True)
class WorkerBody:
    """What a route hands a worker instead of a parsed body (:func:`run_worker_body`).

    ``design_defaults`` None: the service's default design is the built-in robot (nothing
    to complete). Pickled as one flat tuple (:meth:`__reduce__`): the dataclasses' own
    pickling runs Python per field and per nested object, which was most of the loop's
    cost of handing a small body over (~20 us against ~5 us)."""

    spec_model: type[BaseModel]
    prepare: Callable[[Any, RouteLimits], Any]
    job: Job
    raw: bytes
    limits: Limits
    design_defaults: DesignModel | None
    budget: JobBudget
    request_id: str | None

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        limits, budget = self.limits, self.budget
        return _rebuilt, (
            self.spec_model,
            self.prepare,
            self.job,
            self.raw,
            (
                limits.max_obstacles,
                limits.max_sequence_targets,
                limits.max_batch,
                limits.request_timeout_s,
            ),
            self.design_defaults,
            budget.deadline,
            budget.max_samples,
            self.request_id,
        )


def _rebuilt(
    model: type[BaseModel],
    prepare: Callable[[Any, RouteLimits], Any],
    job: Job,
    raw: bytes,
    limits: tuple[int, int, int, float],
    defaults: DesignModel | None,
    deadline: float | None,
    max_samples: int | None,
    request_id: str | None,
) -> WorkerBody:
    """A :class:`WorkerBody` from its :meth:`~WorkerBody.__reduce__` tuple (in the worker)."""
    budget = JobBudget(deadline, max_samples)
    return WorkerBody(model, prepare, job, raw, Limits(*limits), defaults, budget, request_id)


def worker_body(
    model: type[BaseModel],
    job: Job,
    raw: bytes,
    settings: Any,
    budget: JobBudget,
    prepare: Callable[[Any, RouteLimits], Any] | None = None,
) -> WorkerBody:
    """A :class:`WorkerBody` of a route's request: the service's limits and default design
    from ``settings``, the request id of the request being served; ``prepare`` None: the
    body's checks were made already (:func:`unchanged`)."""
    return WorkerBody(
        model,
        prepare or unchanged,
        job,
        raw,
        Limits.of(settings),
        settings.custom_design_defaults,
        budget,
        REQUEST_ID.get(),
    )


class BodyInvalidError(Exception):
    """The body breaks the JSON syntax or the model's rules: ``items`` are the 422's
    ``detail`` entries (``loc``, ``msg``, ``type``; plain data, so that they cross the pipe)."""

    def __init__(self, items: list[dict[str, Any]]) -> None:
        super().__init__(items)
        self.items = items


def unchanged(body: Any, limits: RouteLimits) -> Any:
    """The ``prepare`` of a body whose checks were made already (or of a route that has none
    to make here)."""
    return body


def parse_body(model: type[BaseModel], raw: bytes) -> Any:
    """``raw`` parsed as FastAPI parses a JSON body and validated into ``model`` (Python
    mode, as FastAPI validates a body parameter); :class:`BodyInvalidError` with FastAPI's
    locations (``["body", position]`` for bad JSON, ``["body", field, ...]`` for a rule) and the
    service's answers for a body too deep or a number too long to read."""
    return validate_data(model, load_json(raw))


def load_json(raw: bytes) -> Any:
    """The JSON of a body, as FastAPI reads it (:func:`parse_body`'s first half)."""
    try:
        return json.loads(raw)
    except json.JSONDecodeError as exc:
        raise BodyInvalidError(
            [{"loc": ["body", exc.pos], "msg": "JSON decode error", "type": "json_invalid"}]
        ) from None
    except RecursionError:
        raise BodyInvalidError(
            [
                {
                    "loc": ["body"],
                    "msg": "the body is nested too deeply to read",
                    "type": "json_too_deep",
                }
            ]
        ) from None
    except ValueError as exc:  # an integer longer than Python converts (sys.int_info)
        raise BodyInvalidError(
            [
                {
                    "loc": ["body"],
                    "type": "number_too_long",
                    "msg": f"a number in the body is too long to read ({str(exc).split(';')[0]})",
                }
            ]
        ) from None


def validate_data(model: type[BaseModel], data: Any) -> Any:
    """A body's JSON validated into ``model`` (:func:`parse_body`'s second half)."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise BodyInvalidError(
            [
                {"loc": ["body", *e["loc"]], "msg": e["msg"], "type": e["type"]}
                for e in exc.errors(include_url=False, include_context=False, include_input=False)
            ]
        ) from None


def run_worker_body(work: WorkerBody) -> tuple[str, Any]:
    """In a worker: parse and check the body, then run the route's job on it:
    ``("done", (answer bytes, metrics sample))``, or ``("scene", request)`` when the request
    names a scene (the route resolves it in the server)."""
    body = work.prepare(parse_body(work.spec_model, work.raw), work.limits)
    if getattr(body, "scene", None) is not None:
        return "scene", body
    if work.design_defaults is not None:
        body = with_design_defaults(body, work.design_defaults)
    return "done", run_measured(work.job, body, budget=work.budget, request_id=work.request_id)


def answer_of_worker_body(work: WorkerBody) -> tuple[bytes, Any]:
    """In a worker: :func:`run_worker_body` of a body known to name no scene (a batch's plans,
    checked): its (answer bytes, metrics sample)."""
    kind, value = run_worker_body(work)
    assert kind == "done"  # the batch's check sends every request naming a scene back
    return value


def parsed_in_worker(spec: BodySpec) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Mark a route's endpoint: a body larger than ``PLANNER_INLINE_PARSE_BYTES`` is parsed
    in a worker (:class:`WorkerBodyRoute` reads the mark). Apply it below ``@router.post``."""

    def mark(endpoint: Callable[..., Any]) -> Callable[..., Any]:
        endpoint.__worker_body__ = spec  # type: ignore[attr-defined]
        return endpoint

    return mark


class WorkerBodyRoute(APIRoute):
    """An :class:`fastapi.routing.APIRoute` whose endpoint, if marked with
    :func:`parsed_in_worker`, has a large body parsed in a worker. The route's OpenAPI
    document is FastAPI's own (the endpoint still declares its body model)."""

    def get_route_handler(self) -> Callable[[Request], Any]:
        standard = super().get_route_handler()
        spec: BodySpec | None = getattr(self.endpoint, "__worker_body__", None)
        if spec is None:
            return standard

        async def handler(request: Request) -> Response:
            raw = await request.body()  # kept by the request: FastAPI's path reads it again
            if len(raw) <= request.app.state.settings.inline_parse_bytes:
                return await standard(request)
            if spec.handle is not None:
                return await spec.handle(request, raw)
            return await _in_worker(request, spec, raw)

        return handler


async def _in_worker(request: Request, spec: BodySpec, raw: bytes) -> Response:
    """The route's work for a large body: parsed, checked and run in one worker call. The
    gate checked the API key before the body was read; the client is watched as the routes'
    dependency watches it (a client gone cancels the job). A body that breaks a rule is a 422
    with the worker's locations (:class:`BodyInvalidError`)."""
    async with ClientWatch(request):
        try:
            return await cross_to_worker(request, spec, raw)
        except BodyInvalidError as exc:
            raise RequestValidationError(exc.items) from None


async def cross_to_worker(request: Request, spec: BodySpec, raw: bytes) -> Response:
    """The route's work on its body as JSON text: parsed, checked and run in one worker call
    (:func:`run_worker_body`); a body naming a scene comes back parsed, has its scene resolved
    here and crosses again as a parsed request. Raises :class:`BodyInvalidError` (from the
    worker) when the body does not parse or validate; the caller answers it (a large body:
    :func:`_in_worker`; a small one: :mod:`planner_api.routes.direct`, FastAPI's own 422)."""
    settings = request.app.state.settings
    pool = await get_pool(request)
    deadline = await get_deadline(request)
    job = spec.job(request)
    assert job is not None  # a route with a job of its own has a handle instead
    samples = answer_sample_limit(settings.max_trajectory_samples, settings.max_response_bytes)
    work = worker_body(spec.model, job, raw, settings, JobBudget(deadline, samples), spec.prepare)
    kind, value = await pool.run(run_worker_body, work, deadline=deadline)
    if kind == "scene":
        assert spec.resolve_scene is not None  # a model without a scene has none to name
        body = await spec.resolve_scene(request, value)
        return await run_job(
            pool,
            job,
            body,
            deadline,
            design_defaults=settings.design_defaults,
            max_samples=samples,
        )
    content, sample = value
    record_job(sample)
    return json_response(content)


async def checked_here(request: Request, spec: BodySpec, raw: bytes) -> bool:
    """The checks the loop made before a job when it parsed the body itself, made here on
    ``raw``: False when the body does not parse or validate into the model (FastAPI's path
    answers its own 422); the route's own checks (:attr:`BodySpec.prepare`, a 422 at the
    field), the scene's resolution (an unknown scene's 422) and the design completed from the
    service's default (a merged design that breaks a rule) raise as they would have; True
    when all pass. For :mod:`planner_api.routes.direct`, when a body sent to a worker
    unparsed met an error of the pool (full, past its deadline) that may have come before
    the worker checked it: a bad body still gets its 422, never the pool's error."""
    try:
        body = parse_body(spec.model, raw)
    except BodyInvalidError:
        return False
    settings = request.app.state.settings
    body = spec.prepare(body, settings)
    if spec.resolve_scene is not None:
        body = await spec.resolve_scene(request, body)
    with_design_defaults(body, settings.design_defaults)
    return True
