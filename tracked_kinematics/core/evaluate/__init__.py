"""
Evaluation: score terrain models on recordings, the way the field measures them.

The face of the sub-package; the modules behind it hold the definitions: :mod:`.pieces`
(gap-free, jump-free stretches and odometry along them), :mod:`.metrics` (window errors,
evo's relative pose error, horizons), :mod:`.prediction` (predictions from the encoders and
from the commands), :mod:`.online` (the icr_estimator's EKF replayed) and :mod:`.scoring`
(:func:`evaluate`, the report's figures), :mod:`.noise` (the odometry noise model's
constants fitted to the windows). The ground-truth delay is identify_icr's
(:func:`tracked_kinematics.core.identify.estimate_delays`).
"""

from .metrics import (evo_path_pairs, horizon_members, relative_errors, rpe, summary,
                      window_pairs)
from .noise import (ErrorWindows, fit_noise, held_out_windows, NoiseFit, piece_windows,
                    recording_windows)
from .online import OnlineRun, replay
from .pieces import (Cut, cut, icr_increments, mean_track_speeds, moving_windows, odometry,
                     Piece)
from .prediction import command_horizons, Commands, encoder_horizons, HorizonErrors
from .scoring import Candidate, Data, evaluate, Evaluation, rpe_key, Settings, window_key

__all__ = [
    'Candidate', 'Commands', 'Cut', 'Data', 'ErrorWindows', 'Evaluation', 'HorizonErrors',
    'NoiseFit', 'OnlineRun', 'Piece', 'Settings', 'command_horizons', 'cut', 'encoder_horizons',
    'evaluate', 'evo_path_pairs', 'fit_noise', 'held_out_windows', 'horizon_members',
    'icr_increments', 'mean_track_speeds', 'moving_windows', 'odometry', 'piece_windows',
    'recording_windows', 'relative_errors', 'replay', 'rpe', 'rpe_key', 'summary',
    'window_key', 'window_pairs',
]
