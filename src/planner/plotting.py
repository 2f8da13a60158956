"""Figures of the design analysis (matplotlib; the only plotting module, core never imports it).

:func:`write_figures` reproduces the seed paper's figures 4-15 as PNG and SVG files, one per
figure, each titled with the design used; axes in metres (the linkage plane: u along AB, w
normal to it) or radians (joint space theta2-theta3). Figures are built on
:class:`matplotlib.figure.Figure` objects (no pyplot global state), so this module is safe to
use from a server thread.

Speed: a worker draws the figures of the design a user is looking at again and again (the
viewer asks for the workspace section and the isoconditioning map of the current design), so
the sections and loci behind a figure are computed once per (design, resolution) and kept in
small per-process LRU caches (:func:`functools.lru_cache`; :class:`Design` is a frozen,
hashable dataclass), and so are the rendered bytes of :func:`render_figure`. Cached arrays are
made read-only so that no figure can alter another's data. :data:`SCREEN_RESOLUTION` (the
HTTP default) and :data:`PRINT_RESOLUTION` (the CLI and the committed PNGs) are the two grid
sizes used; ``tests/analysis/test_analysis_figures.py`` checks that they agree.
"""

from __future__ import annotations

import dataclasses
import io
import logging
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.colors import BoundaryNorm, ListedColormap, LogNorm
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from planner.analysis._common import MODE_INDEX
from planner.analysis.loci import (
    Locus,
    isoconditioning_loci,
    parallel_loci,
    serial_loci,
)
from planner.analysis.sections import Section, cartesian_section, joint_section
from planner.design import Design
from planner.kinematics import WORKING_MODES, conditioning, inverse_batch, link_points

__all__ = [
    "FIGURES",
    "FIGURE_FORMATS",
    "GENERAL_DESIGN",
    "MODE_CHANGE_DESIGN",
    "NAMED_FIGURES",
    "PRINT_RESOLUTION",
    "SCREEN_RESOLUTION",
    "clear_caches",
    "draw_posture",
    "figure_04",
    "figure_05",
    "figure_06",
    "figure_07",
    "figure_08",
    "figure_09",
    "figure_10",
    "figure_11",
    "figure_12",
    "figure_13",
    "figure_13_regions",
    "figure_14",
    "figure_14_regions",
    "figure_15",
    "figure_region_images",
    "figure_region_map",
    "plot_loci",
    "render_figure",
    "write_figures",
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
_LOCUS_STYLE = {
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

#: Rendered figures and their inputs kept per worker process (a few designs' worth).
_CACHE_SIZE = 16


def _legend_below(ax: Axes, ncol: int = 3, handles: list | None = None) -> None:
    """The axes' legend in a frameless row under the x label, with line samples long and
    thick enough to be told apart at a glance."""
    if handles is None:
        handles = ax.get_legend_handles_labels()[0]
    if not handles:  # nothing labelled is drawn (e.g. a design without that locus)
        return
    kwargs = {"handles": handles}
    leg = ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=ncol, fontsize=7,
                    frameon=False, handlelength=2.6, **kwargs)  # fmt: skip
    for line in leg.get_lines():
        line.set_linewidth(max(line.get_linewidth(), 2.0))


# ----------------------------------------------------------------------------- caches
def _read_only(obj: object) -> None:
    """Make every numpy array field of a (frozen) dataclass read-only, in place."""
    for f in dataclasses.fields(obj):  # type: ignore[arg-type]
        value = getattr(obj, f.name)
        if isinstance(value, np.ndarray):
            value.setflags(write=False)


@lru_cache(maxsize=_CACHE_SIZE)
def _section(kind: str, design: Design, n: int) -> Section:
    """:func:`cartesian_section` or :func:`joint_section` of a design, once per process."""
    section = cartesian_section(design, n) if kind == "cartesian" else joint_section(design, n)
    _read_only(section)
    return section


@lru_cache(maxsize=_CACHE_SIZE)
def _loci(kind: str, design: Design) -> dict[str, Locus]:
    """:func:`parallel_loci` or :func:`serial_loci` of a design, once per process (a fresh
    dict each call; the loci in it are shared and read-only)."""
    loci = parallel_loci(design) if kind == "parallel" else serial_loci(design)
    for locus in loci.values():
        _read_only(locus)
    return loci


def clear_caches() -> None:
    """Forget every cached section, locus and rendered figure of this process (for a
    benchmark of cold renders, or to free memory)."""
    for cached in (_section, _loci, _iso, _render):
        cached.cache_clear()


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
        ax.annotate(" = ".join(names), pt, xytext=pt + off * away, fontsize=9,
                    fontweight="bold", ha="center", va="center",
                    bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none",
                          "alpha": 0.8})  # fmt: skip


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
            ax.plot(*finite[0], "x", color=style["color"], ms=10, mew=2, label=label,
                    path_effects=effects)  # fmt: skip
            continue
        if space == "joint" and kind == "C=D" and not locus.fills_region:
            ax.plot(xy[:, 0], xy[:, 1], "o", color=style["color"], ms=7, mfc="none",
                    label=label, path_effects=effects)  # fmt: skip
            continue
        ax.plot(xy[:, 0], xy[:, 1], label=label, path_effects=effects, **style)
    if legend:
        _legend_below(ax)


