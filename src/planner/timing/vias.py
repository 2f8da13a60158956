"""Pass-through corners timed as free via states: the trajectory passes within a ball.

A sequence's pass-through target asks the trajectory to pass within ``blend`` rad (joint
space) of the target's posture without stopping. Rounding the corner with a circular arc
(:mod:`planner.timing.path`) and following that arc (toppra, or Ruckig through the arc's
states) meets it, but the arc is small where a leg is short (a pick-and-place lift: about
0.09 rad), and the speed on an arc of radius r is at most about sqrt(a r). On the benchmark's
Adept cycle that leaves 18-20 % of the all-stops cycle time on the table against a lower bound
near 27 % (``docs/sequences.md``): the time is lost on the path, not on the limits.

Here such a corner is a *via state*: a posture within the ball of radius ``blend`` around the
vertex, and a velocity, both free, chosen for time. A rest-to-rest section whose interior
vertices are all vias (a pick-and-place cycle's straight legs) becomes a chain of Ruckig moves
from rest, through each via state, to rest: second-order moves (acceleration-limited, jerk
unbounded: the limits toppra times under) for ``toppra``, jerk-limited ones for ``ruckig``.
Each move is Ruckig's time-optimal synchronised move between its two states, so the chain's
duration is the sum of their durations, a function of the via states alone; it is minimised
by Nelder-Mead per via (its offset in the ball and its velocity, the two moves next to it),
one sweep in path order, from two starts per via (the arc's own state, toppra's profile at
the arc's middle, and a point half-way into the ball along the corner's bisector), keeping
the fastest result whose two moves stay within the allowance (sampled).
Exact for a given set of via states, the chain is a feasible trajectory of the time-optimal
problem "pass within each ball", so its duration bounds that problem's optimum from above;
the per-joint bound of ``benchmarks/sequences.py`` bounds it from below.

The chain is kept only when it is faster than the blended path's section, and only after the
same dense re-check (validity, joint limits, assembly, the limits, the deviation allowance);
a chain that fails it is dropped for that section, which is timed on the blended path again
(:func:`planner.timing.parameterize.time_path`'s repair loop). Between its via states a move
leaves the planned segments (as a Ruckig move around a blend does): its postures stand for
the segments next to its vias and may be as far from them as the smaller of the vias' balls.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, RuckigError
from ruckig import Trajectory as RuckigTrajectory
from scipy.optimize import minimize

from planner.timing.checks import CheckReport
from planner.timing.limits import JointLimits
from planner.timing.path import BlendedPath, distance_to_polyline
from planner.timing.ruckig_method import RuckigCurve, _moves_from
from planner.timing.toppra_method import PathProfile, check_deadline
from planner.timing.trajectory import Curve, TimeScaledCurve

__all__ = [
    "MAX_VIAS",
    "VIA_ITERATIONS",
    "SplicedCurve",
    "ViaSection",
    "build_via_chain",
    "drop_failed_vias",
    "splice_vias",
    "via_sections",
]

#: Nelder-Mead iterations per via state (6 unknowns). On the benchmark cycle 120 come within
#: 0.1 % of a global search (differential evolution) and cost about 800 moves per two vias.
VIA_ITERATIONS = 120
#: Most vias in a section timed as a chain: a pick-and-place cycle has two per section (its
#: top corners); a longer run of pass-through targets keeps the blended path's timing. Why:
#: each via costs some 20-40 ms of moves on the benchmark machine, and on a 12-target ring
#: (blend 0.01 rad) the chain, 10 % faster, strayed from the 0.01 rad allowance between its
#: vias (each via's moves are checked only against its neighbours' earlier states), so the
#: re-check dropped it after 0.4 s of work.
MAX_VIAS = 4
#: Sweeps over the vias of a section (each via's moves depend on its neighbours' states).
SWEEPS = 1
#: States are pulled this far inside the limits and the ball (relative), as in the Ruckig chain.
_INSIDE = 1.0 - 1e-9
#: Postures per move at which a chosen via state's moves are checked against the allowance.
_DEVIATION_SAMPLES = 32
#: A move Ruckig refuses costs this much (s): the search steps away from it.
_REFUSED = 1e3


@dataclass(frozen=True, eq=False)
class ViaSection:
    """A rest-to-rest section of a blended path whose interior vertices are all vias.

    ``vertices``: merged-waypoint indices from the resting start to the resting end;
    ``s_start``, ``s_end``: the section's path positions (the rests)."""

    vertices: tuple[int, ...]
    s_start: float
    s_end: float


