"""Figures of the design analysis (matplotlib; the only plotting package, core never imports it).

Modules: :mod:`~planner.plotting._common` (designs, colours, caches, drawing helpers),
:mod:`~planner.plotting.paper` (the paper's figures 4-15), :mod:`~planner.plotting.regions`
(the region-map figures), :mod:`~planner.plotting.dynamics` (the reflected-inertia map); this module names the figures for any design
(:data:`NAMED_FIGURES`, :func:`render_figure`). Every public name is importable from here.

:func:`write_figures` reproduces the seed paper's figures 4-15 as PNG and SVG files, one per
figure, each titled with the design used; axes in metres (the linkage plane: u along AB, w
normal to it) or radians (joint space theta2-theta3). Figures are built on
:class:`matplotlib.figure.Figure` objects (no pyplot global state), so this module is safe to
use from a server thread.

Speed: a worker draws the figures of the design a user is looking at again and again (the
viewer asks for the workspace section and the isoconditioning map of the current design), so
the sections and loci behind a figure are computed once per (design, resolution) and kept in
small per-process LRU caches (``plotting.*`` of :mod:`planner.caching`; :class:`Design` is
a frozen, hashable dataclass), and so are the rendered bytes of :func:`render_figure`. Cached arrays are
made read-only so that no figure can alter another's data. :data:`SCREEN_RESOLUTION` (the
HTTP default) and :data:`PRINT_RESOLUTION` (the CLI and the committed PNGs) are the two grid
sizes used; ``tests/analysis/test_analysis_figures.py`` checks that they agree.
"""

from __future__ import annotations

import io
from collections.abc import Callable

from matplotlib.figure import Figure

from planner.caching import cached
from planner.design import Design
from planner.plotting._common import (
    CONVEX,
    GENERAL_DESIGN,
    MODE_CHANGE_DESIGN,
    NONCONVEX,
    PRINT_RESOLUTION,
    SCREEN_RESOLUTION,
    draw_posture,
    plot_loci,
)
from planner.plotting.dynamics import figure_inertia_map
from planner.plotting.paper import (
    FIGURES,
    ISO_LEVELS,
    _cartesian_section_figure,
    _joint_section_figure,
    check_formats,
    figure_04,
    figure_05,
    figure_06,
    figure_07,
    figure_08,
    figure_09,
    figure_10,
    figure_11,
    figure_12,
    figure_13,
    figure_14,
    figure_15,
    write_figures,
)
from planner.plotting.regions import (
    figure_13_regions,
    figure_14_regions,
    figure_region_images,
    figure_region_map,
)

__all__ = [
    "CONVEX",
    "FIGURES",
    "FIGURE_FORMATS",
    "GENERAL_DESIGN",
    "ISO_LEVELS",
    "MODE_CHANGE_DESIGN",
    "NAMED_FIGURES",
    "NONCONVEX",
    "PRINT_RESOLUTION",
    "SCREEN_RESOLUTION",
    "check_formats",
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
    "figure_inertia_map",
    "figure_region_images",
    "figure_region_map",
    "plot_loci",
    "render_figure",
    "write_figures",
]


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
        design,
        n,
        "Lines: serial and parallel singularity loci.",
    )


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
    # the reflected inertia against the serial counterpart (planner.plotting.dynamics)
    "inertia_map": lambda d, n: figure_inertia_map(d, n),
}

#: Formats :func:`render_figure` writes.
FIGURE_FORMATS: tuple[str, ...] = ("png", "svg")


def render_figure(
    name: str, design: Design, *, n: int = SCREEN_RESOLUTION, fmt: str = "png", dpi: int = 80
) -> bytes:
    """One figure of :data:`NAMED_FIGURES` for ``design``, as PNG or SVG bytes.

    The bytes are cached per process (``plotting.figures``, :mod:`planner.caching`), and the
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


@cached("plotting.figures")
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
