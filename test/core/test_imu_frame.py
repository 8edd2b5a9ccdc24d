"""The gyro in the vehicle frame: core.imu_frame against scipy and finite differences."""

import math

from hypothesis import given, strategies as st
import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from tracked_kinematics.core.imu_frame import (
    heading_rate, MAX_TILT, mount_rotation, orientation_heading)

angles = st.floats(-math.pi, math.pi)

# Garbage axes are refused without a RuntimeWarning on the way (a node's log shows them).
pytestmark = pytest.mark.filterwarnings('error::RuntimeWarning')


@given(angles, angles, angles)
def test_mount_rotation_is_urdf_rpy(roll, pitch, yaw):
    expected = Rotation.from_euler('xyz', [roll, pitch, yaw]).as_matrix()   # extrinsic x, y, z
    np.testing.assert_allclose(mount_rotation(roll, pitch, yaw), expected, atol=1e-12)


def heading(rotation):
    """Return the heading of base x projected on the horizontal plane (world z up)."""
    x = rotation.apply([1.0, 0.0, 0.0])
    return math.atan2(x[1], x[0])


@given(st.floats(-1.2, 1.2), st.floats(-1.0, 1.0), angles, st.floats(-2.0, 2.0),
       st.floats(-2.0, 2.0), st.floats(-2.0, 2.0), angles, angles, angles)
def test_the_rate_is_the_heading_s_derivative(roll, pitch, yaw, wx, wy, wz, m_roll, m_pitch,
                                              m_yaw):
    """Any base attitude within the tilt limit, any mount: d heading / dt by finite differences."""
    base = Rotation.from_euler('ZYX', [yaw, pitch, roll])   # world <- base
    mount = Rotation.from_euler('xyz', [m_roll, m_pitch, m_yaw])   # base <- imu
    tilt = math.acos(np.clip(base.apply([0.0, 0.0, 1.0])[2], -1.0, 1.0))
    if tilt > MAX_TILT - 0.05:
        return
    omega_imu = np.array([wx, wy, wz])
    imu = base * mount   # world <- imu
    rate, used = heading_rate(tuple(omega_imu), mount.as_matrix(), tuple(imu.as_quat()), True)
    assert used
    h = 1e-6
    step = Rotation.from_rotvec(imu.apply(omega_imu) * h)   # a world-frame rotation over h
    expected = (np.unwrap([heading(step.inv() * base), heading(step * base)]) @ [-1, 1]) / (2 * h)
    assert rate == pytest.approx(expected, abs=1e-5)
    # Without the orientation: the body z rate (the mount's).
    body, used = heading_rate(tuple(omega_imu), mount.as_matrix())
    assert not used and body == pytest.approx(mount.apply(omega_imu)[2], abs=1e-12)


def test_twenty_degrees_of_slope_along_the_contour_is_cos_20():
    q = (Rotation.from_euler('x', math.radians(20.0))).as_quat()
    rate, used = heading_rate((0.0, 0.0, 1.0), mount_rotation(0, 0, 0), tuple(q), True)
    assert used and rate == pytest.approx(math.cos(math.radians(20.0)))


@pytest.mark.parametrize('quaternion, has, why', [
    ((0.0, 0.0, 0.0, 0.0), True, 'all zero: a driver that fills no orientation'),
    ((0.0, 0.0, 0.0, 1.0), False, 'orientation_covariance[0] = -1'),
    ((0.0, 0.0, 0.0, 1.1), True, 'not a unit quaternion'),
    ((math.nan, 0.0, 0.0, 1.0), True, 'not finite'),
    (tuple(Rotation.from_euler('x', math.radians(70)).as_quat()), True, 'tilted beyond 60 deg'),
])
def test_an_unusable_orientation_gives_the_body_rate(quaternion, has, why):
    mount = mount_rotation(0.1, 0.0, 0.0)
    rate, used = heading_rate((0.2, 0.3, 0.5), mount, quaternion, has)
    assert not used, why
    assert rate == pytest.approx(mount[2] @ [0.2, 0.3, 0.5])


def test_up_is_the_mount_s():
    """An NED orientation with its mount (roll pi) reads right; the wrong mount, mirrored."""
    r = 0.4
    ned_level = (0.0, 0.0, math.sin(0.3), math.cos(0.3))   # FRD in NED, heading 0.6 rad
    right, used = heading_rate((0.0, 0.0, -r), mount_rotation(math.pi, 0, 0), ned_level, True)
    assert used and right == pytest.approx(r)
    wrong, _ = heading_rate((0.0, 0.0, -r), mount_rotation(0, 0, 0), ned_level, True)
    assert wrong == pytest.approx(-r)


