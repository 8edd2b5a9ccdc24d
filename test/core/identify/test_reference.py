"""Calibration without ground truth: gyro heading, GNSS / straight-drive distance, bad input."""

import math

from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
import pytest
from tracked_kinematics.core.errors import ExcitationError, SensorDataError
from tracked_kinematics.core.identify.reference import (
    check_gyro, fit_from_reference, fit_recordings)
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.models import ConstantIcr
from tracked_kinematics.core.recording import Recording

TRUE = IcrParams(B, *AURIGA)
S_TRUE = 0.5 * (TRUE.scale_left + TRUE.scale_right)
RHO_TRUE = TRUE.scale_right / TRUE.scale_left


@pytest.fixture(scope='module')
def drive():
    """Five minutes of the Auriga-alpha, exact pose at 100 Hz."""
    return simulate(ConstantIcr(B), np.array(AURIGA), duration=300.0, gt_rate=100.0, seed=5)


def gyro_of(rec, bias=0.0, noise=0.0, latency=0.0, seed=0):
    """Yaw rates between pose samples (mean over each interval), stamped ``latency`` late."""
    rng = np.random.default_rng(seed)
    yaw = np.unwrap(rec.gt_yaw)
    rate = np.diff(yaw) / np.diff(rec.gt_t)
    stamps = 0.5 * (rec.gt_t[1:] + rec.gt_t[:-1]) + latency
    return stamps, rate + bias + rng.normal(0.0, noise, rate.size) if noise else rate + bias


def gnss(positions):
    """Return the GNSS fields of a Recording from ``(t, x, y)``."""
    return dict(zip(('gnss_t', 'gnss_x', 'gnss_y'), positions))


def test_gyro_alone_gives_chi_ratio_bias_and_delay(drive):
    gyro_t, rate = gyro_of(drive, bias=0.015, noise=0.02, latency=0.12)
    fit = fit_from_reference(drive.enc_t, drive.left, drive.right, track_width=B, gyro_t=gyro_t,
                             gyro_rate=rate)
    assert fit.reference == 'imu'
    assert fit.determined == ['chi', 'scale_ratio']
    assert fit.held == ['distance_scale', 'icr.x', 'icr_offset']
    assert fit.imu_delay.delay == pytest.approx(0.12, abs=0.01)
    assert fit.biases[0] == pytest.approx(0.015, abs=5e-4)
    assert fit.scale_ratio == pytest.approx(RHO_TRUE, abs=2e-3)
    # At the held (ideal) distance scale 1, chi is the true chi times the true scale.
    assert fit.icr.chi == pytest.approx(TRUE.chi * S_TRUE, rel=5e-3)
    assert fit.icr.x == 0.0 and fit.icr.y_left == pytest.approx(-fit.icr.y_right)
    assert fit.report['held'] == fit.held and fit.report['imu_delay']['determined']
    noise = fit.report['gyro']['noise_rad_per_sqrt_s']
    assert 0.5 * 0.02 * math.sqrt(0.01) < noise < 2.0 * 0.02 * math.sqrt(0.01)


def test_held_values_come_from_the_base(drive):
    gyro_t, rate = gyro_of(drive)
    base = IcrParams(B, 0.30, -0.20, 0.05, 1.0, 1.0)
    fit = fit_from_reference(drive.enc_t, drive.left, drive.right, track_width=B, gyro_t=gyro_t,
                             gyro_rate=rate, base=base, imu_delay=0.0)
    assert fit.icr.x == 0.05
    assert 0.5 * (fit.icr.y_left + fit.icr.y_right) == pytest.approx(0.05)
    assert 0.5 * (fit.icr.scale_left + fit.icr.scale_right) == pytest.approx(1.0)


def test_gnss_fits_the_distance_scale(drive):
    gyro_t, rate = gyro_of(drive, bias=0.01, noise=0.01)
    rng = np.random.default_rng(3)
    pick = slice(0, None, 20)   # 5 Hz
    positions = (drive.gt_t[pick], drive.gt_x[pick] + rng.normal(0, 0.5, drive.gt_t[pick].size),
                 drive.gt_y[pick] + rng.normal(0, 0.5, drive.gt_t[pick].size))
    # Long windows: the exact constant-ICR model does not drift, and the scale is unbiased.
    fit = fit_recordings([Recording(drive.enc_t, drive.left, drive.right, gyro_t=gyro_t,
                                    gyro_rate=rate, **gnss(positions))], B,
                         position_window=120.0)
    assert fit.reference == 'imu+gnss'
    assert 'distance_scale' in fit.determined
    assert fit.distance_scale == pytest.approx(S_TRUE, abs=0.01)
    assert fit.icr.chi == pytest.approx(TRUE.chi, rel=0.02)
    assert fit.report['positions']['gnss']['residual_std_m'] == pytest.approx(0.5, rel=0.3)


def test_gyro_and_pose_together_fit_everything(drive):
    gyro_t, rate = gyro_of(drive, bias=0.01, noise=0.02)
    pick = slice(0, None, 10)
    pose = (drive.gt_t[pick], drive.gt_x[pick], drive.gt_y[pick], drive.gt_yaw[pick])
    fit = fit_from_reference(drive.enc_t, drive.left, drive.right, track_width=B, gyro_t=gyro_t,
                             gyro_rate=rate, pose=pose, imu_delay=0.0, pose_delay=0.0)
    assert fit.reference == 'imu+pose'
    assert fit.determined == ['chi', 'scale_ratio', 'distance_scale', 'icr.x', 'icr_offset']
    assert fit.held == []
    for name in ('y_left', 'y_right', 'x', 'scale_left', 'scale_right'):
        assert getattr(fit.icr, name) == pytest.approx(getattr(TRUE, name), abs=3e-3), name


