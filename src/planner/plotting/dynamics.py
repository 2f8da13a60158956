"""The reflected-inertia map (named figure ``inertia_map``): the largest eigenvalue of the
mass matrix over the (theta2, theta3) plane of assembly mode '+', per working mode, for the
five-bar and for its serial counterpart in the same postures
(:func:`planner.dynamics.analysis.serial_comparison`), like the isoconditioning map of
kappa(A). M does not depend on theta1, so the plane is the whole workspace; assembly mode '-'
is its mirror image (the same values)."""

from __future__ import annotations

import numpy as np
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure

from planner.design import Design
from planner.kinematics import WORKING_MODES
from planner.plotting._common import _design_text, _joint_axes, _legend_below, _parallel, _serial
from planner.plotting._common import plot_loci as _plot_loci

__all__ = ["figure_inertia_map"]


def figure_inertia_map(design: Design, n: int = 128) -> Figure:
    """Three panels over (theta2, theta3), assembly mode '+', with the default inertia: the
    five-bar's largest eigenvalue of M, the serial counterpart's (one colour scale, log), and
    their ratio; each working mode's region labelled with its median, the singularity loci
    (which bound the working modes) drawn; cells outside kappa(A) <= 10 or a serial measure
    below 0.05 blank."""
    from planner.dynamics import Inertia
    from planner.dynamics.analysis import serial_comparison

    cmp = serial_comparison(design, Inertia.default(design), resolution=min(int(n), 256))
    stats = cmp.by_mode()
    extent = (cmp.theta2[0], cmp.theta2[-1], cmp.theta3[0], cmp.theta3[-1])
    both = np.concatenate(
        [cmp.parallel[np.isfinite(cmp.parallel)], cmp.serial[np.isfinite(cmp.serial)]]
    )
    norm = LogNorm(vmin=float(np.min(both)), vmax=float(np.max(both))) if both.size else None
    loci = {
        kind: loc.select(assembly_mode="+") if kind != "C=D" else loc
        for kind, loc in {**_serial(design), **_parallel(design)}.items()
    }
    panels = (
        ("five-bar (motors on the base)", cmp.parallel, "viridis", norm, "parallel_median"),
        ("serial counterpart (elbow motor at C)", cmp.serial, "viridis", norm, "serial_median"),
        ("ratio five-bar / serial", cmp.parallel / cmp.serial, "coolwarm",
         LogNorm(vmin=0.1, vmax=10.0), "ratio_median"),
    )  # fmt: skip
    fig = Figure(figsize=(15, 6.2))
    for k, (title, image, cmap, nrm, key) in enumerate(panels):
        ax = fig.add_subplot(1, 3, k + 1)
        shown = ax.imshow(
            image.T,
            origin="lower",
            extent=extent,
            cmap=cmap,
            norm=nrm,
            interpolation="nearest",
            aspect="equal",
        )
        fig.colorbar(
            shown, ax=ax, shrink=0.7, label="largest eigenvalue of M [kg m^2]" if k < 2 else "ratio"
        )
        _plot_loci(ax, loci, "joint", legend=False, halo=True)
        for slot, label in enumerate(WORKING_MODES):
            cells = np.argwhere(cmp.working_mode == slot)
            if not len(cells) or label not in stats:
                continue
            i, j = cells[len(cells) // 2]
            ax.annotate(
                f"{label}\nmedian {stats[label][key]:.3g}",
                (cmp.theta2[i], cmp.theta3[j]),
                fontsize=7,
                ha="center",
                va="center",
                bbox={"boxstyle": "round", "fc": "white", "alpha": 0.8},
            )
        if k == 0:
            _legend_below(ax, ncol=2)
        ax.set_title(title, fontsize=9)
        _joint_axes(ax)
    fig.suptitle(
        "Reflected inertia over the workspace: largest eigenvalue of M per working mode "
        f"(assembly mode '+'; default inertia)\n{_design_text(design)}",
        fontsize=10,
    )
    return fig
