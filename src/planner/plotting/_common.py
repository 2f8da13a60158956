"""What the figures share: the paper's designs, colours, the per-process caches of sections
and loci, and the drawing helpers (posture, loci, section panels)."""

from __future__ import annotations

import dataclasses
import logging
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.colors import ListedColormap, LogNorm
from matplotlib.figure import Figure

from planner.analysis.loci import (
    Locus,
    parallel_loci,
    serial_loci,
)
from planner.analysis.sections import Section, cartesian_section, joint_section
from planner.caching import cached
from planner.design import Design
from planner.kinematics import link_points

__all__ = [
    "CONVEX",
    "GENERAL_DESIGN",
    "MODE_CHANGE_DESIGN",
    "NONCONVEX",
    "PRINT_RESOLUTION",
    "SCREEN_RESOLUTION",
    "draw_posture",
    "plot_loci",
]

logger = logging.getLogger(__name__)

#: Design of figures 4-7: both parallel-singularity kinds occur (L0 <= 2 L1, L0 >= 2 (L2 - L1)).
GENERAL_DESIGN = Design(L0=0.3, L1=0.3, L2=0.4)
#: Design of figures 12-15: no C = D (2 L1 < L0) but a stretched CD, which lies only in some
#: working modes (the convex one, '+-+'), so a change of working mode avoids it (section 3.3).
MODE_CHANGE_DESIGN = Design(L0=0.6, L1=0.25, L2=0.45)
#: Convex and non-convex working modes (upper half-plane) and their mirrors about AB.
CONVEX = ("+-+", "-+-")
NONCONVEX = ("++-", "--+")

_MODE_COLOURS = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#17becf",
]  # fmt: skip
_LOCUS_STYLE: dict[str, dict[str, Any]] = {
    "CD_stretched": {"color": "red", "lw": 1.6, "ls": "-", "label": "parallel: CD stretched"},
    "C=D": {"color": "magenta", "lw": 1.6, "ls": "--", "label": "parallel: C = D"},
    "leg_A_stretched": {"color": "navy", "lw": 1.4, "ls": "-", "label": "serial: leg A"},
    "leg_A_folded": {"color": "navy", "lw": 1.4, "ls": "-", "label": None},
    "leg_B_stretched": {"color": "darkgreen", "lw": 1.4, "ls": "-", "label": "serial: leg B"},
    "leg_B_folded": {"color": "darkgreen", "lw": 1.4, "ls": "-", "label": None},
    "P_on_axis": {"color": "black", "lw": 1.2, "ls": ":", "label": "serial: P on AB"},
}


#: Cells per axis of the section grids of a figure served over HTTP (``GET /v1/figures``):
#: coarse enough that every figure renders well under the viewer's 2 s, fine enough that the
#: areas it shows agree with :data:`PRINT_RESOLUTION` within about 1 %.
SCREEN_RESOLUTION = 96
#: Cells per axis of the print-quality figures (``planner figures``, ``docs/figures``; over
#: HTTP: ``?resolution=256&dpi=150``).
PRINT_RESOLUTION = 256


def _legend_below(ax: Axes, ncol: int = 3, handles: list | None = None) -> None:
    """The axes' legend in a frameless row under the x label, with line samples long and
    thick enough to be told apart at a glance."""
    if handles is None:
        handles = ax.get_legend_handles_labels()[0]
    if not handles:  # nothing labelled is drawn (e.g. a design without that locus)
        return
    kwargs = {"handles": handles}
    leg = ax.legend(
        loc="upper center",
        bbox_to_anchor=(0.5, -0.13),
        ncol=ncol,
        fontsize=7,
        frameon=False,
        handlelength=2.6,
        **kwargs,
    )
    for line in leg.get_lines():
        line.set_linewidth(max(line.get_linewidth(), 2.0))


# ----------------------------------------------------------------------------- caches
def _read_only(obj: object) -> None:
    """Make every numpy array field of a (frozen) dataclass read-only, in place."""
    for f in dataclasses.fields(obj):  # type: ignore[arg-type]
        value = getattr(obj, f.name)
        if isinstance(value, np.ndarray):
            value.setflags(write=False)


@cached("plotting.sections")
def _section(kind: str, design: Design, n: int) -> Section:
    """:func:`cartesian_section` or :func:`joint_section` of a design, once per process."""
    section = cartesian_section(design, n) if kind == "cartesian" else joint_section(design, n)
    _read_only(section)
    return section


