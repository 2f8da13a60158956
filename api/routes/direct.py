"""Routes answered without FastAPI's per-request dependency solving, and the routing index.

Why: on the cheapest requests (fk, ik, a small plan) the event loop's own CPU was 4-5x a bare
FastAPI app's, and the largest parts were FastAPI's ``solve_dependencies`` (24-32 %: it walks
the route's dependency tree, settings, pool, deadline, API key, client watch, job function,
body, on every request) and Starlette's routing (8-13 %: one regular expression per route,
in order, until one matches). Both answers are the same for every request of a route:

- :class:`DirectRoute` works out once, when the route is built, which of its dependencies
  it has (the API key, the client watch; anything else and the route keeps FastAPI's path),
  and answers a request by reading its body, validating it into the route's model, checking
  the key, watching the client and calling the endpoint's :class:`DirectSpec` ``answer``
  with the request and the body, which reads the settings, the pool and the deadline itself.
  The rules are FastAPI's: the same JSON reading and model validation (Python mode), the key
  checked before the body (FastAPI resolves dependencies before the body). Any case that is
  not the plain one takes FastAPI's path unchanged, so its answer is FastAPI's to the byte: a
  body that does not validate (its 422 is FastAPI's own), an empty body, a body larger than
  ``PLANNER_INLINE_PARSE_BYTES`` (parsed in a worker: :mod:`planner_api.routes.worker_body`),
  and any application with ``dependency_overrides`` (tests replace a job that way).
- Bodies validated in the worker (a :class:`DirectSpec` without ``answer``: the routes that
  run their job in the worker pool, a plan, a straight line, a sequence, a timing): the
  plain request's body crosses to a worker as its JSON text, and the worker reads, validates
  and checks it (the route's :class:`~planner_api.routes.worker_body.BodySpec`) and runs the
  job in the same call, as a large body's path always did
  (:func:`~planner_api.routes.worker_body.cross_to_worker`). Why: the loop's share of a small
  plan was reading and validating the body (~28 us) and pickling the eight nested models it
  made (~23 us, Python per model), for the worker to unpickle them (~29 us); the bytes and
  the route's checks pickle in ~5-8 us, and the worker reads and validates them in about
  what it spent unpickling (~33 us). Where validation stays on the loop, decided so: a bad
  body must not take a slot in the pool's queue from good requests (a client sending bad
  bodies in a loop while the workers are busy), nor cost a worker round trip (a 422 that
  crossed measured 1.6-5.3 ms p50 against ~1.0 ms, the worker's wake-up mostly). So the loop
  checks every body first, cheaply: pydantic's JSON-mode validation in one pass (~19 us; its
  models thrown away, never pickled) and the route's limits (:func:`_passes_here`); a body
  that fails takes FastAPI's path at once, whose 422 is the one it always was (same status,
  ``loc``, message), and no worker sees it. (Checking only while no worker was idle, so that
  good bodies skipped the check then, made a 422's cost depend on the pool's state, and
  schemathesis's thousands of bad bodies slower by ~1 ms each.) JSON mode is not FastAPI's Python
  mode, so the worker validates again as FastAPI does; a body it refuses (a case JSON mode
  lets through) also takes FastAPI's path. A merged design that breaks a rule or an unknown
  scene is found in the worker (a round trip, as rare). One case must not reach the pool's
  own errors first: when the crossing fails with a full pool, a pool not running, a deadline
  passed in the queue or a worker gone, the loop checks the body itself
  (:func:`~planner_api.routes.worker_body.checked_here`: validation, the route's limits, the
  scene, the design) and a bad body gets its 422, a good one the pool's error, as when the
  loop validated first.
- :func:`index_routes` puts a table in front of the router: the route a (method, path) pair
  matched is remembered (for the routes without path parameters, in a bounded table), and the
  next request with that pair tries that one route's pattern instead of every route's in
  order. The route found is the one the ordered scan found, so nothing changes but the cost;
  a miss, a path with parameters or a partial match (405) takes Starlette's scan.
- The front door's direct answer: once the table has handed a (method, path) to a
  :class:`DirectRoute` (its second request), that route's plain answer is kept in
  ``app.state.direct_answers``, and the gate (:class:`planner_api.middleware.RequestGate`),
  having read the body, calls it itself: no FastAPI exception middleware, exit stack, router,
  route wrapper or ``Request`` per layer (with the observer and the gate, about half of a
  plain fk's loop time in-process: ~180 of ~320 us, against ~140 us for the route's handler
  alone, on a loaded machine). What those layers do for such a request is done there: the
  route set in the scope (the metrics' label), an error answered by the application's
  handler for it through Starlette's own ``wrap_app_handling_exceptions`` (the handlers
  FastAPI gives its exception middleware), an error without one raised to the outer
  middleware (the 500). A request that is not the plain case (also a body the worker refused
  after crossing) is declined before anything is sent (the scope marked :data:`DECLINED`) and takes the layers with its body replayed,
  its route's handler going straight to FastAPI's path; so is every request while FastAPI's
  tracing is on (it names the request's span as it routes it).
"""

