"""The motion container: one recording of one body, whatever format it came from.

Conventions, used everywhere in kinectdata:

- ``times`` [T] float64, seconds, strictly increasing. Readers make the first frame 0.0 and keep
  the file's own first timestamp in ``metadata["time_origin"]`` as ``{"value", "unit"}`` (None
  for formats without timestamps, such as NTU).
- ``positions`` [T, J, D] float64: metres for 3-D joint sets (D = 3), pixels for 2-D ones
  (D = 2). Sensor formats give Kinect v2 camera space: x to the sensor's left (the right of a
  person facing it), y up, z away from the sensor; HTR gives its own world frame
  (``metadata["gravity_axis"]`` says which axis is up).
- ``orientations`` [T, J, 4] float64 unit quaternions in scipy's scalar-last order (x, y, z, w),
  or None when the format has none.
- ``confidence`` [T, J] float32 in 0..1 (Kinect: tracked 1.0, inferred 0.5, not tracked 0.0);
  always 0 where the position is masked.
- ``position_mask`` / ``orientation_mask`` [T, J] bool: True where the value is valid. Invalid
  values are NaN, so that using one by mistake cannot go unnoticed.

Arrays given in their convention's dtype are kept as they are, not copied (a recording of an hour
holds hundreds of megabytes): the motion is a view of them, so change them only through a copy.
They are copied when making the invalid values NaN would write into them.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from kinectdata.core.errors import ConfigError
from kinectdata.core.jointsets import JointSet


def _nan_where_invalid(values: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``values`` [T, J, K] with NaN wherever ``mask`` [T, J] is False: the same array when it is so
    already, else a copy (the caller's array is never written)."""
    invalid = ~mask
    if not invalid.any() or np.isnan(values[invalid]).all():
        return values
    values = values.copy()
    values[invalid] = np.nan
    return values


