"""The figures: the screen resolution served over HTTP shows what the print resolution shows,
the caches return what a fresh computation returns, and the readability fixes are in place.

Areas are compared between :data:`planner.plotting.SCREEN_RESOLUTION` (96 cells per axis) and
:data:`planner.plotting.PRINT_RESOLUTION` (256): each area a figure shows (the reached
section, the bands of kappa(A) of figure 15, the working-mode regions of the joint section):
a reached area within 1 % of its value, a band or mode region within 4 % (most are within
1 %; the worst are thin regions of about 1 % of the section), or for any area 0.2 % of the
whole section. The error of a cell count is about the boundary length times one cell.
Singular cells are not compared: they flag the cells a singular curve meets, a band one cell
wide whose area shrinks with the cell.
"""

from __future__ import annotations

import numpy as np
import pytest

from planner import Design
from planner.analysis._common import MODE_INDEX
from planner.analysis.sections import Section, cartesian_section, joint_section
from planner.kinematics import WORKING_MODES
from planner.plotting import (
    CONVEX,
    ISO_LEVELS,
    NONCONVEX,
    PRINT_RESOLUTION,
    SCREEN_RESOLUTION,
    figure_06,
    figure_09,
    figure_15,
    render_figure,
)

DESIGNS = {
    "default": Design.default(),
    "paper-optimum": Design.paper_optimum(),
    "mode-change": Design(L0=0.6, L1=0.25, L2=0.45),
    "general": Design(L0=0.3, L1=0.3, L2=0.4),
}
REACHED_REL_TOL = 0.01
REGION_REL_TOL = 0.04
ABS_TOL = 0.002  # of the section's whole area


def _cell_area(section: Section) -> float:
    return float((section.x[1] - section.x[0]) * (section.y[1] - section.y[0]))


def _cartesian_areas(section: Section) -> dict[str, float]:
    """m^2: reached and each band of kappa(A) of figure 15, per group of working modes."""
    out = {}
    cell = _cell_area(section)
    for group, modes in (("all", WORKING_MODES), ("convex", CONVEX), ("nonconvex", NONCONVEX)):
        slots = [MODE_INDEX[m] for m in modes]
        reached = section.reached[..., slots]
        kappa = np.where(reached, section.kappa_A[..., slots], np.inf).min(axis=-1)
        out[f"{group} reached"] = reached.any(axis=-1).sum() * cell
        for level in ISO_LEVELS[1:]:
            out[f"{group} kappa <= {level:g}"] = np.sum(kappa <= level) * cell
    return out


def _joint_areas(section: Section) -> dict[str, float]:
    """rad^2: each (assembly mode, working mode) region of the joint section."""
    cell = _cell_area(section)
    out = {}
    for k, am in enumerate(section.labels):
        wm = section.working_mode[..., k, :]
        for mode in WORKING_MODES:
            signs = np.array([1 if c == "+" else -1 for c in mode])
            inside = section.reached[..., k] & np.all(wm == signs, axis=-1)
            out[f"{am} {mode}"] = inside.sum() * cell
    return out


def _assert_agree(coarse: dict[str, float], fine: dict[str, float], whole: float) -> None:
    for key, value in fine.items():
        rel = REACHED_REL_TOL if key.endswith("reached") else REGION_REL_TOL
        tol = max(rel * value, ABS_TOL * whole)
        assert abs(coarse[key] - value) <= tol, (key, coarse[key], value, tol)


@pytest.mark.parametrize("name", sorted(DESIGNS))
def test_screen_and_print_resolution_show_the_same_cartesian_areas(name):
    design = DESIGNS[name]
    coarse = cartesian_section(design, SCREEN_RESOLUTION)
    fine = cartesian_section(design, PRINT_RESOLUTION)
    whole = float(np.ptp(fine.x) * np.ptp(fine.y))
    areas = _cartesian_areas(fine)
    assert areas["all reached"] > 0.2 * whole  # a real region, not an empty section
    _assert_agree(_cartesian_areas(coarse), areas, whole)


@pytest.mark.parametrize("name", sorted(DESIGNS))
def test_screen_and_print_resolution_show_the_same_joint_regions(name):
    design = DESIGNS[name]
    coarse = joint_section(design, SCREEN_RESOLUTION)
    fine = joint_section(design, PRINT_RESOLUTION)
    whole = float(np.ptp(fine.x) * np.ptp(fine.y))
    areas = _joint_areas(fine)
    assert sum(areas.values()) > 0.4 * whole
    _assert_agree(_joint_areas(coarse), areas, whole)


def test_a_cached_figure_is_the_same_image_and_its_inputs_are_read_only():
    from planner.plotting import _common

    design = Design(L0=0.45, L1=0.2, L2=0.55)  # used by no other test: a cold cache
    first = render_figure("cartesian_section", design, n=24, dpi=30)
    again = render_figure("cartesian_section", design, n=24, dpi=30)
    assert again == first
    other = render_figure("cartesian_section", design, n=32, dpi=30)
    assert other != first  # the resolution is part of the key
    section = _common._section("cartesian", design, 24)
    fresh = cartesian_section(design, 24)
    np.testing.assert_array_equal(section.reached, fresh.reached)
    np.testing.assert_array_equal(section.kappa_A, fresh.kappa_A)
    with pytest.raises(ValueError, match="read-only"):
        section.kappa_A[0, 0, 0] = 1.0


def test_figure_6_names_the_coincident_joints_once():
    fig = figure_06()
    texts = [t.get_text() for t in fig.axes[0].texts]
    assert "C = D" in texts
    assert "C" not in texts and "D" not in texts  # neither label hides under the other
    assert {"A", "B", "P"} <= set(texts)


def test_figure_9_legend_names_only_what_is_drawn():
    fig = figure_09(n=48)
    for ax in fig.axes[:2]:
        labels = [t.get_text() for t in ax.get_legend().get_texts()]
        assert "serial: P on AB" in labels and "parallel: C = D" in labels
        # with L0 = 0, L1 = L2 no stretched leg or stretched CD is traced in joint space
        assert "serial: leg A" not in labels and "parallel: CD stretched" not in labels
        assert "P = A = B (erratum 6)" in labels


def test_figure_15_labels_every_level_on_its_curves():
    fig = figure_15(n=48)
    convex, nonconvex = ({t.get_text() for t in ax.texts} for ax in fig.axes[:2])
    assert {"1 isotropic", *(f"{v:g}" for v in ISO_LEVELS[1:])} <= convex, convex
    # the non-convex modes stay below kappa = 10 (no parallel singularity there): no 10 curve
    assert {"1 isotropic", "1.25", "1.5", "2", "3", "5"} <= nonconvex, nonconvex
    assert "10" not in nonconvex
