"""Joint limits: validation with errors naming the field and the rule."""

from __future__ import annotations

import math

import numpy as np
import pytest

from planner import Design, InputError
from planner.exceptions import LimitsError
from planner.timing import JointLimits, time_path

GOOD = (1.0, 2.0, 3.0)


def test_valid_limits_are_stored_as_float_triples():
    lim = JointLimits(velocity=[1, 2, 3], acceleration=np.array([4.0, 5.0, 6.0]), jerk=GOOD)
    assert lim.velocity == (1.0, 2.0, 3.0)
    assert lim.acceleration == (4.0, 5.0, 6.0)
    assert lim.jerk == GOOD
    assert JointLimits(GOOD, GOOD).jerk is None


@pytest.mark.parametrize("field", ["velocity", "acceleration", "jerk"])
@pytest.mark.parametrize(
    ("value", "rule"),
    [
        ((1.0, 0.0, 1.0), "limits.{f}[1] must lie in [1e-06, 1e+06]"),
        ((1.0, 1.0, -2.0), "limits.{f}[2] must lie in [1e-06, 1e+06]"),
        ((1e-300, 1.0, 1.0), "limits.{f}[0] must lie in [1e-06, 1e+06]"),  # squares underflow
        ((1.0, 1e9, 1.0), "limits.{f}[1] must lie in [1e-06, 1e+06]"),
        ((math.nan, 1.0, 1.0), "limits.{f}[0] must be finite"),
        ((1.0, math.inf, 1.0), "limits.{f}[1] must be finite"),
        ((1.0, 1.0), "limits.{f} must be 3 numbers"),
        ((1.0, 1.0, 1.0, 1.0), "limits.{f} must be 3 numbers"),
        (("a", 1.0, 1.0), "limits.{f} must be 3 numbers"),
        (2.0, "limits.{f} must be 3 numbers"),
    ],
)
def test_bad_limits_are_rejected_naming_the_field(field, value, rule):
    kwargs = {"velocity": GOOD, "acceleration": GOOD, "jerk": GOOD, field: value}
    with pytest.raises(LimitsError) as err:
        JointLimits(**kwargs)
    assert rule.format(f=field) in str(err.value)
    assert isinstance(err.value, InputError) and isinstance(err.value, ValueError)


def test_ruckig_without_a_jerk_takes_its_default():
    """No jerk asked: Ruckig (which needs one) is timed under RUCKIG_DEFAULT_JERK, exactly
    as if that jerk had been given; toppra is not jerk-limited (its jerk undefined)."""
    from planner.timing.limits import RUCKIG_DEFAULT_JERK

    w = np.array([[0.0, 0.5, 1.0], [0.3, 0.7, 1.2]])
    free = time_path(Design.default(), w, JointLimits(GOOD, GOOD), method="ruckig")
    given = JointLimits(GOOD, GOOD, (RUCKIG_DEFAULT_JERK,) * 3)
    same = time_path(Design.default(), w, given, method="ruckig")
    assert free.duration == pytest.approx(same.duration, rel=1e-12)
    assert np.max(np.abs(free.jerk)) <= RUCKIG_DEFAULT_JERK * (1 + 1e-6)
    assert np.max(np.abs(free.jerk)) >= 0.99 * RUCKIG_DEFAULT_JERK  # it binds: no other jerk
    toppra = time_path(Design.default(), w, JointLimits(GOOD, GOOD), method="toppra")
    assert toppra.jerk is None


def test_scaled_keeps_jerk_and_rejects_bad_factor():
    lim = JointLimits(GOOD, GOOD, GOOD).scaled(0.5)
    assert lim.velocity == (0.5, 1.0, 1.5) and lim.jerk == GOOD
    with pytest.raises(LimitsError):
        JointLimits(GOOD, GOOD).scaled(0.0)
