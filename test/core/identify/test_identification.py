"""core.identify.procedure: the whole identification, from recordings to compared models."""

from helpers.recordings import late, noisy, pieces
from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
import pytest
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.models import AdaptiveIcr, ConstantIcr

TRUTH = ConstantIcr(B)
P_TRUE = np.array(AURIGA)
# Adaptive-ICR parameters, as SAMPLE_P['adaptive_icr'] of test_segment_problem.py.
ADAPTIVE_P = [0.05, 0.07, 0.09, 0.08, 0.02, 0.03]


def test_noise_and_quantisation_stated_tolerance():
    # Ground truth 3 mm / 0.2 deg noise, joint angles quantised to 4096 counts per turn,
    # ten minutes of driving: ICRs within 5 mm, scales within 0.3 %.
    rec = simulate(TRUTH, P_TRUE, duration=600.0, seed=8, gt_phase=0.004)
    rng = np.random.default_rng(2)
    quantum = 2 * np.pi / 4096 * 0.1
    noisy = ident.Recording(
        rec.enc_t, np.round(rec.left / quantum) * quantum,
        np.round(rec.right / quantum) * quantum, rec.gt_t,
        rec.gt_x + rng.normal(0, 0.003, len(rec.gt_t)),
        rec.gt_y + rng.normal(0, 0.003, len(rec.gt_t)),
        rec.gt_yaw + rng.normal(0, np.radians(0.2), len(rec.gt_t)))
    result = ident.identify([noisy], 'icr_scales', B, holdout=0.0)
    np.testing.assert_allclose(result.fit.p[:3], P_TRUE[:3], atol=5e-3)
    np.testing.assert_allclose(result.fit.p[3:], P_TRUE[3:], rtol=3e-3)
    assert np.all(result.fit.std[:3] < 5e-3)


def test_identify_compares_models_on_held_out_blocks(clean):
    truth = AdaptiveIcr(B)
    rec = simulate(truth, ADAPTIVE_P, duration=240.0, seed=6)
    result = ident.identify([rec], 'adaptive_icr', B, holdout_block=20.0)
    names = [e.name for e in result.evaluations]
    assert names == list(ident.COMPARE_MODELS)
    ideal, adaptive = result.evaluation('ideal'), result.evaluation('adaptive_icr')
    assert adaptive.segments.position_mean < 1e-6
    assert adaptive.windows.improvement_over(ideal.windows)['position'] > 99.0
    assert result.evaluation('icr_scales').windows.improvement_over(
        ideal.windows)['heading'] > 25.0
    # adaptive_icr has no constant ICRs: the ICR keys come from the icr_scales fit.
    assert result.icr_source == 'icr_scales'
    assert 0 < result.icr.chi < 1


def test_ground_truth_stamped_late_is_timed_and_corrected():
    rec = simulate(TRUTH, P_TRUE, duration=120.0, enc_rate=50.0, gt_rate=10.0, seed=5)
    stamped = late(rec, 0.23)
    result = ident.identify([stamped], 'icr_scales', B, ground_truth_delay='auto')
    assert result.delay.delay == pytest.approx(0.23, abs=0.002)
    np.testing.assert_allclose(result.fit.p, P_TRUE, atol=1e-4)
    np.testing.assert_allclose(result.recordings[0].gt_t, rec.gt_t, atol=0.002)
    # Taken at face value, the same stamps blur the fit and the hold-out.
    raw = ident.identify([stamped], 'icr_scales', B, ground_truth_delay=0.0)
    assert raw.delay.uncertainty == 'given' and raw.delay.delay == 0.0
    assert raw.fit.rms_position > 20 * result.fit.rms_position
    assert raw.evaluation('icr_scales').windows.position_mean > \
        5 * result.evaluation('icr_scales').windows.position_mean
    with pytest.raises(ValueError, match="a number of seconds or 'auto'"):
        ident.identify([stamped], 'icr_scales', B, ground_truth_delay='later')


