"""The diagnostics of a motion's answer (``diagnostics`` of a plan, sequence, straight path or
timing response): the timings, the margins met, why a path could not be timed and how a
moving start joined its trajectory. Response models only: a request never carries them.
"""

from __future__ import annotations

from pydantic import Field

from planner.wire.common import Vec3, _Response

__all__ = ["DiagnosticsModel", "LeadInModel", "TimingErrorInfo"]


class TimingErrorInfo(_Response):
    """Why a path could not be timed (``diagnostics.timing_error``): the error's type, and for
    a failed dense re-check the rule, the time (s) and joints (rad) of the first failing
    sample; ``index`` names the waypoint of ``POST /v1/timing`` that breaks a validity rule."""

    type: str = Field(description="TimingInfeasibleError, TrajectoryCheckError, InvalidWaypoint...")
    rule: str | None = Field(
        None,
        description="validity, joint_limits, velocity, acceleration, jerk, cartesian_speed or "
        "assembly.",
    )
    time: float | None = Field(None, description="Time of the first failing sample, s.")
    q: Vec3 | None = Field(None, description="Joints of the first failing sample, rad.")
    index: int | None = Field(None, ge=0, description="The failing waypoint (POST /v1/timing).")


class LeadInModel(_Response):
    """How a moving start joined its trajectory (docs/execution.md): the lead-in's
    ``duration`` (s, from the start), the time ``joins_at`` of the rest-to-rest timing where
    it joins it (s), and ``kind``: "direct" (one move onto the path) or "brake_and_return"."""

    duration: float
    joins_at: float
    kind: str


class DiagnosticsModel(_Response):
    """Timings and margins met, every field declared (an unknown one, from a newer server, is
    ignored like any response field). A quantity that does not apply is ``null``."""

    planning_time_s: float | None = Field(None, description="Wall time of the plan, s.")
    timing_time_s: float | None = Field(None, description="Wall time of the timing, s.")
    min_clearance: float | None = Field(
        None,
        description="Least link-obstacle distance at the path's postures sampled every 0.02 "
        "rad, m (null: no obstacle). A sampled reading: between samples the distance can be "
        "lower (by up to 1.5 cm measured where it is large); the rule clearance >= "
        "margins.clearance itself is certified along the whole path.",
    )
    max_kappa_A: float | None = Field(None, description="Largest kappa(A) along the path.")
    min_serial_margin: float | None = Field(
        None, description="Smallest serial measure along the path."
    )
    path_length: float | None = Field(
        None, description="Sum of joint-space distances between waypoints, rad."
    )
    planner: str | None = Field(
        None, description="Planner that found the path ('direct': the straight motion)."
    )
    timing_repairs: int | None = Field(
        None, ge=0, description="Repair rounds of the timing (0: the first trajectory passed)."
    )
    timing_error: TimingErrorInfo | None = Field(
        None, description="Why the path could not be timed (status no_path / invalid_path)."
    )
    proven_infeasible: bool = Field(
        False,
        description="True only with status no_path, when the product proved that no valid "
        "path exists (not merely that the search budget ran out).",
    )
    max_torque_ratio: float | None = Field(
        None,
        description="Largest |tau_j| / limits.torque[j] over the checked samples (<= 1 when "
        "the torque limits hold); null without limits.torque.",
    )
    lead_in: LeadInModel | None = Field(
        None, description="A moving start's lead-in onto the path (null: started at rest)."
    )