def _extent(section: Section) -> list[float]:
    dx = (section.x[1] - section.x[0]) / 2
    dy = (section.y[1] - section.y[0]) / 2
    return [section.x[0] - dx, section.x[-1] + dx, section.y[0] - dy, section.y[-1] + dy]


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
    im = ax.imshow(img, origin="lower", extent=_extent(section), cmap="viridis_r", norm=norm,
                   interpolation="nearest", aspect="equal")  # fmt: skip
    shade = np.where(sing & np.isnan(img), 1.0, np.nan)
    ax.imshow(shade, origin="lower", extent=_extent(section), cmap=ListedColormap(["0.55"]),
              interpolation="nearest", aspect="equal")  # fmt: skip
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


# ----------------------------------------------------------------------------- figures
def _pick(locus: Locus, design: Design) -> int:
    """Row of a locus with P above AB that is farthest from the *other* singularities: the
    largest serial margin for a parallel locus; for a serial locus (whose own margin is 0) the
    larger of the second-smallest serial margin and 1 / kappa(A)."""
    v = locus.valid & (locus.uw[:, 1] > 1e-3 * design.reach)
    c = conditioning(design, locus.q, locus.passive, locus.uw[:, 1])
    if locus.kind in ("C=D", "CD_stretched"):
        score = c.min_serial
    else:
        second = np.sort(c.serial, axis=-1)[..., 1]
        score = np.minimum(second, 1.0 / np.maximum(c.kappa_A, 1.0))
    return int(np.argmax(np.where(v, score, -np.inf)))


def figure_04(design: Design = GENERAL_DESIGN) -> Figure:
    """The four working modes (s_A, s_B) with P above AB, at one point P."""
    u = np.linspace(-0.3, 0.3, 41) * design.reach
    w = np.linspace(0.2, 0.9, 36) * design.reach
    uu, ww = np.meshgrid(u, w)
    p = np.stack([ww.ravel(), uu.ravel(), np.zeros(uu.size)], axis=1)
    b = inverse_batch(design, p)
    c = conditioning(design, b.q, b.passive, b.w)
    spread = np.minimum(np.abs(np.sin(b.q[..., 1])), np.abs(np.sin(b.q[..., 2])))
    good = np.minimum(np.minimum(c.min_serial, 1 / c.kappa_A), spread)
    score = np.where(b.ok[:, :4], good[:, :4], -1).min(axis=1)
    i = int(np.argmax(score))
    fig = Figure(figsize=(8, 6.2))
    # shared axes, labelled on the outer edge only: half the tick text to lay out and draw
    # (this figure's time is matplotlib's text layout) and a less cluttered page
    axes = fig.subplots(2, 2, sharex=True, sharey=True).ravel()
    for k, ax in enumerate(axes):
        draw_posture(ax, design, b.q[i, k], b.passive[i, k], colour=_MODE_COLOURS[k])
        ax.set_title(f"working mode {WORKING_MODES[k]}  (kappa(A) = {c.kappa_A[i, k]:.2f})",
                     fontsize=9)  # fmt: skip
        _cartesian_axes(ax)
        ax.label_outer()
    fig.suptitle(f"Fig. 4: the four working modes (s_axis = +) at P = ({p[i, 1]:.3f}, "
                 f"{p[i, 0]:.3f}) m\n{_design_text(design)}", fontsize=10)  # fmt: skip
    return fig


def _posture_figure(title: str, design: Design, locus: Locus, note: str) -> Figure:
    i = _pick(locus, design)
    fig = Figure(figsize=(6, 5))
    ax = fig.add_subplot(1, 1, 1)
    draw_posture(ax, design, locus.q[i], locus.passive[i], colour="tab:red")
    c = conditioning(design, locus.q[i], locus.passive[i], locus.uw[i, 1])
    ax.set_title(f"{title}\n{_design_text(design)}", fontsize=10)
    ax.text(0.02, 0.02, f"{note}\nkappa(A) = {float(c.kappa_A):.3g}, "
            f"min serial margin = {float(c.min_serial):.3g}",
            transform=ax.transAxes, fontsize=8)  # fmt: skip
    _cartesian_axes(ax)
    return fig


def figure_05(design: Design = GENERAL_DESIGN) -> Figure:
    """Parallel singularity: P the midpoint of a stretched CD."""
    locus = _parallel(design)["CD_stretched"]
    return _posture_figure("Fig. 5: parallel singularity, C, P, D aligned (CD stretched)",
                           design, locus, "A cannot resist a force normal to CD")  # fmt: skip