@cached("plotting.loci")
def _loci(kind: str, design: Design) -> dict[str, Locus]:
    """:func:`parallel_loci` or :func:`serial_loci` of a design, once per process (a fresh
    dict each call; the loci in it are shared and read-only)."""
    loci = parallel_loci(design) if kind == "parallel" else serial_loci(design)
    for locus in loci.values():
        _read_only(locus)
    return loci


def _parallel(design: Design) -> dict[str, Locus]:
    return dict(_loci("parallel", design))


def _serial(design: Design) -> dict[str, Locus]:
    return dict(_loci("serial", design))


def _design_text(design: Design) -> str:
    return f"L0 = {design.L0:g} m, L1 = {design.L1:g} m, L2 = {design.L2:g} m"


def _in_plane(design: Design, q: np.ndarray, passive: np.ndarray) -> np.ndarray:
    """(5, 2) in-plane (u, w) of A, B, C, D, P for planar joints (theta1 ignored)."""
    q0 = np.array([0.0, q[1], q[2]])
    pts = link_points(design, q0, passive)
    return np.stack([pts[:, 1], pts[:, 0]], axis=1)


def _frame(ax: Axes, design: Design) -> None:
    """Same (u, w) window for every posture drawing of a design."""
    r = design.reach
    ax.set_xlim(-1.05 * (design.L0 / 2 + r), 1.05 * (design.L0 / 2 + r))
    ax.set_ylim(-0.45 * r, 1.05 * r)


def draw_posture(
    ax: Axes, design: Design, q: np.ndarray, passive: np.ndarray, *, colour: str = "k"
) -> None:
    """Draw the five-bar A-C-P-D-B of one posture in the (u, w) plane."""
    a, b, c, d, p = _in_plane(design, q, passive)
    chain = np.array([a, c, p, d, b])
    ax.plot(chain[:, 0], chain[:, 1], "-", color=colour, lw=2.5, solid_capstyle="round")
    ax.plot([a[0], b[0]], [a[1], b[1]], "-", color="0.4", lw=4)
    ax.plot(*np.array([a, b, c, d]).T, "o", color=colour, ms=5, mfc="white")
    ax.plot(*p, "o", color=colour, ms=7)
    _joint_labels(ax, design, {"A": a, "B": b, "C": c, "D": d, "P": p})
    _frame(ax, design)


def _joint_labels(ax: Axes, design: Design, points: dict[str, np.ndarray]) -> None:
    """Name each joint beside it, pushed away from the mechanism's centre so that no label
    sits on a link; joints that coincide (C = D on a parallel singularity, P on a pivot) get
    one label naming both ("C = D"), so neither hides the other."""
    groups: list[tuple[list[str], np.ndarray]] = []
    tol = 1e-3 * design.reach
    for name, pt in points.items():
        for names, at in groups:
            if np.hypot(*(pt - at)) < tol:
                names.append(name)
                break
        else:
            groups.append(([name], pt))
    centre = np.mean([pt for _, pt in groups], axis=0)
    off = 0.045 * design.reach
    for names, pt in groups:
        away = pt - centre
        if names[0] in "AB" and len(names) == 1:
            away = np.array([np.sign(pt[0]) or 1.0, -1.0])  # the base: below and outwards
        norm = float(np.hypot(*away))
        away = np.array([0.0, 1.0]) if norm < 1e-9 else away / norm
        tip = pt + off * away
        ax.annotate(
            " = ".join(names),
            (float(pt[0]), float(pt[1])),
            xytext=(float(tip[0]), float(tip[1])),
            fontsize=9,
            fontweight="bold",
            ha="center",
            va="center",
            bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.8},
        )


def plot_loci(
    ax: Axes,
    loci: dict[str, Locus],
    space: str = "cartesian",
    *,
    legend: bool = True,
    labels: bool = True,
    halo: bool = False,
) -> None:
    """Draw singularity loci (from :func:`parallel_loci` / :func:`serial_loci`); a locus that
    is a single point (e.g. the stretched CD at P = O when L0 = 0) is drawn as a cross.

    A locus with no posture in ``space`` (e.g. after :meth:`Locus.select`) is skipped, so the
    legend names only what is drawn. ``halo`` outlines each line in white, so that it shows
    on dark cells too (the black serial-singular bands of a joint section)."""
    from matplotlib import patheffects

    effects = [patheffects.withStroke(linewidth=3.2, foreground="white")] if halo else None
    seen: set[str] = set()
    for kind, locus in loci.items():
        if locus.fills_region and space == "cartesian":
            continue
        xy = locus.polyline(space)
        finite = xy[np.all(np.isfinite(xy), axis=1)]
        if not len(finite):
            continue
        style = dict(_LOCUS_STYLE.get(kind, {"color": "grey"}))
        label = style.pop("label", None)
        if not labels or label in seen:
            label = None
        elif label is not None:
            seen.add(label)
        if np.ptp(finite, axis=0).max() < 1e-6:
            ax.plot(
                *finite[0],
                "x",
                color=style["color"],
                ms=10,
                mew=2,
                label=label,
                path_effects=effects,
            )
            continue
        if space == "joint" and kind == "C=D" and not locus.fills_region:
            ax.plot(
                xy[:, 0],
                xy[:, 1],
                "o",
                color=style["color"],
                ms=7,
                mfc="none",
                label=label,
                path_effects=effects,
            )
            continue
        ax.plot(xy[:, 0], xy[:, 1], label=label, path_effects=effects, **style)
    if legend:
        _legend_below(ax)


