"""Resampling a recording onto an exact time grid, with tracking gaps found, filled or masked.

For every joint, each grid time is computed from the two *valid* source samples around it:
positions linearly, orientations by spherical linear interpolation (:func:`~kinectdata.core.quaternions.slerp`,
checked against scipy's ``Slerp``) after the joint's quaternions have been made sign-continuous
(q . q_prev >= 0), confidence linearly.

A *gap* is a stretch where a joint has no valid sample: two consecutive valid samples further
apart than 1.5 nominal frame intervals (the joint was untracked, or whole frames were dropped).
Its length is the duration of the frames missing in it, ``(round((t_after - t_before) / dt) - 1)
* dt`` with ``dt`` the nominal interval (:func:`kinectdata.core.motion.frame_clock`, the same
interval ``info`` and ``align`` report), so that timestamp jitter cannot change it.
Grid times inside a gap no longer than ``max_gap`` seconds are interpolated and flagged, and
their confidence is at most 0.5 (what Kinect reports for joints it infers); inside a longer gap
they are masked. Grid times before a joint's first or after its last valid sample are masked
(nothing is extrapolated): those are *edge* gaps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinectdata.core.errors import ConfigError
from kinectdata.core.motion import Motion, frame_clock
from kinectdata.core.quaternions import make_continuous, slerp

GAP_FACTOR = 1.5
"""Consecutive valid samples further apart than this many nominal intervals bound a gap."""
GAP_TOLERANCE = 1e-4
"""Relative slack when a gap's length is compared with ``max_gap``: the nominal interval is fitted
to the timestamps, so six frames of a 30 fps recording may last 0.2000002 s; that is still 0.2 s."""
INFERRED_CONFIDENCE = 0.5
"""Highest confidence of a value filled across a gap (Kinect's level for inferred joints)."""


@dataclass(frozen=True)
class Gap:
    """A stretch where one joint's position or orientation has no valid sample.

    ``start`` / ``end`` are the source times (seconds) of the valid samples around it (for an
    edge gap, at the start or end of the recording: the recording's first / last frame time);
    ``length`` is the duration of the missing frames in seconds; ``filled`` tells whether it was
    interpolated (never, for an edge gap).
    """

    joint: str
    quantity: str  # "position" or "orientation"
    start: float
    end: float
    length: float
    filled: bool
    edge: bool = False


@dataclass(eq=False)
class Resampled:
    """A recording on a grid. ``*_interpolated`` [N, J] flag values filled across gaps."""

    motion: Motion
    position_interpolated: np.ndarray
    orientation_interpolated: np.ndarray | None
    gaps: list[Gap]


def nominal_interval(times: np.ndarray) -> float:
    """The recording's frame interval in seconds: 1 / its frame rate, fitted to the [T]
    timestamps (seconds) by :func:`kinectdata.core.motion.frame_clock`."""
    if times.size < 2:
        raise ConfigError("a recording needs at least two frames to be resampled")
    return frame_clock(times)[0]


def longer_than(length: np.ndarray | float, max_gap: float) -> np.ndarray | bool:
    """Whether gaps of ``length`` seconds exceed ``max_gap`` seconds (within :data:`GAP_TOLERANCE`)."""
    return np.asarray(length) > max_gap * (1 + GAP_TOLERANCE) + 1e-9


def _missing_duration(span: np.ndarray | float, dt: float) -> np.ndarray | float:
    """Seconds of frames missing between two valid samples ``span`` seconds apart."""
    return (np.round(np.asarray(span) / dt) - 1) * dt


def _brackets(tv: np.ndarray, grid: np.ndarray, dt: float, max_gap: float):
    """For each grid time: left/right valid-sample indices, weight, validity and gap flag."""
    n = tv.size
    k = np.searchsorted(tv, grid, side="right") - 1
    at_end = (k == n - 1) & (grid == tv[-1])
    inside = ((k >= 0) & (k < n - 1)) | at_end
    a = np.clip(k, 0, n - 1)
    b = np.where(at_end, a, np.clip(k + 1, 0, n - 1))
    span = tv[b] - tv[a]
    with np.errstate(invalid="ignore", divide="ignore"):
        w = np.where(span > 0, (grid - tv[a]) / np.where(span > 0, span, 1.0), 0.0)
    in_gap = inside & (span > GAP_FACTOR * dt) & (w > 0)
    too_long = in_gap & longer_than(_missing_duration(span, dt), max_gap)
    return a, b, w, inside & ~too_long, in_gap & ~too_long


def _gaps(name: str, quantity: str, tv: np.ndarray, t0: float, t1: float, dt: float, max_gap: float) -> list[Gap]:
    if tv.size == 0:
        return [Gap(name, quantity, t0, t1, t1 - t0 + dt, False, edge=True)]
    out = []
    if tv[0] - t0 > GAP_FACTOR * dt / 2:
        out.append(
            Gap(name, quantity, t0, float(tv[0]), float(_missing_duration(tv[0] - t0 + dt, dt)), False, edge=True)
        )
    spans = np.diff(tv)
    for i in np.flatnonzero(spans > GAP_FACTOR * dt):
        length = float(_missing_duration(spans[i], dt))
        out.append(Gap(name, quantity, float(tv[i]), float(tv[i + 1]), length, not bool(longer_than(length, max_gap))))
    if t1 - tv[-1] > GAP_FACTOR * dt / 2:
        out.append(
            Gap(name, quantity, float(tv[-1]), t1, float(_missing_duration(t1 - tv[-1] + dt, dt)), False, edge=True)
        )
    return out


def resample_motion(motion: Motion, grid: np.ndarray, max_gap: float = 0.2) -> Resampled:
    """Resample a recording at the given times.

    Args:
        motion: the source recording.
        grid: [N] increasing times in seconds, on the recording's own clock.
        max_gap: longest gap (seconds without data) that is filled by interpolation.

    Returns:
        A :class:`Resampled` whose motion has ``times == grid``.
    """
    grid = np.asarray(grid, dtype=np.float64)
    times = motion.times
    dt = nominal_interval(times)
    t0, t1 = float(times[0]), float(times[-1])
    N, J, D = grid.size, motion.n_joints, motion.joint_set.dimensions
    names = motion.joint_set.names
    pos = np.full((N, J, D), np.nan)
    pmask = np.zeros((N, J), bool)
    pint = np.zeros((N, J), bool)
    conf = np.zeros((N, J), np.float32)
    gaps: list[Gap] = []
    for j in range(J):
        idx = np.flatnonzero(motion.position_mask[:, j])
        gaps += _gaps(names[j], "position", times[idx], t0, t1, dt, max_gap)
        if idx.size == 0:
            continue
        a, b, w, ok, filled = _brackets(times[idx], grid, dt, max_gap)
        va, vb = motion.positions[idx[a], j], motion.positions[idx[b], j]
        pos[ok, j] = (va + w[:, None] * (vb - va))[ok]
        ca, cb = motion.confidence[idx[a], j], motion.confidence[idx[b], j]
        c = ca + w * (cb - ca)
        conf[ok, j] = np.where(filled, np.minimum(c, INFERRED_CONFIDENCE), c)[ok]
        pmask[:, j], pint[:, j] = ok, filled

    quats = qmask = qint = None
    if motion.has_orientations:
        quats = np.full((N, J, 4), np.nan)
        qmask = np.zeros((N, J), bool)
        qint = np.zeros((N, J), bool)
        for j in range(J):
            if not motion.joint_set.has_orientation[j]:
                continue
            idx = np.flatnonzero(motion.orientation_mask[:, j])
            gaps += _gaps(names[j], "orientation", times[idx], t0, t1, dt, max_gap)
            if idx.size == 0:
                continue
            a, b, w, ok, filled = _brackets(times[idx], grid, dt, max_gap)
            q = make_continuous(motion.orientations[idx, j])  # one joint at a time: memory of [T, 4], not [T, J, 4]
            out = slerp(q[a], q[b], w)
            quats[ok, j] = out[ok]
            qmask[:, j], qint[:, j] = ok, filled

    resampled = Motion(
        times=grid,
        positions=pos,
        joint_set=motion.joint_set,
        position_mask=pmask,
        confidence=conf,
        orientations=quats,
        orientation_mask=qmask,
        metadata=dict(motion.metadata),
    )
    return Resampled(resampled, pint, qint, gaps)