def test_recording_in_300_short_pieces_is_identified():
    # Each piece 2 s, ground truth from 0.3 s before the encoders; 15 min in all.
    rec = simulate(TRUTH, P_TRUE, duration=900.0, enc_rate=50.0, gt_rate=10.0, seed=4,
                   gt_phase=0.0137)
    parts = pieces(late(rec, 0.15), length=2.0, gap=1.0, encoders_late=0.3)
    result = ident.identify(parts, 'icr_scales', B, ground_truth_delay='auto')
    assert result.delay.delay == pytest.approx(0.15, abs=0.002)
    np.testing.assert_allclose(result.fit.p, P_TRUE, atol=1e-4)
    assert result.time.pieces == 300 and result.time.longest_piece < 1.8
    assert result.time.covered == pytest.approx(300 * 1.55, rel=0.05)
    assert result.time.span == pytest.approx(300 * 2.0, rel=0.05)
    # No 10 s window fits in a piece: the comparison is per segment, over every block.
    held = result.holdout
    assert held.cross_validated
    icr = result.evaluation('icr_scales')
    assert icr.windows.n == 0 and icr.segments.n == result.fit.segments > 400
    assert icr.segments.position_mean < 1e-6
    assert icr.windows.improvement_over(result.evaluation('ideal').windows) is None


def test_short_recording_holds_every_block_out_in_turn():
    rec = simulate(TRUTH, P_TRUE, duration=120.0, enc_rate=50.0, gt_rate=10.0, seed=2)
    result = ident.identify([rec], 'icr_scales', B)
    assert result.holdout.cross_validated and len(result.holdout.folds) == 5
    ideal = result.evaluation('ideal')
    # Every block predicted once: windows from the whole recording, not from 20 % of it.
    assert ideal.windows.n >= 15 and ideal.segments.n >= 0.9 * result.fit.segments
    assert len(result.evaluation('icr_scales').fits) == 5


def test_tuned_ddc_is_the_symmetric_icr_model_with_scales():
    # A vehicle that is a diff_drive_controller with multipliers: recovered exactly.
    truth = ident.TunedDiffDrive(B)
    rec = simulate(truth, [1.7, 0.97, 1.03], duration=120.0, enc_rate=50.0, seed=3)
    result = ident.identify([rec], 'icr_scales', B)
    np.testing.assert_allclose(result.ddc.p, [1.7, 0.97, 1.03], atol=1e-6)
    np.testing.assert_allclose(result.fit.p, [1.7 * B / 2, -1.7 * B / 2, 0.0, 0.97, 1.03],
                               atol=1e-6)
    assert result.evaluation('tuned_ddc').windows.position_mean < 1e-6
    values = ident.ddc_parameters(result.ddc.p, B, 0.1)
    assert values == pytest.approx({'wheel_separation': B, 'wheel_separation_multiplier': 1.7,
                                    'wheel_radius': 0.1, 'left_wheel_radius_multiplier': 0.97,
                                    'right_wheel_radius_multiplier': 1.03})
    # On the Auriga-alpha (eccentric ICRs, icr.x 0.032 m) the constant ICRs do better.
    auriga = ident.identify([simulate(TRUTH, P_TRUE, duration=120.0, seed=3)], 'icr_scales', B)
    ddc, icr = auriga.evaluation('tuned_ddc'), auriga.evaluation('icr_scales')
    assert icr.windows.position_mean < 0.1 * ddc.windows.position_mean
    assert 1.0 / auriga.ddc.p[0] == pytest.approx(auriga.icr.chi, abs=0.02)


def test_noisy_ground_truth_is_fitted_reported_and_usable():
    # Lidar ICP on ice: 5 cm / 2 deg per sample and 2 % glitches, 4 Hz, a minute and a half.
    rec = simulate(TRUTH, P_TRUE, duration=90.0, enc_rate=50.0, gt_rate=4.0, seed=8)
    icp = noisy(late(rec, 0.2), 0.05, np.radians(2.0), glitches=0.02, seed=3)
    with pytest.raises(ident.UncertainError) as refused:
        ident.identify([icp], 'icr_scales', B, ground_truth_delay='auto')
    message = str(refused.value)
    # The true cause: the ground-truth noise, not too little driving.
    assert 'is determined but uncertain' in message
    assert 'because the ground truth is noisy' in message and 'RMS per segment' in message
    assert 'drive more' not in message and '--accept-uncertain' in message
    result = ident.identify([icp], 'icr_scales', B, ground_truth_delay='auto',
                            accept_uncertain=True)
    assert result.uncertain and all(u.cause == 'noise' for u in result.uncertain)
    assert result.delay.delay == pytest.approx(0.2, abs=0.05)
    # Usable: within three standard errors of the truth, and odometry as good as the truth's.
    assert np.all(np.abs(result.fit.p - P_TRUE) < 3 * result.fit.std + 1e-3)
    truth_errors = ident.prediction_errors(TRUTH, P_TRUE, ident.build_segments([rec], 10.0))
    fitted_errors = ident.prediction_errors(TRUTH, result.fit.p,
                                            ident.build_segments([rec], 10.0))
    assert truth_errors[0].max() < 1e-9 and fitted_errors[0].mean() < 0.1
