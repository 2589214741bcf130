"""Rhythm of dance motion against the music's beats (definitions and defaults: docs/rhythm.md).

- Lee et al. (2018), "Listen to Dance": the autocorrelation of the joints' x and y trajectories
  peaks at the music's beat period in y and not in x (:func:`trajectory_autocorrelation`,
  :func:`autocorrelation_peaks`, :func:`rhythm_report`);
- the Beat Align Score in both directions (:func:`motion_beats`, :func:`beat_align_score`): averaged
  over the music beats as Bailando's code does, or over the motion beats as the AI Choreographer
  (AIST++) paper defines it; on recordings with masks and sub-frame beats (the peers' exact
  computation on frame indices is :mod:`kinectdata.evaluation.metrics.beat_alignment`);
- the motion-beat F-measure within a tolerance window in seconds (:func:`motion_beat_fmeasure`, mir_eval).

Times are seconds; motion frames are on a uniform grid, frame i at ``i / fps`` s.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.fft import next_fast_len

from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.metrics.beat_alignment import DIRECTIONS as BAS_DIRECTIONS
from kinectdata.evaluation.metrics.beat_alignment import SIGMA_S as BEAT_ALIGN_SIGMA_S
from kinectdata.evaluation.metrics.beat_alignment import SMOOTHING_S as MOTION_BEAT_SMOOTHING_S

DRIFT_WINDOW_S = 2.0
"""Seconds; the centred moving average subtracted from each trajectory before autocorrelation."""
MIN_VALID_FRACTION = 0.5
"""A joint enters the autocorrelation only if its position is valid in at least this fraction of frames."""
MIN_PAIRS = 10
"""Valid (t, t + lag) pairs a joint needs for its correlation at that lag to count."""
STILL_FRACTION = 1e-9
"""A joint whose trajectory, drift removed, varies by less than this share of its coordinates'
size does not move (a constant's round-off): its autocorrelation is not counted."""
PEAK_PROMINENCE = 0.1
"""Minimum prominence of an autocorrelation peak (see :func:`autocorrelation_peaks`)."""
PERIOD_TOLERANCE = 0.10
PERIOD_TOLERANCE_FRAMES = 2
"""A peak is "at the beat period" within max(10% of the period, 2 frames)."""
FMEASURE_WINDOW_S = 0.1
"""Tolerance of the motion-beat F-measure in seconds (+-3 frames at 30 fps, as motion_dance), the
same at every frame rate."""


def beat_period_s(beat_times_s: Sequence[float]) -> float:
    """The median inter-beat interval in seconds of increasing beat times [B] (s), B >= 2."""
    beats = _beat_array(beat_times_s, "beat times")
    if beats.size < 2:
        raise KinectDataError(f"a beat period needs at least 2 beats, got {beats.size}")
    intervals = np.diff(beats)
    if np.any(intervals <= 0):
        i = int(np.argmax(intervals <= 0))
        raise KinectDataError(f"beat times must be strictly increasing: beat {i + 1} at {beats[i + 1]} s")
    return float(np.median(intervals))


def trajectory_autocorrelation(
    positions: np.ndarray,
    mask: np.ndarray | None,
    max_lag_frames: int,
    drift_window_frames: int | None,
) -> np.ndarray:
    """Autocorrelation of the joint trajectories per coordinate axis, averaged over joints.

    For each joint and axis: the slow drift is removed by subtracting a centred moving average over
    ``drift_window_frames`` (rounded up to odd; averaged over the valid frames in the window, so
    truncated at the ends; None: not removed). A moving average, unlike a linear detrend, also
    removes travel that is not at constant speed (walking across the floor and back), whose broad
    autocorrelation would otherwise swamp the beat peaks; periods shorter than the window keep
    87-122% of their amplitude. Then at each lag k the Pearson correlation of the pairs
    (x[t], x[t + k]) where both frames are valid, each lag normalised by its own pairs and
    variances (so lag 0 is 1 and long lags are not shrunk toward 0). Masked frames are left out,
    never filled. The per-joint values are averaged over the joints valid in at least
    :data:`MIN_VALID_FRACTION` of the frames, skipping a joint at lags where it has fewer than
    :data:`MIN_PAIRS` pairs or no variance.

    Args:
        positions: [T, J, C] joint positions (any unit: the result is unitless).
        mask: [T, J] bool, True where valid, or None (valid where finite).
        max_lag_frames: L, the largest lag, 1 <= L < T.
        drift_window_frames: moving-average window in frames, or None.

    Returns:
        [L + 1, C] float64 autocorrelation in -1..1 at lags 0..L frames; NaN where no joint counts.
    """
    pos, valid = _positions_and_mask(positions, mask)
    frames, joints, axes = pos.shape
    if not 1 <= max_lag_frames < frames:
        raise KinectDataError(f"max lag must be 1..{frames - 1} frames for {frames} frames, got {max_lag_frames}")
    used = _usable_joints(valid)
    if not used.any():
        raise KinectDataError(
            f"no joint is valid in at least {MIN_VALID_FRACTION:.0%} of the {frames} frames: nothing to autocorrelate"
        )
    x = _remove_drift(pos[:, used], valid[:, used], drift_window_frames).reshape(frames, -1)  # NaN where invalid
    size = np.nanmax(np.abs(np.where(valid[:, used, None], pos[:, used], np.nan)), axis=0).reshape(-1)
    still = STILL_FRACTION * np.where(np.isfinite(size) & (size > 0), size, 1.0)
    r = _lagged_pearson(x, max_lag_frames, still).reshape(max_lag_frames + 1, -1, axes)  # [L + 1, joints used, C]
    counted = np.isfinite(r).sum(axis=1)
    total = np.where(np.isfinite(r), r, 0.0).sum(axis=1)
    return np.where(counted > 0, total / np.maximum(counted, 1), np.nan)


def autocorrelation_peaks(
    autocorrelation: np.ndarray, fps: float, prominence: float = PEAK_PROMINENCE
) -> list[tuple[float, float]]:
    """Peaks of a 1-D autocorrelation curve, found by ``scipy.signal.find_peaks``.

    A peak must stand ``prominence`` above the higher of the lowest points separating it from
    higher peaks (scipy's definition); the default 0.1 is about 2.5 standard errors of the
    autocorrelation of white noise over 600 frames (20 s at 30 fps). Lag 0 and the last lag are never
    peaks. The curve is searched up to its first NaN. Each peak's lag and height are refined by the
    parabola through it and its two neighbours.

    Args:
        autocorrelation: [L + 1] values at lags 0..L frames.
        fps: frames per second of the motion.
        prominence: minimum prominence (unitless).

    Returns:
        ``[(lag_s, height), ...]`` in increasing lag.
    """
    from scipy.signal import find_peaks

    ac = np.asarray(autocorrelation, dtype=np.float64)
    if ac.ndim != 1:
        raise KinectDataError(f"autocorrelation must be 1-D [L + 1], got shape {ac.shape}")
    finite = np.isfinite(ac)
    ac = ac[: int(np.argmin(finite)) if not finite.all() else ac.size]
    indices, _ = find_peaks(ac, prominence=prominence)
    return [(lag / fps, height) for lag, height in (_parabolic_vertex(ac, i) for i in indices)]


def rhythm_report(
    positions: np.ndarray,
    mask: np.ndarray | None,
    fps: float,
    beat_period_s: float,
    source: str,
    axis_names: Sequence[str] | None = None,
    max_lag_s: float | None = None,
) -> dict:
    """Listen to Dance's evaluation: do the trajectories' autocorrelations peak at the beat period?

    Args:
        positions: [T, J, C] joint positions on a uniform grid of ``fps`` frames per second.
        mask: [T, J] bool, True where valid, or None.
        fps: frames per second.
        beat_period_s: the music's beat period in seconds.
        source: where the period comes from, e.g. "ground truth" or "beat tracker".
        axis_names: C names; default "x", "y", "z".
        max_lag_s: largest lag in seconds; default 3 beat periods, at most half the recording.

    Returns:
        JSON-ready dict (NaN as None): ``beat_period_s``, ``beat_period_source``, ``fps``,
        ``tolerance_s`` (max(10% of the period, 2 frames)), ``drift_window_s``, ``peak_prominence``,
        ``joints_used``, ``joints``, ``lags_s`` [L + 1], and ``axes``: per axis name its
        ``autocorrelation`` [L + 1], ``peaks`` [{lag_s, height}], ``nearest_peak`` (the peak nearest
        the period with ``error_s`` = lag - period and ``error_percent`` of the period, or None),
        ``peak_at_beat`` (|error| <= tolerance) and ``autocorrelation_at_beat`` (linearly
        interpolated at the period).
    """
    pos, valid = _positions_and_mask(positions, mask)
    frames, joints, axes = pos.shape
    if not fps > 0 or not beat_period_s > 0:
        raise KinectDataError(f"fps and beat period must be positive, got {fps} fps and {beat_period_s} s")
    names = list(axis_names) if axis_names is not None else ["x", "y", "z"][:axes]
    if len(names) != axes:
        raise KinectDataError(f"{len(names)} axis names {names} for positions with {axes} axes")
    tolerance_s = max(PERIOD_TOLERANCE * beat_period_s, PERIOD_TOLERANCE_FRAMES / fps)
    wanted_s = 3 * beat_period_s if max_lag_s is None else max_lag_s
    max_lag = min(int(np.ceil(wanted_s * fps)), frames // 2)
    if max_lag / fps < beat_period_s + tolerance_s:
        raise KinectDataError(
            f"{frames / fps:.2f} s of motion with a largest lag of {max_lag / fps:.2f} s cannot show a beat period of "
            f"{beat_period_s:.3f} s: the motion must last at least twice the period plus its tolerance"
        )
    ac = trajectory_autocorrelation(pos, valid, max_lag, max(1, round(DRIFT_WINDOW_S * fps)))
    lags_s = np.arange(max_lag + 1) / fps
    report_axes = {}
    for c, name in enumerate(names):
        peaks = autocorrelation_peaks(ac[:, c], fps)
        nearest = min(peaks, key=lambda p: abs(p[0] - beat_period_s)) if peaks else None
        report_axes[name] = {
            "autocorrelation": _json_floats(ac[:, c]),
            "peaks": [{"lag_s": lag, "height": height} for lag, height in peaks],
            "nearest_peak": None
            if nearest is None
            else {
                "lag_s": nearest[0],
                "height": nearest[1],
                "error_s": nearest[0] - beat_period_s,
                "error_percent": 100.0 * (nearest[0] - beat_period_s) / beat_period_s,
            },
            "peak_at_beat": nearest is not None and abs(nearest[0] - beat_period_s) <= tolerance_s,
            "autocorrelation_at_beat": _json_float(np.interp(beat_period_s, lags_s, ac[:, c])),  # NaN next to it: None
        }
    return {
        "beat_period_s": float(beat_period_s),
        "beat_period_source": source,
        "fps": float(fps),
        "tolerance_s": tolerance_s,
        "drift_window_s": DRIFT_WINDOW_S,
        "peak_prominence": PEAK_PROMINENCE,
        "joints_used": int(_usable_joints(valid).sum()),
        "joints": joints,
        "lags_s": lags_s.tolist(),
        "axes": report_axes,
    }


def motion_beats(
    positions: np.ndarray, mask: np.ndarray | None, fps: float, sigma_frames: float | None = None
) -> np.ndarray:
    """Motion beats: the local minima of the mean joint speed after Gaussian smoothing (as Bailando).

    Each joint's speed at frame t is the norm of its central-difference velocity
    (p[t + 1] - p[t - 1]) * fps / 2 (one-sided at the ends), so it is not shifted by half a frame as
    the forward differences of Bailando's code are; a joint counts at frame t when both frames it
    uses are valid. The speeds are averaged over the counted joints; frames where none counts are
    filled by linear interpolation. The result is smoothed by ``scipy.ndimage.gaussian_filter1d``
    (``mode="nearest"``) with ``sigma_frames``, and its strict local minima
    (``scipy.signal.argrelmin``, as Bailando's ``argrelextrema(np.less)``: a flat plateau is
    no minimum) are the beats, refined to sub-frame by a parabola through the three samples; minima
    on filled frames are dropped.

    Args:
        positions: [T, J, C] joint positions on a uniform grid of ``fps`` frames per second.
        mask: [T, J] bool, True where valid, or None.
        fps: frames per second.
        sigma_frames: smoothing sigma in frames (0: none); default :data:`MOTION_BEAT_SMOOTHING_S`
            (5 frames at 60 fps) at this ``fps``.

    Returns:
        [K] increasing beat times in seconds, frame 0 at 0 s.
    """
    from scipy.ndimage import gaussian_filter1d
    from scipy.signal import argrelmin

    pos, valid = _positions_and_mask(positions, mask)
    if not fps > 0:
        raise KinectDataError(f"fps must be positive, got {fps}")
    sigma = MOTION_BEAT_SMOOTHING_S * fps if sigma_frames is None else sigma_frames
    if sigma < 0:
        raise KinectDataError(f"smoothing sigma must be >= 0 frames, got {sigma}")
    if pos.shape[0] < 3:
        raise KinectDataError(f"motion beats need at least 3 frames, got {pos.shape[0]}")
    speed = np.linalg.norm(np.gradient(np.where(valid[..., None], pos, np.nan), axis=0), axis=2) * fps  # [T, J]
    counted = np.isfinite(speed)
    have = counted.any(axis=1)
    if have.sum() < 2:
        raise KinectDataError("motion beats need a joint valid in at least 2 pairs of neighbouring frames")
    mean_speed = np.where(counted, speed, 0.0).sum(axis=1) / np.maximum(counted.sum(axis=1), 1)
    frames = np.arange(pos.shape[0])
    mean_speed = np.interp(frames, frames[have], mean_speed[have])
    smooth = gaussian_filter1d(mean_speed, sigma, mode="nearest") if sigma > 0 else mean_speed
    minima = argrelmin(smooth)[0]
    minima = minima[have[minima]]
    return np.array([_parabolic_vertex(smooth, i)[0] for i in minima], dtype=np.float64) / fps


def beat_align_score(
    music_beats_s: Sequence[float],
    motion_beats_s: Sequence[float],
    sigma_s: float = BEAT_ALIGN_SIGMA_S,
    direction: str = "music_to_motion",
) -> float:
    """Beat Align Score: mean of exp(-d^2 / (2 sigma^2)) over one set of beats, in 0..1.

    ``direction="music_to_motion"`` (Bailando's code, ``utils/beat_align_score.py``, and the tables
    of Bailando, EDGE and FineDance): averaged over the music beats, d the distance to the nearest
    motion beat. ``"motion_to_music"`` (the AI Choreographer / AIST++ paper's definition): averaged
    over the motion beats, d the distance to the nearest music beat. The default sigma is 0.05 s
    (3 frames at 60 fps).

    Args:
        music_beats_s: [B] music beat times in seconds.
        motion_beats_s: [K] motion beat times in seconds, same clock.
        sigma_s: Gaussian width in seconds.
        direction: one of :data:`BAS_DIRECTIONS`.

    Returns:
        The score; 0 if the other set is empty. An empty set to average over is an error.
    """
    music = _beat_array(music_beats_s, "music beats")
    motion = _beat_array(motion_beats_s, "motion beats")
    if direction not in BAS_DIRECTIONS:
        raise KinectDataError(f"Beat Align Score direction must be one of {BAS_DIRECTIONS}, got {direction!r}")
    if not sigma_s > 0:
        raise KinectDataError(f"Beat Align Score sigma must be positive, got {sigma_s} s")
    averaged, other = (music, motion) if direction == "music_to_motion" else (motion, music)
    if averaged.size == 0:
        over = "music" if direction == "music_to_motion" else "motion"
        raise KinectDataError(f"Beat Align Score {direction} averages over the {over} beats, and there are none")
    if other.size == 0:
        return 0.0
    distance = np.min(np.abs(averaged[:, None] - other[None, :]), axis=1)
    return float(np.mean(np.exp(-(distance**2) / (2 * sigma_s**2))))


def motion_beat_fmeasure(music_beats_s: Sequence[float], motion_beats_s: Sequence[float], window_s: float) -> float:
    """F-measure of motion beats against music beats, ``mir_eval.beat.f_measure``.

    Reference = music beats, estimate = motion beats. A motion beat is correct when within
    +-``window_s`` (inclusive) of a music beat, each beat matched at most once (maximum bipartite
    matching); F = 2PR / (P + R), 0 when either set is empty. Beats are used as given: mir_eval's
    usual ``trim_beats`` (dropping the first 5 s, where beat trackers settle) is not applied, so
    trim beforehand if the music beats come from a tracker and the first seconds should not count.

    Args:
        music_beats_s: [B] increasing music beat times in seconds.
        motion_beats_s: [K] increasing motion beat times in seconds.
        window_s: tolerance in seconds (mir_eval's default is 0.07).

    Returns:
        F-measure in 0..1.
    """
    import mir_eval

    music = _beat_array(music_beats_s, "music beats", increasing=True)
    motion = _beat_array(motion_beats_s, "motion beats", increasing=True)
    if not window_s > 0:
        raise KinectDataError(f"F-measure window must be positive, got {window_s} s")
    if music.size == 0 or motion.size == 0:
        return 0.0  # mir_eval's value too, without its warning
    return float(mir_eval.beat.f_measure(music, motion, f_measure_threshold=window_s))


def beat_alignment_report(
    music_beats_s: Sequence[float],
    motion_beats_s: Sequence[float],
    fps: float,
    sigma_s: float = BEAT_ALIGN_SIGMA_S,
    direction: str = "music_to_motion",
    window_s: float = FMEASURE_WINDOW_S,
) -> dict:
    """Beat Align Score and F-measure with every choice stated (JSON-ready).

    Args:
        music_beats_s: [B] music beat times in seconds (restricted beforehand to the motion's span).
        motion_beats_s: [K] motion beat times in seconds, same clock.
        fps: the motion's frames per second, to state sigma and the window in frames.
        sigma_s: Beat Align Score sigma in seconds (default 3 frames at 60 fps).
        direction: one of :data:`BAS_DIRECTIONS`, see :func:`beat_align_score`.
        window_s: F-measure tolerance in seconds.

    Returns:
        ``beat_align_score``, ``direction``, ``sigma_s``, ``sigma_frames``, ``f_measure``,
        ``precision``, ``recall``, ``window_s``, ``window_frames``, ``music_beats``, ``motion_beats``.
    """
    import mir_eval

    if not fps > 0:
        raise KinectDataError(f"fps must be positive, got {fps}")
    score = beat_align_score(music_beats_s, motion_beats_s, sigma_s, direction)
    f = motion_beat_fmeasure(music_beats_s, motion_beats_s, window_s)
    music, motion = np.asarray(music_beats_s, np.float64), np.asarray(motion_beats_s, np.float64)
    matched = len(mir_eval.util.match_events(music, motion, window_s)) if music.size and motion.size else 0
    return {
        "beat_align_score": score,
        "direction": direction,
        "sigma_s": float(sigma_s),
        "sigma_frames": float(sigma_s * fps),
        "f_measure": f,
        "precision": matched / motion.size if motion.size else 0.0,
        "recall": matched / music.size if music.size else 0.0,
        "window_s": window_s,
        "window_frames": float(window_s * fps),
        "music_beats": int(music.size),
        "motion_beats": int(motion.size),
    }


def _positions_and_mask(positions: np.ndarray, mask: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """[T, J, C] float64 positions and [T, J] validity (the mask and finite values)."""
    pos = np.asarray(positions, dtype=np.float64)
    if pos.ndim != 3:
        raise KinectDataError(f"positions must be [T, J, C], got shape {pos.shape}")
    valid = np.isfinite(pos).all(axis=2)
    if mask is not None:
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != pos.shape[:2]:
            raise KinectDataError(f"mask shape {mask.shape} does not match positions [T, J] = {pos.shape[:2]}")
        valid &= mask
    return pos, valid


def _usable_joints(valid: np.ndarray) -> np.ndarray:
    """[J] bool: joints valid in at least MIN_VALID_FRACTION of the frames."""
    return valid.mean(axis=0) >= MIN_VALID_FRACTION


def _remove_drift(x: np.ndarray, valid: np.ndarray, window: int | None) -> np.ndarray:
    """[T, J, C] ``x`` minus its centred moving average over the valid frames; NaN where invalid."""
    from scipy.ndimage import uniform_filter1d

    weights = np.broadcast_to(valid[..., None], x.shape).astype(np.float64)
    values = np.where(weights > 0, x, 0.0)
    if window is None:
        return np.where(weights > 0, values, np.nan)
    size = 2 * (int(window) // 2) + 1
    total = uniform_filter1d(values, size, axis=0, mode="constant")
    count = uniform_filter1d(weights, size, axis=0, mode="constant")
    drift = total / np.where(weights > 0, count, 1.0)  # count > 0 wherever the frame itself is valid
    return np.where(weights > 0, values - drift, np.nan)


def _lagged_pearson(x: np.ndarray, max_lag: int, still: np.ndarray) -> np.ndarray:
    """[L + 1, N] Pearson correlation of the pairs (x[t], x[t + k]) of each column of [T, N] ``x``
    at lags k = 0..L, over the pairs where both are finite, as ``numpy.corrcoef`` of those pairs
    gives it lag by lag.

    Every sum the correlations need (pairs, each side's sum and sum of squares, the products) is a
    cross-correlation of ``x`` (0 where not finite) and its validity, for all lags at once by FFT.
    NaN where fewer than MIN_PAIRS pairs, or where a side does not move: its standard deviation
    below the column's ``still`` [N] (round-off of a constant), or its variance below 1e-9 of its
    sum of squares (what FFT round-off leaves of a zero variance).
    """
    valid = np.isfinite(x)
    weight = valid.astype(np.float64)
    value = np.where(valid, x, 0.0)
    size = next_fast_len(2 * len(x))
    spectra = [np.fft.rfft(a, size, axis=0) for a in (weight, value, value * value)]

    def lagged(first: int, second: int) -> np.ndarray:  # sum over t of a[t] b[t + k], k = 0..L
        return np.fft.irfft(np.conj(spectra[first]) * spectra[second], size, axis=0)[: max_lag + 1]

    pairs = np.rint(lagged(0, 0))
    sum_a, sum_b = lagged(1, 0), lagged(0, 1)
    squares_a, squares_b = lagged(2, 0), lagged(0, 2)
    products = lagged(1, 1)
    safe = np.maximum(pairs, 1)
    var_a = squares_a - sum_a * sum_a / safe
    var_b = squares_b - sum_b * sum_b / safe
    covariance = products - sum_a * sum_b / safe
    least = np.maximum(safe * still**2, 0.0)
    spread = (var_a > np.maximum(1e-9 * np.abs(squares_a), least)) & (
        var_b > np.maximum(1e-9 * np.abs(squares_b), least)
    )
    ok = (pairs >= MIN_PAIRS) & spread
    correlation = covariance / np.sqrt(np.where(ok, var_a * var_b, 1.0))
    return np.where(ok, np.clip(correlation, -1.0, 1.0), np.nan)


def _parabolic_vertex(y: np.ndarray, i: int) -> tuple[float, float]:
    """(position, value) of the vertex of the parabola through y[i - 1], y[i], y[i + 1]."""
    left, centre, right = y[i - 1], y[i], y[i + 1]
    curvature = left - 2 * centre + right
    if curvature == 0:
        return float(i), float(centre)
    offset = 0.5 * (left - right) / curvature
    return float(i + offset), float(centre - 0.25 * (left - right) * offset)


def _beat_array(beats: Sequence[float], what: str, increasing: bool = False) -> np.ndarray:
    """[B] float64 finite beat times; ``increasing``: also non-decreasing (mir_eval's requirement)."""
    a = np.asarray(beats, dtype=np.float64)
    if a.ndim != 1:
        raise KinectDataError(f"{what} must be a 1-D list of times in seconds, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise KinectDataError(f"{what}: beat {int(np.argmin(np.isfinite(a)))} is not a finite time")
    if increasing and np.any(np.diff(a) < 0):
        i = int(np.argmax(np.diff(a) < 0)) + 1
        raise KinectDataError(f"{what} must be in increasing order: beat {i} at {a[i]} s comes after {a[i - 1]} s")
    return a


def _json_float(value: float | None) -> float | None:
    return None if value is None or not np.isfinite(value) else float(value)


def _json_floats(values: np.ndarray) -> list[float | None]:
    return [_json_float(v) for v in values]
