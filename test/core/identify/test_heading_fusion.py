"""The pose's and the gyro's headings fused by their noise; the gyro checked against the pose."""

from dataclasses import replace
import math

from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
import pytest
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.identify.fitting import check_bounds, UncertainError
from tracked_kinematics.core.identify.reference.heading_fusion import (
    bias_prior, BIAS_SIGMA_FLOOR, check_gyro_against_pose, fuse_heading, signed_gyro_scale)
from tracked_kinematics.core.models import ConstantIcr


@pytest.fixture(scope='module')
def drive():
    """Three minutes of the Auriga-alpha: exact pose at 10 Hz."""
    return simulate(ConstantIcr(B), np.array(AURIGA), duration=180.0, gt_rate=10.0, seed=7)


def with_gyro(rec, bias=0.0, noise=0.0, pose_noise=0.0, sign=1.0, seed=0):
    """Add a 50-Hz gyro (true rate from the pose, with bias and noise) and pose heading noise."""
    rng = np.random.default_rng(seed)
    yaw = np.unwrap(rec.gt_yaw)
    t = np.arange(rec.gt_t[0], rec.gt_t[-1], 0.02)
    rate = np.gradient(np.interp(t, rec.gt_t, yaw), t)
    rate = sign * rate + bias + rng.normal(0.0, noise, t.size)
    noisy = rec.gt_yaw + rng.normal(0.0, pose_noise, rec.gt_yaw.size)
    return replace(rec, gyro_t=t, gyro_rate=rate, gt_yaw=np.angle(np.exp(1j * noisy)))


def test_fusion_weighs_a_noisy_pose_down_and_finds_the_bias(drive):
    rec = with_gyro(drive, bias=0.01, noise=0.002, pose_noise=0.02)
    fused, fusion = fuse_heading([rec], 0.0)
    truth = np.unwrap(drive.gt_yaw)
    pose_error = np.std(np.unwrap(rec.gt_yaw) - truth)
    fused_error = np.std(np.unwrap(fused[0].gt_yaw) - truth)
    # The pose's 0.02 rad noise measured, and mostly averaged away by the gyro.
    assert fusion.sigma_pose == pytest.approx(0.02, rel=0.25)
    assert fusion.window > 2.0
    assert fused_error < 0.5 * pose_error
    assert fusion.biases[0] == pytest.approx(0.01, abs=0.002)
    # Positions and times untouched.
    assert np.array_equal(fused[0].gt_x, rec.gt_x) and np.array_equal(fused[0].gt_t, rec.gt_t)


def test_a_gyro_turning_the_other_way_is_refused(drive):
    rec = with_gyro(drive, sign=-1.0)
    scale, std = signed_gyro_scale([rec], 0.0)
    assert scale == pytest.approx(-1.0, abs=0.01)
    assert 'sign' in check_gyro_against_pose(scale, std)
    assert 'axis' in check_gyro_against_pose(0.02, 0.001)
    assert check_gyro_against_pose(0.99, 0.002) == ''
    assert 'too few' in check_gyro_against_pose(1.0, math.inf)


def test_bias_prior_is_the_spread_between_runs_at_least_the_floor():
    bias, sigma = bias_prior([0.010, 0.014, 0.012])
    assert bias == pytest.approx(0.012)
    assert sigma == pytest.approx(0.002)
    assert bias_prior([0.001])[1] == BIAS_SIGMA_FLOOR
    assert bias_prior([0.0, 0.05])[1] == pytest.approx(np.std([0.0, 0.05], ddof=1))


def test_a_diameter_given_as_radius_ends_on_the_scale_bound(drive):
    # Encoders reading twice the true travel: scales of 0.5 would be needed.
    doubled = replace(drive, left=2.2 * drive.left, right=2.2 * drive.right)
    segments = ident.build_segments([doubled], 1.0)
    result = ident.fit(ident.build_model('icr_scales', B), segments, check=False)
    with pytest.raises(UncertainError, match='diameter given as --sprocket-radius'):
        check_bounds(result, segments)
    accepted = check_bounds(result, segments, accept_uncertain=True)
    assert any('scale.left' in a for a in accepted)
    right = ident.build_segments([drive], 1.0)
    ok = ident.fit(ident.build_model('icr_scales', B), right, check=False)
    assert check_bounds(ok, right) == []


def test_an_icr_touching_its_physical_bound_is_not_refused(drive):
    # A track that does not slip has its ICR on +-track_width / 2, the bound, where the data
    # want it (the Marmotte on snow): here the Auriga's left ICR at 0.353 m, for a vehicle
    # of track width 0.706 m.
    segments = ident.build_segments([drive], 1.0)
    result = ident.fit(ident.build_model('icr_scales', 2 * AURIGA[0]), segments, check=False)
    assert result.p[0] == pytest.approx(AURIGA[0], abs=1e-3)
    assert check_bounds(result, segments) == []
