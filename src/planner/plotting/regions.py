"""Figures of the region map: the map itself, its regions' Cartesian images, and figures
13-14 drawn from the regions."""

from __future__ import annotations

import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from planner.design import Design
from planner.kinematics import WORKING_MODES
from planner.plotting._common import (
    CONVEX,
    MODE_CHANGE_DESIGN,
    NONCONVEX,
    PRINT_RESOLUTION,
    _cartesian_axes,
    _design_text,
    _joint_axes,
    _legend_below,
)

__all__ = ["figure_13_regions", "figure_14_regions", "figure_region_images", "figure_region_map"]


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
    extent = (lo[1], hi[1], lo[2], hi[2])
    for ai, asm in enumerate(("+", "-")):
        ax = fig.add_subplot(1, 2, ai + 1)
        img = np.ones((n, n, 4))
        for region in rmap.regions:
            if region.assembly_mode != asm:
                continue
            mi = WORKING_MODES.index(region.working_mode)
            cells = rmap.labels[ai, mi] == region.label
            sure = cells & (rmap.status[ai, mi] == VALID)
            pale = cells & ~sure & (img[..., 0] == 1.0) & (img[..., 1] == 1.0)
            img[pale] = 0.55 + 0.45 * colours[region.id]
            img[sure] = colours[region.id]
            if sure.any():
                k3, k2 = np.nonzero(sure)
                m = len(k3) // 2
                ax.text(
                    rmap.theta2[k2[m]],
                    rmap.theta3[k3[m]],
                    f"{region.working_mode}\n#{region.component}",
                    fontsize=7,
                    ha="center",
                    va="center",
                    bbox={"fc": "white", "ec": "none", "alpha": 0.7, "pad": 1},
                )
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
            handles.append(
                Patch(color=colours[region.id], label=f"{region.working_mode} #{region.component}")
            )
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
    extent = (cov.u[0], cov.u[-1], cov.w[0], cov.w[-1])
    for ai, asm in enumerate(("+", "-")):
        ax = fig.add_subplot(1, 2, ai + 1)
        mine = [r for r in rmap.regions if r.assembly_mode == asm and r.valid_cells]
        ids = [r.id for r in mine if r.working_mode in modes]
        img = _coverage_image(cov, ids, colours, [r.id for r in mine])
        ax.imshow(img, origin="lower", extent=extent, interpolation="nearest")
        pair, every = cov.area(ids), cov.area(r.id for r in mine)
        handles = [
            Patch(color=colours[i], label=f"{rmap.regions[i].working_mode} region {i}") for i in ids
        ]
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
