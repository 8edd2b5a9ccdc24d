"""
Evaluation: score terrain models on recordings, the way the field measures them.

:mod:`.pieces`, :mod:`.metrics`, :mod:`.horizons`, :mod:`.online`, :mod:`.scoring`
(:func:`evaluate`), :mod:`.noise` (the noise model fitted to windows), :mod:`.consistency`
and :mod:`.verdict` (the published covariance against the errors); see
docs/tools/evaluate_model.md.
"""

from .horizons import command_horizons, Commands, encoder_horizons, HorizonErrors
from .metrics import (evo_path_pairs, horizon_members, relative_errors, rpe, summary,
                      window_pairs)
from .noise import (ErrorWindows, fit_noise, held_out_windows, NoiseFit, piece_windows,
                    recording_windows)
from .online import OnlineRun, replay
from .pieces import (Cut, cut, icr_increments, mean_track_speeds, moving_windows, odometry,
                     Piece)
from .scoring import Candidate, Data, evaluate, Evaluation, rpe_key, Settings, window_key

__all__ = [
    'Candidate', 'Commands', 'Cut', 'Data', 'ErrorWindows', 'Evaluation', 'HorizonErrors',
    'NoiseFit', 'OnlineRun', 'Piece', 'Settings', 'command_horizons', 'cut', 'encoder_horizons',
    'evaluate', 'evo_path_pairs', 'fit_noise', 'held_out_windows', 'horizon_members',
    'icr_increments', 'mean_track_speeds', 'moving_windows', 'odometry', 'piece_windows',
    'recording_windows', 'relative_errors', 'replay', 'rpe', 'rpe_key', 'summary',
    'window_key', 'window_pairs',
]
