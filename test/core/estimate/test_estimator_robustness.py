"""The estimator on pose sources like lidar ICP: delayed stamps, slip noise, jumps, a prior.

The paper's own simulations stay in test_estimator.py; the real bags of ../shared/realdata are
scored in test/offline/test_evaluate_model.py.
"""

import math

import numpy as np
import pytest
from tracked_kinematics.core.estimate.ekf import EstimatorConfig, SlipEstimator
from tracked_kinematics.core.integration import arc_chord
from tracked_kinematics.core.models import ConstantIcr

TRACK = 1.0
TRUE_ICR = (0.8, -0.8, 0.05)


class _Turning:
    """
    A vehicle on constant-ICR terrain turning on a slalom: 50 Hz encoders, 10 Hz poses.

    ``slip_std`` makes each track's true travel fluctuate about its constant-ICR value
    (relative changes of that size, each held for 0.3 s), as grass does: an error per metre
    travelled that a window cannot average out.
    """

    def __init__(self, icr=TRUE_ICR, slip_std=0.0, pose_std=0.005, seed=0):
        self.icr = np.array(icr, float)
        self.slip_std = slip_std
        self.pose_std = pose_std
        self.rng = np.random.default_rng(seed)
        self.t = 0.0
        self.pose = np.zeros(3)
        self.factor = np.ones(2)

    def speeds(self, t):
        turn = 0.4 * math.sin(2.0 * math.pi * t / 6.0)
        return 1.0 - turn, 1.0 + turn

    def run(self, est, seconds, on_pose=None, pose_delay=0.0, jump_at=None):
        outcomes = []
        for k in range(int(round(seconds * 50))):
            v_left, v_right = self.speeds(self.t)
            self.t = round(self.t + 0.02, 9)
            d_left, d_right = v_left * 0.02, v_right * 0.02
            if k % 15 == 0:
                self.factor = 1.0 + self.slip_std * self.rng.normal(size=2)
            d_left, d_right = d_left * self.factor[0], d_right * self.factor[1]
            yl, yr, x = self.icr
            span = yl - yr
            dth = (d_right - d_left) / span
            dx, dy = (d_right * yl - d_left * yr) / span, -x * dth
            cx, cy = arc_chord(dx, dy, dth)
            c, s = math.cos(self.pose[2]), math.sin(self.pose[2])
            self.pose = self.pose + [c * cx - s * cy, s * cx + c * cy, dth]
            est.add_step(self.t, v_left * 0.02, v_right * 0.02, 0.02)
            if (k + 1) % 5 == 0:
                noisy = self.pose + self.rng.normal(scale=self.pose_std, size=3) * [1, 1, 0.2]
                if jump_at is not None and self.t >= jump_at:
                    noisy = noisy + [2.0, -1.0, 0.0]
                outcomes.append(est.add_pose(self.t + pose_delay, *noisy))
                if on_pose:
                    on_pose(est)
        return outcomes


def _estimator(p0=None, **config):
    model = ConstantIcr(TRACK, with_scales=False)
    # The pose noise as simulated; travel_std the default (1 %), which grass exceeds.
    config = {'pose_std_xy': 0.005, 'pose_std_yaw': 0.001, **config}
    return SlipEstimator(model, p0, EstimatorConfig(**config))


def test_pose_delay_compares_each_pose_with_the_travel_it_belongs_to():
    # Poses stamped 0.3 s late: without pose_delay the windows are misaligned with the
    # encoders and the estimate is biased; with it, the filter sees the undelayed stream.
    exact = _estimator(fallback=False)
    _Turning(seed=1).run(exact, 30.0)
    late = _estimator(fallback=False)
    _Turning(seed=1).run(late, 30.0, pose_delay=0.3)
    fixed = _estimator(fallback=False, pose_delay=0.3)
    _Turning(seed=1).run(fixed, 30.0, pose_delay=0.3)
    np.testing.assert_allclose(fixed.p, exact.p, atol=1e-9)
    np.testing.assert_allclose(exact.p, TRUE_ICR, atol=0.03)
    assert np.max(np.abs(late.p - TRUE_ICR)) > 3.0 * np.max(np.abs(exact.p - TRUE_ICR))


def test_adaptive_noise_learns_the_slip_noise_and_stays_off_without_it():
    quiet = _estimator()
    _Turning(seed=2).run(quiet, 40.0)
    assert quiet.noise_scale == pytest.approx(1.0)
    grass = _estimator()
    outcomes = _Turning(slip_std=0.3, seed=2).run(grass, 40.0)
    assert grass.noise_scale > 20.0
    fixed = _estimator(adaptive_noise=False)
    fixed_outcomes = _Turning(slip_std=0.3, seed=2).run(fixed, 40.0)
    # Slip noise taken for jumps: the fixed noise model refuses many good windows.
    refused = sum(o.status == 'outlier' for o in outcomes)
    assert sum(o.status == 'outlier' for o in fixed_outcomes) > 3 * max(refused, 1)
    assert np.max(np.abs(grass.p - TRUE_ICR)) < np.max(np.abs(fixed.p - TRUE_ICR))