from __future__ import annotations

import json
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Any

import fastapi.routing
from fastapi import FastAPI, Request, Response
from fastapi.routing import APIRoute
from pydantic import BaseModel, ValidationError
from starlette._exception_handler import wrap_app_handling_exceptions
from starlette.middleware.exceptions import ExceptionMiddleware
from starlette.routing import Match, Router
from starlette.types import Receive, Scope, Send

from planner_api.deps import ClientWatch, require_api_key, watch_client
from planner_api.exceptions import (
    DeadlineExceededError,
    LimitExceededError,
    PoolNotRunningError,
    PoolSaturatedError,
    WorkerCrashedError,
)
from planner_api.routes.worker_body import (
    BodyInvalidError,
    BodySpec,
    WorkerBodyRoute,
    checked_here,
    cross_to_worker,
    validate_data,
)

__all__ = [
    "DECLINED",
    "DirectAnswer",
    "DirectRoute",
    "DirectSpec",
    "PlainAnswer",
    "answered_directly",
    "index_routes",
]

#: The dependencies :class:`DirectRoute` resolves itself; a route with any other one keeps
#: FastAPI's path.
_KNOWN = frozenset({require_api_key, watch_client})
#: How many (method, path) pairs :func:`index_routes` remembers (paths with parameters, a
#: scene's or a job's name, are never remembered: they would churn the table).
_INDEX_SIZE = 256


@dataclass(frozen=True, slots=True)
class DirectSpec:
    """How :class:`DirectRoute` answers a route: ``model`` is its body's model,
    ``await answer(request, body)`` its work on the validated body (what the endpoint does
    with its dependencies, which it reads from ``request.app.state`` itself).

    ``answer`` None: the body is not parsed on the loop at all; it crosses to a worker as its
    JSON text and is validated there, with the route's
    :class:`~planner_api.routes.worker_body.BodySpec` (its ``parsed_in_worker`` mark; the
    module docstring, "Bodies validated in the worker")."""

    model: type[BaseModel]
    answer: Callable[[Request, Any], Awaitable[Response]] | None = None