def figure_06(design: Design = GENERAL_DESIGN) -> Figure:
    """Parallel singularity: C = D, P turns freely about them."""
    locus = _parallel(design)["C=D"]
    fig = _posture_figure("Fig. 6: parallel singularity, C = D", design, locus,
                          "P can turn about C = D with the actuators locked")  # fmt: skip
    ax = fig.axes[0]
    i = _pick(locus, design)
    cd = _in_plane(design, locus.q[i], locus.passive[i])[2]
    t = np.linspace(0, 2 * np.pi, 200)
    ax.plot(cd[0] + design.L2 * np.cos(t), cd[1] + design.L2 * np.sin(t), ":", color="tab:red")
    return fig


def figure_07(design: Design = GENERAL_DESIGN) -> Figure:
    """Serial singularity: leg B stretched, P on the workspace boundary."""
    locus = _serial(design)["leg_B_stretched"]
    fig = _posture_figure("Fig. 7: serial singularity, leg B stretched (B, D, P aligned)",
                          design, locus, "P cannot move along BP")  # fmt: skip
    ax = fig.axes[0]
    t = np.linspace(0, 2 * np.pi, 400)
    ax.plot(design.L0 / 2 + design.reach * np.cos(t), design.reach * np.sin(t), ":",
            color="0.5", label="|BP| = L1 + L2")  # fmt: skip
    ax.legend(loc="upper right", fontsize=7)
    return fig


def _cartesian_section_figure(title: str, design: Design, n: int, note: str) -> Figure:
    section = _section("cartesian", design, n)
    loci = {**_serial(design), **_parallel(design)}
    fig = Figure(figsize=(7, 7))
    ax = fig.add_subplot(1, 1, 1)
    _kappa_panel(fig, ax, section, list(range(8)))
    plot_loci(ax, loci, "cartesian")
    ax.set_title(f"{title}\n{_design_text(design)}\n{note}", fontsize=8)
    _cartesian_axes(ax)
    return fig


def _joint_section_figure(title: str, design: Design, n: int) -> Figure:
    """Working mode per (theta2, theta3) cell, one panel per assembly mode, with the loci.

    Thin serial-singular bands are black; the base-point region of erratum 6 (half the plane
    for L0 = 0, L1 = L2) is light grey, so that the loci and their legend stay visible."""
    section = _section("joint", design, n)
    loci = {**_serial(design), **_parallel(design)}
    fig = Figure(figsize=(11, 6.4))
    for k, mode in enumerate(section.labels):
        ax = fig.add_subplot(1, 2, k + 1)
        img = _mode_index_image(section, k)
        ax.imshow(img, origin="lower", extent=_extent(section), cmap=_mode_cmap(), vmin=-0.5,
                  vmax=_BASE_POINT + 0.5, interpolation="nearest", aspect="equal")  # fmt: skip
        mine = {kind: loc.select(assembly_mode=mode) if kind != "C=D" else loc
                for kind, loc in loci.items()}  # fmt: skip
        plot_loci(ax, mine, "joint", legend=False, halo=True)
        handles, _ = ax.get_legend_handles_labels()
        values = {int(v) for v in np.unique(img[np.isfinite(img)])}
        handles += [Patch(color=_MODE_COLOURS[v], label=f"mode {WORKING_MODES[v]}")
                    for v in sorted(values) if v < _SINGULAR]  # fmt: skip
        handles.append(Patch(color=_SINGULAR_COLOUR, label="serial-singular cell"))
        if _BASE_POINT in values:
            handles.append(Patch(color=_BASE_POINT_COLOUR, label="P = A = B (erratum 6)"))
        _legend_below(ax, ncol=3, handles=handles)
        ax.set_title(f"assembly mode '{mode}'", fontsize=9)
        _joint_axes(ax)
    fig.suptitle(f"{title}\n{_design_text(design)}", fontsize=10)
    return fig


def figure_08(design: Design | None = None, n: int = PRINT_RESOLUTION) -> Figure:
    design = design or Design.paper_optimum()
    return _cartesian_section_figure(
        "Fig. 8: cross-section of the Cartesian workspace (L0 = 0, L1 = L2)", design, n,
        "Modes with s_A = s_B are parallel-singular everywhere (C = D): only ++-, +-+ (and "
        "mirrors) operate.\nAll singularities lie on the boundary: |OP| = L1 + L2, the axis, P = O.",
    )  # fmt: skip


def figure_09(design: Design | None = None, n: int = PRINT_RESOLUTION) -> Figure:
    design = design or Design.paper_optimum()
    return _joint_section_figure(
        "Fig. 9: cross-section of the joint space (L0 = 0, L1 = L2); grey: P at the base "
        "point A = B (erratum 6)", design, n,
    )  # fmt: skip


def figure_10(design: Design | None = None, n: int = PRINT_RESOLUTION) -> Figure:
    design = design or Design.singularity_free()
    return _cartesian_section_figure(
        "Fig. 10: Cartesian workspace free of parallel singularities (2 L1 < L0 < 2 (L2 - L1))",
        design, n, "kappa(A) stays bounded: only serial singularities, on the boundary.",
    )  # fmt: skip


