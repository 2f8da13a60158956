"""Service settings, read from environment variables prefixed ``PLANNER_``.

========================  ==============================  ======================================
variable                  default                         meaning
========================  ==============================  ======================================
PLANNER_HOST              127.0.0.1                       interface to bind
PLANNER_PORT              8000                            TCP port
PLANNER_WORKERS           number of CPUs                  worker processes for CPU-bound work
PLANNER_QUEUE_SIZE        4 per worker                    jobs allowed to wait; beyond: 503
PLANNER_REQUEST_TIMEOUT_S 30                              time budget of one request, s
PLANNER_MAX_BODY_BYTES    32 MiB                          largest request body; beyond: 413
PLANNER_INLINE_PARSE_BYTES 64 KiB                         a larger body is parsed in a worker
PLANNER_MAX_BATCH         64                              plan requests in one batch
PLANNER_MAX_OBSTACLES     256                             obstacles in one plan request
PLANNER_MAX_SEQUENCE_TARGETS 64                           targets in one sequence request
PLANNER_RETRY_AFTER_S     1                               Retry-After of a 503, s
PLANNER_MAX_SECTION_RESOLUTION 256                        cells per axis of a section or figure
PLANNER_API_KEY           (none)                          when set, required on /v1 but health
                                                          (one tenant, ``default``)
PLANNER_API_KEYS          (none)                          tenants and their keys: a file of
                                                          'tenant key' lines, or tenant:key,...
PLANNER_ALLOWED_HOSTS     loopback names (keyless), any   Host names answered (comma-separated,
                          (with a key)                    ``*``: any); others: 400
PLANNER_LOG_LEVEL         info                            debug, info, warning, error, critical
PLANNER_LOG_FORMAT        json                            json (one object a line) or text
PLANNER_HEADER_TIMEOUT_S  10                              time to send the request line and headers, s
PLANNER_SEND_TIMEOUT_S    30                              time a client has to take a buffered answer, s
PLANNER_DRAIN_S           5                               on SIGTERM: still listening, ready 503, s
PLANNER_SHUTDOWN_TIMEOUT_S 30                             grace for in-flight work after the drain, s
PLANNER_METRICS           true                            serve Prometheus metrics at /metrics
PLANNER_DEFAULT_DESIGN    default                         design of a request without one: a
                                                          preset name or a JSON design object
PLANNER_OVERRUN_GRACE_S   0.5                             a job computing this long (CPU) past
                                                          its deadline has its worker killed, s
PLANNER_OVERRUN_MAX_S     max(5, 2 x the grace)           ... or running this long (wall), s
PLANNER_WORKER_MAX_RSS_MB 2048                            a worker holding more memory after a
                                                          job is recycled (0: never), MB
PLANNER_CACHE_MB          1024                            budget of each process's caches, MiB
                                                          (below PLANNER_WORKER_MAX_RSS_MB)
PLANNER_JOB_TIMEOUT_S     600                             time budget of one long job, s
PLANNER_JOB_TTL_S         3600                            a finished long job is kept this long
PLANNER_MAX_JOBS          256                             long jobs kept (finished or not)
PLANNER_JOB_RESULT_MAX_MB 32                              largest result of one long job, MB
PLANNER_JOBS_MAX_MB       512                             long jobs' results kept in all, MB
PLANNER_JOBS_RUNNING      half the workers (at least 1)   long jobs running at once (a replica)
PLANNER_JOBS_PER_TENANT   half PLANNER_MAX_JOBS (>= 1)    unfinished long jobs of one tenant; 429
PLANNER_SCENE_STORE       (a SQLite file, see below)      where named scenes and long jobs persist:
                                                          a SQLite file, or a postgresql:// URL
PLANNER_STORE_TIMEOUT_S   3                               longest wait of a scene-store call (a
                                                          lock, a connection); beyond: 503, s
PLANNER_STORE_THREADS     4                               store calls at once (reads, writes
                                                          each); 4 more a thread wait; then 503
PLANNER_SCENES_MAX        1000                            scenes per tenant; beyond: 422
PLANNER_SCENE_BYTES_MAX   1 GiB                           stored scene bytes per tenant; 413
========================  ==============================  ======================================

Without ``PLANNER_SCENE_STORE`` scenes live in ``$XDG_DATA_HOME/planner/scenes.sqlite3``
(``~/.local/share/planner/...``), created on the first scene request.
"""

