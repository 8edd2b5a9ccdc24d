"""core.identify.procedure: the whole identification, from recordings to compared models."""

from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
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
