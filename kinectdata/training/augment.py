"""Changes made to training windows as they are drawn (the dataset on disk stays as built).

:func:`silence_windows`: in a share of the windows the music stops at a random frame and the
dancer holds the pose it had there. Dance corpora hold no silence (the music plays from the first
frame of a dance to its last), so without it nothing tells a model that silence means standing
still, and a model that learned to keep moving on its own keeps moving when the music stops.
Yalta et al. (2016) show their model stopping in silence (their Figure 7); ``evaluate``'s silence
test and the listening controls check it.
"""

from __future__ import annotations

import numpy as np
import torch

from kinectdata.features import compute_features, feature_config

MIN_MUSIC_FRACTION = 0.25
"""A silenced window keeps at least this share of its frames with music (the pose to hold comes from them)."""
MIN_SILENT_FRAMES = 30
"""And goes silent for at least this many frames (a second at 30 fps: long enough to see the stop)."""


def silent_frame(features: dict, fps: float) -> torch.Tensor:
    """The features [*F] of one motion frame of digital silence, for a dataset's feature settings
    (its manifest's ``config.features``) and frame rate: what the build computes for silence."""
    cfg = feature_config(features)
    starts = np.round(np.arange(2) * cfg.sample_rate / fps).astype(np.int64)
    frames, _ = compute_features(np.zeros(int(starts[-1]) + cfg.span[1], np.float32), starts, cfg)
    return torch.from_numpy(np.ascontiguousarray(frames[0]))


def silence_windows(
    batch: dict[str, torch.Tensor], silent: torch.Tensor, share: float, generator: torch.Generator, context: int = 0
) -> dict[str, torch.Tensor]:
    """A training batch with the music of about ``share`` of its windows silenced from a random frame
    on, and their poses held from there.

    Args:
        batch: a :class:`~kinectdata.dataset.windows.WindowDataset` batch: ``audio`` [B, L, *F],
            ``pose`` / ``previous`` / ``mask`` / ``previous_mask`` [B, L, D].
        silent: one frame of silence's features [*F] (:func:`silent_frame`).
        share: probability that a window is silenced, 0..1.
        generator: the draws (seeded: a run stays reproducible and resumable).
        context: the windows' first frames that no loss counts (``TrainConfig.context``): the
            silence starts after them, in the part the losses see, with the music before it
            (:data:`MIN_MUSIC_FRACTION` of that part). Silence from inside the context would leave
            the losses a window of one held pose, whose spectra have nothing to compare with.

    Returns:
        A new batch (the given tensors are not changed). In a silenced window from frame s on the
        audio is ``silent``, the pose is the pose of frame s - 1 (held; its mask too), and the
        previous pose is the held pose from frame s + 1 on, and the next pose from frame s - 1 on;
        rhythm labels (``rhythm_valid``), where the batch has them, are invalid from frame s on.
    """
    audio, pose = batch["audio"], batch["pose"]
    B, L = pose.shape[:2]
    first = context + max(1, int(np.ceil(MIN_MUSIC_FRACTION * (L - context))))
    last = L - MIN_SILENT_FRAMES
    draws = torch.rand(B, generator=generator)
    starts = torch.randint(first, max(first + 1, last + 1), (B,), generator=generator)
    chosen = [(b, int(s)) for b, s in enumerate(starts) if draws[b] < share and first <= int(s) <= last]
    if not chosen:
        return batch
    changed = ("audio", "pose", "previous", "next", "mask", "previous_mask", "rhythm_valid")
    out = {k: v.clone() if k in changed else v for k, v in batch.items()}
    for b, s in chosen:
        out["audio"][b, s:] = silent.to(audio.dtype)
        out["pose"][b, s:] = pose[b, s - 1]
        out["mask"][b, s:] = batch["mask"][b, s - 1]
        if s + 1 < L:
            out["previous"][b, s + 1 :] = pose[b, s - 1]
            out["previous_mask"][b, s + 1 :] = batch["mask"][b, s - 1]
        if "next" in out:
            out["next"][b, s - 1 :] = pose[b, s - 1]
        if "rhythm_valid" in out:
            out["rhythm_valid"][b, s:] = False
    return out