def figure_11(design: Design | None = None, n: int = PRINT_RESOLUTION) -> Figure:
    design = design or Design.singularity_free()
    return _joint_section_figure("Fig. 11: joint space free of parallel singularities", design, n)


def figure_12(design: Design = MODE_CHANGE_DESIGN) -> Figure:
    """The same P: parallel-singular in the convex mode, regular in the non-convex one."""
    locus = _parallel(design)["CD_stretched"].select(working_mode=CONVEX[0])
    i = _pick(locus, design)
    p = np.array([locus.uw[i, 1], locus.uw[i, 0], 0.0])
    b = inverse_batch(design, p)
    c = conditioning(design, b.q, b.passive, b.w)
    fig = Figure(figsize=(10, 3.6))
    for k, mode in enumerate((CONVEX[0], NONCONVEX[0])):
        ax = fig.add_subplot(1, 2, k + 1)
        s = MODE_INDEX[mode]
        draw_posture(ax, design, b.q[0, s], b.passive[0, s], colour=_MODE_COLOURS[s])
        kind = "convex" if k == 0 else "non-convex"
        ax.set_title(f"{kind} working mode {mode}: kappa(A) = {c.kappa_A[0, s]:.3g}", fontsize=9)
        _cartesian_axes(ax)
    fig.suptitle(f"Fig. 12: working mode and parallel singularity, P = ({p[1]:.3f}, {p[0]:.3f}) m"
                 f"\n{_design_text(design)}", fontsize=10)  # fmt: skip
    return fig


def _mode_workspace_figure(title: str, design: Design, modes: tuple[str, str], n: int) -> Figure:
    section = _section("cartesian", design, n)
    slots = [MODE_INDEX[m] for m in modes]
    loci = _parallel(design)
    par = {k: loc.select(working_mode=modes[0]) for k, loc in loci.items()}
    par2 = {k: loc.select(working_mode=modes[1]) for k, loc in loci.items()}
    fig = Figure(figsize=(7, 7))
    ax = fig.add_subplot(1, 1, 1)
    _kappa_panel(fig, ax, section, slots)
    plot_loci(ax, _serial(design), "cartesian", legend=False)
    plot_loci(ax, par, "cartesian", legend=False, labels=False)
    plot_loci(ax, par2, "cartesian", legend=False, labels=False)
    drawn = any(np.isfinite(v.uw).any() for v in (*par.values(), *par2.values()))
    ax.plot([], [], color="red" if drawn else "none",
            label="parallel singularity in these modes" if drawn
            else "no parallel singularity in these modes")  # fmt: skip
    _legend_below(ax, ncol=2)
    ax.set_title(f"{title}\nmodes {modes[0]} (w > 0) and {modes[1]} (w < 0); "
                 f"{_design_text(design)}", fontsize=9)  # fmt: skip
    _cartesian_axes(ax)
    return fig


def figure_13(design: Design = MODE_CHANGE_DESIGN, n: int = PRINT_RESOLUTION) -> Figure:
    return _mode_workspace_figure(
        "Fig. 13: workspace of the convex working mode", design, CONVEX, n
    )


def figure_14(design: Design = MODE_CHANGE_DESIGN, n: int = PRINT_RESOLUTION) -> Figure:
    return _mode_workspace_figure(
        "Fig. 14: workspace of the non-convex working mode", design, NONCONVEX, n
    )


#: Levels of kappa(A) drawn in figure 15 (1 is the isotropy locus).
ISO_LEVELS = (1.0, 1.25, 1.5, 2.0, 3.0, 5.0, 10.0)
#: Samples along each isoconditioning curve of figure 15.
ISO_SAMPLES = 4001


@lru_cache(maxsize=_CACHE_SIZE)
def _iso(design: Design, level: float) -> Locus:
    """:func:`isoconditioning_loci` at one level, once per process (read-only)."""
    locus = isoconditioning_loci(design, level, samples=ISO_SAMPLES)
    _read_only(locus)
    return locus


def _segments(xy: np.ndarray) -> list[np.ndarray]:
    """The runs of finite rows (k, 2), k >= 2, of a NaN-separated polyline."""
    ok = np.all(np.isfinite(xy), axis=1).astype(np.int8)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], ok, [0]])))
    return [xy[i:j] for i, j in zip(edges[::2], edges[1::2], strict=True) if j - i >= 2]


def _length(xy: np.ndarray) -> float:
    """Arc length of a polyline (k, 2), m."""
    return float(np.hypot(*np.diff(xy, axis=0).T).sum())


def _iso_label(level: float) -> str:
    return "1 isotropic" if level == 1.0 else f"{level:g}"