def via_sections(path: BlendedPath, via: np.ndarray) -> list[ViaSection]:
    """The sections of ``path`` (between consecutive rests) with 1 to :data:`MAX_VIAS`
    interior vertices, every one of them a via (``via``: bool per merged waypoint)."""
    out = []
    vs = path.vertex_s
    for lo, hi in zip(path.stops[:-1], path.stops[1:], strict=True):
        first = int(np.flatnonzero(np.isclose(vs, lo, rtol=0.0, atol=1e-12))[-1])
        last = int(np.flatnonzero(np.isclose(vs, hi, rtol=0.0, atol=1e-12))[0])
        inner = list(range(first + 1, last))
        if 0 < len(inner) <= MAX_VIAS and all(bool(via[k]) for k in inner):
            out.append(ViaSection((first, *inner, last), float(lo), float(hi)))
    return out


class _Mover:
    """One Ruckig instance for the durations of candidate moves (lists in, the lean path)."""

    def __init__(self, limits: JointLimits, jerk: bool) -> None:
        self.otg = Ruckig(3)
        self.inp = InputParameter(3)
        self.inp.max_velocity = limits.velocity_array.tolist()
        self.inp.max_acceleration = limits.acceleration_array.tolist()
        j = limits.jerk_array if jerk else None
        self.inp.max_jerk = [math.inf] * 3 if j is None else j.tolist()
        self.traj = RuckigTrajectory(3)
        self.zero = [0.0, 0.0, 0.0]
        self.calls = 0

    def move(self, p0: list, v0: list, p1: list, v1: list) -> RuckigTrajectory | None:
        inp = self.inp
        inp.current_position, inp.current_velocity, inp.current_acceleration = p0, v0, self.zero
        inp.target_position, inp.target_velocity, inp.target_acceleration = p1, v1, self.zero
        self.calls += 1
        traj = RuckigTrajectory(3)
        try:
            result = self.otg.calculate(inp, traj)
        except RuckigError:
            return None
        return traj if result in (Result.Working, Result.Finished) else None

    def duration(self, p0: list, v0: list, p1: list, v1: list) -> float:
        inp = self.inp
        inp.current_position, inp.current_velocity, inp.current_acceleration = p0, v0, self.zero
        inp.target_position, inp.target_velocity, inp.target_acceleration = p1, v1, self.zero
        self.calls += 1
        try:
            result = self.otg.calculate(inp, self.traj)
        except RuckigError:
            return _REFUSED
        if result not in (Result.Working, Result.Finished):
            return _REFUSED
        return float(self.traj.duration)


def _in_ball(offset: np.ndarray, radius: float) -> np.ndarray:
    """``offset`` projected into the ball of ``radius`` (pulled inside by :data:`_INSIDE`)."""
    r = radius * _INSIDE
    n = float(np.linalg.norm(offset))
    return offset if n <= r else offset * (r / n)