def answered_directly(spec: DirectSpec) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Mark a route's endpoint: :class:`DirectRoute` answers its plain requests with
    ``spec`` (the endpoint itself stays FastAPI's path and its OpenAPI document). Apply it
    below ``@router.post`` (and below :func:`~planner_api.routes.worker_body.parsed_in_worker`
    when both apply)."""

    def mark(endpoint: Callable[..., Any]) -> Callable[..., Any]:
        endpoint.__direct__ = spec  # type: ignore[attr-defined]
        return endpoint

    return mark


class DirectRoute(WorkerBodyRoute):
    """A :class:`~planner_api.routes.worker_body.WorkerBodyRoute` whose endpoint, if marked
    with :func:`answered_directly`, answers its plain requests without FastAPI's dependency
    solving (the module docstring). Its plain answer (:data:`PlainAnswer`) is kept on the
    route (``planner_plain``) for the front door's direct answer (:func:`index_routes`)."""

    planner_plain: PlainAnswer | None = None
    #: (keyed, watched) of the route's first inclusion with a plain answer, and whether an
    #: inclusion (in any application: the routers are shared) differed from it since
    _planner_flags: tuple[bool, bool] | None = None
    _planner_mixed: bool = False

    def get_route_handler(self) -> Callable[[Request], Any]:
        fallback = super().get_route_handler()
        spec: DirectSpec | None = getattr(self.endpoint, "__direct__", None)
        dependencies = _included_dependencies(self)
        if spec is None or dependencies is None:
            return fallback
        found = {d.dependency for d in dependencies}
        if not found <= _KNOWN:
            return fallback
        keyed, watched = require_api_key in found, watch_client in found
        if spec.answer is None:
            plain = _crossing_plain(_body_spec(self, spec), keyed, watched)
        else:
            plain = _answer_plain(spec.model, spec.answer, keyed, watched)
        # kept for the front door only while every inclusion of the route answers alike
        if self._planner_flags is None:
            self._planner_flags = (keyed, watched)
        elif self._planner_flags != (keyed, watched):
            self._planner_mixed = True
        self.planner_plain = None if self._planner_mixed else plain

        async def handler(request: Request) -> Response:
            if DECLINED not in request.scope:  # else the front door made these checks
                answer = await plain(request, await request.body())
                if answer is not None:
                    return answer
            return await fallback(request)  # FastAPI's own path (and 422)

        return handler


#: A route's plain answer to a request and its body: the answer, or None when the request
#: is not the plain case (FastAPI's path answers it).
PlainAnswer = Callable[[Request, bytes], Awaitable[Response | None]]
#: Set in a request's scope when the front door's direct answer declined it
#: (:func:`index_routes`): the route's handler then takes FastAPI's path at once, without
#: making the checks (or a worker crossing) a second time.
DECLINED = "planner.direct_declined"


async def _plain_case(request: Request, raw: bytes, keyed: bool) -> bool:
    """Whether a request may take its route's plain answer: no ``dependency_overrides``, a
    body neither empty nor over ``inline_parse_bytes`` (else FastAPI's path answers it); the
    API key checked first where the route asks one (a missing or wrong key raises its 401)."""
    app = request.app
    settings = app.state.settings
    if app.dependency_overrides or not raw or len(raw) > settings.inline_parse_bytes:
        return False
    if keyed:
        await require_api_key(request, settings)
    return True


def _answer_plain(
    model: type[BaseModel],
    answer: Callable[[Request, Any], Awaitable[Response]],
    keyed: bool,
    watched: bool,
) -> PlainAnswer:
    """The plain answer of a route whose work runs on the validated body (fk, ik, analyze)."""

    async def plain(request: Request, raw: bytes) -> Response | None:
        if not await _plain_case(request, raw, keyed):
            return None
        try:  # read as FastAPI reads it (Starlette's request.json() is json.loads of the body)
            body = validate_data(model, json.loads(raw))
        except (BodyInvalidError, ValueError, RecursionError):
            return None  # FastAPI's own 422
        if not watched:
            return await answer(request, body)
        async with ClientWatch(request):
            return await answer(request, body)

    return plain


def _body_spec(route: APIRoute, spec: DirectSpec) -> BodySpec:
    """The :class:`~planner_api.routes.worker_body.BodySpec` a crossing route's body is
    parsed with in the worker (its endpoint's ``parsed_in_worker`` mark, for ``spec.model``)."""
    body: BodySpec | None = getattr(route.endpoint, "__worker_body__", None)
    if body is None or body.handle is not None or body.model is not spec.model:
        raise TypeError(
            f"{route.path}: a DirectSpec without an answer needs the route's parsed_in_worker "
            f"mark with a job for {spec.model.__name__}"
        )
    return body


def _crossing_plain(spec: BodySpec, keyed: bool, watched: bool) -> PlainAnswer:
    """The plain answer of a route whose small bodies cross to a worker unparsed (the module
    docstring, "Bodies validated in the worker")."""

    async def plain(request: Request, raw: bytes) -> Response | None:
        if not await _plain_case(request, raw, keyed):
            return None
        if not _passes_here(spec, raw, request.app.state.settings):
            return None  # FastAPI's own 422, no pool slot taken
        return await _crossed(request, spec, raw, watched)

    return plain


def _passes_here(spec: BodySpec, raw: bytes, settings: Any) -> bool:
    """The loop's own check of a body about to cross: pydantic's JSON-mode validation of
    ``raw`` (one pass in pydantic-core, ~2/3 of ``json.loads`` and Python-mode validation;
    its models are thrown away, never pickled) and the route's limits. False: FastAPI's path
    answers (a bad body's 422 as it always was, before any worker). JSON mode is not
    FastAPI's Python mode, so this is a filter, not the verdict: a body it passes is
    validated again in the worker as FastAPI would, and one the worker refuses still gets
    FastAPI's 422; one it refuses and FastAPI accepts is served by FastAPI's path."""
    try:
        body = spec.model.__pydantic_validator__.validate_json(raw)
    except (ValidationError, ValueError, RecursionError):
        return False
    try:
        spec.prepare(body, settings)
    except LimitExceededError:
        return False
    return True


#: The pool's errors that may come before the worker has checked the body (refused, not
#: running, past the deadline in the queue, a worker gone): answered only once the loop has
#: checked the body itself (:func:`~planner_api.routes.worker_body.checked_here`).
_BEFORE_THE_CHECK = (
    PoolSaturatedError,
    PoolNotRunningError,
    DeadlineExceededError,
    WorkerCrashedError,
)


async def _crossed(request: Request, spec: BodySpec, raw: bytes, watched: bool) -> Response | None:
    """The answer of ``raw`` crossed to a worker; None when it does not parse or validate
    (FastAPI's path then answers its own 422, the same to the byte as before)."""
    try:
        if not watched:
            return await cross_to_worker(request, spec, raw)
        async with ClientWatch(request):
            return await cross_to_worker(request, spec, raw)
    except BodyInvalidError:
        return None
    except _BEFORE_THE_CHECK:
        if not await checked_here(request, spec, raw):
            return None
        raise


def _included_dependencies(route: APIRoute) -> list[Any] | None:
    """The dependencies of ``route`` as included in the application (its router's
    ``include_router(dependencies=...)`` with its own), or None when the handler being built
    is not an included route's. FastAPI (0.165) builds an included route's handler once per
    inclusion, the inclusion's context in a context variable that its own
    ``APIRoute.get_route_handler`` reads; the route's own ``dependencies`` lack the
    router's. None (FastAPI's path kept) if a FastAPI version has no such variable."""
    var = getattr(fastapi.routing, "_effective_route_context_var", None)
    context = var.get() if var is not None else None
    if context is None or getattr(context, "original_route", None) is not route:
        return None
    return list(context.dependencies)


def index_routes(app: FastAPI) -> None:
    """Route ``app``'s requests through a table of the routes already matched (the module
    docstring), and keep in ``app.state.direct_answers`` the front door's direct answer
    (:func:`_direct_answer`) of each (method, path) that the table handed to a route with a
    plain answer. Call once, after every route is included."""
    router: Router = app.router
    scan = router.middleware_stack
    table: dict[tuple[str, str], int] = {}
    routes = router.routes
    direct: dict[tuple[str, str], DirectAnswer] = {}
    app.state.direct_answers = direct

    async def routed(scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await scan(scope, receive, send)
            return
        key = (scope["method"], scope["path"])
        at = table.get(key)
        if at is not None and at < len(routes):
            route = routes[at]
            match, child = route.matches(scope)
            if match is Match.FULL:  # as Starlette's router hands a full match over
                scope.setdefault("router", router)
                scope["route"] = route
                scope.update(child)
                await route.handle(scope, receive, send)
                if key not in direct and len(direct) < _INDEX_SIZE:
                    _remember_direct(app, direct, key, scope.get("route"))
                return
        if at is None:
            found = _first_full_match(routes, scope)
            if found is not None:
                if len(table) >= _INDEX_SIZE:
                    table.pop(next(iter(table)))
                table[key] = found
        await scan(scope, receive, send)

    router.middleware_stack = routed


#: The front door's direct answer of a request whose body it has read: True when answered,
#: False when declined (the request then takes the application's own path, the body
#: replayed).
DirectAnswer = Callable[[Scope, Receive, Send, bytes], Awaitable[bool]]


def _remember_direct(
    app: FastAPI, direct: dict[tuple[str, str], DirectAnswer], key: tuple[str, str], route: Any
) -> None:
    """Keep the direct answer of ``key`` when the route the table handed it to has a plain
    answer (a :class:`DirectRoute` included once, or alike each time)."""
    plain = getattr(route, "planner_plain", None) if isinstance(route, DirectRoute) else None
    if plain is None:
        return
    handlers = _exception_handlers(app)

    async def answer(scope: Scope, receive: Receive, send: Send, raw: bytes) -> bool:
        return await _direct_answer(route, plain, handlers, scope, receive, send, raw)

    direct[key] = answer


def _exception_handlers(app: FastAPI) -> tuple[Any, Any]:
    """The (exception, status) handler tables of ``app``'s ``ExceptionMiddleware``, as
    FastAPI builds that middleware (every handler but the 500 one, which is the outermost
    middleware's)."""
    handlers = {k: v for k, v in app.exception_handlers.items() if k not in (500, Exception)}
    middleware = ExceptionMiddleware(app.router, handlers=handlers)
    return middleware._exception_handlers, middleware._status_handlers


async def _direct_answer(
    route: APIRoute,
    plain: PlainAnswer,
    handlers: tuple[Any, Any],
    scope: Scope,
    receive: Receive,
    send: Send,
    raw: bytes,
) -> bool:
    """``route``'s answer to a request whose body ``raw`` the front door read
    (:class:`planner_api.middleware.RequestGate`), without the layers between the front door
    and the route: FastAPI's exception middleware, its exit stack, the router, the route's
    own wrapper. What they would do for this request is done here: the route set in the
    scope (the metrics' label), an error answered by the application's handler for it, as
    the route's wrapper answers it (Starlette's own ``wrap_app_handling_exceptions``), an
    error without one raised to the outer middleware. False (the scope marked
    :data:`DECLINED`) when the request is not the plain case, and when FastAPI's tracing is
    on (it names the request's span as it routes it)."""
    if "fastapi.telemetry" in scope:
        return False
    scope["route"] = route
    scope["starlette.exception_handlers"] = handlers
    request = Request(scope, receive)
    request._body = raw  # what an exception handler reading the body would read
    answered = True

    async def respond(scope: Scope, receive: Receive, send: Send) -> None:
        nonlocal answered
        response = await plain(request, raw)
        if response is None:
            answered = False
            return
        await response(scope, receive, send)

    await wrap_app_handling_exceptions(respond, request)(scope, receive, send)
    if not answered:
        scope[DECLINED] = True
    return answered


def _first_full_match(routes: list[Any], scope: Scope) -> int | None:
    """The position of the router's entry that the ordered scan hands ``scope`` to, when
    that is a full match of a path without parameters (a partial one, a 405, may be beaten
    by a later entry; a path with parameters would churn the table); else None."""
    probe = dict(scope)
    for i, route in enumerate(routes):
        match, child = route.matches(probe)
        if match is Match.FULL:
            inner = child.get("route", route)
            if getattr(inner, "param_convertors", None) or child.get("path_params"):
                return None
            return i
    return None
