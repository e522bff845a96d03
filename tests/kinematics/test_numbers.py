"""``finite_or_none``: the one place NaN and infinities become JSON's null."""

from __future__ import annotations

import math

import numpy as np
import pytest

import kinematics
from kinematics.numbers import finite_or_none


@pytest.mark.parametrize("x", [math.inf, -math.inf, math.nan, np.float64("nan"),
                               np.float32("inf")])
def test_non_finite_numbers_become_none(x):
    assert finite_or_none(x) is None


@pytest.mark.parametrize("x, expected", [(0, 0.0), (-2.5, -2.5), (np.float64(3.25), 3.25),
                                         (np.int64(7), 7.0), (1e308, 1e308)])
def test_finite_numbers_come_back_as_plain_floats(x, expected):
    out = finite_or_none(x)
    assert out == expected and type(out) is float


def test_it_is_re_exported_from_the_package():
    assert kinematics.finite_or_none is finite_or_none
    assert "finite_or_none" in kinematics.__all__
