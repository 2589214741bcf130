"""Kinect v2 sensor defects: frame timing, noise and tracking states, applied to a true motion.

Two steps, so that the true motion can be evaluated exactly at the frames the sensor keeps:

1. :func:`sensor_frame_times` gives the frame timestamps of a recording: a nominal 30 fps grid
   with independent Gaussian jitter per frame (not cumulative) and a few dropped frames. The
   first frame is never dropped and has no jitter, so the recording's clock starts at 0.0.
   A frame's timestamp is the instant its pose was captured (the true pose at that time).
2. :func:`apply_sensor_defects` adds position and orientation noise and tracking-state spans:
   short spans where one hand (wrist, hand, hand tip, thumb) is inferred (noisier, with a
   drifting bias) or not tracked, and one longer loss of one foot (ankle and foot not tracked).
   Not-tracked joints hold the last value the sensor wrote, as a Kinect writes them; the
   returned Motion marks them invalid (NaN), the raw arrays keep what a file would contain.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from kinectdata.core.motion import Motion

TRACKED, INFERRED, NOT_TRACKED = 2, 1, 0
CONFIDENCE = {TRACKED: 1.0, INFERRED: 0.5, NOT_TRACKED: 0.0}

HAND_GROUPS = {
    "left": ("WristLeft", "HandLeft", "HandTipLeft", "ThumbLeft"),
    "right": ("WristRight", "HandRight", "HandTipRight", "ThumbRight"),
}
FOOT_GROUPS = {"left": ("AnkleLeft", "FootLeft"), "right": ("AnkleRight", "FootRight")}


@dataclass(frozen=True)
class SensorModel:
    """Defect levels (SI units). The defaults resemble a Kinect v2 in a well-lit room."""

    fps: float = 30.0
    jitter_sd_s: float = 0.002
    drop_rate: float = 0.005
    position_sd_m: float = 0.003
    orientation_sd_rad: float = float(np.radians(1.0))
    inferred_position_sd_m: float = 0.010
    inferred_bias_m: tuple[float, float] = (0.015, 0.04)
    inferred_orientation_sd_rad: float = float(np.radians(4.0))
    hand_events_per_s: float = 1 / 7
    hand_span_s: tuple[float, float] = (0.1, 0.3)
    hand_inferred_probability: float = 0.6
    foot_span_s: tuple[float, float] = (0.7, 1.2)


@dataclass
class SensorOutput:
    """What the sensor recorded.

    Attributes:
        motion: the recorded Motion (recording clock): noisy positions and orientations,
            confidence 1.0 / 0.5 / 0.0 for tracked / inferred / not tracked, not-tracked joints
            masked (NaN).
        states: [T, J] int8 Kinect tracking states (2 tracked, 1 inferred, 0 not tracked).
        raw_positions: [T, J, 3] positions as the sensor writes them (not-tracked joints hold
            their last written value; zeros if never tracked), no NaN.
        raw_orientations: [T, J, 4] (x, y, z, w) likewise; NaN for leaf joints, which carry none.
        spans: tracking-state spans, one dict per joint and span: ``joint``, ``state``,
            ``start_s`` / ``end_s`` (times of the first and last affected frames, recording
            clock, inclusive), ``first_frame`` / ``last_frame``, ``group`` (span number).
    """

    motion: Motion
    states: np.ndarray
    raw_positions: np.ndarray
    raw_orientations: np.ndarray
    spans: list[dict[str, Any]] = field(default_factory=list)


def sensor_frame_times(
    *,
    seed: int | np.random.SeedSequence,
    duration_s: float,
    model: SensorModel = SensorModel(),
) -> tuple[np.ndarray, dict[str, Any]]:
    """Frame timestamps of a recording of ``duration_s`` seconds (recording clock, first = 0.0).

    Returns:
        ``(times, info)``: ``times`` [T] float64 seconds, strictly increasing; ``info`` with
        ``n_nominal`` (frames on the nominal grid), ``dropped_frames`` (count),
        ``dropped_nominal_times_s`` (grid times of the dropped frames) and ``jitter_sd_s``.
    """
    rng = np.random.default_rng(seed)
    n = int(np.floor(duration_s * model.fps + 1e-9)) + 1
    nominal = np.arange(n) / model.fps
    jitter = np.clip(rng.normal(0.0, model.jitter_sd_s, n), -0.3 / model.fps, 0.3 / model.fps)
    jitter[0] = 0.0
    drop = rng.random(n) < model.drop_rate
    drop[[0, -1]] = False
    if not drop.any() and n >= 200:  # long enough recordings always show at least one drop
        drop[int(rng.integers(1, n - 1))] = True
    times = nominal + jitter
    info = {
        "n_nominal": n,
        "dropped_frames": int(drop.sum()),
        "dropped_nominal_times_s": nominal[drop].tolist(),
        "jitter_sd_s": model.jitter_sd_s,
    }
    return times[~drop], info


def apply_sensor_defects(
    truth: Motion,
    *,
    seed: int | np.random.SeedSequence,
    protect: Sequence[tuple[float, float]] = (),
    foot_window: tuple[float, float] | None = None,
    model: SensorModel = SensorModel(),
) -> SensorOutput:
    """Turn the true motion into what the sensor writes.

    Args:
        truth: the true motion, sampled at the frame times (Kinect v2 joint set, orientations).
        seed: seed of the noise and the tracking spans.
        protect: (start, end) time ranges (``truth``'s clock) where no tracking span may fall,
            e.g. around the sync clap.
        foot_window: (start, end) where the foot loss should preferably fall (e.g. while dancing).
        model: defect levels.
    """
    rng = np.random.default_rng(seed)
    js = truth.joint_set
    t = truth.times
    T, J = truth.n_frames, len(js)
    states = np.full((T, J), TRACKED, np.int8)
    spans: list[dict[str, Any]] = []
    busy = [tuple(p) for p in protect]

    def place(length_s: float, window: tuple[float, float]) -> tuple[int, int] | None:
        lo, hi = max(window[0], t[0] + 0.5), min(window[1], t[-1] - 0.5) - length_s
        for _ in range(50):
            if hi <= lo:
                return None
            start = rng.uniform(lo, hi)
            if all(start + length_s + 0.3 < a or start > b + 0.3 for a, b in busy):
                i0, i1 = np.searchsorted(t, [start, start + length_s])
                if i1 > i0:
                    busy.append((start, start + length_s))
                    return int(i0), int(i1) - 1
        return None

    duration = t[-1] - t[0] if T else 0.0
    events = []
    if duration >= 3:  # the long foot loss first: it needs the most room
        side = ("left", "right")[int(rng.integers(2))]
        length = rng.uniform(*model.foot_span_s)
        frames = place(length, foot_window) if foot_window else None
        frames = frames or place(length, (t[0], t[-1]))
        if frames:
            events.append((FOOT_GROUPS[side], NOT_TRACKED, frames))
    n_hand = max(1, int(rng.poisson(model.hand_events_per_s * duration))) if duration >= 3 else 0
    for _ in range(n_hand):
        side = ("left", "right")[int(rng.integers(2))]
        state = INFERRED if rng.random() < model.hand_inferred_probability else NOT_TRACKED
        frames = place(rng.uniform(*model.hand_span_s), (t[0], t[-1]))
        if frames:
            events.append((HAND_GROUPS[side], state, frames))
    events.sort(key=lambda e: e[2][0])
    for group, (joints, state, (i0, i1)) in enumerate(events):
        for name in joints:
            states[i0 : i1 + 1, js.index(name)] = state
            spans.append(
                {
                    "joint": name,
                    "state": int(state),
                    "start_s": float(t[i0]),
                    "end_s": float(t[i1]),
                    "first_frame": i0,
                    "last_frame": i1,
                    "group": group,
                }
            )

    pos = np.array(truth.positions)
    pos += rng.normal(0.0, model.position_sd_m, pos.shape)
    inferred = states == INFERRED
    pos[inferred] += rng.normal(0.0, model.inferred_position_sd_m, (int(inferred.sum()), 3))
    for joints, state, (i0, i1) in events:
        if state == INFERRED:  # inferred joints drift away from the truth and back
            n = i1 - i0 + 1
            bias = rng.normal(0, 1, 3)
            bias *= rng.uniform(*model.inferred_bias_m) / np.linalg.norm(bias)
            shape = np.sin(np.pi * (np.arange(n) + 0.5) / n)[:, None]
            for name in joints:
                pos[i0 : i1 + 1, js.index(name)] += shape * bias

    quat = None
    if truth.orientations is not None:
        rot_ok = js.orientation_mask
        q = truth.orientations[:, rot_ok]
        sd = np.where(inferred[:, rot_ok], model.inferred_orientation_sd_rad, model.orientation_sd_rad)
        noise = Rotation.from_rotvec((rng.normal(0.0, 1.0, q.shape[:2] + (3,)) * sd[..., None]).reshape(-1, 3))
        noisy = (noise * Rotation.from_quat(q.reshape(-1, 4))).as_quat().reshape(q.shape)
        noisy *= np.where(np.sum(noisy * q, axis=-1, keepdims=True) < 0, -1.0, 1.0)  # keep the truth's sign
        quat = np.full((T, J, 4), np.nan)
        quat[:, rot_ok] = noisy

    # Not tracked: the sensor repeats the last value it wrote (zeros if it never had one).
    lost = states == NOT_TRACKED
    for j in np.flatnonzero(lost.any(axis=0)):
        for i in np.flatnonzero(lost[:, j]):
            pos[i, j] = pos[i - 1, j] if i > 0 else 0.0
            if quat is not None and rot_ok[j]:
                quat[i, j] = quat[i - 1, j] if i > 0 else (0.0, 0.0, 0.0, 1.0)

    confidence = np.vectorize(CONFIDENCE.get, otypes=[np.float32])(states)
    valid = states != NOT_TRACKED
    motion = Motion(
        times=t,
        positions=pos,
        joint_set=js,
        position_mask=valid,
        confidence=confidence,
        orientations=quat,
        orientation_mask=None if quat is None else valid,
        metadata={**truth.metadata, "generator": "kinectdata.synth.sensor"},
    )
    return SensorOutput(motion=motion, states=states, raw_positions=pos, raw_orientations=quat, spans=spans)