def _extent(section: Section) -> tuple[float, float, float, float]:
    dx = (section.x[1] - section.x[0]) / 2
    dy = (section.y[1] - section.y[0]) / 2
    return (section.x[0] - dx, section.x[-1] + dx, section.y[0] - dy, section.y[-1] + dy)


#: Image values of :func:`_mode_index_image` beyond the eight working-mode slots.
_SINGULAR, _BASE_POINT = 8, 9
#: Colours of those two: thin serial-singular bands black; the two-dimensional base-point
#: region of erratum 6 a light grey, so the loci drawn over it stay visible.
_SINGULAR_COLOUR, _BASE_POINT_COLOUR = "black", "0.82"


def _mode_index_image(section: Section, slot: int) -> np.ndarray:
    """(ny, nx) float: working-mode slot index 0-7, 8 where singular, 9 where P is on the base
    point A = B (every working-mode sign 0: erratum 6), NaN where not reached."""
    wm = section.working_mode[..., slot, :]
    idx = 4 * (wm[..., 0] < 0) + 2 * (wm[..., 1] < 0) + (wm[..., 2] < 0)
    img = idx.astype(float)
    img[section.singular[..., slot]] = _SINGULAR
    img[np.all(wm == 0, axis=-1)] = _BASE_POINT
    img[~section.reached[..., slot]] = np.nan
    return img


def _mode_cmap() -> ListedColormap:
    return ListedColormap([*_MODE_COLOURS, _SINGULAR_COLOUR, _BASE_POINT_COLOUR])


def _best_kappa(section: Section, slots: list[int]) -> np.ndarray:
    """Smallest regular kappa(A) over ``slots`` (NaN where none reaches)."""
    reached = section.reached[..., slots] & ~section.singular[..., slots]
    k = np.where(reached, section.kappa_A[..., slots], np.inf).min(axis=-1)
    return np.where(np.isfinite(k), k, np.nan)


#: Colour range and ticks of kappa(A) in the section figures (log scale: kappa 1 to 30).
_KAPPA_RANGE = (1.0, 30.0)
_KAPPA_TICKS = (1, 1.5, 2, 3, 5, 10, 20, 30)


def _kappa_panel(fig: Figure, ax: Axes, section: Section, slots: list[int]) -> None:
    """Best regular kappa(A) per cell on a log colour scale whose bar is labelled in kappa
    itself (not its logarithm); cells reached only on a singularity in grey."""
    img = _best_kappa(section, slots)
    sing = np.any(section.reached[..., slots] & section.singular[..., slots], axis=-1)
    norm = LogNorm(*_KAPPA_RANGE, clip=True)
    im = ax.imshow(
        img,
        origin="lower",
        extent=_extent(section),
        cmap="viridis_r",
        norm=norm,
        interpolation="nearest",
        aspect="equal",
    )
    shade = np.where(sing & np.isnan(img), 1.0, np.nan)
    ax.imshow(
        shade,
        origin="lower",
        extent=_extent(section),
        cmap=ListedColormap(["0.55"]),
        interpolation="nearest",
        aspect="equal",
    )
    cb = fig.colorbar(im, ax=ax, shrink=0.8, ticks=_KAPPA_TICKS)
    cb.ax.set_yticklabels([f"{t:g}" for t in _KAPPA_TICKS])
    cb.ax.minorticks_off()
    cb.set_label("kappa(A) of the best regular posture (log scale; 1 = isotropic)")


def _cartesian_axes(ax) -> None:
    ax.set_xlabel("u (along AB) [m]")
    ax.set_ylabel("w (in the linkage plane) [m]")
    ax.set_aspect("equal")


def _joint_axes(ax) -> None:
    ax.set_xlabel("theta2 [rad]")
    ax.set_ylabel("theta3 [rad]")
    ax.set_aspect("equal")
