"""
Benchmark: how much the tracks say about the gyro's timing, per terrain (issue 36).

identify_icr times the gyro against the turns the tracks make (``imu_delay``). On the
Warthog's windowed bags (one logging set-up: asphalt, sand, gravel, ice) the firm grounds give
the same delay, and ice is refused: "the tracks slip too much to time the gyro". This
benchmark shows why, with no model: inside each 2-s piece (linear trend removed, Hann
window) the cross-spectrum of the tracks' turn rate ``(v_right - v_left) / B`` and the gyro's
rate, averaged over the pieces. Printed per set and frequency: the coherence (how much of
the gyro's fluctuation the tracks' explains, 0-1) and the group delay the phase gives
(``-phase / (2 pi f)``, s; negative: the gyro's stamps ahead of the encoders'); then the
band's coherence-weighted delay, where the coherence is at least :data:`MIN_COHERENCE`.

Measured: asphalt, sand, gravel coherence 0.83 / 0.58 / 0.78 at 0.31 Hz and 0.71 / 0.39 /
0.71 at 0.94 Hz, band delays -0.115 / -0.092 / -0.124 s (identify_icr: -0.13 s on each); ice
0.03-0.04 at every frequency of the band: inside a piece the tracks' turning carries no
timing of the body's turns (the body slides). What identify_icr's correlation finds there
(+0.49 s, heading r 0.88) comes from the pieces' mean turns alone, which any delay fits about
as well; no estimator against the tracks can time the gyro on ice, and the delay of the
robot's set-up has to be given (``--imu-delay``, measured on firm ground).

Run: ``python benchmarks/bench_imu_delay_coherence.py [REALDATA_FOLDER] [SET ...]``.
"""

from pathlib import Path
import sys

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'test'))

from helpers.realdata import from_argv  # noqa: E402 -- the test helpers, from the tree
import numpy as np  # noqa: E402
from tracked_kinematics.offline.bags import EncoderSource, read_recording  # noqa: E402

SETS = {'asphalt': 'warthog_asphalt_2024-09-20_09h09',
        'sand': 'warthog_sand_2024-09-25_14h13',
        'gravel': 'warthog_gravel_2024-08-06_11h37_part1',
        'ice': 'warthog_ice_2024-07-30_16h30_part1'}
RADIUS, WIDTH = 0.3, 1.08
#: Rows of a piece used (the pieces hold 40 rows at 20 Hz; some a few fewer).
ROWS = 36
#: FFT length (zero-padded): bins of 20 / 128 Hz.
NFFT = 128
#: Frequencies printed and used for the band's delay, Hz.
BAND = (0.3, 1.6)
MIN_COHERENCE = 0.2


def pieces(t, gap=0.5):
    """Return the index arrays of the stretches without a gap longer than ``gap`` s."""
    return np.split(np.arange(len(t)), np.flatnonzero(np.diff(t) > gap) + 1)


def detrended(x):
    k = np.arange(len(x))
    return x - np.polyval(np.polyfit(k, x, 1), k)


def cross_spectrum(rec):
    """Return the frequencies, the pieces' mean cross-spectrum and the two power spectra."""
    tracks = (rec.speeds[:, 1] - rec.speeds[:, 0]) / WIDTH
    gyro = np.interp(rec.speed_t, rec.gyro_t, rec.gyro_rate)
    dt = float(np.median(np.diff(rec.speed_t)))
    window = np.hanning(ROWS)
    cross, p_tracks, p_gyro, n = 0.0, 0.0, 0.0, 0
    for idx in pieces(rec.speed_t):
        if len(idx) < ROWS:
            continue
        idx = idx[:ROWS]
        a = np.fft.rfft(detrended(tracks[idx]) * window, NFFT)
        b = np.fft.rfft(detrended(gyro[idx]) * window, NFFT)
        cross, p_tracks, p_gyro, n = (cross + np.conj(a) * b, p_tracks + abs(a) ** 2,
                                      p_gyro + abs(b) ** 2, n + 1)
    return np.fft.rfftfreq(NFFT, dt), cross / n, p_tracks / n, p_gyro / n, n


def main(argv) -> int:
    base, names = from_argv(argv, SETS)
    for name in names:
        rec = read_recording(base / SETS[name], EncoderSource(sprocket_radius=RADIUS),
                             imu_topic='/imu/data')
        f, cross, p_tracks, p_gyro, n = cross_spectrum(rec)
        coherence = abs(cross) ** 2 / (p_tracks * p_gyro)
        phase = np.angle(cross)
        band = (f >= BAND[0]) & (f <= BAND[1])
        print(f'{name}: {n} pieces of {ROWS} rows')
        for k in np.flatnonzero(band)[::2]:
            print(f'  {f[k]:4.2f} Hz  coherence {coherence[k]:.2f}  group delay '
                  f'{-phase[k] / (2 * np.pi * f[k]):+.3f} s')
        used = band & (coherence >= MIN_COHERENCE)
        if used.any():
            w = coherence[used] * (2 * np.pi * f[used]) ** 2
            delay = -np.sum(w * phase[used] / (2 * np.pi * f[used])) / np.sum(w)
            print(f'  band delay {delay:+.3f} s over {used.sum()} bins')
        else:
            print(f'  no bin with coherence >= {MIN_COHERENCE:g}: the tracks do not time the '
                  'gyro here')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