def build_via_chain(
    path: BlendedPath,
    profile: PathProfile,
    section: ViaSection,
    radius: np.ndarray,
    limits: JointLimits,
    *,
    jerk: bool,
    corridor: np.ndarray | None = None,
    iterations: int = VIA_ITERATIONS,
    deadline: float | None = None,
) -> tuple[RuckigCurve, int]:
    """The chain of Ruckig moves through optimised via states over ``section`` (module
    docstring), and the number of moves solved.

    Parameters
    ----------
    path, profile : the blended path and its toppra profile (the starting via states: each
        via's arc middle, at toppra's velocity there).
    section : from :func:`via_sections`.
    radius : shape (N,), rad -- each merged waypoint's ball (where a via's posture may lie).
    corridor : shape (N,), rad -- how far a via's moves may stray from the segments they
        stand for (default ``radius``: the requested allowance).
    limits : velocity and acceleration (and jerk with ``jerk``).
    jerk : jerk-limited moves (``ruckig``) or second-order ones (``toppra``).
    iterations : Nelder-Mead iterations per via.
    deadline : ``time.monotonic()`` value checked before each via.

    Raises
    ------
    TimingInfeasibleError
        Ruckig has no move between two chosen states (cannot happen from the starting ones,
        which are toppra's, pulled inside the limits).
    """
    mover = _Mover(limits, jerk)
    chain = _ViaChain(
        path, profile, section, radius, radius if corridor is None else corridor, limits, mover
    )
    for i in [*range(1, len(section.vertices) - 1)] * SWEEPS:
        check_deadline(deadline, "while choosing via states")
        chain.choose(i, iterations)
    return chain.curve(limits), mover.calls


