"""Motion a model must beat, made for the same test songs without any learning from their music.

- :func:`mean_pose_noise`: the mean training pose with smooth random motion at a given speed per
  component (its mean squared frame-to-frame change, :func:`mean_square_steps`; noise low-passed
  at :data:`NOISE_CUTOFF_HZ`): alive, but listening to nothing. The baseline a model must beat
  moves at the training dances' speed; the same noise at each test song's own real speed is
  reported beside it as an oracle (it knows how fast the answer moves, which is most of what the
  kinetic features measure);
- :func:`retrieval`: the real training motion of the training song whose music is most like the
  test song's (the nearest by :func:`music_descriptor`: the mean and spread of the model's input
  features), as long as the test song (repeated when shorter): real dance, to other music.

Both return denormalised target vectors [T - 1, D] for frames 1..T-1, as a model's free run is
scored (:func:`kinectdata.evaluation.run_field.run_field_scores`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinectdata.core.errors import KinectDataError

NOISE_CUTOFF_HZ = 3.0
"""The mean-pose baseline's noise has no frequencies above this (dance moves are slower; sensor jitter faster)."""


@dataclass(frozen=True)
class TrainingSong:
    """A training recording for :func:`retrieval`: its name, its music's descriptor
    (:func:`music_descriptor`) and its real motion as denormalised targets [T, D]."""

    name: str
    descriptor: np.ndarray
    values: np.ndarray


def music_descriptor(features: np.ndarray) -> np.ndarray:
    """A song's music as one vector: the mean and standard deviation over its frames of each
    feature value (features [T, ...], the model's inputs: its spectrum and how much it changes),
    scaled to unit length."""
    x = np.asarray(features, np.float64).reshape(len(features), -1)
    if x.shape[0] < 2:
        raise KinectDataError(f"a music descriptor needs at least 2 frames, got {x.shape[0]}")
    summary = np.concatenate([x.mean(axis=0), x.std(axis=0)])
    return summary / max(np.linalg.norm(summary), 1e-12)


def retrieval(test_descriptor: np.ndarray, frames: int, training: list[TrainingSong]) -> tuple[np.ndarray, str]:
    """(denormalised targets [frames - 1, D] of the nearest training song's real motion, its name):
    the training song whose descriptor is nearest (Euclidean) to ``test_descriptor``, its motion
    from its second frame on, repeated end to end when shorter than the test song."""
    if not training:
        raise KinectDataError("the retrieval baseline needs at least one training song")
    if frames < 2:
        raise KinectDataError(f"the retrieval baseline needs a test song of at least 2 frames, got {frames}")
    distances = [np.linalg.norm(np.asarray(t.descriptor) - test_descriptor) for t in training]
    nearest = training[int(np.argmin(distances))]
    motion = np.asarray(nearest.values, np.float64)[1:]
    if len(motion) < 1:
        raise KinectDataError(f"training song {nearest.name} has no motion after its first frame")
    repeats = -(-(frames - 1) // len(motion))
    return np.concatenate([motion] * repeats)[: frames - 1], nearest.name


def mean_square_steps(motions: list[tuple[np.ndarray, np.ndarray | None]]) -> np.ndarray:
    """Per component, the mean squared frame-to-frame change [D] (target units per frame, squared)
    pooled over the frame pairs valid in both frames of every motion: ``(values [T, D], mask [T, D]
    or None)`` pairs. 0 for a component never valid in two consecutive frames."""
    if not motions:
        raise KinectDataError("the speed of no motion was asked for")
    total = count = 0.0
    for values, mask in motions:
        real = np.asarray(values, np.float64)
        valid = np.ones_like(real, bool) if mask is None else np.asarray(mask, bool)
        both = valid[1:] & valid[:-1]
        total = total + np.where(both, np.diff(real, axis=0) ** 2, 0.0).sum(axis=0)
        count = count + both.sum(axis=0)
    return total / np.maximum(count, 1)


def mean_pose_noise(
    mean_pose: np.ndarray,
    mean_square_step: np.ndarray,
    frames: int,
    fps: float,
    rng: np.random.Generator,
    cutoff_hz: float = NOISE_CUTOFF_HZ,
) -> np.ndarray:
    """The mean pose [D] plus smooth Gaussian noise, [frames - 1, D] for a song of ``frames`` frames.

    Each component's noise is white noise low-passed at ``cutoff_hz`` (a 4th-order Butterworth
    filter run forwards and backwards), scaled so that its mean squared frame-to-frame change is
    ``mean_square_step`` [D] (:func:`mean_square_steps` of the real motion it stands for): that
    motion's speed, none of its rhythm.
    """
    from scipy.signal import butter, sosfiltfilt

    if frames < 3:
        raise KinectDataError(f"the mean-pose baseline needs a song of at least 3 frames, got {frames}")
    wanted = np.asarray(mean_square_step, np.float64)
    sos = butter(4, min(cutoff_hz / (fps / 2), 0.99), output="sos")
    pad = 3 * 4 * 2  # noise beyond both ends, so that sosfiltfilt has room to pad however short the motion
    noise = sosfiltfilt(sos, rng.normal(size=(frames - 1 + 2 * pad, wanted.size)), axis=0)[pad : pad + frames - 1]
    noise_speed = np.sqrt(np.mean(np.diff(noise, axis=0) ** 2, axis=0))
    scale = np.where(noise_speed > 0, np.sqrt(wanted) / np.maximum(noise_speed, 1e-12), 0.0)
    return np.asarray(mean_pose, np.float64)[None, :] + noise * scale


HEADLINE = ("FID_k", "FID_g")
"""The metrics a model must do better on than a baseline to beat it (lower is better)."""


def baseline_comparison(scores: dict) -> dict[str, dict[str, float | bool | None]]:
    """Per baseline, the generated motion's FID_k and FID_g beside the baseline's and whether the
    model is lower on both (``beats``): ``scores`` maps ``generated`` and each baseline's name to its
    :class:`~kinectdata.evaluation.field_scores.FieldScores`."""
    model = scores["generated"]
    out = {}
    for name, baseline in scores.items():
        if name == "generated":
            continue
        row: dict[str, float | bool | None] = {}
        wins = []
        for metric in HEADLINE:
            mine, theirs = model.metric(metric).generated, baseline.metric(metric).generated
            row[metric] = mine
            row[f"{metric}_baseline"] = theirs
            wins.append(mine is not None and theirs is not None and mine < theirs)
        row["beats"] = all(wins)
        out[name] = row
    return out