def figure_15(design: Design = MODE_CHANGE_DESIGN, n: int = PRINT_RESOLUTION) -> Figure:
    """Isoconditioning curves of kappa(A) for the convex and the non-convex working modes.

    The curves are the exact loci (:func:`isoconditioning_loci`, not contours of a grid),
    wrapped in a :class:`matplotlib.contour.ContourSet` so that ``clabel`` writes each level
    on its curve; the bands between levels are shaded from the Cartesian section so that the
    well-conditioned regions show at a glance."""
    from matplotlib.contour import ContourSet

    section = _section("cartesian", design, n)
    loci = {level: _iso(design, level) for level in ISO_LEVELS}
    par = _parallel(design)
    bounds = [*ISO_LEVELS, 1e12]
    base = colormaps["YlGnBu"](np.linspace(0.05, 0.7, len(bounds) - 2))[:, :3]
    worst = np.array([0.96, 0.62, 0.62])  # beyond the last level: near a parallel singularity
    # pale (mixed with white) so that the black labels stay legible on every band
    band_colours = ListedColormap(np.vstack([0.6 * base + 0.4, worst]))
    norm = BoundaryNorm(bounds, band_colours.N)
    long_enough = 0.12 * design.reach  # shorter pieces (near a cusp) are drawn, not labelled
    fig = Figure(figsize=(11, 6.8))
    for k, modes in enumerate((CONVEX, NONCONVEX)):
        ax = fig.add_subplot(1, 2, k + 1)
        slots = [MODE_INDEX[m] for m in modes]
        reached = section.reached[..., slots]
        kappa = np.where(reached, section.kappa_A[..., slots], np.inf).min(axis=-1)
        kappa = np.where(reached.any(axis=-1), kappa, np.nan)
        ax.imshow(kappa, origin="lower", extent=_extent(section), cmap=band_colours, norm=norm,
                  interpolation="nearest", aspect="equal")  # fmt: skip
        segs = [[seg for m in modes
                 for seg in _segments(loci[level].select(working_mode=m).polyline("cartesian"))]
                for level in ISO_LEVELS]  # fmt: skip
        widths = [2.4 if level == 1.0 else 1.0 for level in ISO_LEVELS]
        colours = ["tab:blue" if level == 1.0 else "0.15" for level in ISO_LEVELS]
        long = [[g for g in ss if _length(g) >= long_enough] for ss in segs]
        short = [[g for g in ss if _length(g) < long_enough] for ss in segs]
        for ss, c, lw in zip(short, colours, widths, strict=True):
            for g in ss:
                ax.plot(g[:, 0], g[:, 1], color=c, lw=lw)
        cs = ContourSet(ax, list(ISO_LEVELS), long, colors=colours, linewidths=widths)
        with_curves = [lvl for lvl, ss in zip(ISO_LEVELS, long, strict=True) if ss]
        ax.clabel(cs, with_curves, inline=True, inline_spacing=2, fontsize=7,
                  fmt=_iso_label)  # fmt: skip
        for m in modes:
            sel = {kk: v.select(working_mode=m) for kk, v in par.items()}
            plot_loci(ax, sel, "cartesian", legend=False, labels=False)
        handles = [
            Line2D([], [], color="tab:blue", lw=2.4, label="isotropy, kappa(A) = 1"),
            Line2D([], [], color="0.15", lw=1.0,
                   label="kappa(A) = " + ", ".join(f"{v:g}" for v in ISO_LEVELS[1:])),
            Line2D([], [], color="red", lw=1.6, label="parallel singularity"),
            Patch(color=band_colours(band_colours.N - 1), label="kappa(A) > 10"),
            Patch(color=band_colours(0), label="kappa(A) < 1.25"),
        ]  # fmt: skip
        _legend_below(ax, ncol=2, handles=handles)
        kind = "convex" if k == 0 else "non-convex"
        ax.set_title(f"{kind} modes {modes[0]} (w > 0) / {modes[1]} (w < 0)", fontsize=9)
        _cartesian_axes(ax)
    fig.suptitle(f"Fig. 15: isoconditioning curves of kappa(A) for two working modes "
                 f"(labels: kappa)\n{_design_text(design)}", fontsize=10)  # fmt: skip
    return fig


#: Figure number -> (file stem, builder taking the grid size).
FIGURES: dict[int, tuple[str, Callable[[int], Figure]]] = {
    4: ("fig04_working_modes", lambda n: figure_04()),
    5: ("fig05_parallel_cd_stretched", lambda n: figure_05()),
    6: ("fig06_parallel_c_equals_d", lambda n: figure_06()),
    7: ("fig07_serial_singularity", lambda n: figure_07()),
    8: ("fig08_cartesian_section_optimum", lambda n: figure_08(n=n)),
    9: ("fig09_joint_section_optimum", lambda n: figure_09(n=n)),
    10: ("fig10_cartesian_section_singularity_free", lambda n: figure_10(n=n)),
    11: ("fig11_joint_section_singularity_free", lambda n: figure_11(n=n)),
    12: ("fig12_working_mode_and_parallel_singularity", lambda n: figure_12()),
    13: ("fig13_workspace_convex_mode", lambda n: figure_13(n=n)),
    14: ("fig14_workspace_nonconvex_mode", lambda n: figure_14(n=n)),
    15: ("fig15_isoconditioning", lambda n: figure_15(n=n)),
}