class _ViaChain:
    """The via states of one section while :func:`build_via_chain` chooses them: per vertex
    of the section (the resting ends included), its offset in its ball (rad) and its
    velocity (rad/s), first those of toppra's profile at each via's arc middle; then one via
    at a time (:meth:`choose`), and the chain of moves through them (:meth:`curve`)."""

    def __init__(
        self,
        path: BlendedPath,
        profile: PathProfile,
        section: ViaSection,
        radius: np.ndarray,
        corridor: np.ndarray,
        limits: JointLimits,
        mover: _Mover,
    ) -> None:
        self.mover = mover
        self.w = path.waypoints
        self.ks = ks = section.vertices
        self.radius = radius
        self.corridor = corridor
        self.v_max = v_max = limits.velocity_array * _INSIDE
        self.vertex = [self.w[k] for k in ks]
        self.offset = [np.zeros(3) for _ in ks]
        self.vel = [np.zeros(3) for _ in ks]
        s_mid = np.array([path.vertex_s[k] for k in ks[1:-1]])
        q_mid = path.evaluate(s_mid, 0)
        tangent = path.evaluate(s_mid, 1)
        _, sd, _ = profile.at_path(s_mid)
        for i in range(1, len(ks) - 1):
            self.offset[i] = _in_ball(q_mid[i - 1] - self.vertex[i], float(radius[ks[i]]))
            self.vel[i] = np.clip(tangent[i - 1] * sd[i - 1], -v_max, v_max)

    def state(self, i: int, o: np.ndarray, v: np.ndarray) -> tuple[list, list]:
        """Vertex i's posture at offset ``o`` (projected into its ball) and velocity ``v``,
        as lists for Ruckig."""
        return (self.vertex[i] + _in_ball(o, float(self.radius[self.ks[i]]))).tolist(), v.tolist()

    def near_plan(self, i: int, z: np.ndarray) -> bool:
        """The moves into and out of via i at ``z`` stay within the smaller corridor of
        their vias from the segments they stand for (at :data:`_DEVIATION_SAMPLES` points)."""
        ks, corridor, offset, vel = self.ks, self.corridor, self.offset, self.vel
        here = self.state(i, z[:3], np.clip(z[3:], -self.v_max, self.v_max))
        ends = ((self.state(i - 1, offset[i - 1], vel[i - 1]), here, i - 1, i),
                (here, self.state(i + 1, offset[i + 1], vel[i + 1]), i, i + 1))  # fmt: skip
        for a, b, j0, j1 in ends:
            traj = self.mover.move(*a, *b)
            if traj is None:
                return False
            tau = np.linspace(0.0, traj.duration, _DEVIATION_SAMPLES)
            q = np.array([traj.at_time(float(x))[0] for x in tau])
            inner = [j for j in (j0, j1) if 0 < j < len(ks) - 1]
            allowed = min(float(corridor[ks[j]]) for j in inner)
            seg = np.tile([ks[min(inner)] - 1, ks[max(inner)]], (q.shape[0], 1))
            if np.max(distance_to_polyline(self.w, q, seg)[0]) > allowed * _INSIDE:
                return False
        return True

    def cost_of(self, i: int) -> Callable[[np.ndarray], float]:
        """The duration of the two moves next to via i as a function of its state z (6,):
        offset and velocity, the neighbours' states as they are now."""
        before = self.state(i - 1, self.offset[i - 1], self.vel[i - 1])
        after = self.state(i + 1, self.offset[i + 1], self.vel[i + 1])
        r_i = float(self.radius[self.ks[i]])
        corner, r_in, v_lim = self.vertex[i].tolist(), r_i * _INSIDE, self.v_max.tolist()
        duration = self.mover.duration

        def cost(z: np.ndarray) -> float:
            # plain floats: this runs some 500 times per via. Outside the ball or the
            # velocity limits: projected, with a penalty that points back inside (so the
            # simplex does not wander off)
            o0, o1, o2, *v = z.tolist()
            n = math.sqrt(o0 * o0 + o1 * o1 + o2 * o2)
            penalty = max(0.0, n - r_i)
            f = 1.0 if n <= r_in else r_in / n
            here = [corner[0] + f * o0, corner[1] + f * o1, corner[2] + f * o2]
            for j in range(3):
                if abs(v[j]) > v_lim[j]:
                    penalty += abs(v[j]) - v_lim[j]
                    v[j] = math.copysign(v_lim[j], v[j])
            return duration(*before, here, v) + duration(here, v, *after) + (10.0 * penalty)

        return cost

    def starts(self, i: int) -> list[np.ndarray]:
        """The searches' starts for via i: the arc's own state, and a state half-way into
        the ball along the corner's bisector, moving along the corner at half the speed
        limit (the cost has local minima: a jerk-limited chain from the arc's state alone
        stays 2 % slower on the benchmark cycle)."""
        vertex, r_i = self.vertex, float(self.radius[self.ks[i]])
        starts = [np.concatenate([self.offset[i], self.vel[i]])]
        u_in, u_out = vertex[i] - vertex[i - 1], vertex[i + 1] - vertex[i]
        inward = u_out / np.linalg.norm(u_out) - u_in / np.linalg.norm(u_in)
        along = u_out / np.linalg.norm(u_out) + u_in / np.linalg.norm(u_in)
        if np.linalg.norm(inward) > 1e-9 and np.linalg.norm(along) > 1e-9:
            inward, along = inward / np.linalg.norm(inward), along / np.linalg.norm(along)
            starts.append(np.concatenate([0.5 * r_i * inward, 0.5 * self.v_max * along]))
        return starts

    def choose(self, i: int, iterations: int) -> None:
        """Via i's state: each start searched (Nelder-Mead, ``iterations``), the fastest of
        the starts and the ends whose two moves stay within the allowance (sampled: the dense
        re-check decides), else the arc's own state."""
        cost = self.cost_of(i)
        starts = self.starts(i)
        found = [starts[0], *starts[1:]]
        for z0 in starts:
            found.append(
                minimize(
                    cost,
                    z0,
                    method="Nelder-Mead",
                    options={"maxiter": iterations, "xatol": 1e-7, "fatol": 1e-10},
                ).x
            )
        z = starts[0]
        for cand in sorted(found, key=cost):
            if self.near_plan(i, cand):
                z = cand
                break
        self.offset[i] = _in_ball(z[:3], float(self.radius[self.ks[i]]))
        self.vel[i] = np.clip(z[3:], -self.v_max, self.v_max)

    def curve(self, limits: JointLimits) -> RuckigCurve:
        """The chain of moves through the chosen states, from rest to rest.

        Raises
        ------
        TimingInfeasibleError
            Ruckig has no move between two chosen states.
        """
        from planner.exceptions import TimingInfeasibleError

        ks, offset, vel = self.ks, self.offset, self.vel
        trajs, corners = [], []
        for i in range(len(ks) - 1):
            traj = self.mover.move(
                *self.state(i, offset[i], vel[i]), *self.state(i + 1, offset[i + 1], vel[i + 1])
            )
            if traj is None:
                raise TimingInfeasibleError("ruckig found no move between two via states")
            trajs.append(traj)
            corners.append(tuple(k for k in (ks[i], ks[i + 1]) if k not in (ks[0], ks[-1])))
        moves = _moves_from(trajs, corners)
        start = np.concatenate([[0.0], np.cumsum([m.duration for m in moves])])
        return RuckigCurve(moves, start, float(np.linalg.norm(limits.velocity_array)))


