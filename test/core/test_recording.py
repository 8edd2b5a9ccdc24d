"""The one recording type: checked where it is built, its derived track speeds."""

import numpy as np
import pytest
from tracked_kinematics.core.recording import Recording

T = np.arange(5) * 0.1
TRAVEL = np.array([0.0, 0.01, 0.03, 0.06, 0.10])


def test_only_the_encoders_are_required():
    rec = Recording(T, TRAVEL, 2 * TRAVEL)
    assert rec.gt_t is None and rec.pose is None and rec.positions is None
    assert rec.gyro_t is None and rec.commands is None and rec.duration == 0.0
    assert rec.enc_t.dtype == float


@pytest.mark.parametrize('fields, match', [
    ({'enc_t': T[::-1]}, 'enc_t must be strictly increasing'),
    ({'left': np.append(TRAVEL[:-1], np.nan)}, 'left has non-finite values'),
    ({'right': TRAVEL[:-1]}, r'enc_t, left, right must have the shapes \(N,\), \(N,\), \(N,\)'),
    ({'gt_t': T, 'gt_x': T, 'gt_y': T}, 'give gt_t, gt_x, gt_y, gt_yaw together'),
    ({'gt_t': T, 'gt_x': T, 'gt_y': T, 'gt_yaw': T + np.inf}, 'gt_yaw has non-finite'),
    ({'gnss_t': np.zeros(5), 'gnss_x': T, 'gnss_y': T}, 'gnss_t must be strictly increasing'),
    ({'gyro_rate': T}, 'gyro_rate needs gyro_t'),
    ({'gyro_t': T}, 'give gyro_rate or gyro_yaw with gyro_t'),
    ({'gyro_t': T, 'gyro_rate': T[:-1]}, 'gyro_t, gyro_rate must have the shapes'),
    ({'command_t': T, 'commands': T}, r'command_t, commands must have the shapes \(N,\), '
                                      r'\(N, 2\), got \(5,\), \(5,\)'),
    ({'speed_t': T}, 'give speed_t, speeds together'),
])
def test_a_malformed_stream_is_refused_where_the_recording_is_built(fields, match):
    arrays = {'enc_t': T, 'left': TRAVEL, 'right': TRAVEL, **fields}
    with pytest.raises(ValueError, match=match):
        Recording(**arrays)


def test_gyro_and_command_values_may_be_non_finite():
    # Cleaned by the fitters (a few NaN gyro readings, command rows), not refused.
    rec = Recording(T, TRAVEL, TRAVEL, gyro_t=T, gyro_rate=np.append(T[:-1], np.nan),
                    command_t=T, commands=np.full((5, 2), np.nan))
    assert np.isnan(rec.gyro_rate[-1]) and np.all(np.isnan(rec.commands))


def test_track_speeds_are_the_encoders_own_else_the_travel_differentiated():
    rec = Recording(T, TRAVEL, 2 * TRAVEL)
    t, speeds = rec.track_speeds()
    np.testing.assert_allclose(t, [0.05, 0.15, 0.25, 0.35])
    np.testing.assert_allclose(speeds[:, 0], [0.1, 0.2, 0.3, 0.4])
    np.testing.assert_allclose(speeds[:, 1], 2 * speeds[:, 0])
    own = Recording(T, TRAVEL, TRAVEL, speed_t=T, speeds=np.ones((5, 2)))
    assert own.track_speeds()[0] is own.speed_t
    with pytest.raises(ValueError, match='fewer than two encoder samples'):
        Recording(T[:1], TRAVEL[:1], TRAVEL[:1]).track_speeds()


def test_a_gyro_row_may_carry_the_raw_angular_velocity():
    from tracked_kinematics.core.recording import from_stamped_rows
    # The heading rate used (here: of an IMU with z down) and the message's own (wx, wy, wz),
    # sorted together, the first of a stamp kept.
    rec = from_stamped_rows(encoder=[(0, 0.0, 0.0), (30, 0.1, 0.1)],
                            imu=[(20, 0.2, 0, 0, 0, 1, -1.0, 0.01, 0.02, -0.2),
                                 (10, 0.1, 0, 0, 0, 1, -1.0, 0.03, 0.04, -0.1),
                                 (20, 0.5, 0, 0, 0, 1, -1.0, 0.0, 0.0, -0.5)])
    assert rec.gyro_rate.tolist() == [0.1, 0.2]
    assert rec.gyro_omega.tolist() == [[0.03, 0.04, -0.1], [0.01, 0.02, -0.2]]
    assert from_stamped_rows(encoder=[(0, 0.0, 0.0)],
                             imu=[(1, 0.1, 0, 0, 0, 1, -1.0)]).gyro_omega is None
    with pytest.raises(ValueError, match='imu rows have 7 or 10 values, got 8'):
        from_stamped_rows(imu=[(1, 0.1, 0, 0, 0, 1, -1.0, 0.0)])
    with pytest.raises(ValueError, match=r'gyro_omega must have the shapes .*\(N, 3\)'):
        Recording(T, TRAVEL, TRAVEL, gyro_t=T, gyro_rate=T, gyro_omega=np.zeros((5, 2)))
