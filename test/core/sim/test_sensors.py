"""Sensor models: gyro (bias, noise, latency, saturation), GNSS, local plane, streams."""

import math

import numpy as np
import pytest
from tracked_kinematics.core.geodesy import enu_to_geodetic, geodetic_to_enu, GeoOrigin
from tracked_kinematics.core.sim.sensors import (gnss_samples, GnssModel, GnssStream,
                                                 gyro_samples, GyroModel, GyroStream,
                                                 STATUS_FIX, STATUS_NO_FIX)

DT = 0.01


def truth(duration=20.0, seed=3):
    """Return a smooth yaw-rate profile held over 10-ms steps and its exact heading."""
    t = np.arange(0.0, duration, DT)
    w = 0.8 * np.sin(0.7 * t) + 0.3 * np.sin(2.3 * t + 1.0)
    heading = np.r_[0.0, np.cumsum(w[:-1] * DT)]
    return t, w, heading


def test_noise_free_gyro_integrates_to_the_true_heading():
    t, w, heading = truth()
    stamps, z = gyro_samples(t, w, GyroModel(rate=50.0), np.random.default_rng(0))
    assert stamps[0] == t[0] and np.allclose(np.diff(stamps), 0.02)
    assert stamps[-1] <= t[-1]
    # Reading k is the mean rate over [s_k - T/2, s_k + T/2]: summed, the heading change.
    change = np.sum(z[1:-1]) * 0.02
    expected = (np.interp(stamps[-2] + 0.01, t, heading)
                - np.interp(stamps[1] - 0.01, t, heading))
    assert change == pytest.approx(expected, abs=1e-9)


def test_bias_noise_and_scale_are_what_the_model_says():
    t, w, _ = truth(200.0)
    clean = gyro_samples(t, w, GyroModel(), np.random.default_rng(0))[1]
    model = GyroModel(bias=0.02, noise_std=0.005, scale=1.01)
    _, z = gyro_samples(t, w, model, np.random.default_rng(1))
    residual = z - 1.01 * clean
    assert np.mean(residual) == pytest.approx(0.02, abs=3 * 0.005 / math.sqrt(z.size))
    assert np.std(residual) == pytest.approx(0.005, rel=0.05)


def test_latency_shifts_the_readings_later():
    t, w, _ = truth()
    s0, z0 = gyro_samples(t, w, GyroModel(rate=100.0), np.random.default_rng(0))
    s1, z1 = gyro_samples(t, w, GyroModel(rate=100.0, latency=0.17), np.random.default_rng(0))
    np.testing.assert_array_equal(s0, s1)
    # A reading stamped s with latency 0.17 s equals the one stamped s - 0.17 s without.
    np.testing.assert_allclose(z1[17 + 1:-1], z0[1:-17 - 1], atol=1e-9)


def test_bias_walk_grows_like_a_random_walk():
    t = np.arange(0.0, 100.0, DT)
    model = GyroModel(rate=100.0, bias_walk=0.001)
    ends = [gyro_samples(t, np.zeros(t.size), model, np.random.default_rng(seed))[1][-1]
            for seed in range(200)]
    # After ~100 s the bias has a standard deviation of 0.001 * sqrt(100) = 0.01 rad/s.
    assert np.std(ends) == pytest.approx(0.01, rel=0.2)


def test_saturation_clips():
    t = np.arange(0.0, 5.0, DT)
    _, z = gyro_samples(t, np.full(t.size, 3.0), GyroModel(saturation=2.0),
                        np.random.default_rng(0))
    assert np.max(np.abs(z)) == 2.0


def test_gyro_model_refuses_a_scale_of_zero():
    # Its other values are checked where they enter: simulate_bag's --imu-* options
    # (test/offline/test_simulate_bag.py) and tracked_simulator's gyro_* parameters.
    with pytest.raises(ValueError, match='scale'):
        GyroModel(scale=0.0)


def test_gyro_refuses_bad_truth():
    with pytest.raises(ValueError, match='increasing'):
        gyro_samples([0.0, 0.0, 1.0], [0.0, 0.0, 0.0], GyroModel(), np.random.default_rng(0))
    with pytest.raises(ValueError, match='yaw_rate_true'):
        gyro_samples([0.0, 1.0, 2.0], [0.0], GyroModel(), np.random.default_rng(0))


def circle(duration=60.0):
    t = np.arange(0.0, duration, DT)
    theta = 0.2 * t
    return t, 5.0 * np.sin(theta), 5.0 * (1.0 - np.cos(theta)), theta


