"""The field's Beat Align Score, computed as the peers compute it, in both directions.

Two incompatible definitions are in use, both with sigma = 3 frames at 60 fps (0.05 s):

- **music -> motion** (Bailando's code, ``utils/beat_align_score.py``, and the tables of Bailando,
  EDGE and FineDance): for each **music** beat, the distance to the nearest motion beat; averaged
  over the music beats. Extra motion beats cost nothing, so jitter scores high.
- **motion -> music** (the AI Choreographer / AIST++ paper, Li et al. 2021, which publishes no code
  for it): for each **motion** beat, the distance to the nearest music beat; averaged over the
  motion beats.

Motion beats as Bailando's ``calc_db``: the mean over joints of each joint's displacement from
frame t to t + 1 (a speed in metres per frame, T - 1 values), smoothed by a Gaussian of sigma 5
frames at 60 fps (``scipy.ndimage.gaussian_filter``, reflecting edges), and its strict local minima;
the beat of step t is at frame t. Music beats are frame indices ``round(t * fps)``, and those at or
after frame T - 1 are dropped, as Bailando's ``get_mb`` truncates them to the speed curve's length.

Everything here is in frames of a uniform grid; sigmas are given in seconds and converted with the
frame rate. For the analysis on recordings with masks and sub-frame beats see
:mod:`kinectdata.evaluation.rhythm`. Equality with the peers' code: tests/evaluation/
test_field_metrics.py on ``shared/fixtures/metrics``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from kinectdata.core.errors import KinectDataError

SIGMA_S = 3 / 60
"""Beat Align Score sigma: 3 frames at 60 fps (Bailando; the AIST++ paper states the same)."""
SMOOTHING_S = 5 / 60
"""Gaussian sigma of the speed curve: 5 frames at 60 fps (Bailando's ``calc_db``)."""
DIRECTIONS = ("music_to_motion", "motion_to_music")
"""Beat Align Score directions: each music beat to its nearest motion beat, averaged over the music
beats (Bailando's code); each motion beat to its nearest music beat, averaged over the motion beats
(the AI Choreographer paper)."""


def peer_motion_beats(positions: np.ndarray, fps: float, smoothing_s: float = SMOOTHING_S) -> np.ndarray:
    """Motion beats as Bailando's ``calc_db``: frame indices of the smoothed speed's local minima.

    Args:
        positions: [T, J, 3] joint positions (metres), T >= 3, on a uniform grid of ``fps``.
        fps: frames per second.
        smoothing_s: Gaussian sigma in seconds (5 frames at 60 fps).

    Returns:
        [K] int64 increasing frame indices in 1..T-3.
    """
    from scipy.ndimage import gaussian_filter1d
    from scipy.signal import argrelextrema

    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[0] < 3:
        raise KinectDataError(f"motion beats need [T >= 3, J, C] positions, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise KinectDataError("motion beats need finite positions (fill or drop missing frames first)")
    if not fps > 0:
        raise KinectDataError(f"fps must be positive, got {fps}")
    speed = np.mean(np.linalg.norm(np.diff(p, axis=0), axis=2), axis=1)
    smooth = gaussian_filter1d(speed, smoothing_s * fps, mode="reflect")
    return argrelextrema(smooth, np.less)[0].astype(np.int64)


def music_beat_frames(music_beats_s: Sequence[float], fps: float, frames: int) -> np.ndarray:
    """Music beat times [B] (s) as frame indices ``round(t * fps)``, keeping those < ``frames`` - 1."""
    beats = np.asarray(music_beats_s, dtype=np.float64)
    beats = beats[np.isfinite(beats)]
    indices = np.rint(beats * fps).astype(np.int64)
    return indices[(indices >= 0) & (indices < frames - 1)]


def peer_beat_align_score(
    music_frames: Sequence[int], motion_frames: Sequence[int], fps: float, direction: str, sigma_s: float = SIGMA_S
) -> float:
    """Beat Align Score on frame indices: mean of exp(-d^2 / (2 sigma^2)) over one set of beats.

    Args:
        music_frames: [B] music beat frame indices.
        motion_frames: [K] motion beat frame indices.
        fps: frames per second (sigma in frames = ``sigma_s * fps``).
        direction: ``"music_to_motion"`` (Bailando) or ``"motion_to_music"`` (AIST++ paper).
        sigma_s: Gaussian width in seconds.

    Returns:
        The score in 0..1; NaN when the beats to average over are none, 0 when the other set is empty.
    """
    if direction not in DIRECTIONS:
        raise KinectDataError(f"Beat Align Score direction must be one of {DIRECTIONS}, got {direction!r}")
    music = np.asarray(music_frames, dtype=np.float64)
    motion = np.asarray(motion_frames, dtype=np.float64)
    averaged, other = (music, motion) if direction == "music_to_motion" else (motion, music)
    if averaged.size == 0:
        return float("nan")
    if other.size == 0:
        return 0.0
    sigma = sigma_s * fps
    distance = np.min(np.abs(averaged[:, None] - other[None, :]), axis=1)
    return float(np.mean(np.exp(-(distance**2) / (2 * sigma**2))))