@dataclass(eq=False)
class Motion:
    """A recording of one body: times, positions, orientations, confidence, masks, joint set."""

    times: np.ndarray
    positions: np.ndarray
    joint_set: JointSet
    position_mask: np.ndarray | None = None
    confidence: np.ndarray | None = None
    orientations: np.ndarray | None = None
    orientation_mask: np.ndarray | None = None
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.times = np.asarray(self.times, dtype=np.float64)
        self.positions = np.asarray(self.positions, dtype=np.float64)
        T, J = self.times.shape[0], len(self.joint_set)
        D = self.joint_set.dimensions
        if self.times.ndim != 1:
            raise ConfigError(f"times must be [T], got shape {self.times.shape}")
        if self.positions.shape != (T, J, D):
            raise ConfigError(f"positions must be [T={T}, J={J}, {D}], got {self.positions.shape}")
        if T > 1 and not np.all(np.diff(self.times) > 0):
            raise ConfigError("times must be strictly increasing")
        if self.position_mask is None:
            self.position_mask = np.isfinite(self.positions).all(axis=-1)
        self.position_mask = np.array(self.position_mask, dtype=bool)
        if self.position_mask.shape != (T, J):
            raise ConfigError(f"position_mask must be [T, J] = {(T, J)}, got {self.position_mask.shape}")
        self.positions = _nan_where_invalid(self.positions, self.position_mask)
        if self.confidence is None:
            self.confidence = self.position_mask.astype(np.float32)
        self.confidence = np.asarray(self.confidence, dtype=np.float32)
        if self.confidence.shape != (T, J):
            raise ConfigError(f"confidence must be [T, J] = {(T, J)}, got {self.confidence.shape}")
        self.confidence = np.where(self.position_mask, self.confidence, np.float32(0.0))
        if self.orientations is not None:
            self.orientations = np.asarray(self.orientations, dtype=np.float64)
            if self.orientations.shape != (T, J, 4):
                raise ConfigError(f"orientations must be [T, J, 4], got {self.orientations.shape}")
            if self.orientation_mask is None:
                self.orientation_mask = np.isfinite(self.orientations).all(axis=-1)
            self.orientation_mask = np.array(self.orientation_mask, dtype=bool)
            if self.orientation_mask.shape != (T, J):
                raise ConfigError(f"orientation_mask must be [T, J], got {self.orientation_mask.shape}")
            self.orientation_mask &= self.joint_set.orientation_mask[None, :]
            self.orientations = _nan_where_invalid(self.orientations, self.orientation_mask)
        elif self.orientation_mask is not None:
            raise ConfigError("orientation_mask given without orientations")

    # -- shape ---------------------------------------------------------------------------------
    @property
    def n_frames(self) -> int:
        return int(self.times.shape[0])

    @property
    def n_joints(self) -> int:
        return len(self.joint_set)

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame."""
        return float(self.times[-1] - self.times[0]) if self.n_frames else 0.0

    @property
    def has_orientations(self) -> bool:
        return self.orientations is not None

    # -- access --------------------------------------------------------------------------------
    def joint_positions(self, name: str) -> np.ndarray:
        """[T, D] positions of one joint (NaN where invalid)."""
        return self.positions[:, self.joint_set.index(name)]

    def select(self, frames: slice | np.ndarray) -> Motion:
        """A new Motion holding only the given frames (a slice, indices or a [T] bool mask)."""

        def take(a):
            return None if a is None else a[frames]

        return replace(
            self,
            times=self.times[frames],
            positions=self.positions[frames],
            position_mask=self.position_mask[frames],
            confidence=self.confidence[frames],
            orientations=take(self.orientations),
            orientation_mask=take(self.orientation_mask),
            metadata=dict(self.metadata),
        )

    def timing(self) -> dict[str, float | int]:
        """Frame timing of the recording (:func:`frame_clock` fits it).

        Returns ``fps`` (frames per second: the slope of a least-squares line through the
        timestamps against frame numbers, dropped frames counted, so a recorder whose intervals
        alternate 33.0 and 34.1 ms is at the rate of their mean, not of their median),
        ``interval_ms`` (1000 / fps), ``jitter_ms`` (standard deviation of the intervals that are
        not drops), ``dropped_frames`` (frames missing where an interval spans more than one
        fitted interval, counted as round(dt / interval) - 1) and ``frozen_frames`` (frames whose
        positions repeat the previous frame's exactly, valid joints only: a tracker that stalled
        and wrote its last pose again; :meth:`frozen_runs` gives where). fps, interval and jitter
        are NaN for fewer than two frames.
        """
        if self.n_frames < 2:
            return {
                "fps": float("nan"),
                "interval_ms": float("nan"),
                "jitter_ms": float("nan"),
                "dropped_frames": 0,
                "frozen_frames": self.frozen_frames(),
            }
        interval, number = frame_clock(self.times)
        steps = np.diff(number)
        regular = np.diff(self.times)[steps == 1]
        return {
            "fps": 1.0 / interval,
            "interval_ms": interval * 1e3,
            "jitter_ms": float(np.std(regular) * 1e3) if regular.size else 0.0,
            "dropped_frames": int(np.sum(steps - 1)),
            "frozen_frames": self.frozen_frames(),
        }

    def frozen_runs(self) -> list[tuple[int, int]]:
        """Runs of frozen frames as (first frozen frame index, frames in the run), in order.

        A frame is frozen when, with at least one joint valid in it and in the frame before, every
        joint valid in both has exactly the previous frame's position (joints valid in only one of
        the two are not compared): a stalled tracker writing its last pose again.
        """
        if self.n_frames < 2:
            return []
        same = (self.positions[1:] == self.positions[:-1]).all(axis=-1)
        both = self.position_mask[1:] & self.position_mask[:-1]
        frozen = np.concatenate([[False], both.any(axis=1) & (same | ~both).all(axis=1), [False]])
        edges = np.flatnonzero(np.diff(frozen.astype(np.int8)))
        return [(int(a) + 1, int(b - a)) for a, b in zip(edges[::2], edges[1::2])]  # edge i: frame i + 1

    def frozen_frames(self) -> int:
        """Frames (after the first) that repeat the previous frame: the total of :meth:`frozen_runs`."""
        return sum(n for _, n in self.frozen_runs())

    def __repr__(self) -> str:
        return (
            f"Motion({self.n_frames} frames, {self.duration:.2f} s, joint_set={self.joint_set.name!r}, "
            f"orientations={'yes' if self.has_orientations else 'no'})"
        )


def true_runs(flags: np.ndarray) -> tuple[tuple[int, int], ...]:
    """The runs of True in ``flags`` [T] as ``(first, last)`` indices, inclusive, in order."""
    edges = np.diff(np.concatenate([[0], np.asarray(flags, bool).astype(np.int8), [0]]))
    return tuple((int(a), int(b) - 1) for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def sides_exchanged(motion: Motion, frames: np.ndarray) -> Motion:
    """The motion with each joint's positions, masks, confidences and orientations exchanged with
    its mirror image's (:meth:`JointSet.mirror_image`: left and right) in ``frames`` [T] bool: what a
    tracker that mirrored a body writes, and the repair of it (exchanging twice is the identity)."""
    image = motion.joint_set.mirror_image()
    exchanged = {}
    for name in ("positions", "position_mask", "confidence", "orientations", "orientation_mask"):
        values = getattr(motion, name)
        if values is not None:
            values = np.array(values, copy=True)
            values[frames] = values[frames][:, image]
            exchanged[name] = values
    return replace(motion, **exchanged)


def held_from_nearest(values: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``values`` [T, J, ...] with each masked entry taken from the nearest valid frame before it
    (after it, before a joint's first valid frame); a joint never valid is left as it is.

    Args:
        values: [T, J, ...] per-frame, per-joint values (positions [T, J, 3], ...).
        mask: [T, J] True where valid.
    """
    T = values.shape[0]
    frames = np.arange(T)[:, None]
    last = np.maximum.accumulate(np.where(mask, frames, -1), axis=0)
    source = np.where(last >= 0, last, np.argmax(mask, axis=0)[None, :])
    source = np.where(mask.any(axis=0)[None, :], source, frames)
    return np.take_along_axis(values, source.reshape(source.shape + (1,) * (values.ndim - 2)), axis=0)


