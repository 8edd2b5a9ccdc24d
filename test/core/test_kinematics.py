"""Kinematics: paper numbers, round trips, limits, validation."""

import math

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
import pytest

from tracked_kinematics.core.kinematics import (
    forward, IcrParams, inverse, nominal_speeds, true_speeds)


# Martinez et al. (2005), sec. 5.3: GA identification on hard floor, paper frame.
AURIGA_GA = IcrParams.from_paper(-0.353, 0.425, 0.032, track_width=0.42,
                                 alpha_left=1.0072, alpha_right=1.0275)


def test_auriga_ga_maps_to_interface_example():
    # docs/model.md: icr.y_left 0.353, icr.y_right -0.425, icr.x 0.032.
    assert AURIGA_GA.y_left == pytest.approx(0.353)
    assert AURIGA_GA.y_right == pytest.approx(-0.425)
    assert AURIGA_GA.x == pytest.approx(0.032)
    assert AURIGA_GA.scale_left == pytest.approx(1.0072)
    assert AURIGA_GA.to_paper()['x_icr_right'] == pytest.approx(0.425)


def test_auriga_ga_indices():
    # Sec. 5.3 prints chi = 0.55 and e = 0.092 for these ICRs. Eq. (12) with L = 0.42 m gives
    # 0.42 / (0.425 + 0.353) = 0.5398, not 0.55 (0.55 would need the ICRs 0.764 m apart):
    # the printed chi is a rounding or typo in the paper, and we test what eq. (12) gives.
    assert AURIGA_GA.chi == pytest.approx(0.540, abs=5e-4)
    # Eq. (13): (0.425 - 0.353) / 0.778 = 0.0925.
    assert AURIGA_GA.eccentricity == pytest.approx(0.092, abs=1e-3)


def test_symmetric_experimental_model():
    # Sec. 5.3: chi = 0.526 from spin-in-place tests gives ICRs at +-0.399 m (eq. 12).
    icr = IcrParams.symmetric(0.42, 0.526)
    assert icr.y_left == pytest.approx(0.399, abs=5e-4)
    assert icr.y_right == pytest.approx(-0.399, abs=5e-4)
    assert icr.eccentricity == pytest.approx(0.0)


def test_dynamic_model_averages():
    # Sec. 5.2, asymmetric map average: x_ICRl -0.375, x_ICRr 0.457, y_ICRv 0.0492 ->
    # chi = 0.505, e = 0.098 by eq. (13). The paper prints e = 0.108; eq. (13) on its own
    # numbers gives 0.0986, so we test the equation, like chi above.
    icr = IcrParams.from_paper(-0.375, 0.457, 0.0492, track_width=0.42)
    assert icr.chi == pytest.approx(0.505, abs=5e-4)
    assert icr.eccentricity == pytest.approx(0.0986, abs=5e-4)


def test_ideal_is_differential_drive():
    icr = IcrParams.ideal(0.5)
    v_x, v_y, w = forward([0.3, -0.2, 1.0], [0.7, 0.2, 1.0], icr)
    np.testing.assert_allclose(v_x, [0.5, 0.0, 1.0])
    np.testing.assert_allclose(v_y, 0.0)
    np.testing.assert_allclose(w, [0.8, 0.8, 0.0])
    assert icr.chi == 1.0


def test_forward_hand_computed():
    # Left track stopped, right at 0.778 m/s with the Auriga ICRs: w = 0.778 / 0.778 = 1 rad/s,
    # v_x = V_r y_left / (y_left - y_right) = 0.353 m/s, v_y = -x w = -0.032 m/s.
    icr = AURIGA_GA
    v_x, v_y, w = forward(0.0, 0.778, icr)
    assert float(w) == pytest.approx(1.0)
    assert float(v_x) == pytest.approx(0.353)
    assert float(v_y) == pytest.approx(-0.032)


def test_forward_broadcasts_over_large_arrays():
    rng = np.random.default_rng(1)
    v_l, v_r = rng.normal(size=(2, 100_000))
    v_x, v_y, w = forward(v_l, v_r, AURIGA_GA)
    assert v_x.shape == v_y.shape == w.shape == (100_000,)
    # Spot check one sample against the scalar call.
    assert float(forward(v_l[7], v_r[7], AURIGA_GA)[2]) == pytest.approx(w[7])