from __future__ import annotations

import ipaddress
import json
import os
from functools import lru_cache
from typing import Literal

from pydantic import (
    Field,
    PrivateAttr,
    SecretStr,
    ValidationError,
    field_validator,
    model_validator,
)
from pydantic_settings import BaseSettings, SettingsConfigDict

from planner.caching import DEFAULT_BUDGET_MB
from planner.design import PRESET_NAMES, Design
from planner.exceptions import DesignError
from planner.wire import (
    MAX_BATCH_REQUESTS,
    MAX_OBSTACLES,
    MAX_SECTION_RESOLUTION,
    MAX_SEQUENCE_TARGETS,
    DesignModel,
)
from planner_api.tenants import DEFAULT_TENANT, parse_api_keys

__all__ = ["LOOPBACK_HOSTS", "Settings", "parse_allowed_hosts"]

#: The default ``allowed_hosts`` of a service without an API key: the names a client on the
#: same machine uses (a browser's ``localhost``, the image's health check's ``127.0.0.1``).
LOOPBACK_HOSTS = frozenset({"localhost", "127.0.0.1", "[::1]"})


def _cpu_count() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


class Settings(BaseSettings):
    """Settings of one service process (environment variables ``PLANNER_<NAME>``)."""

    # hide_input_in_errors: an error must not print PLANNER_API_KEY(S) back into a log
    model_config = SettingsConfigDict(
        env_prefix="PLANNER_", extra="ignore", hide_input_in_errors=True
    )

    host: str = Field("127.0.0.1", description="Interface to bind.")
    port: int = Field(8000, ge=1, le=65535, description="TCP port.")
    workers: int = Field(
        default_factory=_cpu_count,
        ge=1,
        le=256,
        description="Worker processes running the CPU-bound work (default: the usable CPUs).",
    )
    queue_size: int | None = Field(
        None,
        ge=0,
        le=100_000,
        description="Jobs allowed to wait for a worker; one more is answered 503 "
        "(default: 4 per worker).",
    )
    request_timeout_s: float = Field(
        30.0, gt=0.0, le=3600.0, allow_inf_nan=False, description="Time budget of one request, s."
    )
    body_timeout_s: float = Field(
        10.0,
        gt=0.0,
        le=3600.0,
        allow_inf_nan=False,
        description="Time a client has to send its whole request body, s (at most the request "
        "budget); a slower or stalled body is answered 408 and its connection closed.",
    )
    header_timeout_s: float = Field(
        10.0,
        gt=0.0,
        le=3600.0,
        allow_inf_nan=False,
        description="Time a connection has to send a request's line and headers, s (from "
        "its opening, or from the previous answer of a keep-alive connection); a slower one is "
        "answered 408 and closed (planner_api.protocol).",
    )
    send_timeout_s: float = Field(
        30.0,
        gt=0.0,
        le=3600.0,
        allow_inf_nan=False,
        description="Time a client has to take an answer the service could not hand to the "
        "socket at once (the connection's write buffer drained), s; a client that reads more "
        "slowly has its connection aborted and the answer's bytes dropped.",
    )
    max_body_bytes: int = Field(
        32 * 1024 * 1024,
        ge=1024,
        le=1024**3,
        description="Largest request body, bytes (the default lets in a point cloud of "
        "planner.constants.MAX_POINTS points, about 65 bytes each at full precision).",
    )
    max_response_bytes: int = Field(
        32 * 1024 * 1024,
        ge=64 * 1024,
        le=1024**3,
        description="Largest answer, bytes: bounds the trajectory samples of one answer (and "
        "of each answer of a batch, which share it), decided before the samples are computed.",
    )
    max_trajectory_samples: int = Field(
        50_000,
        ge=2,
        le=1_000_000,
        description="Most trajectory samples in one answer (duration x timing.sample_rate_hz); "
        "beyond it a 422 names timing.sample_rate_hz and the count it would produce.",
    )
    max_batch: int = Field(64, ge=1, le=MAX_BATCH_REQUESTS, description="Plans in one batch.")
    max_obstacles: int = Field(
        256, ge=0, le=MAX_OBSTACLES, description="Obstacles in one plan request."
    )
    max_sequence_targets: int = Field(
        MAX_SEQUENCE_TARGETS,
        ge=1,
        le=MAX_SEQUENCE_TARGETS,
        description="Targets in one sequence request (PLANNER_MAX_SEQUENCE_TARGETS; beyond: "
        "422 at targets).",
    )
    retry_after_s: int = Field(1, ge=1, le=3600, description="Retry-After of a 503, s.")
    max_section_resolution: int = Field(
        256,
        ge=2,
        le=MAX_SECTION_RESOLUTION,
        description="Cells per axis of a workspace section or a figure's grid (beyond: 422).",
    )
    api_key: SecretStr | None = Field(
        None,
        description="When set, every /v1 route except /v1/health requires it "
        "(header X-API-Key or Authorization: Bearer); its tenant is 'default'.",
    )
    api_keys: SecretStr | None = Field(
        None,
        description="Tenants and their keys (planner_api.tenants): a file path (starting "
        "with /, ./, ../ or ~) of 'tenant key' lines (# comments), or an inline list "
        "'tenant:key,tenant:key'. Each key is a tenant; its scenes and long jobs are its own. "
        "Not together with PLANNER_API_KEY.",
    )

    log_level: Literal["debug", "info", "warning", "error", "critical"] = Field(
        "info", description="Least severity of the log lines written."
    )
    log_format: Literal["json", "text"] = Field(
        "json", description="json: one JSON object a line with the request id; text: for people."
    )
    drain_s: float = Field(
        5.0,
        ge=0.0,
        le=3600.0,
        allow_inf_nan=False,
        description="On SIGTERM/SIGINT: how long the service keeps listening and serving, "
        "its /v1/ready answering 503 'stopping' so that load balancers take it out, before it "
        "closes its listener, s (a second signal ends the drain at once).",
    )
    shutdown_timeout_s: float = Field(
        30.0,
        ge=0.0,
        le=3600.0,
        allow_inf_nan=False,
        description="After the drain: how long in-flight requests may finish before they "
        "are cancelled and the workers stopped, s.",
    )
    metrics: bool = Field(True, description="Serve Prometheus metrics at GET /metrics.")
    default_design: str = Field(
        "default",
        description="The robot of a request that sends no design: a preset name "
        f"({', '.join(PRESET_NAMES)}) or a JSON design object such as "
        '{"L0": 0, "L1": 0.4, "L2": 0.4}. A request\'s partial design takes its missing '
        "fields from it.",
    )
    overrun_grace_s: float = Field(
        0.5,
        ge=0.0,
        le=60.0,
        allow_inf_nan=False,
        description="A job that has computed this long (CPU time) past its deadline and still "
        "runs has its worker killed (SIGKILL) and replaced by a warm fork, s. CPU time, not "
        "wall time: on a busy machine a job that waits for a CPU gets its grace to stop by "
        "itself. The jobs check their deadline in every long loop; this bounds the rest (a "
        "native loop, a job that ignores it).",
    )
    overrun_max_s: float | None = Field(
        None,
        ge=0.0,
        le=600.0,
        allow_inf_nan=False,
        description="A job still running this long (wall time) after its deadline is killed "
        "whatever CPU it spent, s; at least PLANNER_OVERRUN_GRACE_S (default: the larger of "
        "5 s and twice the grace).",
    )
    worker_max_rss_mb: int = Field(
        2048,
        ge=0,
        le=1024**2,
        description="A worker whose resident memory after a job exceeds this many MB is "
        "recycled: a replacement warms up first, then the old worker stops (0: never).",
    )
    cache_mb: float = Field(
        DEFAULT_BUDGET_MB,
        ge=0.0,
        le=1024.0**2,
        allow_inf_nan=False,
        description="Budget of the caches of each process (a worker's packed scenes, region "
        "maps, corridor grids, figures; the server's resolved scenes), MiB, shared among them "
        "as planner.caching.CACHES says (0: nothing kept); below PLANNER_WORKER_MAX_RSS_MB.",
    )
    worker_nice: int = Field(
        5,
        ge=0,
        le=19,
        description="Added to the worker processes' niceness once they are warm (0: as the "
        "server): on a busy machine the event loop, which only parses and answers, runs ahead "
        "of the workers' computations, so probes and cheap requests are not kept waiting "
        "behind them.",
    )
    job_timeout_s: float = Field(
        600.0,
        gt=0.0,
        le=86400.0,
        allow_inf_nan=False,
        description="Time budget of one long job (POST /v1/jobs), s, from when it starts.",
    )
    job_ttl_s: float = Field(
        3600.0,
        gt=0.0,
        le=7 * 86400.0,
        allow_inf_nan=False,
        description="How long a finished long job's status and result are kept, s; then its "
        "id answers 404.",
    )
    max_jobs: int = Field(
        256,
        ge=1,
        le=100_000,
        description="Long jobs kept at once in the store (finished or not, every replica's): "
        "a new one evicts the oldest finished job; when none is finished, POST /v1/jobs "
        "answers 503.",
    )
    jobs_per_tenant: int | None = Field(
        None,
        ge=1,
        le=100_000,
        description="Unfinished (queued or running) long jobs one tenant may have at once, "
        "over every replica: one more is answered 429 too_many_jobs, so that one tenant "
        "cannot fill the job list for all (default: half PLANNER_MAX_JOBS, at least 1; at "
        "most PLANNER_MAX_JOBS).",
    )
    jobs_running: int | None = Field(
        None,
        ge=1,
        le=256,
        description="Long jobs running at once in each replica (the others wait, 'queued'), "
        "so that long jobs leave workers to the interactive requests (default: half the "
        "workers, at least 1).",
    )
    inline_parse_bytes: int = Field(
        65536,
        ge=0,
        le=1 << 30,
        description="Largest request body parsed on the event loop, bytes: a larger body of "
        "/v1/plan, /v1/plan/batch, /v1/sequence, /v1/cartesian, /v1/timing, PUT "
        "/v1/scenes/{name} or POST "
        "/v1/jobs is handed to "
        "a worker as bytes and "
        "parsed there (the same rules and 422s), so that large bodies never hold up the "
        "event loop; 0: every such body in a worker.",
    )
    job_result_max_mb: float = Field(
        32.0,
        gt=0.0,
        le=4096.0,
        allow_inf_nan=False,
        description="Largest result of one long job, MB (2^20 bytes): a trajectory job's "
        "samples are bounded by it before they are computed (a 422 naming "
        "timing.sample_rate_hz), any other result over it fails the job.",
    )
    jobs_max_mb: float = Field(
        512.0,
        gt=0.0,
        le=65536.0,
        allow_inf_nan=False,
        description="Results of long jobs kept at once in the store, MB in all: a new result "
        "evicts the oldest finished jobs until it fits.",
    )
    scene_store: str | None = Field(
        None,
        description="Where named scenes and long jobs persist: a SQLite file path (default "
        "$XDG_DATA_HOME/planner/scenes.sqlite3), or a postgresql:// URL shared by replicas.",
    )
    allowed_hosts: str | None = Field(
        None,
        description="The host names the service answers, comma-separated (no port, no "
        "scheme; '*': any): a request whose Host header (its port stripped) names another is "
        "answered 400, except the probes /v1/health and /v1/ready. Default: the loopback names "
        "(localhost, 127.0.0.1, ::1) without an API key, any with one. Against DNS "
        "rebinding: a web page that makes its own name resolve to 127.0.0.1 cannot drive a "
        "keyless service on the user's machine.",
    )
    store_timeout_s: float = Field(
        3.0,
        gt=0.0,
        le=300.0,
        allow_inf_nan=False,
        description="Longest wait of one scene-store call, s: SQLite's wait for a write lock, "
        "PostgreSQL's connection and lock waits; beyond it the request is answered 503 "
        "store_unavailable with Retry-After.",
    )
    store_threads: int = Field(
        4,
        ge=1,
        le=64,
        description="Threads of each of the scene store's own two pools (reads, writes): "
        "store calls running at once; 4 more per thread may wait, one more is answered 503 "
        "store_unavailable at once (never queued), so a stuck store cannot take the threads "
        "other routes need, nor writes stuck on a lock the threads of the reads.",
    )
    scenes_max: int = Field(
        1000,
        ge=1,
        le=10_000_000,
        description="Scenes one tenant may store; a PUT of a new name beyond it is a 422 "
        "naming PLANNER_SCENES_MAX.",
    )
    scene_bytes_max: int = Field(
        1024**3,
        ge=1024,
        le=1024**4,
        description="Bytes of scene bodies (their stored JSON) one tenant may store, summed "
        "over its scenes; a PUT beyond it is a 413 naming PLANNER_SCENE_BYTES_MAX.",
    )
    _design_defaults: DesignModel = PrivateAttr(default_factory=DesignModel)
    _custom_design: DesignModel | None = PrivateAttr(default=None)
    _tenant_keys: dict[str, str] | None = PrivateAttr(default=None)
    _hosts: frozenset[str] | None = PrivateAttr(default=None)

    @field_validator("allowed_hosts")
    @classmethod
    def _host_names(cls, value: str | None) -> str | None:
        if value is not None:
            parse_allowed_hosts(value)
        return value

    @field_validator("default_design")
    @classmethod
    def _known_design(cls, value: str) -> str:
        _parse_design(value)
        return value

    @field_validator("api_keys")
    @classmethod
    def _readable_keys(cls, value: SecretStr | None) -> SecretStr | None:
        if value is not None and value.get_secret_value().strip():
            parse_api_keys(value.get_secret_value())  # the error at api_keys, file and line
        return value

    @model_validator(mode="after")
    def _cache_below_recycle(self) -> Settings:
        """The caches' budget must leave a worker room under its memory bound: a worker
        whose caches filled would otherwise be recycled after every job."""
        if self.worker_max_rss_mb and self.cache_mb >= self.worker_max_rss_mb:
            raise ValueError(
                f"PLANNER_CACHE_MB ({self.cache_mb:g}) must be below PLANNER_WORKER_MAX_RSS_MB "
                f"({self.worker_max_rss_mb}): a worker whose caches filled would be recycled "
                "after every job (leave room for the libraries and the jobs' own memory)"
            )
        return self

    @model_validator(mode="after")
    def _fill_queue(self) -> Settings:
        if self.queue_size is None:
            self.queue_size = 4 * self.workers
        if self.jobs_running is None:
            self.jobs_running = max(1, self.workers // 2)
        if self.jobs_per_tenant is None:
            self.jobs_per_tenant = max(1, self.max_jobs // 2)
        elif self.jobs_per_tenant > self.max_jobs:
            raise ValueError(
                f"PLANNER_JOBS_PER_TENANT ({self.jobs_per_tenant}) must be at most "
                f"PLANNER_MAX_JOBS ({self.max_jobs}): a tenant's jobs are kept among them"
            )
        if self.overrun_max_s is not None and self.overrun_max_s < self.overrun_grace_s:
            raise ValueError(
                f"PLANNER_OVERRUN_MAX_S ({self.overrun_max_s:g}) must be at least "
                f"PLANNER_OVERRUN_GRACE_S ({self.overrun_grace_s:g})"
            )
        if self.job_result_max_mb > self.jobs_max_mb:
            raise ValueError(
                f"PLANNER_JOB_RESULT_MAX_MB ({self.job_result_max_mb:g}) must be at most "
                f"PLANNER_JOBS_MAX_MB ({self.jobs_max_mb:g}): a result must fit in the jobs' memory"
            )
        if self.api_key is not None and not self.api_key.get_secret_value():
            self.api_key = None  # PLANNER_API_KEY="" means no key
        if self.api_keys is not None and not self.api_keys.get_secret_value().strip():
            self.api_keys = None
        self._design_defaults = _parse_design(self.default_design)
        built_in = self._design_defaults == DesignModel()
        self._custom_design = None if built_in else self._design_defaults
        if self.api_keys is not None:
            if self.api_key is not None:
                raise ValueError(
                    "PLANNER_API_KEY and PLANNER_API_KEYS are both set: set one (to keep the "
                    f"single key, list it in PLANNER_API_KEYS as the tenant {DEFAULT_TENANT!r})"
                )
            self._tenant_keys = parse_api_keys(self.api_keys.get_secret_value())
        elif self.api_key is not None:
            self._tenant_keys = {self.api_key.get_secret_value(): DEFAULT_TENANT}
        if self.allowed_hosts is not None:
            self._hosts = parse_allowed_hosts(self.allowed_hosts)
        else:
            self._hosts = None if self.keyed else LOOPBACK_HOSTS
        return self

    @property
    def tenant_keys(self) -> dict[str, str] | None:
        """Every accepted key and its tenant (key -> tenant); None when no key is asked
        (every request is then the tenant ``default``)."""
        return self._tenant_keys

    @property
    def design_defaults(self) -> DesignModel:
        """The parsed ``default_design``: what a request's absent design fields take."""
        return self._design_defaults

    @property
    def custom_design_defaults(self) -> DesignModel | None:
        """:attr:`design_defaults` when they are not the built-in robot's, else None (a
        request's design has nothing to take from them): what crosses to a worker with a
        body, the built-in case costing no pickling."""
        return self._custom_design

    @property
    def keyed(self) -> bool:
        """Whether the service requires a key on its ``/v1`` routes (``PLANNER_API_KEY`` or
        ``PLANNER_API_KEYS``): the one place that says so for the settings' defaults
        (``allowed_hosts``)."""
        return self._tenant_keys is not None

    @property
    def host_names(self) -> frozenset[str] | None:
        """The Host names answered (lower case, an IPv6 address in brackets), or None for
        any: ``allowed_hosts`` parsed, or its default (:attr:`keyed`)."""
        return self._hosts


def parse_allowed_hosts(value: str) -> frozenset[str] | None:
    """The host names of a ``PLANNER_ALLOWED_HOSTS`` value (None: ``*``, any), as a request's
    Host header names them once its port is stripped: lower case, an IPv6 address in brackets
    (``::1`` and ``[::1]`` alike). ValueError naming the variable and the entry that breaks
    the rule (an empty one, a port, a scheme or a path)."""
    names: set[str] = set()
    for raw in value.split(","):
        name = raw.strip().lower().rstrip(".")
        if name == "*":
            return None
        rule = "PLANNER_ALLOWED_HOSTS: comma-separated host names without port or scheme"
        if not name:
            raise ValueError(f"{rule} ('*': any), got an empty name in {value!r}")
        bare = name[1:-1] if name.startswith("[") and name.endswith("]") else name
        if ":" in bare:  # only an IPv6 address holds a colon
            try:
                names.add(f"[{ipaddress.IPv6Address(bare)}]")
            except ValueError:
                raise ValueError(f"{rule}, got {raw.strip()!r}") from None
            continue
        if any(c in name for c in "/[]@ ") or "*" in name:
            raise ValueError(f"{rule}, got {raw.strip()!r}")
        names.add(name)
    return frozenset(names)


def _parse_design(value: str) -> DesignModel:
    """A preset name or a JSON design object as a wire design; ValueError naming the rule."""
    text = value.strip()
    if not text.startswith("{"):
        try:
            return DesignModel.from_design(Design.preset(text))
        except DesignError as exc:
            raise ValueError(f"{exc}, or a JSON design object") from exc
    try:
        return DesignModel.model_validate(json.loads(text))
    except (json.JSONDecodeError, ValidationError) as exc:
        raise ValueError(f"not a valid JSON design object: {exc}") from exc


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """The process's settings, read once (inject with ``Depends(get_settings)``)."""
    return Settings()
