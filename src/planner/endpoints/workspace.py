"""Jobs of ``/v1/workspace`` and ``/v1/figures``: the workspace sections and the paper's figures."""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from planner.endpoints import UNBOUNDED, JobBudget
from planner.kinematics import mode_label
from planner.wire import (
    DesignModel,
    FigureQuery,
    SectionGrid,
    WorkspaceRequest,
    WorkspaceResponse,
    located,
    sampled_value,
)

__all__ = ["figure", "section_grid", "workspace"]


def _bits(mask: np.ndarray) -> list[list[int]]:
    """(ny, nx, K) bool -> (ny, nx) int bit masks, bit k for slot k."""
    weights = 1 << np.arange(mask.shape[-1], dtype=np.int64)
    return (mask.astype(np.int64) * weights).sum(axis=-1).tolist()


def section_grid(section: Any) -> SectionGrid:
    """The wire form of a :class:`planner.analysis.sections.Section`."""
    best = section.best_kappa
    best_list = [[float(v) if math.isfinite(v) else None for v in row] for row in best]
    working_mode = None
    if section.kind == "joint":
        wm = section.working_mode
        working_mode = [
            [
                [mode_label(wm[j, i, k]) if section.reached[j, i, k] else None for k in range(2)]
                for i in range(wm.shape[1])
            ]
            for j in range(wm.shape[0])
        ]
    return SectionGrid(
        kind=section.kind,
        x=section.x.tolist(),
        y=section.y.tolist(),
        theta1=section.theta1,
        labels=list(section.labels),
        reached=_bits(section.reached),
        singular=_bits(section.singular),
        best_kappa=best_list,
        working_mode=working_mode,
    )


def workspace(request: WorkspaceRequest, budget: JobBudget = UNBOUNDED) -> WorkspaceResponse:
    """``POST /v1/workspace``: closed-form and sampled volumes (per working mode, well
    conditioned, GCI) and the Cartesian and joint sections as grids."""
    from planner.analysis.sections import cartesian_section, joint_section
    from planner.analysis.workspace import closed_form_volume, sample_workspace

    with located("body", "design"):
        design = request.design.to_design()
    deadline = budget.deadline
    sample = sample_workspace(
        design,
        rel_se=request.rel_se,
        kappa_max=request.kappa_max,
        working_modes=request.working_modes,
        joint_limits=request.joint_limits,
        seed=request.seed,
        # half of what is left of the request's budget (the sections come next)
        deadline=None if deadline is None else (time.monotonic() + deadline) / 2,
    )
    opts = request.sections
    cart = joint = None
    with located("body", "sections"):
        if opts.cartesian:
            cart = section_grid(
                cartesian_section(
                    design, opts.resolution, theta1=opts.theta1, joint_limits=request.joint_limits
                )
            )
        if opts.joint:
            joint = section_grid(
                joint_section(
                    design, opts.resolution, theta1=opts.theta1, joint_limits=request.joint_limits
                )
            )
    return WorkspaceResponse(
        design=DesignModel.from_design(design),
        volume=closed_form_volume(design),
        sampled_volume=sampled_value(sample.volume),
        per_mode={label: sampled_value(e) for label, e in sample.per_mode.items()},
        kappa_max=request.kappa_max,
        well_conditioned_volume=sampled_value(sample.well_conditioned),
        well_conditioned_fraction=sampled_value(sample.well_conditioned_fraction),
        gci=sampled_value(sample.gci),
        cartesian_section=cart,
        joint_section=joint,
    )


def figure(args: tuple[str, str, FigureQuery]) -> bytes:
    """``GET /v1/figures/{name}.{fmt}``: the image bytes (``args`` = name, format, query)."""
    from planner.plotting import render_figure

    name, fmt, query = args
    with located("query"):
        return render_figure(name, query.design(), n=query.resolution, fmt=fmt, dpi=query.dpi)