def frame_clock(times: np.ndarray) -> tuple[float, np.ndarray]:
    """The frame interval of timestamps, and the frame number of each timestamp.

    The one place kinectdata derives a recording's frame rate from its timestamps. Each interval
    between consecutive timestamps is counted as ``max(1, round(dt / interval))`` frames (more than
    one where frames were dropped), and the interval is the slope of a least-squares line through
    the timestamps against those frame numbers. The first count uses the median interval; the
    counts are then taken again with the fitted interval until they no longer change (at most three
    rounds), so a recorder whose median is off its mean (33.0, 33.0, 34.0 ms in turn: median 33.0,
    mean 33.33) still counts a long pause as the frames it lasted. A late frame beside an early one
    is jitter, not a drop: a recorder that stamps frames when they arrive (Lab Streaming Layer) has
    a frame 52 ms after the one before and the next 15 ms after it, two intervals for two frames;
    where an interval counted as more than one frame and a neighbour counted as one make fewer
    intervals together than their counts say, the long one gives up the difference
    (:func:`_late_frames_are_not_drops`).

    Args:
        times: [T] strictly increasing timestamps in seconds, T >= 2.

    Returns:
        (interval in seconds, [T] float64 frame numbers starting at 0).

    Raises:
        ConfigError: fewer than two timestamps.
    """
    times = np.asarray(times, dtype=np.float64)
    if times.size < 2:
        raise ConfigError(f"a frame rate needs at least two timestamps, got {times.size}")
    dt = np.diff(times)
    interval = float(np.median(dt))
    steps = number = None
    for _ in range(3):
        new = _late_frames_are_not_drops(dt, interval, np.maximum(1.0, np.round(dt / interval)))
        if steps is not None and np.array_equal(new, steps):
            break
        steps = new
        number = np.concatenate([[0.0], np.cumsum(steps)])
        interval = float(np.polyfit(number, times - times[0], 1)[0])  # shifted: slope unchanged, precision kept
    return interval, number


def _late_frames_are_not_drops(dt: np.ndarray, interval: float, steps: np.ndarray) -> np.ndarray:
    """``steps`` [T - 1] (frames each interval ``dt`` spans) with each interval counted as more than
    one frame reduced where it and a neighbour counted as one span fewer intervals together
    (``round((dt_i + dt_j) / interval)``) than their counts: a late frame followed (or preceded) by
    an early one. Each neighbour makes up for one long interval at most."""
    steps = steps.copy()
    used = np.zeros(steps.size, bool)
    for i in np.flatnonzero(steps > 1):
        for j in (i + 1, i - 1):
            if 0 <= j < steps.size and steps[j] == 1 and not used[j]:
                together = max(2.0, float(np.round((dt[i] + dt[j]) / interval)))
                if together < steps[i] + 1:
                    steps[i], used[j] = together - 1, True
                    break
    return steps
