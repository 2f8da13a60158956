"""What each endpoint of the client sends: one request builder per endpoint, returning a
:class:`_Call` (method, path, validated body, answer model). :class:`planner.client.PlannerClient`
and :class:`~planner.client.AsyncPlannerClient` make their public methods from these builders
(the same builder for both, so the two cannot drift apart); the transport, the retry policy
and the error translation live in :mod:`planner.client`.

A new endpoint is one builder here plus one line in each client class.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from pydantic import BaseModel, ValidationError

from planner.client_errors import InvalidRequestError
from planner.design import Design
from planner.wire import (
    SCENE_NAME_PATTERN,
    AnalyzeRequest,
    AnalyzeResponse,
    CartesianRequest,
    CartesianResponse,
    DesignCheckRequest,
    DesignCheckResponse,
    DesignModel,
    DesignOptimizeRequest,
    DesignOptimizeResponse,
    DesignsResponse,
    DynamicsRequest,
    DynamicsResponse,
    FigureQuery,
    FKRequest,
    FKResponse,
    Health,
    IKRequest,
    IKResponse,
    JobList,
    JobRequest,
    JobStatus,
    MjcfRequest,
    PlanBatchRequest,
    PlanBatchResponse,
    PlanRequest,
    PlanResponse,
    Readiness,
    RegionsRequest,
    RegionsResponse,
    Scene,
    SceneInfo,
    SceneList,
    SceneRequest,
    SequenceRequest,
    SequenceResponse,
    SimulateRequest,
    SimulateResponse,
    TimingRequest,
    TimingResponse,
    TrajectoryModel,
    TrajectoryPointsModel,
    VersionInfo,
    WorkspaceRequest,
    WorkspaceResponse,
    trajectory_arrays,
)
from planner.wire.calibration import (
    CalibrateRequest,
    CalibrateResponse,
    CalibrationPosesRequest,
    CalibrationPosesResponse,
    IdentifyRequest,
    IdentifyResponse,
)

__all__ = ["DesignLike", "MarginsLike", "Requests", "none_as_absent"]

M = TypeVar("M", bound=BaseModel | bytes)
#: A wire model class (what :func:`_validated` builds).
ModelT = TypeVar("ModelT", bound=BaseModel)


@dataclass(frozen=True, slots=True)
class _Call(Generic[M]):
    """One API call: what to send and what to parse the answer into (``bytes``: the raw
    body, e.g. an image)."""

    method: str
    path: str
    body: BaseModel | None
    model: type[M]
    ok_statuses: frozenset[int] = frozenset({200})
    retry: bool = True
    params: Mapping[str, Any] | None = None


DesignLike = DesignModel | Design | Mapping[str, Any] | None
#: Margins as a wire model, the library's :class:`planner.validity.Margins` or a mapping.
MarginsLike = BaseModel | Mapping[str, Any] | Any | None


def _validated(model: type[ModelT], data: Any) -> ModelT:
    """``model`` from ``data``, a local validation error raised as InvalidRequestError."""
    try:
        return data if isinstance(data, model) else model.model_validate(data)
    except ValidationError as exc:
        detail = [{"loc": list(e["loc"]), "msg": e["msg"], "type": e["type"]} for e in exc.errors()]
        raise InvalidRequestError(
            "; ".join(_describe_item(d) for d in detail), status_code=None, detail=detail
        ) from None


def _design(design: DesignLike) -> DesignModel | dict[str, Any]:
    if design is None:
        return {}
    if isinstance(design, Design):
        return DesignModel.from_design(design)
    return design if isinstance(design, DesignModel) else dict(design)


def _margins(margins: MarginsLike) -> dict[str, Any]:
    """Margins as the wire's mapping: a wire model, the library's dataclass or a mapping."""
    if isinstance(margins, BaseModel):
        return margins.model_dump(exclude_none=True)
    if dataclasses.is_dataclass(margins) and not isinstance(margins, type):
        return dataclasses.asdict(margins)
    # what is left of MarginsLike is a mapping or None; its Any member defeats the narrowing
    return dict(margins or {})  # type: ignore[arg-type]


def _floats(values: Any) -> Any:
    """A numpy array or other sequence as a list of floats (anything else left to pydantic)."""
    try:
        return [float(x) for x in values]
    except (TypeError, ValueError):
        return values


def _rows(values: Any) -> Any:
    """N x 3 (or one row of 3) numbers, numpy or nested sequences, as lists of floats."""
    if hasattr(values, "tolist"):
        return values.tolist()
    try:
        return [_floats(r) if hasattr(r, "__len__") else float(r) for r in values]
    except (TypeError, ValueError):
        return values


def _scene_path(name: str) -> str:
    """``/v1/scenes/{name}``, the name checked first (a safe identifier, never a path)."""
    if not isinstance(name, str) or re.fullmatch(SCENE_NAME_PATTERN, name) is None:
        detail = [
            {
                "loc": ["path", "name"],
                "msg": f"a scene name must match {SCENE_NAME_PATTERN}, got {name!r}",
                "type": "string_pattern_mismatch",
            }
        ]
        raise InvalidRequestError(_describe_item(detail[0]), status_code=None, detail=detail)
    return f"/v1/scenes/{name}"


def _obstacle_data(obstacles: Sequence[Any]) -> list[Any]:
    """Obstacles as the wire's data: a point cloud's numpy ``points`` as lists of floats."""
    out = []
    for ob in obstacles:
        if isinstance(ob, Mapping) and hasattr(ob.get("points"), "tolist"):
            ob = {**ob, "points": ob["points"].tolist()}
        out.append(ob)
    return out


def _simulate_body(
    trajectory: Any,
    request: Any,
    controller: str | Mapping[str, Any],
    design: DesignLike,
    options: Mapping[str, Any],
) -> SimulateRequest:
    """The validated body of ``POST /v1/simulate`` (and ``/bag``) from the client's
    arguments."""
    data: dict[str, Any] = dict(options)
    data["controller"] = {"kind": controller} if isinstance(controller, str) else dict(controller)
    if design is not None:
        data["design"] = _design(design)
    if trajectory is not None:
        data["trajectory"] = _trajectory_fields(trajectory)
    if request is not None:
        data["request"] = (
            request.model_dump(exclude_unset=True)
            if isinstance(request, BaseModel)
            else dict(request)
        )
    return _validated(SimulateRequest, data)


def _trajectory_fields(trajectory: Any) -> dict[str, Any]:
    """``t``, ``q``, ``qd``, ``qdd`` of a trajectory: a wire answer in either form, a
    mapping (a points mapping is read as one), or any object with those attributes (the
    library's trajectory)."""
    if isinstance(trajectory, Mapping):
        kind = TrajectoryPointsModel if "points" in trajectory else TrajectoryModel
        if "points" in trajectory or "duration" in trajectory:
            trajectory = kind.model_validate(trajectory)
        else:
            return {k: trajectory[k] for k in ("t", "q", "qd", "qdd") if k in trajectory}
    if isinstance(trajectory, TrajectoryPointsModel):
        trajectory = trajectory_arrays(trajectory)
    return {
        "t": _floats(trajectory.t),
        "q": [_floats(r) for r in trajectory.q],
        "qd": [_floats(r) for r in trajectory.qd],
        "qdd": [_floats(r) for r in trajectory.qdd],
    }
def none_as_absent(build: Callable[..., _Call[M]]) -> Callable[..., _Call[M]]:
    """``build`` with None meaning absent for every optional argument: an argument with a
    default given as None takes that default, and a keyword of ``**fields``/``**options``
    given as None is dropped (so ``client.plan(..., obstacles=None)`` sends no
    ``obstacles``). Both clients make their methods through this (:mod:`planner.client`)."""
    sig = inspect.signature(build)

    @functools.wraps(build)
    def call(*args: Any, **kwargs: Any) -> _Call[M]:
        bound = sig.bind(*args, **kwargs)
        for name, value in list(bound.arguments.items()):
            param = sig.parameters[name]
            if param.kind is param.VAR_KEYWORD:
                bound.arguments[name] = {k: v for k, v in value.items() if v is not None}
            elif value is None and param.default is not param.empty:
                del bound.arguments[name]
        return build(*bound.args, **bound.kwargs)

    return call


def _request_body(model: type[ModelT], request: Any, fields: Mapping[str, Any]) -> ModelT:
    """The body of a plan-like endpoint (plan, cartesian, sequence): ``request`` (the model,
    a mapping or None) with ``fields`` over it; a top-level None is absent, and a point
    cloud's numpy ``points`` are lists (as :meth:`Requests._put_scene` takes them)."""
    if isinstance(request, model) and not fields:
        return request
    data = dict(
        request.model_dump(exclude_unset=True) if isinstance(request, model) else request or {}
    )
    merged = {k: v for k, v in {**data, **fields}.items() if v is not None}
    if isinstance(merged.get("obstacles"), Sequence):
        merged["obstacles"] = _obstacle_data(merged["obstacles"])
    return _validated(model, merged)


def _describe_item(item: Any) -> str:
    if not isinstance(item, dict):
        return str(item)
    loc = ".".join(str(x) for x in item.get("loc", []))
    msg = str(item.get("msg", ""))
    return f"{loc}: {msg}" if loc else msg


class Requests:
    """The request builders, one per endpoint (``_fk`` -> the clients' ``fk``)."""

    def _health(self) -> _Call[Health]:
        """Liveness of the server."""
        return _Call("GET", "/v1/health", None, Health)

    def _ready(self) -> _Call[Readiness]:
        """Readiness of the server's workers (a 503 answer is returned, not raised)."""
        return _Call("GET", "/v1/ready", None, Readiness, frozenset({200, 503}), retry=False)

    def _version(self) -> _Call[VersionInfo]:
        """Versions of the server and its libraries."""
        return _Call("GET", "/v1/version", None, VersionInfo)

    def _designs(self) -> _Call[DesignsResponse]:
        """The preset designs (``default`` first)."""
        return _Call("GET", "/v1/designs", None, DesignsResponse)

    def _fk(
        self, q: Sequence[float], assembly_mode: str | None = None, *, design: DesignLike = None
    ) -> _Call[FKResponse]:
        """Direct kinematics of q (rad): the postures in both assembly modes, or in the one
        given ('+' or '-')."""
        body = _validated(
            FKRequest, {"q": _floats(q), "assembly_mode": assembly_mode, "design": _design(design)}
        )
        return _Call("POST", "/v1/fk", body, FKResponse)

    def _ik(
        self, p: Sequence[float], working_mode: str = "any", *, design: DesignLike = None
    ) -> _Call[IKResponse]:
        """Inverse kinematics of P (m): one posture per working mode reaching it (or the one
        asked, e.g. '+-+')."""
        body = _validated(
            IKRequest, {"p": _floats(p), "working_mode": working_mode, "design": _design(design)}
        )
        return _Call("POST", "/v1/ik", body, IKResponse)

    def _analyze(
        self,
        q: Sequence[float],
        assembly_mode: str,
        *,
        qd: Sequence[float] | None = None,
        design: DesignLike = None,
    ) -> _Call[AnalyzeResponse]:
        """Jacobians, kappa(A), kappa(B), singularity margins and modes of one posture
        (and the velocity of P for joint rates ``qd``, rad/s)."""
        data: dict[str, Any] = {
            "q": _floats(q),
            "assembly_mode": assembly_mode,
            "design": _design(design),
        }
        if qd is not None:
            data["qd"] = _floats(qd)
        return _Call("POST", "/v1/analyze", _validated(AnalyzeRequest, data), AnalyzeResponse)

    def _check_design(
        self,
        design: DesignLike = None,
        *,
        kappa_max: float | None = None,
        rel_se: float | None = None,
        seed: int | None = None,
    ) -> _Call[DesignCheckResponse]:
        """Design check: parallel-singularity kinds and why, operative working modes,
        closed-form and sampled workspace volumes (absent options: the server's defaults)."""
        data: dict[str, Any] = {"design": _design(design)}
        for name, value in (("kappa_max", kappa_max), ("rel_se", rel_se), ("seed", seed)):
            if value is not None:
                data[name] = value
        body = _validated(DesignCheckRequest, data)
        return _Call("POST", "/v1/design/check", body, DesignCheckResponse)

    def _regions(
        self,
        design: DesignLike = None,
        *,
        margins: MarginsLike = None,
        resolution: int | None = None,
    ) -> _Call[RegionsResponse]:
        """Region map of a design: the connected regions of each working and assembly mode in
        the (theta2, theta3) grid and the transits joining them across serial surfaces.
        ``margins``: ``kappa_max``, ``serial_min`` (absent: the server's defaults);
        ``resolution``: cells per axis, 16 .. 512 (absent: 256)."""
        data: dict[str, Any] = {"design": _design(design)}
        if margins is not None:
            data["margins"] = _margins(margins)
        if resolution is not None:
            data["resolution"] = resolution
        body = _validated(RegionsRequest, data)
        return _Call("POST", "/v1/design/regions", body, RegionsResponse)

    def _plan(
        self, request: PlanRequest | Mapping[str, Any] | None = None, **fields: Any
    ) -> _Call[PlanResponse]:
        """Plan a motion: a :class:`PlanRequest` (or its dict), and/or its fields as keywords
        (``start=..., goal=..., obstacles=...``). A finished search returns its ``status``."""
        return _Call("POST", "/v1/plan", _request_body(PlanRequest, request, fields), PlanResponse)

    def _cartesian(
        self, request: CartesianRequest | Mapping[str, Any] | None = None, **fields: Any
    ) -> _Call[CartesianResponse]:
        """A straight tool path: P moves on straight segments from the start's P through
        ``waypoints`` (m) in the start's working mode, within ``path_tolerance`` (m, default
        1 mm). A :class:`CartesianRequest` (or its dict), and/or its fields as keywords
        (``start=..., waypoints=..., timing=..., limits=...``). The answer's ``status`` is
        ``solved`` exactly when ``fraction`` = 1; otherwise ``message`` and ``stop`` say which
        rule stopped it, the value measured and where."""
        if fields.get("waypoints") is not None:
            fields["waypoints"] = [_floats(w) for w in fields["waypoints"]]
        body = _request_body(CartesianRequest, request, fields)
        return _Call("POST", "/v1/cartesian", body, CartesianResponse)

    def _sequence(
        self, request: SequenceRequest | Mapping[str, Any] | None = None, **fields: Any
    ) -> _Call[SequenceResponse]:
        """A task sequence: one trajectory from ``start`` through ``targets`` (each
        ``{"goal", "stop", "blend"}``), back to the start with ``cycle=True``; a
        :class:`SequenceRequest` (or its dict), and/or its fields as keywords. The answer
        lists the ``legs`` with their time spans and the ``cycle_time``."""
        body = _request_body(SequenceRequest, request, fields)
        return _Call("POST", "/v1/sequence", body, SequenceResponse)

    def _put_scene(
        self, name: str, obstacles: Sequence[Any] = (), *, design: DesignLike = None
    ) -> _Call[SceneInfo]:
        """Store the scene ``name``: its obstacles (every type of a plan's, point clouds'
        ``points`` may be numpy arrays) and optionally its design; a scene of that name is
        replaced whole. The answer: its ``version`` and content ``hash``."""
        data: dict[str, Any] = {"obstacles": _obstacle_data(obstacles)}
        if design is not None:
            data["design"] = _design(design)
        return _Call("PUT", _scene_path(name), _validated(SceneRequest, data), SceneInfo)

    def _scene(self, name: str) -> _Call[Scene]:
        """The stored scene ``name`` (metadata and body); NotFoundError when there is none."""
        return _Call("GET", _scene_path(name), None, Scene)

    def _delete_scene(self, name: str) -> _Call[SceneInfo]:
        """Forget the scene ``name``; what the server kept about it."""
        return _Call("DELETE", _scene_path(name), None, SceneInfo)

    def _scenes(self) -> _Call[SceneList]:
        """Every stored scene's metadata, by name."""
        return _Call("GET", "/v1/scenes", None, SceneList)

    def _plan_batch(
        self, requests: Sequence[PlanRequest | Mapping[str, Any]]
    ) -> _Call[PlanBatchResponse]:
        """Many plan requests in one call; ``results`` come in the same order."""
        body = _validated(
            PlanBatchRequest,
            {
                "requests": [
                    r if isinstance(r, PlanRequest) else _validated(PlanRequest, r)
                    for r in requests
                ]
            },
        )
        return _Call("POST", "/v1/plan/batch", body, PlanBatchResponse)

    def _workspace(
        self,
        design: DesignLike = None,
        *,
        resolution: int | None = None,
        theta1: float | None = None,
        cartesian: bool | None = None,
        joint: bool | None = None,
        **options: Any,
    ) -> _Call[WorkspaceResponse]:
        """Workspace of a design: closed-form and sampled volumes (per working mode, well
        conditioned, GCI, with standard errors) and the Cartesian (u, w) and joint
        (theta2, theta3) sections as grids of ``resolution`` cells per axis. ``options``:
        ``rel_se``, ``kappa_max``, ``working_modes``, ``joint_limits``, ``seed``."""
        sections = {
            k: v
            for k, v in (
                ("resolution", resolution),
                ("theta1", theta1),
                ("cartesian", cartesian),
                ("joint", joint),
            )
            if v is not None
        }
        data: dict[str, Any] = {"design": _design(design), **options}
        if sections:
            data["sections"] = sections
        return _Call("POST", "/v1/workspace", _validated(WorkspaceRequest, data), WorkspaceResponse)

    def _figure(
        self,
        name: str,
        fmt: str = "png",
        *,
        design: DesignLike = None,
        resolution: int | None = None,
        dpi: int | None = None,
    ) -> _Call[bytes]:
        """A figure of a design as PNG or SVG bytes (``name``: e.g. ``"cartesian_section"``,
        ``"joint_section"``, ``"isoconditioning"``; an unknown name raises NotFoundError
        listing the names). Only L0, L1 and L2 of ``design`` are drawn."""
        d = _design(design)
        d = d.model_dump() if isinstance(d, DesignModel) else d
        data: dict[str, Any] = {k: d[k] for k in ("L0", "L1", "L2") if k in d}
        for k, v in (("resolution", resolution), ("dpi", dpi)):
            if v is not None:
                data[k] = v
        query = _validated(FigureQuery, data)
        if fmt not in ("png", "svg") or not name or "/" in name:
            raise InvalidRequestError(
                f"figure: fmt must be 'png' or 'svg' and name a figure name, got {name!r}.{fmt!r}",
                status_code=None,
            )
        params = query.model_dump(exclude_unset=True)
        return _Call("GET", f"/v1/figures/{name}.{fmt}", None, bytes, params=params)

    def _timing(
        self,
        waypoints: Any,
        *,
        design: DesignLike = None,
        method: str = "toppra",
        limits: Mapping[str, Any] | None = None,
        **options: Any,
    ) -> _Call[TimingResponse]:
        """Time-parameterise a joint path (N x 3 waypoints, rad) from rest to rest with
        ``method`` ('toppra' or 'ruckig') under ``limits`` (``velocity``, ``acceleration``,
        ``jerk``, ``cartesian_speed``). ``options``: ``assembly_mode``, ``sample_rate_hz``,
        ``max_deviation``, ``stop_at``, ``margins``, ``obstacles``, ``working_mode``. The
        answer's ``status`` is ``solved`` with a ``trajectory``, or why not."""
        data: dict[str, Any] = {
            "waypoints": [_floats(w) for w in waypoints],
            "design": _design(design),
            "method": method,
            **options,
        }
        if limits is not None:
            data["limits"] = {
                k: (_floats(v) if k != "cartesian_speed" else v) for k, v in dict(limits).items()
            }
        return _Call("POST", "/v1/timing", _validated(TimingRequest, data), TimingResponse)

    def _dynamics(
        self,
        q: Any,
        qd: Any = None,
        qdd: Any = None,
        *,
        design: DesignLike = None,
        assembly_mode: str = "+",
        gravity: Sequence[float] | None = None,
    ) -> _Call[DynamicsResponse]:
        """Inverse dynamics of N motions (q, qd, qdd: N x 3 each, rad, rad/s, rad/s^2; ``q``
        may be one posture, 3 numbers; ``qd``, ``qdd`` absent: zeros, a static query): the
        actuator torques ``tau`` (N m, always N rows) and mass matrices ``M(q)``; ``design``
        may carry ``inertia``; ``gravity`` m/s^2 (default [0, 0, -9.81])."""
        data: dict[str, Any] = {"design": _design(design), "assembly_mode": assembly_mode}
        for name, value in (("q", q), ("qd", qd), ("qdd", qdd)):
            if value is not None:
                data[name] = _rows(value)
        if gravity is not None:
            data["gravity"] = _floats(gravity)
        return _Call("POST", "/v1/dynamics", _validated(DynamicsRequest, data), DynamicsResponse)

    def _calibrate(
        self,
        measurements: Sequence[Mapping[str, Any]],
        *,
        design: DesignLike = None,
        identify: Sequence[str] | None = None,
        frame: Mapping[str, Any] | None = None,
    ) -> _Call[CalibrateResponse]:
        """Kinematic calibration from ``measurements`` (each ``{"q": [3] rad, "p": [3] m in
        the tracker's frame, "working_mode"?, "assembly_mode"?}``): the identified design,
        offsets, tracker frame, residuals, standard deviations and unidentified parameters
        (docs/calibration.md)."""
        data: dict[str, Any] = {
            "measurements": [
                {k: (_floats(v) if k in ("q", "p") else v) for k, v in dict(m).items()}
                for m in measurements
            ],
            "design": _design(design),
        }
        if identify is not None:
            data["identify"] = list(identify)
        if frame is not None:
            data["frame"] = {k: _floats(v) for k, v in dict(frame).items()}
        return _Call("POST", "/v1/calibrate", _validated(CalibrateRequest, data), CalibrateResponse)

    def _calibration_poses(
        self,
        n: int = 30,
        *,
        design: DesignLike = None,
        identify: Sequence[str] | None = None,
        seed: int = 0,
    ) -> _Call[CalibrationPosesResponse]:
        """``n`` postures worth measuring for a calibration, each with its modes."""
        data: dict[str, Any] = {"n": n, "design": _design(design), "seed": seed}
        if identify is not None:
            data["identify"] = list(identify)
        return _Call(
            "POST",
            "/v1/calibrate/poses",
            _validated(CalibrationPosesRequest, data),
            CalibrationPosesResponse,
        )

    def _identify(
        self,
        q: Any,
        qd: Any,
        qdd: Any,
        tau: Any,
        *,
        design: DesignLike = None,
        assembly_mode: str = "+",
        gravity: Sequence[float] | None = None,
        friction: bool = False,
    ) -> _Call[IdentifyResponse]:
        """Dynamic identification from measured motions and torques (N x 3 each): the
        identified ``inertia`` (a design.inertia), friction when asked, the unidentified
        parameters; ``design.inertia``, when given, is the prior."""
        data: dict[str, Any] = {
            "q": [_floats(r) for r in q],
            "qd": [_floats(r) for r in qd],
            "qdd": [_floats(r) for r in qdd],
            "tau": [_floats(r) for r in tau],
            "design": _design(design),
            "assembly_mode": assembly_mode,
            "friction": friction,
        }
        if gravity is not None:
            data["gravity"] = _floats(gravity)
        return _Call("POST", "/v1/identify", _validated(IdentifyRequest, data), IdentifyResponse)
    def _simulate(
        self,
        trajectory: Any = None,
        *,
        request: PlanRequest | SequenceRequest | Mapping[str, Any] | None = None,
        controller: str | Mapping[str, Any] = "computed_torque",
        design: DesignLike = None,
        **options: Any,
    ) -> _Call[SimulateResponse]:
        """Run a trajectory on the simulated robot (``POST /v1/simulate``, MuJoCo on the
        product's model): ``trajectory`` (a plan's answer trajectory in either form, a
        library trajectory, or a mapping with ``t``, ``q``, ``qd``, ``qdd``) or ``request``
        (a plan or sequence request, planned first; its robot is the simulated one).
        ``controller``: ``"computed_torque"``, ``"pd"`` or ``{"kind", "kp", "kd"}``.
        ``options``: ``rate_hz``, ``limits`` (``{"torque": [3]}``), ``gravity``,
        ``assembly_mode``, ``settle_tolerance_mm``, ``hold_s``. The answer: the realised
        samples, the ``tracking`` error, ``settle_times``, the planned and realised
        durations."""
        body = _simulate_body(trajectory, request, controller, design, options)
        return _Call("POST", "/v1/simulate", body, SimulateResponse)

    def _simulate_bag(
        self,
        trajectory: Any = None,
        *,
        request: PlanRequest | SequenceRequest | Mapping[str, Any] | None = None,
        controller: str | Mapping[str, Any] = "computed_torque",
        design: DesignLike = None,
        **options: Any,
    ) -> _Call[bytes]:
        """The same run as :meth:`simulate`, answered as a ROS 2 bag (``POST
        /v1/simulate/bag``): the MCAP file's bytes (``docs/simulation.md``)."""
        body = _simulate_body(trajectory, request, controller, design, options)
        return _Call("POST", "/v1/simulate/bag", body, bytes)

    def _design_mjcf(
        self,
        design: DesignLike = None,
        *,
        assembly_mode: str = "+",
        gravity: Sequence[float] | None = None,
        home: Sequence[float] | None = None,
    ) -> _Call[bytes]:
        """The robot as an MJCF model for MuJoCo (``POST /v1/design/mjcf``), as the XML's
        bytes (``mujoco.MjModel.from_xml_string(answer.decode())``): ``design`` may carry
        ``inertia``; ``home`` the keyframe's joints (rad), assembled in ``assembly_mode``."""
        data: dict[str, Any] = {"design": _design(design), "assembly_mode": assembly_mode}
        if gravity is not None:
            data["gravity"] = _floats(gravity)
        if home is not None:
            data["home"] = _floats(home)
        return _Call("POST", "/v1/design/mjcf", _validated(MjcfRequest, data), bytes)

    def _optimize_design(
        self, objective: str = "volume", *, design: DesignLike = None, **options: Any
    ) -> _Call[DesignOptimizeResponse]:
        """Maximise ``objective`` ('volume', 'well_conditioned_volume' or 'gci') over the link
        lengths; ``design`` is the template (link radius, joint limits) of the candidates.
        ``options``: ``reach``, ``L0_bounds``, ``L1_bounds``, ``L2_bounds``, ``kappa_max``,
        ``n_samples``, ``maxiter``, ``seed``."""
        data = {"objective": objective, "design": _design(design), **options}
        body = _validated(DesignOptimizeRequest, data)
        return _Call("POST", "/v1/design/optimize", body, DesignOptimizeResponse)

    def _submit_job(self, kind: str, request: BaseModel | Mapping[str, Any]) -> _Call[JobStatus]:
        """Run an endpoint's request as a long job (``kind``: one of
        :data:`planner.wire.JOB_KINDS`, e.g. ``"design_optimize"``; ``request``: that
        endpoint's body, a wire model or a mapping): its :class:`JobStatus` (``id``, ``status``
        ``queued`` or ``running``). Poll with :meth:`job`, cancel with :meth:`cancel_job`."""
        data = (
            request.model_dump(mode="json", exclude_unset=True)
            if isinstance(request, BaseModel)
            else dict(request)
        )
        body = _validated(JobRequest, {"kind": kind, "request": data})
        return _Call("POST", "/v1/jobs", body, JobStatus, frozenset({202}))

    def _job(self, job_id: str) -> _Call[JobStatus]:
        """A long job's status; with status ``done``, ``result`` is the endpoint's response
        body (parse it with the endpoint's response model, e.g.
        ``DesignOptimizeResponse.model_validate(status.result)``)."""
        return _Call("GET", f"/v1/jobs/{job_id}", None, JobStatus)

    def _jobs(self) -> _Call[JobList]:
        """The long jobs of this client's tenant still kept, oldest first (id, kind, status,
        times; no results: :meth:`job`)."""
        return _Call("GET", "/v1/jobs", None, JobList)

    def _cancel_job(self, job_id: str) -> _Call[JobStatus]:
        """Cancel a queued or running long job (its worker is freed at once)."""
        return _Call("DELETE", f"/v1/jobs/{job_id}", None, JobStatus)