def write_figures(
    outdir: str | Path,
    *,
    n: int = PRINT_RESOLUTION,
    formats: tuple[str, ...] = ("png", "svg"),
    dpi: int = 80,
    only: tuple[int, ...] | None = None,
) -> list[Path]:
    """Write the paper's figures 4-15 into ``outdir``, one file per figure and format.

    Parameters
    ----------
    outdir : path
        Created if missing.
    n : int
        Cells per axis of the section grids.
    formats : tuple of str
        Matplotlib output formats.
    dpi : int
        Resolution of raster formats.
    only : tuple of int, optional
        Figure numbers to write (default: all of :data:`FIGURES`).

    Returns
    -------
    list of Path
        The files written.
    """
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for number, (stem, build) in FIGURES.items():
        if only is not None and number not in only:
            continue
        fig = build(n)
        fig.tight_layout()
        for fmt in formats:
            path = out / f"{stem}.{fmt}"
            fig.savefig(path, format=fmt, dpi=dpi, bbox_inches="tight")
            written.append(path)
        logger.info("figure %d written: %s", number, stem)
    return written


# ---------------------------------------------------------------------------- figures by name
def _needs_parallel(design: Design, kind: str, name: str) -> None:
    """Refuse a figure about a parallel singularity the design does not have."""
    from planner.analysis.design_check import parallel_singularity_kinds
    from planner.exceptions import DesignError

    kinds, reasons = parallel_singularity_kinds(design)
    if kind not in kinds:
        raise DesignError(f"figure {name!r} needs a {kind} parallel singularity: {reasons[kind]}")


def _named_cartesian_section(design: Design, n: int) -> Figure:
    return _cartesian_section_figure(
        "Cross-section of the Cartesian workspace (best kappa(A) over the working modes)",
        design, n, "Lines: serial and parallel singularity loci.",
    )  # fmt: skip


def _named_joint_section(design: Design, n: int) -> Figure:
    return _joint_section_figure(
        "Cross-section of the joint space (working mode per cell; black: singular)", design, n
    )


def _checked(kind: str, name: str, build: Callable[[Design], Figure]) -> Callable[..., Figure]:
    def make(design: Design, n: int) -> Figure:
        _needs_parallel(design, kind, name)
        return build(design)

    return make


#: Figures drawn for any design, by name: name -> builder(design, n). The paper's figure of
#: each is in :data:`FIGURES`; these have titles that do not assume the paper's designs.
NAMED_FIGURES: dict[str, Callable[[Design, int], Figure]] = {
    "working_modes": lambda d, n: figure_04(d),
    "parallel_cd_stretched": _checked("CD_stretched", "parallel_cd_stretched", figure_05),
    "parallel_c_equals_d": _checked("C=D", "parallel_c_equals_d", figure_06),
    "serial_singularity": lambda d, n: figure_07(d),
    "cartesian_section": _named_cartesian_section,
    "joint_section": _named_joint_section,
    "working_mode_and_parallel_singularity": _checked(
        "CD_stretched", "working_mode_and_parallel_singularity", figure_12
    ),
    "workspace_convex_mode": lambda d, n: figure_13(d, n),
    "workspace_nonconvex_mode": lambda d, n: figure_14(d, n),
    "isoconditioning": lambda d, n: figure_15(d, n),
    # from the region map (functions below): the map, its regions' images, figures 13-14
    "region_map": lambda d, n: figure_region_map(d, n),
    "region_images": lambda d, n: figure_region_images(d, n),
    "regions_convex_mode": lambda d, n: figure_13_regions(d, n),
    "regions_nonconvex_mode": lambda d, n: figure_14_regions(d, n),
}

#: Formats :func:`render_figure` writes.
FIGURE_FORMATS: tuple[str, ...] = ("png", "svg")


def render_figure(
    name: str, design: Design, *, n: int = SCREEN_RESOLUTION, fmt: str = "png", dpi: int = 80
) -> bytes:
    """One figure of :data:`NAMED_FIGURES` for ``design``, as PNG or SVG bytes.

    The bytes are cached per process (the last :data:`_CACHE_SIZE` distinct requests), and the
    sections and loci behind them per design, so a viewer asking again for the figures of the
    design on screen gets them without recomputing or redrawing.

    Parameters
    ----------
    name : str
        A key of :data:`NAMED_FIGURES`.
    design : Design
    n : int
        Cells per axis of the section grids: :data:`SCREEN_RESOLUTION` by default,
        :data:`PRINT_RESOLUTION` for print quality.
    fmt : 'png' | 'svg'
    dpi : int
        Resolution of a PNG.

    Raises
    ------
    InputError
        Unknown name or format.
    DesignError
        The figure shows something this design does not have (e.g. a stretched-CD
        singularity of a singularity-free design), or it cannot be drawn for it.
    """
    from planner.exceptions import InputError

    if name not in NAMED_FIGURES:
        raise InputError(f"name must be one of {sorted(NAMED_FIGURES)}, got {name!r}")
    if fmt not in FIGURE_FORMATS:
        raise InputError(f"format must be one of {FIGURE_FORMATS}, got {fmt!r}")
    return _render(name, design, int(n), fmt, int(dpi))