@dataclass(frozen=True, eq=False)
class SplicedCurve:
    """``base`` with some of its rest-to-rest sections replaced by other curves (via chains).

    ``parts``: per replaced section, (start, end) on ``base``'s time axis (two of its rests)
    and the curve that replaces it (from rest to rest between the same postures); ``keys``
    names each replaced section (its vertices), so that a repair can drop it. The time axis
    is ``base``'s, shifted after each replacement by how much shorter it is."""

    base: Curve
    parts: tuple[tuple[float, float, Curve], ...]
    keys: tuple[tuple[int, ...], ...] = ()

    def _pieces(self) -> list[tuple[float, float, Curve | None, float]]:
        """(start, end) on the new axis, the curve (None: ``base``) and its time offset (the
        curve's own time = new time - offset)."""
        out: list[tuple[float, float, Curve | None, float]] = []
        t_new, t_base = 0.0, 0.0
        for b0, b1, curve in self.parts:
            if b0 > t_base:
                out.append((t_new, t_new + b0 - t_base, None, t_new - t_base))
                t_new += b0 - t_base
            out.append((t_new, t_new + curve.duration, curve, t_new))
            t_new += curve.duration
            t_base = b1
        out.append((t_new, t_new + self.base.duration - t_base, None, t_new - t_base))
        return out

    @property
    def duration(self) -> float:
        return self._pieces()[-1][1]

    def piece_of(self, t: np.ndarray) -> np.ndarray:
        """Index into :meth:`_pieces` of each time (a boundary belongs to the later piece)."""
        ends = np.array([p[0] for p in self._pieces()[1:]])
        return np.searchsorted(ends, np.asarray(t, dtype=float), side="right")

    def base_time(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For each time: ``base``'s time (NaN inside a replacement) and the index of the
        replacement holding it (-1 on ``base``)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        pieces = self._pieces()
        idx = self.piece_of(t)
        out = np.full(t.shape, np.nan)
        part = np.full(t.shape, -1)
        n_part = 0
        for j, (_, _, curve, off) in enumerate(pieces):
            sel = idx == j
            if curve is None:
                out[sel] = t[sel] - off
            else:
                part[sel] = n_part
                n_part += 1
        return out, part

    def evaluate(
        self, t: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        t = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), 0.0, self.duration)
        idx = self.piece_of(t)
        q, qd, qdd = (np.zeros((t.shape[0], 3)) for _ in range(3))
        jerk: np.ndarray | None = np.zeros((t.shape[0], 3))
        for j, (t0, t1, curve, off) in enumerate(self._pieces()):
            sel = idx == j
            if not np.any(sel):
                continue
            c = self.base if curve is None else curve
            tau = np.clip(t[sel] - off, t0 - off, t1 - off)
            a, b, d, jk = c.evaluate(tau)
            q[sel], qd[sel], qdd[sel] = a, b, d
            if jk is None or jerk is None:
                jerk = None
            else:
                jerk[sel] = jk
        return q, qd, qdd, jerk

    def check_times(self, resolution: float) -> np.ndarray:
        out: list[np.ndarray | list[float]] = []
        for t0, t1, curve, off in self._pieces():
            c = self.base if curve is None else curve
            tc = c.check_times(resolution) + off
            out += [tc[(tc >= t0) & (tc <= t1)], [t0, t1]]
        return np.unique(np.concatenate(out))

    def rest_times(self) -> np.ndarray:
        out: list[np.ndarray | list[float]] = []
        for t0, t1, curve, off in self._pieces():
            c = self.base if curve is None else curve
            tc = c.rest_times() + off
            out += [tc[(tc > t0) & (tc < t1)], [t0, t1]]
        t = np.unique(np.concatenate(out))
        return t[(t > 0.0) & (t < self.duration)]

    def plan_segments(self, t: np.ndarray) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        idx = self.piece_of(t)
        out = np.full((t.shape[0], 2), -1)
        for j, (_, _, curve, off) in enumerate(self._pieces()):
            sel = idx == j
            if np.any(sel):
                c = self.base if curve is None else curve
                out[sel] = c.plan_segments(t[sel] - off)
        return out


