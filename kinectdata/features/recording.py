"""Features of every motion frame of an aligned recording, with the rates checked."""

from __future__ import annotations

import numpy as np

from kinectdata.align.aligned import AlignedRecording
from kinectdata.features import FeatureConfig, compute_features


def recording_features(rec: AlignedRecording, config: FeatureConfig) -> tuple[np.ndarray, np.ndarray]:
    """``(features [T, *config.output_shape] float32, padded [T] bool)``: one input per motion frame
    of ``rec`` (frame k's audio slice starts at sample ``round(k * sample_rate / fps)``), as a dataset
    build computes them; ``padded`` marks slices that run past the audio (zeros there).

    ConfigError when the configuration's sample rate is not the recording's or its slices are not
    one frame period long (:meth:`AlignedRecording.frame_starts`). ``rec`` must hold its audio
    (``AlignedRecording.load(path)``, not ``audio=False``)."""
    starts = rec.frame_starts(config.sample_rate, config.slice_samples)
    return compute_features(rec.audio, starts, config)
