"""Motion a model must beat, made for the same test songs without any learning from their music.

- :func:`mean_pose_noise`: the mean training pose with smooth random motion of the real motion's
  speed (the same mean squared frame-to-frame change per component, noise low-passed at
  :data:`NOISE_CUTOFF_HZ`): alive, but listening to nothing;
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


def mean_pose_noise(
    mean_pose: np.ndarray,
    real_values: np.ndarray,
    real_mask: np.ndarray | None,
    fps: float,
    rng: np.random.Generator,
    cutoff_hz: float = NOISE_CUTOFF_HZ,
) -> np.ndarray:
    """The mean pose [D] plus smooth Gaussian noise, [T - 1, D] for a real motion of T frames.

    Each component's noise is white noise low-passed at ``cutoff_hz`` (a 4th-order Butterworth
    filter run forwards and backwards), scaled so that its mean squared frame-to-frame change
    equals that of the real motion's component ``real_values`` [T, D] (over frames valid in both,
    ``real_mask`` [T, D]): the real motion's speed, none of its rhythm.
    """
    from scipy.signal import butter, sosfiltfilt

    real = np.asarray(real_values, np.float64)
    mask = np.ones_like(real, bool) if real_mask is None else np.asarray(real_mask, bool)
    T, D = real.shape
    if T < 3:
        raise KinectDataError(f"the mean-pose baseline needs a real motion of at least 3 frames, got {T}")
    step = np.diff(real, axis=0)
    both = mask[1:] & mask[:-1]
    real_speed = np.sqrt(np.where(both, step**2, 0.0).sum(axis=0) / np.maximum(both.sum(axis=0), 1))
    sos = butter(4, min(cutoff_hz / (fps / 2), 0.99), output="sos")
    pad = 3 * 4 * 2  # noise beyond both ends, so that sosfiltfilt has room to pad however short the motion
    noise = sosfiltfilt(sos, rng.normal(size=(T - 1 + 2 * pad, D)), axis=0)[pad : pad + T - 1]
    noise_speed = np.sqrt(np.mean(np.diff(noise, axis=0) ** 2, axis=0))
    scale = np.where(noise_speed > 0, real_speed / np.maximum(noise_speed, 1e-12), 0.0)
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
