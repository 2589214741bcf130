"""A dancer who turns her back to the sensor, and a frontal tracker that mirrors her sides then: the
known truth for :mod:`kinectdata.cleaning.sides`.

- :func:`draw_turns`: a heading over time (radians about the vertical) made of turns of half a circle
  (the dancer then dances facing away for a while and turns back) and of whole spins (she faces away
  for a moment on the way round), each turn taking ``turn_s`` seconds.
- :func:`turn_about_vertical`: a motion turned by that heading about its root's vertical line
  (positions and joint orientations).
- :func:`frontal_tracker`: what a tracker that assumes a frontal body writes: the left and right
  labels of every mirrored joint pair exchanged in the frames where the body faces away from the
  sensor (its hips' left-to-right line pointing the other way than when it faces the sensor), with
  the mirrored stretches returned as the truth.

Kinect camera space: y up, the dancer facing the sensor along -z at heading 0.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial.transform import Rotation

from kinectdata.core.motion import Motion, sides_exchanged, true_runs


def _smootherstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (x * (6 * x - 15) + 10)


def draw_turns(
    times: np.ndarray,
    rng: np.random.Generator,
    turns_per_minute: float = 4.0,
    turn_s: float = 0.8,
    away_s: tuple[float, float] = (1.5, 5.0),
    spin_share: float = 0.4,
) -> np.ndarray:
    """[T] a heading in radians at ``times`` (seconds): 0 (facing the sensor) at the start, then about
    ``turns_per_minute`` events, each a half turn away that is held ``away_s`` seconds before the turn
    back (either way round), or, with probability ``spin_share``, a whole spin; no event in the first
    and last 2 s."""
    t = np.asarray(times, np.float64)
    heading = np.zeros_like(t)
    start, end = t[0] + 2.0, t[-1] - 2.0
    clock = start + rng.exponential(60.0 / turns_per_minute)
    while clock < end:
        way = rng.choice([-1.0, 1.0])
        if rng.random() < spin_share:
            heading += way * 2 * np.pi * _smootherstep((t - clock) / (2 * turn_s))
            clock += 2 * turn_s
        else:
            held = rng.uniform(*away_s)
            back = rng.choice([-1.0, 1.0])
            if clock + 2 * turn_s + held >= end:
                break
            heading += way * np.pi * _smootherstep((t - clock) / turn_s)
            heading += back * np.pi * _smootherstep((t - clock - turn_s - held) / turn_s)
            clock += 2 * turn_s + held
        clock += 1.0 + rng.exponential(60.0 / turns_per_minute)
    return heading


def turn_about_vertical(motion: Motion, heading: np.ndarray, root: int = 0) -> Motion:
    """The motion turned by ``heading`` [T] radians about the vertical (y) line through its root joint
    in each frame: positions and joint orientations."""
    turn = Rotation.from_euler("y", np.asarray(heading, np.float64)[:, None])
    pos = np.asarray(motion.positions, np.float64)
    centre = pos[:, root : root + 1].copy()
    centre[..., 1] = 0.0
    flat = (pos - centre).reshape(len(pos), -1, 3)
    turned = np.einsum("tij,tkj->tki", turn.as_matrix(), flat) + centre
    quat = motion.orientations
    if quat is not None:
        ok = np.isfinite(quat).all(axis=-1)
        q = np.where(ok[..., None], quat, (0.0, 0.0, 0.0, 1.0))
        per_joint = Rotation.from_quat(np.repeat(turn.as_quat(), q.shape[1], axis=0))
        q = (per_joint * Rotation.from_quat(q.reshape(-1, 4))).as_quat().reshape(q.shape)
        quat = np.where(ok[..., None], q, np.nan)
    return dataclasses.replace(motion, positions=turned, orientations=quat)


def frontal_tracker(motion: Motion, left: str, right: str) -> tuple[Motion, tuple[tuple[int, int], ...]]:
    """The motion with every mirrored pair's labels exchanged where the body faces away from the
    sensor: where the line from joint ``left`` to joint ``right`` (the hips) points the other way
    along x than it does facing the sensor (+x, Kinect camera space); and those stretches
    ``(first frame, last frame)``, inclusive."""
    js = motion.joint_set
    away = motion.positions[:, js.index(right), 0] < motion.positions[:, js.index(left), 0]
    return sides_exchanged(motion, away), true_runs(away)
