"""Transit postures lie on the serial singularity they claim, and crossings flip one sign."""

from __future__ import annotations

import numpy as np
import pytest

from planner import Design, InputError, Manipulator, forward_batch
from planner.transits import (
    FLIPPED_SIGN,
    TRANSIT_KINDS,
    crossing_through,
    kinds_flipping,
    sample_transits,
)

GENERAL = Design(L0=0.3, L1=0.3, L2=0.45)  # every kind of transit exists


def _mode_of(design, q, assembly_mode):
    b = forward_batch(design, np.atleast_2d(q), assembly_mode)
    return "".join("+" if s > 0 else "-" if s < 0 else "0" for s in b.working_mode_signs[0])


@pytest.mark.parametrize("kind", TRANSIT_KINDS)
@pytest.mark.parametrize(("working_mode", "assembly"), [("++-", "-"), ("-+-", "-"), ("+-+", "+")])
def test_sampled_transits_are_on_their_surface(kind, working_mode, assembly):
    rng = np.random.default_rng(4)
    q = sample_transits(
        GENERAL, kind, working_mode=working_mode, assembly_mode=assembly, n=300, rng=rng
    )
    assert len(q) > 10
    m = Manipulator(GENERAL)
    a, b = np.array([0, -GENERAL.L0 / 2, 0]), np.array([0, GENERAL.L0 / 2, 0])
    flipped = FLIPPED_SIGN[kind]
    for qi in q[:25]:
        post = m.posture(qi, assembly)
        assert m.within_limits(qi)
        # the flipped sign is 0, the two others are the requested ones
        idx = {"axis": 0, "A": 1, "B": 2}[flipped]
        for j in range(3):
            expected = "0" if j == idx else working_mode[j]
            assert post.working_mode[j] == expected
        # geometric meaning, from the 3-D points
        if kind == "P_on_axis":
            np.testing.assert_allclose(post.p[[0, 2]], 0, atol=1e-12)
        else:
            pivot = a if flipped == "A" else b
            reach = (
                GENERAL.L1 + GENERAL.L2 if kind.endswith("stretched") else GENERAL.L2 - GENERAL.L1
            )
            assert np.linalg.norm(post.p - pivot) == pytest.approx(reach, abs=1e-9)


def test_paper_optimum_changes_mode_only_through_the_axis():
    """L0 = 0, L1 = L2: a stretched leg stretches both (C = D: parallel singular) and a folded
    leg puts P on the base point, so only axis transits exist."""
    rng = np.random.default_rng(0)
    d = Design.paper_optimum()
    for kind in TRANSIT_KINDS[1:]:
        q = sample_transits(d, kind, working_mode="+-+", assembly_mode="+", n=200, rng=rng)
        if len(q):
            b = forward_batch(d, q, "+")
            assert not np.any(b.ok), kind  # nothing that assembles regularly
    q = sample_transits(d, "P_on_axis", working_mode="+-+", assembly_mode="+", n=200, rng=rng)
    assert len(q) > 50


def test_singularity_free_design_never_reaches_the_axis():
    """Both legs reach a point u on the axis only if |u -+ L0/2| lies in [L2 - L1, L1 + L2] for
    both pivots; for (0.5, 0.2, 0.6) those intervals do not meet."""
    d = Design.singularity_free()
    u = np.linspace(-2, 2, 40001)
    both = np.all(
        [(np.abs(u - c) >= d.L2 - d.L1) & (np.abs(u - c) <= d.L1 + d.L2) for c in (-0.25, 0.25)],
        axis=0,
    )
    assert not both.any()
    q = sample_transits(
        d, "P_on_axis", working_mode="+-+", assembly_mode="+", n=500, rng=np.random.default_rng(1)
    )
    assert len(q) == 0


@pytest.mark.parametrize("kind", TRANSIT_KINDS)
def test_crossing_flips_exactly_one_sign_once(kind):
    rng = np.random.default_rng(8)
    mode = "+-+"
    q = sample_transits(GENERAL, kind, working_mode=mode, assembly_mode="+", n=300, rng=rng)
    flipped = FLIPPED_SIGN[kind]
    idx = {"axis": 0, "A": 1, "B": 2}[flipped]
    built = 0
    for qt in q[:10]:
        c = crossing_through(
            GENERAL, qt, assembly_mode="+", flipped=flipped, sign_before=1, margin=0.05
        )
        if c is None:
            continue
        built += 1
        assert c.kind == kind and c.flipped == flipped
        before, after = _mode_of(GENERAL, c.q_in, "+"), _mode_of(GENERAL, c.q_out, "+")
        assert before[idx] == "+" and after[idx] == "-"
        assert [before[j] for j in range(3) if j != idx] == [after[j] for j in range(3) if j != idx]
        np.testing.assert_allclose(c.q_in + c.q_out, 2 * c.q_transit, atol=1e-12)  # collinear
        # dense independent walk: the sign changes exactly once along the line
        s = np.linspace(0, 1, 2001)
        line = c.q_in + s[:, None] * (c.q_out - c.q_in)
        b = forward_batch(GENERAL, line, "+")
        assert b.ok.all()
        measure = b.serial_measures[:, idx]
        assert np.count_nonzero(np.diff(np.sign(measure[np.abs(measure) > 1e-12]))) == 1
        assert abs(measure[0]) >= 0.05 and abs(measure[-1]) >= 0.05
    assert built >= 5


def test_kinds_flipping_and_bad_input():
    assert kinds_flipping("A") == ("leg_A_stretched", "leg_A_folded")
    assert kinds_flipping("axis") == ("P_on_axis",)
    with pytest.raises(InputError, match="flipped"):
        kinds_flipping("C")
    with pytest.raises(InputError, match="kind"):
        sample_transits(
            GENERAL,
            "elbow",
            working_mode="+++",
            assembly_mode="+",
            n=3,
            rng=np.random.default_rng(),
        )
    with pytest.raises(InputError, match="working_mode"):
        sample_transits(
            GENERAL,
            "P_on_axis",
            working_mode="+0+",
            assembly_mode="+",
            n=3,
            rng=np.random.default_rng(),
        )