def test_adaptive_noise_switched_off_at_runtime_uses_travel_std_as_given():
    # icr_estimator's adaptive_noise parameter reaches the filter through configure():
    # switched off, the learnt factor no longer widens the windows' noise.
    grass = _estimator()
    _Turning(slip_std=0.3, seed=2).run(grass, 40.0)
    assert grass.noise_scale > 20.0
    grass.configure(EstimatorConfig(pose_std_xy=0.005, pose_std_yaw=0.001,
                                    adaptive_noise=False))
    assert grass.noise_scale == 1.0
    _Turning(slip_std=0.3, seed=3).run(grass, 10.0)
    assert grass.noise_scale == 1.0
    grass.configure(EstimatorConfig(pose_std_xy=0.005, pose_std_yaw=0.001, noise_memory=20))
    _Turning(slip_std=0.3, seed=4).run(grass, 20.0)
    assert grass.noise_scale > 20.0   # learnt again, from the last 20 moving windows


def test_prior_holds_identified_values_against_noise_and_yields_to_insistent_data():
    # Right start values on noisy terrain: the prior keeps the estimate near them.
    held, free = [], []
    right = _estimator(p0=TRUE_ICR, fallback=False)
    _Turning(slip_std=0.3, seed=3).run(right, 60.0, on_pose=lambda e: held.append(e.p.copy()))
    loose = _estimator(p0=TRUE_ICR, fallback=False, prior_std=math.inf)
    _Turning(slip_std=0.3, seed=3).run(loose, 60.0, on_pose=lambda e: free.append(e.p.copy()))
    spread = np.abs(np.array(held[100:]) - TRUE_ICR).max(axis=1).mean()
    assert spread < 0.6 * np.abs(np.array(free[100:]) - TRUE_ICR).max(axis=1).mean()
    # Wrong start values (ICRs 0.15 m too wide) on clean terrain: the data insist.
    wrong = _estimator(p0=(0.95, -0.95, 0.05), fallback=False)
    _Turning(seed=3).run(wrong, 60.0)
    assert abs(wrong.p[0] - TRUE_ICR[0]) < 0.05 and abs(wrong.p[1] - TRUE_ICR[1]) < 0.05


def test_ideal_start_has_no_prior():
    # The paper's setting: without identified start values the parameters follow the data.
    est = _estimator()
    assert not est.informed
    _Turning(icr=(1.2, -1.2, 0.2), seed=4).run(est, 30.0)
    np.testing.assert_allclose(est.p, (1.2, -1.2, 0.2), atol=0.05)


def test_fallback_stands_behind_the_start_values_until_the_filter_predicts_better():
    trusted = []
    right = _estimator(p0=TRUE_ICR)
    _Turning(slip_std=0.3, seed=5).run(right, 60.0, on_pose=lambda e: trusted.append(e._trusted))
    assert np.mean(trusted) < 0.5
    if not right._trusted:
        np.testing.assert_array_equal(right.estimate, TRUE_ICR)
        assert right.icr() == pytest.approx(TRUE_ICR)
    wrong = _estimator(p0=(1.0, -1.0, 0.0))
    _Turning(seed=5).run(wrong, 30.0)
    assert wrong._trusted
    np.testing.assert_array_equal(wrong.estimate, wrong.p)
    off = _estimator(p0=(1.0, -1.0, 0.0), fallback=False)
    assert not off._trusted
    np.testing.assert_array_equal(off.estimate, off.p)


def test_a_jump_re_anchors_without_widening_and_lasting_disagreement_widens():
    est = _estimator(p0=TRUE_ICR, prior_std=math.inf, fallback=False)
    drive = _Turning(seed=6)
    drive.run(est, 20.0)
    before = est.P.copy()
    statuses = [o.status for o in drive.run(est, 3.0, jump_at=drive.t + 0.5)]
    assert 'anchored' in statuses and statuses[-1] == 'updated'
    assert np.trace(est.P) < 10.0 * np.trace(before)     # re-localised, not widened
    # The terrain changes beyond the gate: after the re-anchor the windows still disagree.
    drive.icr = np.array([2.0, -2.0, 0.0])
    reasons = [o.reason for o in drive.run(est, 5.0)]
    assert any('widened' in r for r in reasons)
    assert abs(est.p[0] - 2.0) < 0.2