def straight_run(turn_rate=0.0, duration=30.0):
    t = np.arange(0.0, duration, 0.01)
    v = np.clip(t, 0, 1) * np.clip(duration - 1 - t, 0, 1) * 0.8
    w = np.full(t.size, turn_rate)
    left = np.r_[0.0, np.cumsum((v - 0.5 * B * w)[:-1] * 0.01)]
    right = np.r_[0.0, np.cumsum((v + 0.5 * B * w)[:-1] * 0.01)]
    return t, left, right, w


def test_straight_distance_fixes_the_distance_scale():
    t, left, right, w = straight_run()
    distance = 0.97 * float(left[-1])    # the tracks say 3 % more than was measured
    fit = fit_from_reference(t, left, right, track_width=B, gyro_t=t, gyro_rate=w + 1e-4,
                             straight_distance=distance, imu_delay=0.0)
    assert fit.distance_scale == pytest.approx(0.97, rel=1e-3)
    assert fit.reference == 'imu+straight'
    assert 'distance_scale' in fit.determined and 'chi' in fit.held


def test_a_straight_drive_that_turns_is_refused():
    t, left, right, w = straight_run(turn_rate=0.05)
    with pytest.raises(ExcitationError, match='not a straight drive'):
        fit_from_reference(t, left, right, track_width=B, gyro_t=t, gyro_rate=w,
                           straight_distance=20.0, imu_delay=0.0)


@pytest.mark.parametrize('rates, match', [
    (np.zeros(500), 'no angular velocity'),
    (np.full(500, np.nan), 'no angular velocity'),
])
def test_unusable_gyro_readings_are_refused(rates, match):
    with pytest.raises(SensorDataError, match=match):
        check_gyro(rates)


def test_a_saturated_gyro_is_refused_by_the_fit(drive):
    gyro_t, rate = gyro_of(drive)
    with pytest.raises(SensorDataError, match='saturated'):
        fit_from_reference(drive.enc_t, drive.left, drive.right, track_width=B,
                           gyro_t=gyro_t, gyro_rate=np.clip(rate, -0.5, 0.5))


def test_too_little_turning_is_an_excitation_error():
    t, left, right, w = straight_run()
    with pytest.raises(ExcitationError, match='turns'):
        fit_recordings([Recording(t, left, right, gyro_t=t, gyro_rate=w + 1e-4)], B, imu_delay=0.0)


def test_an_orientation_yaw_serves_as_the_heading(drive):
    # An AHRS's yaw, offset and wrapped: the same chi and ratio as the rates give.
    yaw = np.angle(np.exp(1j * (np.unwrap(drive.gt_yaw) + 1.3)))
    fit = fit_from_reference(drive.enc_t, drive.left, drive.right, track_width=B,
                             gyro_t=drive.gt_t, gyro_yaw=yaw, imu_delay=0.0)
    assert fit.determined == ['chi', 'scale_ratio']
    assert fit.scale_ratio == pytest.approx(RHO_TRUE, abs=2e-3)
    assert fit.icr.chi == pytest.approx(TRUE.chi * S_TRUE, rel=5e-3)
    assert abs(fit.biases[0]) < 1e-4


def test_heading_reference_removes_bias_and_delay_and_skips_gaps(drive):
    from tracked_kinematics.core.identify.reference import heading_reference
    gyro_t, rate = gyro_of(drive, bias=0.02, latency=0.1)
    keep = (gyro_t < 100.0) | (gyro_t > 103.0)     # a 3-s gap in the gyro
    rec = Recording(drive.enc_t, drive.left, drive.right, gyro_t=gyro_t[keep],
                    gyro_rate=rate[keep])
    ref = heading_reference(rec, 0.1, 0.02)
    assert not np.any((ref.gt_t > 100.2) & (ref.gt_t < 102.9))
    before = ref.gt_t < 99.0
    true = np.interp(ref.gt_t[before], drive.gt_t, np.unwrap(drive.gt_yaw))
    got = np.unwrap(ref.gt_yaw[before])
    np.testing.assert_allclose(got - got[0], true - true[0], atol=2e-3)
    assert np.all(ref.gt_x == 0.0) and np.all(ref.gt_y == 0.0)


def test_an_offset_antenna_is_not_taken_for_icr_x(drive):
    gyro_t, rate = gyro_of(drive, bias=0.005, noise=0.005)
    pick = slice(0, None, 10)
    yaw = np.unwrap(drive.gt_yaw[pick])
    ax, ay = 0.5, 0.1
    positions = (drive.gt_t[pick], drive.gt_x[pick] + np.cos(yaw) * ax - np.sin(yaw) * ay,
                 drive.gt_y[pick] + np.sin(yaw) * ax + np.cos(yaw) * ay)
    rec = Recording(drive.enc_t, drive.left, drive.right, gyro_t=gyro_t, gyro_rate=rate,
                    **gnss(positions))
    told = fit_recordings([rec], B, imu_delay=0.0, gnss_antenna=(ax, ay))
    assert 'icr.x' in told.determined
    assert told.icr.x == pytest.approx(TRUE.x, abs=0.005)
    # (within the ICR offset's lever, held at 0 with a GNSS: 0.036 m here)
    assert told.distance_scale == pytest.approx(S_TRUE, abs=5e-3)
    # Not told, the lever arm passes for ICRs 0.5 m behind where they are.
    blind = fit_recordings([rec], B, imu_delay=0.0)
    assert blind.icr.x == pytest.approx(TRUE.x - ax, abs=0.01)
