"""
The fitted odometry noise model: propagation, fit, consistency (core/noise_model.py).

The propagation is checked against Monte Carlo runs with the model's own slip noise, the fit
on simulated drives with known noise, the consistency figures on Gaussian errors, and the
whole on the real Warthog runs of ../shared/realdata (skipped when absent).
"""

import math

from helpers import realdata
import numpy as np
import pytest
from tracked_kinematics.core import covariance as cov
from tracked_kinematics.core import noise_model as nm
from tracked_kinematics.core.evaluate import noise
from tracked_kinematics.core.integration import arc_chord
from tracked_kinematics.core.kinematics import IcrParams

ICR = IcrParams(1.0, 0.8, -0.75, 0.05, 0.97, 0.95)
DT = 0.05
MODEL = nm.NoiseModel(track=2e-3, turn=1e-3, slip=1e-2, timing=0.0, floor=0.0)


def manoeuvres(seconds, rng):
    """Nominal track travel per step of a drive: straights, curves, pivots and spins."""
    steps = []
    while len(steps) * DT < seconds:
        kind = rng.integers(4)
        v = rng.uniform(0.2, 1.0)
        if kind == 0:
            speeds = (v, v)
        elif kind == 1:
            speeds = (v, v * rng.uniform(0.4, 0.8))[::rng.choice([1, -1])]
        elif kind == 2:
            speeds = (0.0, v)[::rng.choice([1, -1])]
        else:
            speeds = (-v, v)[::rng.choice([1, -1])]
        steps += [speeds] * int(rng.integers(20, 80))
    travel = np.array(steps) * DT
    return travel[:, 0], travel[:, 1]


def integrate_rows(dx, dy, dth):
    """Integrate body increments (runs x steps) along arcs from the origin; final poses."""
    heading = np.cumsum(dth, axis=-1)
    before = heading - dth
    cx, cy = arc_chord(dx, dy, dth)
    x = np.sum(np.cos(before) * cx - np.sin(before) * cy, axis=-1)
    y = np.sum(np.sin(before) * cx + np.cos(before) * cy, axis=-1)
    return np.stack([x, y, heading[..., -1]], axis=-1)


def body_increments(d_left, d_right):
    """Return the nominal body increments (N, 3)."""
    return np.column_stack([d_left, d_right]) @ np.asarray(cov.body_jacobian(ICR)).T


def sample_increments(model, d_left, d_right, runs, rng):
    """Body increments of ``runs`` drives with the model's noise: (runs, N, 3)."""
    s = model.body_covariance(ICR, d_left, d_right)
    chol = np.linalg.cholesky(s + 1e-18 * np.eye(3))
    noise_ = np.einsum('nij,rnj->rni', chol, rng.standard_normal((runs, len(d_left), 3)))
    return body_increments(d_left, d_right)[None] + noise_


def window_covariance(model, d_left, d_right, start, end):
    bases, motion = nm.window_bases(ICR, d_left, d_right, np.full(len(d_left), DT),
                                    np.atleast_1d(start), np.atleast_1d(end))
    return np.einsum('wmij,m->wij', bases, model.constants), motion


# The model -------------------------------------------------------------------------------


def test_constants_are_checked():
    with pytest.raises(ValueError, match='slip'):
        nm.NoiseModel(slip=-1.0)
    with pytest.raises(ValueError, match='timing'):
        nm.NoiseModel(timing=math.nan)


def test_default_model_is_todays_track_noise():
    # Today's track random walk (TrackNoise's 1e-3 m^2/m) gives today's step covariance (the
    # floors differ: per track there, per body increment here).
    d_left, d_right = 0.03, -0.01
    today = cov.TrackNoise(floor=0.0)
    m = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    g = cov.travel_jacobian(m, cov.body_jacobian(ICR))
    var_l, var_r = today.travel_variances(abs(d_left), abs(d_right))
    expected = cov.full_matrix(cov.propagate((0.0,) * 6, 0.0, 0.0, g, var_l, var_r))
    s = nm.NoiseModel(floor=0.0).body_covariance(ICR, d_left, d_right)
    assert nm.propagate_body(np.zeros((3, 3)), 0.0, 0.0, m, s) == pytest.approx(
        expected, rel=1e-9, abs=1e-15)