def splice_vias(
    curve: Curve,
    path: BlendedPath,
    profile: PathProfile,
    via: np.ndarray,
    radius: np.ndarray,
    limits: JointLimits,
    *,
    jerk: bool,
    fit: Callable[[Curve], Curve],
    corridor: np.ndarray | None = None,
    chains: dict,
    dropped: set,
    key: object = None,
    deadline: float | None = None,
) -> Curve:
    """``curve`` (the blended path's timing) with each section whose interior waypoints are
    all vias (``via``, per merged waypoint) replaced by its via chain
    (:func:`build_via_chain`, then ``fit``: the uniform slow-downs of the Cartesian speed
    bound and the torque limits) where that is faster, or where a via has radius 0 (only
    the chain passes it exactly). ``chains``: chains built in earlier
    rounds, by (section, ``key``); ``dropped``: sections whose chain failed a re-check."""
    sections = [s for s in via_sections(path, via) if s.vertices not in dropped]
    if not sections:
        return curve
    spans = _stop_spans(curve, path)
    if spans is None:
        return curve  # the rests do not follow the stops: no splice
    parts, keys = [], []
    for sec in sections:
        chain = chains.get((sec.vertices, key))
        if chain is None:
            built, _ = build_via_chain(
                path, profile, sec, radius, limits, jerk=jerk, corridor=corridor, deadline=deadline
            )
            chain = chains[(sec.vertices, key)] = fit(built)
        i = int(np.searchsorted(path.stops, sec.s_start - 1e-12))
        b0, b1 = spans[i][1], spans[i + 1][0]
        # a via of radius 0 asks for the vertex itself, which the blended path's arc does
        # not pass: the chain is the only timing that meets it, faster or not
        exact = any(float(radius[k]) == 0.0 for k in sec.vertices[1:-1])
        if exact or chain.duration < (b1 - b0) * (1.0 - 1e-9):
            parts.append((b0, b1, chain))
            keys.append(sec.vertices)
    return SplicedCurve(curve, tuple(parts), tuple(keys)) if parts else curve


def _stop_spans(curve: Curve, path: BlendedPath) -> list[tuple[float, float]] | None:
    """For each stop of ``path`` in order, the first and last instant ``curve`` rests at its
    posture (a chain may rest a moment longer there, at a zero-length move), or None when
    the rests do not follow the stops."""
    t = np.concatenate([[0.0], curve.rest_times(), [curve.duration]])
    q = curve.evaluate(t)[0]
    spans, i = [], 0
    for target in path.evaluate(path.stops, 0):
        while i < t.shape[0] and np.linalg.norm(q[i] - target) > 1e-7:
            i += 1
        if i == t.shape[0]:
            return None
        first = i
        while i + 1 < t.shape[0] and np.linalg.norm(q[i + 1] - target) <= 1e-7:
            i += 1
        spans.append((float(t[first]), float(t[i])))
        i += 1
    return spans


def drop_failed_vias(curve: Curve, report: CheckReport) -> list[tuple[int, ...]]:
    """The sections (their vertices) of the via chains in ``curve`` that a failed re-check
    blames: those holding a bad posture, or every one when a limit is exceeded (a chain's
    moves are exact, so it is the first suspect). The caller drops them: their sections are
    timed on the blended path again."""
    while isinstance(curve, TimeScaledCurve):
        curve = curve.base
    if not isinstance(curve, SplicedCurve):
        return []
    if not report.limits_ok:
        return list(curve.keys)
    _, part = curve.base_time(report.t[report.bad_state])
    return [curve.keys[j] for j in sorted(set(part[part >= 0].tolist()))]