@lru_cache(maxsize=_CACHE_SIZE)
def _render(name: str, design: Design, n: int, fmt: str, dpi: int) -> bytes:
    """The work of :func:`render_figure` (a refused figure raises and is not cached)."""
    from planner.analysis.workspace import closed_form_volume
    from planner.exceptions import DesignError, PlannerError

    if closed_form_volume(design) <= 0.0:
        raise DesignError(
            f"figure {name!r}: the workspace is empty (L0 = {design.L0:g} m >= 2 (L1 + L2) = "
            f"{2 * design.reach:g} m)"
        )
    try:
        fig = NAMED_FIGURES[name](design, n)
        fig.tight_layout()
        buffer = io.BytesIO()
        fig.savefig(buffer, format=fmt, dpi=dpi, bbox_inches="tight")
    except DesignError:
        raise
    except (PlannerError, ValueError, IndexError, KeyError) as exc:  # a locus it lacks
        raise DesignError(f"figure {name!r} cannot be drawn for this design: {exc}") from exc
    return buffer.getvalue()


# ---------------------------------------------------------------------------- region maps
def _region_colours(count: int) -> np.ndarray:
    """(count, 4) RGBA: one distinguishable colour per region id (tab20 without its two
    greys, which the figures keep for what is not a region, cycled)."""
    cmap = colormaps["tab20"]
    palette = [cmap(k) for k in range(20) if k not in (14, 15)]
    return np.array([palette[k % len(palette)] for k in range(max(count, 1))])


def figure_region_map(design: Design, n: int = PRINT_RESOLUTION, *, margins=None) -> Figure:
    """The region map of ``design`` in joint space (theta2, theta3), one panel per assembly
    mode, coloured by region (the certified cells of each region; pale: its undecided
    cells; white: surely invalid in every mode; black dots: cells where a transit may
    happen), each region labelled with its working mode and its union-graph component.

    Parameters
    ----------
    design : Design
    n : int, cells per axis of the map.
    margins : planner.validity.Margins, optional (default margins).
    """
    from planner.analysis.regions import VALID, region_map

    rmap = region_map(design, margins, n)
    colours = _region_colours(len(rmap.regions))
    fig = Figure(figsize=(12, 6.2))
    lo, hi = design.joint_min, design.joint_max
    extent = [lo[1], hi[1], lo[2], hi[2]]
    for ai, asm in enumerate(("+", "-")):
        ax = fig.add_subplot(1, 2, ai + 1)
        img = np.ones((n, n, 4))
        for region in rmap.regions:
            if region.assembly_mode != asm:
                continue
            mi = MODE_INDEX[region.working_mode]
            cells = rmap.labels[ai, mi] == region.label
            sure = cells & (rmap.status[ai, mi] == VALID)
            pale = cells & ~sure & (img[..., 0] == 1.0) & (img[..., 1] == 1.0)
            img[pale] = 0.55 + 0.45 * colours[region.id]
            img[sure] = colours[region.id]
            if sure.any():
                k3, k2 = np.nonzero(sure)
                m = len(k3) // 2
                ax.text(rmap.theta2[k2[m]], rmap.theta3[k3[m]],
                        f"{region.working_mode}\n#{region.component}", fontsize=7,
                        ha="center", va="center",
                        bbox={"fc": "white", "ec": "none", "alpha": 0.7, "pad": 1})  # fmt: skip
        ax.imshow(img, origin="lower", extent=extent, aspect="auto", interpolation="nearest")
        tk3, tk2 = np.nonzero(rmap.transit_cells[ai].max(axis=0) > 0)
        ax.plot(rmap.theta2[tk2], rmap.theta3[tk3], ",", color="black")
        count = sum(r.assembly_mode == asm for r in rmap.regions)
        ax.set_title(f"assembly mode {asm}: {count} regions", fontsize=9)
        _joint_axes(ax)
    fig.suptitle(
        f"Region map (labels: working mode, #union-graph component; pale: undecided; "
        f"dots: possible transits); {_design_text(design)}",
        fontsize=9,
    )
    return fig


