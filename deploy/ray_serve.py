"""The service as a Ray Serve deployment, for a cluster of machines.

Ray Serve's FastAPI ingress wraps the very app of :func:`planner_api.app.create_app`: every route,
setting, error, metric and log line is the same as under ``planner serve``. Each replica is one
copy of the service with its own worker pool (``PLANNER_WORKERS`` processes, reserved as
``num_cpus`` of the replica's actor), so a replica is sized like one container, and Ray spreads
replicas over the cluster's machines and routes requests among them (the service is
stateless). Needs the optional extra: ``pip install 'hybrid-planner[ray]'``.

Run it::

    ray start --head                                   # or an existing cluster
    serve run deploy.ray_serve:app_builder num_replicas=2 workers=2   # PLANNER_* from env
    # or from Python
    from ray import serve
    from deploy.ray_serve import build
    serve.run(build(num_replicas=4, workers=2), route_prefix="/")

``/metrics`` of a request answers for the replica that served it; scrape each replica's
metrics through Ray's own metrics export or run the replicas as separate containers.
"""

from __future__ import annotations

from typing import Any

from ray import serve
from ray.serve.deployment import Application

from planner_api.settings import Settings

__all__ = ["PlannerDeployment", "app_builder", "build"]


def _app_builder(settings: dict[str, Any]) -> Any:
    """A builder evaluated on each replica: the FastAPI app of ``settings`` (fields of
    :class:`planner_api.settings.Settings`; the rest from the replica's PLANNER_* environment)."""

    def build_app() -> Any:
        from planner_api.app import create_app

        return create_app(Settings(**settings))

    return build_app


def build(
    *,
    num_replicas: int = 1,
    workers: int | None = None,
    max_ongoing_requests: int | None = None,
    **settings: Any,
) -> Application:
    """A bound Ray Serve application of the service.

    Parameters
    ----------
    num_replicas : int
        Copies of the service (each with its own worker pool).
    workers : int, optional
        Worker processes per replica (default: ``PLANNER_WORKERS`` or the CPUs); also the
        CPUs Ray reserves for the replica.
    max_ongoing_requests : int, optional
        Requests a replica accepts at once (default: its pool's capacity, workers + queue),
        so Ray queues the excess instead of the replica answering 503.
    **settings
        Other fields of :class:`planner_api.settings.Settings` (e.g. ``request_timeout_s=10``).
    """
    if workers is not None:
        settings["workers"] = workers
    resolved = Settings(**settings)  # validate here, on the driver, with a clear error
    capacity = resolved.workers + (resolved.queue_size or 0)
    deployment = serve.deployment(
        serve.ingress(_app_builder(settings))(PlannerDeployment),
        name="hybrid-planner",
        num_replicas=num_replicas,
        max_ongoing_requests=max_ongoing_requests or capacity,
        ray_actor_options={"num_cpus": resolved.workers},
        graceful_shutdown_timeout_s=resolved.shutdown_timeout_s,
    )
    return deployment.bind()


class PlannerDeployment:
    """The replica class: the routes all come from the ingress app."""


def app_builder(args: dict[str, str]) -> Application:
    """Ray Serve's application builder for ``serve run deploy.ray_serve:app_builder key=value
    ...``: ``num_replicas``, ``workers``, ``max_ongoing_requests`` and any field of
    :class:`planner_api.settings.Settings` (strings, converted and validated by the settings)."""
    args = dict(args)
    kwargs: dict[str, Any] = {}
    for key in ("num_replicas", "workers", "max_ongoing_requests"):
        if key in args:
            kwargs[key] = int(args.pop(key))
    return build(**kwargs, **args)