def test_gnss_white_noise_latency_antenna_and_dropouts():
    t, x, y, theta = circle()
    model = GnssModel(rate=5.0, noise_std=0.0, latency=0.2, antenna_x=0.5)
    stamps, east, north, status = gnss_samples(t, x, y, theta, model, np.random.default_rng(0))
    assert np.allclose(np.diff(stamps), 0.2) and np.all(status == STATUS_FIX)
    at = stamps - 0.2
    th = np.interp(at, t, theta)
    np.testing.assert_allclose(east, np.interp(at, t, x) + 0.5 * np.cos(th), atol=1e-4)
    np.testing.assert_allclose(north, np.interp(at, t, y) + 0.5 * np.sin(th), atol=1e-4)

    noisy = GnssModel(noise_std=2.0, dropout=0.1)
    t, x, y, theta = circle(2000.0)
    stamps, e2, n2, status = gnss_samples(t, x, y, theta, noisy, np.random.default_rng(1))
    lost = status == STATUS_NO_FIX
    assert np.mean(lost) == pytest.approx(0.1, abs=0.02)
    assert np.all(np.isnan(e2[lost])) and np.all(np.isfinite(e2[~lost]))
    err = e2[~lost] - np.interp(stamps[~lost], t, x)
    assert np.std(err) == pytest.approx(2.0, rel=0.05)
    assert abs(np.corrcoef(err[1:], err[:-1])[0, 1]) < 0.05


def test_gnss_correlated_noise_keeps_its_variance_and_wanders():
    t = np.arange(0.0, 4000.0, 0.1)
    zeros = np.zeros(t.size)
    model = GnssModel(rate=5.0, noise_std=2.0, correlation_time=30.0)
    _, east, _, _ = gnss_samples(t, zeros, zeros, zeros, model, np.random.default_rng(2))
    assert np.std(east) == pytest.approx(2.0, rel=0.2)
    lag1 = np.corrcoef(east[1:], east[:-1])[0, 1]
    assert lag1 == pytest.approx(math.exp(-1.0 / (5.0 * 30.0)), abs=0.01)


def test_local_plane_round_trip_and_scale():
    origin = GeoOrigin(46.52, 6.57, 420.0)
    rng = np.random.default_rng(0)
    east, north, up = rng.uniform(-2000, 2000, (3, 500))
    lat, lon, alt = enu_to_geodetic(east, north, up, origin)
    e2, n2, u2 = geodetic_to_enu(lat, lon, alt, origin)
    np.testing.assert_allclose(np.c_[e2, n2, u2], np.c_[east, north, up], atol=1e-6)
    # One arc-second of latitude is about 30.9 m here; the origin maps to 0.
    e, n, u = geodetic_to_enu(origin.latitude + 1 / 3600, origin.longitude, origin.altitude,
                              origin)
    assert float(n) == pytest.approx(30.89, abs=0.05) and abs(float(e)) < 1e-6
    assert abs(float(u)) < 1e-3
    lat0, lon0, alt0 = enu_to_geodetic(0.0, 0.0, 0.0, origin)
    assert float(lat0) == pytest.approx(46.52, abs=1e-11)
    assert float(alt0) == pytest.approx(420.0, abs=1e-6)


def test_geo_origin_refuses_a_latitude_off_the_globe():
    with pytest.raises(ValueError, match='latitude'):
        GeoOrigin(91.0, 0.0)


def test_gyro_stream_matches_the_batch_function():
    t, w, _ = truth()
    model = GyroModel(rate=50.0, bias=0.01, latency=0.05, bias_walk=0.0)
    stamps, z = gyro_samples(t, w, model, np.random.default_rng(0))
    stream = GyroStream(model, np.random.default_rng(0))
    got_s, got_z = [], []
    for chunk in np.array_split(np.arange(t.size), 37):
        s, zz = stream.push(t[chunk], w[chunk])
        assert np.all(s <= t[chunk[-1]] + 1e-12)
        got_s.append(s)
        got_z.append(zz)
    got_s, got_z = np.concatenate(got_s), np.concatenate(got_z)
    n = got_s.size
    assert n >= stamps.size - 3
    np.testing.assert_allclose(got_s, stamps[:n])
    np.testing.assert_allclose(got_z, z[:n], atol=1e-9)


def test_gnss_stream_matches_the_batch_function():
    t, x, y, theta = circle(30.0)
    model = GnssModel(rate=5.0, noise_std=0.0, latency=0.1)
    stamps, east, north, _ = gnss_samples(t, x, y, theta, model, np.random.default_rng(0))
    stream = GnssStream(model, np.random.default_rng(0))
    out = [stream.push(t[c], x[c], y[c], theta[c])
           for c in np.array_split(np.arange(t.size), 11)]
    got = np.concatenate([o[0] for o in out])
    got_e = np.concatenate([o[1] for o in out])
    assert got.size >= stamps.size - 1
    np.testing.assert_allclose(got, stamps[:got.size])
    np.testing.assert_allclose(got_e, east[:got.size], atol=1e-9)
    correlated = GnssStream(GnssModel(noise_std=1.0, correlation_time=10.0),
                            np.random.default_rng(0))
    for c in np.array_split(np.arange(t.size), 50):
        s, e, n, status = correlated.push(t[c], x[c], y[c], theta[c])
        assert np.all(np.isfinite(e))