def test_slip_is_weighted_by_the_tightness_of_the_turn():
    model = nm.NoiseModel(track=0.0, slip=1.0, floor=0.0)
    ideal = IcrParams(1.0, 0.5, -0.5)
    spin = model.body_covariance(ideal, -0.05, 0.05)
    assert spin == pytest.approx(np.diag([0.1, 0.1, 0.0]))   # on the spot: w = 1
    gentle = model.body_covariance(ICR, 0.5, 0.51)
    dx, _, dth = body_increments(0.5, 0.51)[0]
    assert gentle[1, 1] == pytest.approx(dth ** 2 / (abs(dth) + dx / ICR.track_width))
    assert gentle[1, 1] < 0.01 * abs(dth)
    # A random walk: two half steps add up to the whole one.
    halves = model.body_covariance(ICR, np.array([0.25, 0.25]), np.array([0.255, 0.255]))
    assert halves.sum(axis=0) == pytest.approx(gentle)


def test_twist_covariance_is_the_mean_over_the_twist_time():
    model = nm.NoiseModel(track=1e-3, turn=1e-3, slip=1e-2)
    t = cov.TWIST_TIME
    expected = model.body_covariance(ICR, 0.4 * t, 0.6 * t) / t ** 2
    assert model.twist(ICR, 0.4, 0.6) == pytest.approx(expected)


# Propagation -----------------------------------------------------------------------------


def test_propagation_matches_monte_carlo():
    rng = np.random.default_rng(3)
    d_left, d_right = manoeuvres(12.0, rng)
    runs = integrate_rows(*np.moveaxis(sample_increments(MODEL, d_left, d_right, 4000, rng),
                                       -1, 0))
    nominal = integrate_rows(*body_increments(d_left, d_right).T)
    p, motion = window_covariance(MODEL, d_left, d_right, 0, len(d_left))
    assert motion[0] == pytest.approx(nominal, abs=0.02)   # midpoint rule against arcs
    sample = np.cov((runs - nominal).T)
    p = p[0]
    assert np.diag(sample) == pytest.approx(np.diag(p), rel=0.1)
    # Consistent as a whole: E[e^T P^-1 e] = 3.
    e = runs - runs.mean(axis=0)
    assert np.mean(np.einsum('ri,ij,rj->r', e, np.linalg.inv(p), e)) == pytest.approx(3.0,
                                                                                      rel=0.1)


def test_window_bases_match_the_step_by_step_propagation():
    # The node's propagation (one step at a time, exact arcs) and the windows' closed form.
    rng = np.random.default_rng(4)
    d_left, d_right = manoeuvres(10.0, rng)
    body = body_increments(d_left, d_right)
    p = np.zeros((3, 3))
    theta = 0.0
    s = MODEL.body_covariance(ICR, d_left, d_right)
    for k, (dx, dy, dth) in enumerate(body):
        delta_x, delta_y, m = cov.arc_step(theta, dx, dy, dth)
        p = nm.propagate_body(p, delta_x, delta_y, m, s[k])
        theta += dth
    window, _ = window_covariance(MODEL, d_left, d_right, 0, len(d_left))
    # The windows' covariance is in the frame of the start heading, here 0.
    assert window[0] == pytest.approx(p, rel=0.03, abs=1e-6)


def test_windows_are_in_the_frame_of_their_start():
    rng = np.random.default_rng(5)
    d_left, d_right = manoeuvres(20.0, rng)
    n = len(d_left)
    start, end = n // 3, n - 1
    whole, motion = window_covariance(MODEL, d_left, d_right, start, end)
    alone, motion_alone = window_covariance(MODEL, d_left[start:end], d_right[start:end], 0,
                                            end - start)
    assert whole == pytest.approx(alone, rel=1e-6, abs=1e-12)
    assert motion == pytest.approx(motion_alone, abs=1e-9)


def test_timing_adds_the_rate_at_both_ends():
    # Straight at 0.5 m/s: sigma_t^2 v^2 from each end, along the path only.
    d = np.full(40, 0.5 * DT)
    model = nm.NoiseModel(track=0.0, timing=0.01, floor=0.0)
    bases, _ = nm.window_bases(IcrParams(1.0, 0.5, -0.5), d, d, np.full(40, DT), [5], [30])
    p = np.einsum('wmij,m->wij', bases, model.constants)
    assert p[0] == pytest.approx(np.diag([2 * 0.01 * 0.25, 0.0, 0.0]), abs=1e-12)


