"""core.models' registry: a model is one class, and the identification reads it from there."""

from helpers.vehicle_sim import B, simulate
import numpy as np
import pytest
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.errors import ExcitationError
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.models import (
    make_model, model_class, MODEL_NAMES, model_names, MotionModel, Parameter, register_model,
    unregister_model)


class OffsetSymmetricIcr(MotionModel):
    """Symmetric tread ICRs at +-B / (2 alpha), both at ``x`` ahead: a model no module knows."""

    name = 'offset_symmetric'
    parameters = (
        Parameter('alpha', 'chi', 'turning', (0.05, 1.0), std_checked=True),
        Parameter('x', 'icr.x', 'turning', (-5.0, 5.0), (-1.0, 1.0), per_track_width=True,
                  std_checked=True),
    )
    constant_icr = True

    def initial(self):
        return np.array([1.0, 0.0])

    def guess(self, chi, segments):
        return np.array([chi, 0.0])

    def twist_and_jacobian(self, p, v_left, v_right):
        alpha, x = (float(v) for v in np.asarray(p, float))
        v_left = np.atleast_1d(np.asarray(v_left, float))
        v_right = np.atleast_1d(np.asarray(v_right, float))
        w_ideal = (v_right - v_left) / self.track_width
        w = alpha * w_ideal
        zero = np.zeros_like(w)
        twist = np.stack([0.5 * (v_left + v_right), -x * w, w], axis=-1)
        jac = np.stack([np.stack([zero, -x * w_ideal, w_ideal], -1),
                        np.stack([zero, -w, zero], -1)], axis=-1)
        return twist, jac

    def as_icr(self, p):
        alpha, x = (float(v) for v in np.asarray(p, float))
        half = 0.5 * self.track_width / alpha
        return IcrParams(self.track_width, half, -half, x, 1.0, 1.0)


P_TRUE = np.array([0.8, 0.04])


@pytest.fixture
def registered():
    register_model(OffsetSymmetricIcr)
    yield OffsetSymmetricIcr
    unregister_model(OffsetSymmetricIcr.name)


def test_a_new_model_is_one_class_identified_end_to_end(registered):
    # Registered in this test only: no other file names it, and identify fits, checks,
    # writes and compares it from what the class declares.
    assert 'offset_symmetric' in ident.fit_models()
    rec = simulate(OffsetSymmetricIcr(B), P_TRUE, duration=240.0, seed=5)
    result = ident.identify([rec], 'offset_symmetric', B, holdout_block=20.0,
                            compare=('ideal', 'tuned_ddc', 'offset_symmetric'))
    np.testing.assert_allclose(result.fit.p, P_TRUE, atol=1e-6)
    assert result.fit.params == pytest.approx({'alpha': 0.8, 'x': 0.04}, abs=1e-6)
    # It has constant ICRs: the written model is its own.
    assert result.icr_source == 'offset_symmetric'
    assert result.icr.y_left == pytest.approx(0.5 * B / 0.8, abs=1e-6)
    assert result.icr.x == pytest.approx(0.04, abs=1e-6)
    own, ideal = result.evaluation('offset_symmetric'), result.evaluation('ideal')
    assert own.segments.position_mean < 1e-6
    assert own.windows.improvement_over(ideal.windows)['position'] > 99.0
    # Its declared bounds, box and excitation are what the fit and the checks use.
    model = ident.build_model('offset_symmetric', B)
    np.testing.assert_array_equal(ident.bounds(model)[0], [0.05, -5.0 * B])
    np.testing.assert_array_equal(ident.search_box(model)[1], [1.0, B])
    straight = ident.Excitation(segments=50, moving=50, distance=20.0, turning=0.1,
                                straight=20.0)
    with pytest.raises(ExcitationError, match='to identify chi, icr.x:'):
        ident.check_excitation(model, straight)


def test_the_registry_gives_the_side_tables_of_old():
    assert ident.FIT_MODELS == ('effective_wheel_base', 'icr', 'icr_scales', 'general_slip',
                                'adaptive_icr')
    assert ident.BASELINES == ('ideal', 'tuned_ddc')
    assert MODEL_NAMES == ('ideal', 'effective_wheel_base', 'symmetric', 'icr', 'icr_scales',
                           'general_slip', 'adaptive_icr')
    assert 'offset_symmetric' not in model_names()
    assert make_model('symmetric', B).name == 'effective_wheel_base'
    assert ident.build_model('icr', B, (0.9, 1.1)).as_icr([0.3, -0.3, 0.0]).scale_right == 1.1


@pytest.mark.parametrize('name', model_names())
def test_each_model_declares_what_it_is(name):
    model = ident.build_model(name, B)
    assert model.param_names == tuple(p.name for p in model.parameters)
    assert all(p.excited_by in ('turning', 'straight') for p in model.parameters)
    # constant_icr says whether the fit itself is written as icr.*.
    assert (model.as_icr(model.initial()) is not None) == model.constant_icr


def test_a_name_is_registered_once(registered):
    class Clash(OffsetSymmetricIcr):
        pass

    with pytest.raises(ValueError, match="'offset_symmetric' is already registered"):
        register_model(Clash)
    assert register_model(OffsetSymmetricIcr) is OffsetSymmetricIcr
    assert model_class('offset_symmetric') is OffsetSymmetricIcr
    with pytest.raises(ValueError, match="unknown motion model 'bicycle'; choose one of"):
        model_class('bicycle')