def test_arrays_give_what_samples_give():
    rng = np.random.default_rng(1)
    n = 50
    omega = rng.normal(size=(3, n))
    quats = Rotation.from_euler('xyz', rng.uniform(-0.8, 0.8, size=(n, 3))).as_quat()
    quats[::7] = 0.0
    has = rng.uniform(size=n) > 0.2
    mount = mount_rotation(0.2, -0.1, 1.0)
    rates, used = heading_rate(tuple(omega), mount, tuple(quats.T), has)
    for k in range(n):
        rate, one = heading_rate(tuple(omega[:, k]), mount, tuple(quats[k]), bool(has[k]))
        assert rates[k] == pytest.approx(rate, abs=1e-12) and used[k] == one
    assert used.any() and not used.all()


@given(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), angles, angles, angles, angles)
def test_the_orientation_s_heading_is_base_x_on_the_horizontal(
        roll, pitch, yaw, m_roll, m_pitch, m_yaw):
    """Any base attitude within the tilt limit, any mount: the base's heading; arrays too."""
    base = Rotation.from_euler('ZYX', [yaw, pitch, roll])   # world <- base
    mount = Rotation.from_euler('xyz', [m_roll, m_pitch, m_yaw])   # base <- imu
    if base.apply([0.0, 0.0, 1.0])[2] < math.cos(MAX_TILT - 0.05):
        return
    q = tuple((base * mount).as_quat())
    got = orientation_heading(q, mount.as_matrix())
    assert math.cos(got - heading(base)) == pytest.approx(1.0, abs=1e-9)
    arrays = orientation_heading(tuple(np.array([v, v]) for v in q), mount.as_matrix(),
                                 np.array([True, False]))
    assert arrays[0] == pytest.approx(got, abs=1e-12) and math.isnan(arrays[1])


def test_an_ned_heading_grows_as_the_enu_one_with_its_mount():
    """NED (FRD in NED, heading pi/2 - psi): through roll pi, psi up to a constant; else -psi."""
    psi = np.linspace(-1.0, 1.0, 9)
    ned = tuple(Rotation.from_euler('z', (0.5 * math.pi - psi)[:, None]).as_quat().T)
    right = orientation_heading(ned, mount_rotation(math.pi, 0.0, 0.0))
    wrong = orientation_heading(ned, mount_rotation(0.0, 0.0, 0.0))
    np.testing.assert_allclose(np.unwrap(right - psi) - (right[0] - psi[0]), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.unwrap(wrong + psi) - (wrong[0] + psi[0]), 0.0, atol=1e-12)


@pytest.mark.parametrize('rpy, sign', [((0.0, 0.0, 0.0), 1.0), ((math.pi, 0.0, 0.0), -1.0),
                                       ((3.14159, 0.0, 0.0), -1.0), ((0.0, 0.0, 1.0), 1.0)])
@pytest.mark.parametrize('garbage', [math.nan, math.inf])
def test_a_garbage_axis_the_mount_does_not_read_spoils_nothing(rpy, sign, garbage):
    # Before: 0 * NaN: a one-axis gyro publishing NaN on x and y had every sample refused as
    # non-finite (the node), and identify_icr said "no angular velocity: is
    # angular_velocity.z filled?".
    mount = mount_rotation(*rpy)
    omega = (garbage, garbage, 0.5 * sign)
    assert heading_rate(omega, mount) == (pytest.approx(0.5), False)
    # With a level orientation: the orientation's rate needs x and y: the body rate.
    level = tuple(Rotation.from_euler('xyz', [rpy[0], 0.0, 0.3]).as_quat())
    assert heading_rate(omega, mount, level, True) == (pytest.approx(0.5), False)
    # Arrays: the same, where the good samples keep the orientation.
    omegas = tuple(np.array([v, 0.1]) for v in omega)
    rates, used = heading_rate(omegas, mount, tuple(np.array([v, v]) for v in level),
                               np.array([True, True]))
    assert rates[0] == pytest.approx(0.5) and used.tolist() == [False, True]
    # The z axis the mount reads: still not finite (refused downstream).
    assert math.isnan(heading_rate((0.0, 0.0, math.nan), mount)[0])