def test_scales_round_trip():
    v_l, v_r = true_speeds(0.5, -0.25, AURIGA_GA)
    assert float(v_l) == pytest.approx(0.5 * 1.0072)
    back = nominal_speeds(v_l, v_r, AURIGA_GA)
    np.testing.assert_allclose(back, [0.5, -0.25])


@st.composite
def icr_params(draw):
    track_width = draw(st.floats(0.1, 3.0))
    chi = draw(st.floats(0.2, 1.0))
    span = track_width / chi
    ecc = draw(st.floats(-0.5, 0.5))
    center = -ecc * span / 2.0
    return IcrParams(track_width, center + span / 2.0, center - span / 2.0,
                     draw(st.floats(-0.5, 0.5)), draw(st.floats(0.8, 1.2)),
                     draw(st.floats(0.8, 1.2)))


speeds = st.floats(-3.0, 3.0)


@given(icr_params(), speeds, speeds)
def test_inverse_of_forward_recovers_track_speeds(icr, v_l, v_r):
    v_x, _, w = forward(v_l, v_r, icr)
    back_l, back_r = inverse(v_x, w, icr)
    assert float(back_l) == pytest.approx(v_l, abs=1e-9)
    assert float(back_r) == pytest.approx(v_r, abs=1e-9)


@given(icr_params(), speeds, st.floats(-3.0, 3.0))
def test_forward_of_inverse_recovers_twist(icr, v_x, w):
    v_x2, v_y2, w2 = forward(*inverse(v_x, w, icr), icr)
    assert float(v_x2) == pytest.approx(v_x, abs=1e-9)
    assert float(w2) == pytest.approx(w, abs=1e-9)
    # The lateral velocity is not commanded: it is what the ICRs impose.
    assert float(v_y2) == pytest.approx(-icr.x * w, abs=1e-9)


@given(icr_params(), speeds)
def test_equal_track_speeds_drive_straight(icr, v):
    v_x, v_y, w = forward(v, v, icr)
    assert float(w) == 0.0
    assert float(v_y) == 0.0
    assert float(v_x) == pytest.approx(v, abs=1e-12)


@given(icr_params(), speeds, speeds)
def test_mirror_symmetry(icr, v_l, v_r):
    # Swapping the tracks of the mirrored vehicle mirrors the motion.
    mirrored = IcrParams(icr.track_width, -icr.y_right, -icr.y_left, icr.x)
    v_x, v_y, w = forward(v_l, v_r, icr)
    mv_x, mv_y, mw = forward(v_r, v_l, mirrored)
    assert float(mv_x) == pytest.approx(float(v_x), abs=1e-9)
    assert float(mv_y) == pytest.approx(-float(v_y), abs=1e-9)
    assert float(mw) == pytest.approx(-float(w), abs=1e-9)


@given(icr_params())
def test_indices_in_range(icr):
    assert 0.0 < icr.chi <= 1.0 + 1e-12
    assert math.isfinite(icr.eccentricity)


@pytest.mark.parametrize('kwargs, match', [
    ({'y_left': -0.3, 'y_right': -0.2}, 'y_left .* must be greater than y_right'),
    ({'y_left': 0.1, 'y_right': -0.1}, 'chi .* outside'),
    ({'y_left': float('nan')}, 'y_left must be finite'),
    ({'x': float('inf')}, 'x must be finite'),
    ({'scale_left': 0.0}, 'scale_left must be > 0'),
    ({'scale_right': -1.0}, 'scale_right must be > 0'),
    ({'track_width': 0.0}, 'track_width must be > 0'),
    ({'y_left': 'abc'}, 'y_left must be a number'),
])
def test_invalid_parameters_rejected(kwargs, match):
    values = {'track_width': 0.42, 'y_left': 0.3, 'y_right': -0.3, **kwargs}
    with pytest.raises(ValueError, match=match):
        IcrParams(**values)


def test_frozen():
    with pytest.raises(AttributeError):
        AURIGA_GA.x = 1.0
