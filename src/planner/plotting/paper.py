"""The seed paper's figures 4-15 (:data:`FIGURES`) and :func:`write_figures`, which writes
them as files."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from planner.analysis.loci import (
    Locus,
    isoconditioning_loci,
)
from planner.caching import cached
from planner.design import Design
from planner.kinematics import WORKING_MODES, conditioning, inverse_batch
from planner.plotting._common import (
    _BASE_POINT,
    _BASE_POINT_COLOUR,
    _MODE_COLOURS,
    _SINGULAR,
    _SINGULAR_COLOUR,
    CONVEX,
    GENERAL_DESIGN,
    MODE_CHANGE_DESIGN,
    NONCONVEX,
    PRINT_RESOLUTION,
    _cartesian_axes,
    _design_text,
    _extent,
    _in_plane,
    _joint_axes,
    _kappa_panel,
    _legend_below,
    _mode_cmap,
    _mode_index_image,
    _parallel,
    _read_only,
    _section,
    _serial,
    draw_posture,
    logger,
    plot_loci,
)

__all__ = [
    "FIGURES",
    "ISO_LEVELS",
    "ISO_SAMPLES",
    "check_formats",
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
    "figure_14",
    "figure_15",
    "write_figures",
]


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
        ax.set_title(
            f"working mode {WORKING_MODES[k]}  (kappa(A) = {c.kappa_A[i, k]:.2f})", fontsize=9
        )
        _cartesian_axes(ax)
        ax.label_outer()
    fig.suptitle(
        f"Fig. 4: the four working modes (s_axis = +) at P = ({p[i, 1]:.3f}, "
        f"{p[i, 0]:.3f}) m\n{_design_text(design)}",
        fontsize=10,
    )
    return fig


def _posture_figure(title: str, design: Design, locus: Locus, note: str) -> Figure:
    i = _pick(locus, design)
    fig = Figure(figsize=(6, 5))
    ax = fig.add_subplot(1, 1, 1)
    draw_posture(ax, design, locus.q[i], locus.passive[i], colour="tab:red")
    c = conditioning(design, locus.q[i], locus.passive[i], locus.uw[i, 1])
    ax.set_title(f"{title}\n{_design_text(design)}", fontsize=10)
    ax.text(
        0.02,
        0.02,
        f"{note}\nkappa(A) = {float(c.kappa_A):.3g}, min serial margin = {float(c.min_serial):.3g}",
        transform=ax.transAxes,
        fontsize=8,
    )
    _cartesian_axes(ax)
    return fig


def figure_05(design: Design = GENERAL_DESIGN) -> Figure:
    """Parallel singularity: P the midpoint of a stretched CD."""
    locus = _parallel(design)["CD_stretched"]
    return _posture_figure(
        "Fig. 5: parallel singularity, C, P, D aligned (CD stretched)",
        design,
        locus,
        "A cannot resist a force normal to CD",
    )


def figure_06(design: Design = GENERAL_DESIGN) -> Figure:
    """Parallel singularity: C = D, P turns freely about them."""
    locus = _parallel(design)["C=D"]
    fig = _posture_figure(
        "Fig. 6: parallel singularity, C = D",
        design,
        locus,
        "P can turn about C = D with the actuators locked",
    )
    ax = fig.axes[0]
    i = _pick(locus, design)
    cd = _in_plane(design, locus.q[i], locus.passive[i])[2]
    t = np.linspace(0, 2 * np.pi, 200)
    ax.plot(cd[0] + design.L2 * np.cos(t), cd[1] + design.L2 * np.sin(t), ":", color="tab:red")
    return fig


def figure_07(design: Design = GENERAL_DESIGN) -> Figure:
    """Serial singularity: leg B stretched, P on the workspace boundary."""
    locus = _serial(design)["leg_B_stretched"]
    fig = _posture_figure(
        "Fig. 7: serial singularity, leg B stretched (B, D, P aligned)",
        design,
        locus,
        "P cannot move along BP",
    )
    ax = fig.axes[0]
    t = np.linspace(0, 2 * np.pi, 400)
    ax.plot(
        design.L0 / 2 + design.reach * np.cos(t),
        design.reach * np.sin(t),
        ":",
        color="0.5",
        label="|BP| = L1 + L2",
    )
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
        ax.imshow(
            img,
            origin="lower",
            extent=_extent(section),
            cmap=_mode_cmap(),
            vmin=-0.5,
            vmax=_BASE_POINT + 0.5,
            interpolation="nearest",
            aspect="equal",
        )
        mine = {
            kind: loc.select(assembly_mode=mode) if kind != "C=D" else loc
            for kind, loc in loci.items()
        }
        plot_loci(ax, mine, "joint", legend=False, halo=True)
        handles, _ = ax.get_legend_handles_labels()
        values = {int(v) for v in np.unique(img[np.isfinite(img)])}
        handles += [
            Patch(color=_MODE_COLOURS[v], label=f"mode {WORKING_MODES[v]}")
            for v in sorted(values)
            if v < _SINGULAR
        ]
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
        "Fig. 8: cross-section of the Cartesian workspace (L0 = 0, L1 = L2)",
        design,
        n,
        "Modes with s_A = s_B are parallel-singular everywhere (C = D): only ++-, +-+ (and "
        "mirrors) operate.\nAll singularities lie on the boundary: |OP| = L1 + L2, the axis, P = O.",
    )


def figure_09(design: Design | None = None, n: int = PRINT_RESOLUTION) -> Figure:
    design = design or Design.paper_optimum()
    return _joint_section_figure(
        "Fig. 9: cross-section of the joint space (L0 = 0, L1 = L2); grey: P at the base "
        "point A = B (erratum 6)",
        design,
        n,
    )


def figure_10(design: Design | None = None, n: int = PRINT_RESOLUTION) -> Figure:
    design = design or Design.singularity_free()
    return _cartesian_section_figure(
        "Fig. 10: Cartesian workspace free of parallel singularities (2 L1 < L0 < 2 (L2 - L1))",
        design,
        n,
        "kappa(A) stays bounded: only serial singularities, on the boundary.",
    )


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
        s = WORKING_MODES.index(mode)
        draw_posture(ax, design, b.q[0, s], b.passive[0, s], colour=_MODE_COLOURS[s])
        kind = "convex" if k == 0 else "non-convex"
        ax.set_title(f"{kind} working mode {mode}: kappa(A) = {c.kappa_A[0, s]:.3g}", fontsize=9)
        _cartesian_axes(ax)
    fig.suptitle(
        f"Fig. 12: working mode and parallel singularity, P = ({p[1]:.3f}, {p[0]:.3f}) m"
        f"\n{_design_text(design)}",
        fontsize=10,
    )
    return fig


def _mode_workspace_figure(title: str, design: Design, modes: tuple[str, str], n: int) -> Figure:
    section = _section("cartesian", design, n)
    slots = [WORKING_MODES.index(m) for m in modes]
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
    ax.plot(
        [],
        [],
        color="red" if drawn else "none",
        label="parallel singularity in these modes"
        if drawn
        else "no parallel singularity in these modes",
    )
    _legend_below(ax, ncol=2)
    ax.set_title(
        f"{title}\nmodes {modes[0]} (w > 0) and {modes[1]} (w < 0); {_design_text(design)}",
        fontsize=9,
    )
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


@cached("plotting.iso")
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
        slots = [WORKING_MODES.index(m) for m in modes]
        reached = section.reached[..., slots]
        kappa = np.where(reached, section.kappa_A[..., slots], np.inf).min(axis=-1)
        kappa = np.where(reached.any(axis=-1), kappa, np.nan)
        ax.imshow(
            kappa,
            origin="lower",
            extent=_extent(section),
            cmap=band_colours,
            norm=norm,
            interpolation="nearest",
            aspect="equal",
        )
        segs = [
            [
                seg
                for m in modes
                for seg in _segments(loci[level].select(working_mode=m).polyline("cartesian"))
            ]
            for level in ISO_LEVELS
        ]
        widths = [2.4 if level == 1.0 else 1.0 for level in ISO_LEVELS]
        colours = ["tab:blue" if level == 1.0 else "0.15" for level in ISO_LEVELS]
        long = [[g for g in ss if _length(g) >= long_enough] for ss in segs]
        short = [[g for g in ss if _length(g) < long_enough] for ss in segs]
        for ss, c, lw in zip(short, colours, widths, strict=True):
            for g in ss:
                ax.plot(g[:, 0], g[:, 1], color=c, lw=lw)
        cs = ContourSet(ax, list(ISO_LEVELS), long, colors=colours, linewidths=widths)
        with_curves = [lvl for lvl, ss in zip(ISO_LEVELS, long, strict=True) if ss]
        ax.clabel(cs, with_curves, inline=True, inline_spacing=2, fontsize=7, fmt=_iso_label)
        for m in modes:
            sel = {kk: v.select(working_mode=m) for kk, v in par.items()}
            plot_loci(ax, sel, "cartesian", legend=False, labels=False)
        handles = [
            Line2D([], [], color="tab:blue", lw=2.4, label="isotropy, kappa(A) = 1"),
            Line2D(
                [],
                [],
                color="0.15",
                lw=1.0,
                label="kappa(A) = " + ", ".join(f"{v:g}" for v in ISO_LEVELS[1:]),
            ),
            Line2D([], [], color="red", lw=1.6, label="parallel singularity"),
            Patch(color=band_colours(band_colours.N - 1), label="kappa(A) > 10"),
            Patch(color=band_colours(0), label="kappa(A) < 1.25"),
        ]
        _legend_below(ax, ncol=2, handles=handles)
        kind = "convex" if k == 0 else "non-convex"
        ax.set_title(f"{kind} modes {modes[0]} (w > 0) / {modes[1]} (w < 0)", fontsize=9)
        _cartesian_axes(ax)
    fig.suptitle(
        f"Fig. 15: isoconditioning curves of kappa(A) for two working modes "
        f"(labels: kappa)\n{_design_text(design)}",
        fontsize=10,
    )
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


def check_formats(formats: tuple[str, ...], allowed: tuple[str, ...] | None = None) -> None:
    """Refuse, before any figure is drawn, a format that matplotlib cannot write (or, with
    ``allowed``, one outside it): :class:`~planner.exceptions.InputError` at ``formats``
    naming the format and the ones there are.
    """
    from matplotlib.backend_bases import FigureCanvasBase

    from planner.exceptions import InputError

    known = (
        tuple(sorted(FigureCanvasBase.get_supported_filetypes())) if allowed is None else allowed
    )
    if not formats:
        raise InputError(f"no format given; one or more of {', '.join(known)}", field="formats")
    for fmt in formats:
        if fmt not in known:
            raise InputError(f"no format {fmt!r}; one of {', '.join(known)}", field="formats")


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
    check_formats(formats)
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