def test_timing_at_the_start_swings_the_window_with_its_lever_arm():
    # Issue 35: a window that starts in a spin (1 rad/s) and then drives 2 m straight. A time
    # error dt at the start turns the start heading by dt rad: the end moves 2 dt sideways.
    spin = int(0.5 / DT)
    d_left = np.r_[np.full(spin, -0.5 * DT), np.full(100, 2.0 / 100)]
    d_right = np.r_[np.full(spin, 0.5 * DT), np.full(100, 2.0 / 100)]
    icr = IcrParams(1.0, 0.5, -0.5)
    model = nm.NoiseModel(track=0.0, turn=0.0, slip=0.0, timing=0.01, floor=0.0)
    bases, motion = nm.window_bases(icr, d_left, d_right, np.full(len(d_left), DT), [spin],
                                    [len(d_left)])
    p = np.einsum('wmij,m->wij', bases, model.constants)[0]
    assert motion[0, :2] == pytest.approx([2.0, 0.0], abs=1e-9)
    # The start's rate is the spin's (1 rad/s, no translation): lateral 0.01 * 2^2.
    assert p[1, 1] == pytest.approx(0.01 * 4.0, rel=0.01)
    # The same from the published covariance of the node's path (reset at the spin's end).
    published = nm.published_covariance((0.0,) * 6, (2.0, 0.0, 0.0), (2.0 / 100 / DT, 0.0, 0.0),
                                        (0.0, 0.0, 1.0), model)
    assert published[3] == pytest.approx(p[1, 1], rel=0.01)


# Consistency -----------------------------------------------------------------------------


def random_covariances(n, rng):
    a = rng.normal(size=(n, 2, 2)) * rng.uniform(0.01, 1.0, size=(n, 1, 1))
    return a @ np.swapaxes(a, 1, 2) + 1e-4 * np.eye(2)


def test_consistency_of_gaussian_errors():
    rng = np.random.default_rng(6)
    p = random_covariances(20000, rng)
    e = np.einsum('nij,nj->ni', np.linalg.cholesky(p), rng.standard_normal((20000, 2)))
    c = nm.consistency(e, p)
    assert c['windows'] == 20000
    assert c['inside_50'] == pytest.approx(0.5, abs=0.015)
    assert c['inside_95'] == pytest.approx(0.95, abs=0.006)
    assert c['mean_nees'] == pytest.approx(2.0, abs=0.08)
    # Errors 1.5 times larger than published: caught.
    worse = nm.consistency(1.5 * e, p)
    assert worse['inside_95'] < 0.85 and worse['mean_nees'] > 4.0


def test_heading_consistency_of_gaussian_errors():
    rng = np.random.default_rng(7)
    var = rng.uniform(1e-4, 1e-2, 20000)
    c = nm.heading_consistency(rng.standard_normal(20000) * np.sqrt(var), var)
    assert c['inside_50'] == pytest.approx(0.5, abs=0.015)
    assert c['inside_95'] == pytest.approx(0.95, abs=0.006)
    assert c['mean_nees'] == pytest.approx(1.0, abs=0.04)


def test_consistency_without_windows():
    assert nm.consistency(np.zeros((0, 2)), np.zeros((0, 2, 2))) == {
        'inside_50': None, 'inside_95': None, 'mean_nees': None, 'windows': 0}


# The fit ---------------------------------------------------------------------------------