def figure_region_images(design: Design, n: int = PRINT_RESOLUTION, *, margins=None) -> Figure:
    """Each region's image in the Cartesian section (the linkage plane (u, w), m): the apex
    P of its certified cells, coloured as in :func:`figure_region_map`, one panel per
    assembly mode; the legend names each region's working mode and component."""
    from planner.analysis.coverage import cartesian_images
    from planner.analysis.regions import region_map

    rmap = region_map(design, margins, n)
    images = cartesian_images(rmap)
    colours = _region_colours(len(rmap.regions))
    fig = Figure(figsize=(12, 6.6))
    reach = design.reach
    for ai, asm in enumerate(("+", "-")):
        ax = fig.add_subplot(1, 2, ai + 1)
        handles = []
        for region in rmap.regions:
            if region.assembly_mode != asm:
                continue
            _, p = images[region.id]
            if len(p) == 0:
                continue
            ax.scatter(p[:, 0], p[:, 1], s=0.6, color=colours[region.id], lw=0, rasterized=True)
            handles.append(Patch(color=colours[region.id],
                                 label=f"{region.working_mode} #{region.component}"))  # fmt: skip
        for x in (-design.L0 / 2, design.L0 / 2):
            ax.plot([x], [0.0], "ko", ms=3)
        ax.set_xlim(-reach - design.L0 / 2, reach + design.L0 / 2)
        ax.set_ylim(-reach, reach)
        ax.set_title(f"assembly mode {asm}", fontsize=9)
        _legend_below(ax, ncol=4, handles=handles)
        _cartesian_axes(ax)
    fig.suptitle(
        f"Images of the regions in the linkage plane (certified cells); {_design_text(design)}",
        fontsize=9,
    )
    return fig


def _coverage_image(cov, ids: list[int], colours: np.ndarray, background: list[int]) -> np.ndarray:
    """RGBA raster (rows w, columns u) of a coverage: light grey where some region of
    ``background`` reaches, each region of ``ids`` in its colour on top, white elsewhere."""
    img = np.ones((len(cov.w), len(cov.u), 4))
    for i in background:
        img[cov.reached[i]] = (0.85, 0.85, 0.85, 1.0)
    for i in ids:
        img[cov.reached[i]] = colours[i]
    return img


def _figure_mode_regions(
    title: str, design: Design, modes: tuple[str, str], n: int, margins=None
) -> Figure:
    """The Cartesian section (linkage plane) reached by the certified regions of a pair of
    working modes (the mode and its mirror about AB), one panel per assembly mode, over the
    grey area that all certified regions of that assembly mode reach (the workspace a change
    of working mode opens); the title of each panel gives both areas and their ratio."""
    from planner.analysis.coverage import cartesian_coverage
    from planner.analysis.regions import region_map

    rmap = region_map(design, margins, n)
    cov = cartesian_coverage(rmap, min(max(2 * n, 256), 512))
    colours = _region_colours(len(rmap.regions))
    fig = Figure(figsize=(12, 5.8))
    extent = [cov.u[0], cov.u[-1], cov.w[0], cov.w[-1]]
    for ai, asm in enumerate(("+", "-")):
        ax = fig.add_subplot(1, 2, ai + 1)
        mine = [r for r in rmap.regions if r.assembly_mode == asm and r.valid_cells]
        ids = [r.id for r in mine if r.working_mode in modes]
        img = _coverage_image(cov, ids, colours, [r.id for r in mine])
        ax.imshow(img, origin="lower", extent=extent, interpolation="nearest")
        pair, every = cov.area(ids), cov.area(r.id for r in mine)
        handles = [Patch(color=colours[i], label=f"{rmap.regions[i].working_mode} region {i}")
                   for i in ids]  # fmt: skip
        handles.append(Patch(color=(0.85, 0.85, 0.85), label="other working modes only"))
        for x in (-design.L0 / 2, design.L0 / 2):
            ax.plot([x], [0.0], "ko", ms=3)
        ratio = f"{every / pair:.2f}" if pair > 0 else "-"
        ax.set_title(
            f"assembly mode {asm}: {' / '.join(modes)} {pair:.3f} m^2, all modes {every:.3f} m^2 "
            f"(ratio {ratio})",
            fontsize=9,
        )
        _legend_below(ax, ncol=3, handles=handles)
        _cartesian_axes(ax)
    fig.suptitle(
        f"{title}: certified regions (kappa(A) <= {rmap.margins.kappa_max:g}, serial measures "
        f">= {rmap.margins.serial_min:g}) in the linkage plane; {_design_text(design)}",
        fontsize=9,
    )
    return fig


def figure_13_regions(design: Design = MODE_CHANGE_DESIGN, n: int = PRINT_RESOLUTION) -> Figure:
    """The paper's figure 13 from the region map: where the convex working modes ('+-+' and
    its mirror '-+-') reach free of parallel singularities (and of the other margins)."""
    return _figure_mode_regions(
        "Fig. 13 from the region map: convex working mode", design, CONVEX, n
    )


def figure_14_regions(design: Design = MODE_CHANGE_DESIGN, n: int = PRINT_RESOLUTION) -> Figure:
    """The paper's figure 14 from the region map: the non-convex working modes ('++-' and
    '--+')."""
    return _figure_mode_regions(
        "Fig. 14 from the region map: non-convex working mode", design, NONCONVEX, n
    )
