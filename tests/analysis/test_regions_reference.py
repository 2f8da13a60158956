"""The fast region map (issue 17) gives, bit for bit, the map of the build it replaced.

The reference is the old route itself, kept callable in ``_region_reference.py`` (its numba
kernels and pipeline copied unchanged from before the speed-up), not the new code run twice:
every cell state, label, certified label, centre mode, transit cell, measure bound, region
and transit must be equal, on designs with and without the mirror symmetry, on default and
other margins, at three resolutions and with no refinement. The dense-sampling oracles of
``test_regions.py`` check both against the validity checker."""

from __future__ import annotations

import numpy as np
import pytest
from _region_reference import reference_region_map

from planner import caching
from planner.analysis import regions as R
from planner.design import Design
from planner.validity import Margins

#: name -> (design, margins): symmetric boxes (mirrored build) and cut ones (both assembly
#: modes classified), default and other margins.
CASES = {
    "default": (Design.default(), Margins()),
    "paper-optimum": (Design.paper_optimum(), Margins()),
    "general": (Design(0.3, 0.3, 0.4), Margins()),
    "mode-change": (Design(0.6, 0.25, 0.45), Margins()),
    "tight-limits": (
        Design(0.3, 0.3, 0.4, joint_min=(-1, -2, -1.5), joint_max=(1, 2.5, 3)),
        Margins(),
    ),
    "cut": (
        Design(0.3, 0.3, 0.4, joint_min=(-3.14, -0.49, -2.81), joint_max=(3.14, 0.51, -1.72)),
        Margins(),
    ),
    "default-margins-4-0.2": (Design.default(), Margins(kappa_max=4.0, serial_min=0.2)),
    "general-margins-30-0.01": (Design(0.3, 0.3, 0.4), Margins(kappa_max=30.0, serial_min=0.01)),
}
ARRAYS = (
    "theta2", "theta3", "status", "labels", "certified", "centre_mode", "transit_cells",
    "region_index", "measure_low", "measure_high",
)  # fmt: skip


def _assert_same_map(new: R.RegionMap, old: R.RegionMap) -> None:
    for field in ARRAYS:
        a, b = getattr(new, field), getattr(old, field)
        assert a.dtype == b.dtype and a.shape == b.shape, field
        assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), field
    assert (new.h2, new.h3) == (old.h2, old.h3)
    assert new.regions == old.regions
    assert new.transits == old.transits


@pytest.mark.parametrize("n", [64, 128, 256])
@pytest.mark.parametrize("name", sorted(CASES))
def test_fast_map_equals_the_old_build(name, n):
    design, margins = CASES[name]
    caching.clear("regions")
    new = R.region_map(design, margins, n)
    old = reference_region_map(design, margins, n, R.DEFAULT_REFINE)
    _assert_same_map(new, old)
    # the maps are not trivial: regions, transits (where the design has them), decided cells
    assert len(new.regions) > 0
    assert (new.status != R.UNDECIDED).mean() > 0.8


@pytest.mark.parametrize("refine", [1, 3])
@pytest.mark.parametrize("name", ["general", "tight-limits"])
def test_fast_map_equals_the_old_build_at_other_refinements(name, refine):
    design, margins = CASES[name]
    caching.clear("regions")
    new = R.region_map(design, margins, 96, refine=refine)
    _assert_same_map(new, reference_region_map(design, margins, 96, refine))


def test_the_cases_cover_transits_and_both_builds():
    """The comparison above meets maps with transits, and both the mirrored and the direct
    build (a box not symmetric about 0)."""
    maps = {name: R.region_map(d, m, 64) for name, (d, m) in CASES.items()}
    assert sum(len(rmap.transits) > 0 for rmap in maps.values()) >= 4
    assert {R._mirrored(d) for d, _ in CASES.values()} == {True, False}
