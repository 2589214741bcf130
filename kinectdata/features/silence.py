"""What digital silence looks like to a feature configuration, and which frames hear it.

Silence is the features of all-zero audio: the value the build gives a silent stretch (e.g. 0 for the
listen-to-dance log-mel and pulse features, the floor for ``frame_minmax`` STFTs, whose rule also
maps audio below -60 dB there). A frame hears silence when its features are that value.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinectdata.features import FeatureConfig, compute_features, feature_config

__all__ = ["silence_features", "silent_frames"]


def silence_features(features: FeatureConfig | dict[str, Any], fps: float) -> np.ndarray:
    """The features [*F] of one motion frame of digital silence, for a feature configuration (or its
    dict, as a manifest's ``config.features`` holds it) at ``fps`` frames per second."""
    cfg = feature_config(features) if isinstance(features, dict) else features
    starts = np.round(np.arange(2) * cfg.sample_rate / fps).astype(np.int64)
    frames, _ = compute_features(np.zeros(int(starts[-1]) + cfg.span[1], np.float32), starts, cfg)
    return np.ascontiguousarray(frames[0])


def silent_frames(features: np.ndarray, silence: np.ndarray, atol: float = 1e-6) -> np.ndarray:
    """[T] bool: the frames of ``features`` [T, *F] equal to ``silence`` [*F] (within ``atol``)."""
    features = np.asarray(features)
    if features.shape[1:] != np.shape(silence):
        raise ValueError(f"features of shape {features.shape[1:]} per frame, silence of shape {np.shape(silence)}")
    flat = features.reshape(len(features), -1)
    return np.abs(flat - np.asarray(silence).reshape(1, -1)).max(axis=1, initial=0.0) <= atol