def simulated_windows(true, seconds, rng, lengths=(5.0, 10.0)):
    """Windows of a simulated drive whose body increments carry the noise of ``true``."""
    d_left, d_right = manoeuvres(seconds, rng)
    n = len(d_left)
    dt = np.full(n, DT)
    parts = []
    for length in lengths:
        w = int(round(length / DT))
        start = np.arange(0, n - w, w // 2)
        end = start + w
        bases, motion = nm.window_bases(ICR, d_left, d_right, dt, start, end)
        truth = np.empty((len(start), 3))
        for k, (a, b) in enumerate(zip(start, end)):
            inc = sample_increments(true, d_left[a:b], d_right[a:b], 1, rng)[0]
            truth[k] = integrate_rows(*inc.T)
        nominal = np.array([integrate_rows(*body_increments(d_left[a:b], d_right[a:b]).T)
                            for a, b in zip(start, end)])
        parts.append(noise.ErrorWindows(nominal - truth, bases, np.full(len(start), length),
                                        start * DT, np.zeros(len(start), np.intp)))
    return noise.ErrorWindows.concatenate(parts)


def test_fit_recovers_the_constants_of_simulated_drives():
    rng = np.random.default_rng(8)
    true = nm.NoiseModel(track=3e-3, turn=2e-3, slip=2e-2, timing=0.0, floor=0.0)
    windows = simulated_windows(true, 1800.0, rng)
    prior = nm.NoiseModel(track=1e-3, turn=1e-3, slip=1e-3, timing=0.0)
    # The errors are Gaussian here: the Gaussian likelihood's fit is the consistent one; the
    # default Student-t one (robust to glitches) is close.
    for dof in (None, noise.DOF):
        fit = noise.fit_noise(windows, prior, free=('track', 'turn', 'slip'), width=10.0,
                              dof=dof)
        assert fit.held == ('timing',)
        for term in ('track', 'turn', 'slip'):
            assert getattr(fit.model, term) == pytest.approx(getattr(true, term),
                                                             rel=0.35), (term, dof)
        c = windows.consistency(fit.model)
        if dof is None:
            assert 0.45 < c['inside_50'] < 0.55 and 0.93 < c['inside_95'] < 0.97
        else:
            assert 0.45 < c['inside_50'] < 0.6 and 0.93 < c['inside_95'] < 0.99


def test_fit_recovers_timing_from_errors_drawn_from_the_model():
    rng = np.random.default_rng(9)
    d_left, d_right = manoeuvres(1200.0, rng)
    true = nm.NoiseModel(track=2e-3, turn=1e-3, slip=1e-2, timing=0.01)
    start = np.arange(0, len(d_left) - 200, 200)
    bases, _ = nm.window_bases(ICR, d_left, d_right, np.full(len(d_left), DT), start,
                               start + 200)
    p = np.einsum('wmij,m->wij', bases, true.constants) + 1e-12 * np.eye(3)
    e = np.einsum('wij,wj->wi', np.linalg.cholesky(p), rng.standard_normal((len(start), 3)))
    windows = noise.ErrorWindows(e, bases, np.full(len(start), 10.0), start * DT,
                                 np.zeros(len(start), np.intp))
    fit = noise.fit_noise(windows, width=10.0, dof=None)
    assert fit.fitted == nm.FITTED and fit.held == ()
    assert fit.model.timing == pytest.approx(0.01, rel=0.5)
    assert fit.model.track == pytest.approx(2e-3, rel=0.5)


def test_heading_only_fit_holds_slip():
    rng = np.random.default_rng(10)
    true = nm.NoiseModel(track=1e-3, turn=3e-3, slip=5e-2, floor=0.0)
    windows = simulated_windows(true, 900.0, rng)
    prior = nm.NoiseModel(track=1e-3, turn=1e-4, slip=7e-3)
    fit = noise.fit_noise(windows, prior, free=('turn', 'slip'), errors='heading', width=10.0,
                          dof=None)
    assert fit.held == ('track', 'slip', 'timing')
    assert fit.model.slip == prior.slip
    assert fit.model.turn == pytest.approx(3e-3, rel=0.4)
    assert fit.errors == 'heading'


def test_fit_refuses_nothing_to_fit():
    with pytest.raises(ValueError, match='no windows'):
        noise.fit_noise(noise.ErrorWindows.concatenate([]))
    rng = np.random.default_rng(11)
    windows = simulated_windows(MODEL, 60.0, rng)
    with pytest.raises(ValueError, match='unknown'):
        noise.fit_noise(windows, free=('grip',))
    with pytest.raises(ValueError, match='dof'):
        noise.fit_noise(windows, dof=2.0)


# Real data -------------------------------------------------------------------------------

WARTHOG = [n for n in realdata.BAGS if n.startswith('warthog')]


@pytest.mark.long   # through the tools, the same folds: test_realdata_consistency
def test_fitted_on_two_warthog_runs_covers_the_third():
    # Each Warthog run held out in turn: the ICRs identified on the two others (as
    # identify_icr does), the noise fitted on them (each scored with the ICRs of the other),
    # the held-out run's 5-s and 10-s windows (evaluate_model's) scored. The set (the three
    # held-out runs) meets the acceptance band; today's default noise does not.
    from tracked_kinematics.core import identify as ident
    from tracked_kinematics.offline.bags import EncoderSource, GroundTruthSource, read_recording
    from tracked_kinematics.offline.model_evaluation import pose_references

    bags = {n: realdata.bag(n) for n in WARTHOG}
    radius, width, _ = realdata.BAGS[WARTHOG[0]]
    found = {n: (read_recording(bags[n], EncoderSource(sprocket_radius=radius),
                                ground_truth=GroundTruthSource(realdata.TOPIC)), None)
             for n in WARTHOG}

    def recordings(names):
        return [d.recording for d in pose_references([bags[n] for n in names],
                                                     [found[n] for n in names]).data]

    def fit_icr(recs):
        return ident.identify(recs, 'icr_scales', width, ground_truth_delay=0.0,
                              accept_uncertain=True).icr

    scored = {'fitted': [], 'today': []}
    for held in WARTHOG:
        train = recordings([n for n in WARTHOG if n != held])
        fit = noise.fit_noise(noise.held_out_windows(train, fit_icr, (5.0, 10.0),
                                                     track_width=width))
        test = noise.recording_windows(recordings([held]), fit_icr(train), (5.0, 10.0),
                                       track_width=width)
        scored['fitted'].append((test, fit.model))
        scored['today'].append((test, nm.NoiseModel()))
    for length in (5.0, 10.0):
        for name, items in scored.items():
            parts = [(w.of_length(length), m) for w, m in items]
            c = nm.consistency(np.concatenate([w.errors[:, :2] for w, _ in parts]),
                               np.concatenate([nm.covariances(w.bases, m) for w, m in parts]))
            assert c['windows'] > 1500
            inside = 0.35 <= c['inside_50'] <= 0.65 and 0.85 <= c['inside_95'] <= 0.98
            assert inside == (name == 'fitted'), (name, length, c)


def test_the_nodes_float_forms_match_the_arrays():
    rng = np.random.default_rng(12)
    model = nm.NoiseModel(track=2e-3, turn=1e-3, slip=1e-2, timing=0.01, floor=1e-9)
    body = cov.body_jacobian(ICR)
    p_tuple = (0.0,) * 6
    p_array = np.zeros((3, 3))
    theta = 0.0
    for d_left, d_right in zip(*manoeuvres(5.0, rng)):
        s = nm.step_covariance(model, body, ICR.track_width, d_left, d_right)
        s_array = model.body_covariance(ICR, d_left, d_right)
        assert cov.full_matrix(s) == pytest.approx(s_array, rel=1e-12, abs=1e-18)
        dx, dy, dth = body_increments(d_left, d_right)[0]
        delta_x, delta_y, m = cov.arc_step(theta, dx, dy, dth)
        p_tuple = nm.propagate_step(p_tuple, delta_x, delta_y, m, s)
        p_array = nm.propagate_body(p_array, delta_x, delta_y, m, s_array)
        theta += dth
    assert cov.full_matrix(p_tuple) == pytest.approx(p_array, rel=1e-9, abs=1e-15)
    assert cov.full_matrix(nm.timing_covariance(model, 0.5, -0.2, 0.3)) == pytest.approx(
        0.01 * np.outer([0.5, -0.2, 0.3], [0.5, -0.2, 0.3]))


def test_fit_values_name_the_constants_and_their_provenance():
    rng = np.random.default_rng(13)
    windows = simulated_windows(MODEL, 120.0, rng)
    fit = noise.fit_noise(windows, free=('track', 'slip'))
    values = fit.values()
    assert values['covariance.track'] == fit.model.track
    assert values['covariance.timing'] == nm.PRIOR.timing
    assert values['covariance.fit.fitted'] == ['track', 'slip']
    assert values['covariance.fit.held'] == ['turn', 'timing']
    assert values['covariance.fit.errors'] == 'pose'


def test_one_recording_is_held_out_block_by_block():
    from tracked_kinematics.core.identify import Recording

    rng = np.random.default_rng(14)
    d_left, d_right = manoeuvres(200.0, rng)
    body = body_increments(d_left, d_right)
    heading = np.concatenate([[0.0], np.cumsum(body[:, 2])])
    cx, cy = arc_chord(*body.T)
    c, s = np.cos(heading[:-1]), np.sin(heading[:-1])
    x = np.concatenate([[0.0], np.cumsum(c * cx - s * cy)])
    y = np.concatenate([[0.0], np.cumsum(s * cx + c * cy)])
    t = np.arange(len(x)) * DT
    left, right = np.concatenate([[0.0], np.cumsum(d_left)]), np.concatenate(
        [[0.0], np.cumsum(d_right)])
    rec = Recording(t, left, right, t[::2], x[::2], y[::2], heading[::2])
    seen = []

    def fit_icr(recordings):
        seen.append(sum(r.duration for r in recordings))
        return ICR

    windows = noise.held_out_windows([rec], fit_icr, (5.0,), blocks=4)
    assert len(seen) == 4 and all(d < 0.8 * rec.duration for d in seen)
    assert len(windows) > 50
    # The odometry is the drive itself: no error, whatever the block.
    assert np.abs(windows.errors).max() < 1e-9


def test_the_scale_term_is_the_displacement_s_at_any_window_length():
    # A distance scale off by s stretches the path: each window's displacement p is off by
    # s p, whatever its length (through the timing term, constant in the length, it was
    # right for one length only). The same in the published covariance of a pose since reset.
    rng = np.random.default_rng(3)
    d_left, d_right = manoeuvres(120.0, rng)
    only = nm.NoiseModel(track=0.0, scale=0.05 ** 2, floor=0.0)
    for length in (50, 400):
        start = np.arange(0, len(d_left) - length, 97)
        bases, motion = nm.window_bases(ICR, d_left, d_right, np.full(len(d_left), DT), start,
                                        start + length)
        cov = np.einsum('wmij,m->wij', bases, only.constants)
        p = motion[:, :2]
        np.testing.assert_allclose(cov[:, :2, :2], 0.05 ** 2 * p[:, :, None] * p[:, None, :],
                                   atol=1e-12)
        assert np.all(cov[:, 2, :] == 0.0) and np.all(cov[:, :, 2] == 0.0)
    upper = nm.published_covariance((0.0,) * 6, (3.0, -4.0, 0.7), (0.0, 0.0, 0.0),
                                    (0.0, 0.0, 0.0), only)
    assert upper == pytest.approx((0.0225, -0.03, 0.0, 0.04, 0.0, 0.0))


@pytest.mark.parametrize('n', [1, 2, 3, 4])
@pytest.mark.parametrize('dof', [None, 5.0])
def test_the_windows_likelihood_is_numpys_cholesky_and_refuses_what_it_refuses(n, dof):
    # Written out element by element over the windows (ten times faster than numpy's batched
    # LAPACK calls on 3 x 3s): the same -2 log p as numpy's factor and solve, in any dimension.
    rng = np.random.default_rng(n)
    m = rng.normal(size=(500, n, n)) * np.exp(rng.normal(size=(500, 1, 1)))
    covariances = m @ np.swapaxes(m, 1, 2) + 1e-3 * np.eye(n)
    errors = rng.normal(size=(500, n))
    scaled = covariances * ((dof - 2.0) / dof) if dof else covariances
    chol = np.linalg.cholesky(scaled)
    q = np.sum(np.linalg.solve(chol, errors[..., None])[..., 0] ** 2, 1)
    log_det = 2.0 * np.sum(np.log(np.diagonal(chol, axis1=1, axis2=2)), 1)
    expected = log_det + (q if dof is None else (dof + n) * np.log1p(q / dof))
    np.testing.assert_allclose(noise.negative_log_likelihoods(errors, covariances, dof),
                               expected, rtol=1e-10, atol=1e-12)
    for bad in (-np.eye(n), np.full((n, n), np.nan)):
        with pytest.raises(np.linalg.LinAlgError):
            noise.negative_log_likelihoods(errors[:1], bad[None], dof)
