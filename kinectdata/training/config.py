"""Training settings (:class:`TrainConfig`) and each model's defaults."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import torch

from kinectdata.core.errors import KinectDataError


@dataclass(frozen=True)
class TrainConfig:
    """Training settings; the defaults are Yalta et al.'s (:meth:`for_model` gives each model's).

    Attributes:
        model: ``yalta`` (the DCNN + deep LSTM) or ``cdhc`` (the Listen to Dance encoder-decoder).
        units, activation: the yalta model (LSTM units per layer; tanh, relu or elu).
        feedback: yalta: ``predicted`` (the model's own previous pose, the paper's Figure 4) or
            ``teacher`` (the true previous pose). The cdhc model always trains with teacher forcing.
        channels, decoder_channels, dropout: the cdhc model (encoder and decoder widths, dropout
            after each highway block).
        limb_weight: cdhc: weight of the limb-length loss added to the L1 loss.
        sequence: frames per training sequence; stride: frames between sequence starts
            (default: ``sequence``, non-overlapping).
        batch_size: sequences per batch. epochs: passes over the training split.
        lr: Adam's learning rate.
        noise_eta, noise_gamma: annealed Gaussian gradient noise, variance eta / (1 + t)^gamma
            at step t (Neelakantan et al. 2015); eta 0 turns it off.
        clip_norm: clip the gradient's global norm to this before the noise (None: no clipping).
        seed: every random choice (initialisation, batch order, noise).
        device: ``auto`` (CUDA when present, else CPU), ``cpu`` or ``cuda``.
    """

    model: str = "yalta"
    units: int = 500
    activation: str = "elu"
    feedback: str = "predicted"
    sequence: int = 150
    stride: int | None = None
    batch_size: int = 50
    epochs: int = 10
    lr: float = 1e-4
    noise_eta: float = 0.01
    noise_gamma: float = 0.55
    clip_norm: float | None = None
    seed: int = 0
    device: str = "auto"
    channels: int = 256
    decoder_channels: int = 128
    dropout: float = 0.05
    limb_weight: float = 1.0

    def __post_init__(self) -> None:
        if self.model not in MODEL_DEFAULTS:
            raise KinectDataError(f"model must be one of {', '.join(MODEL_DEFAULTS)}, not {self.model!r}")
        if min(self.channels, self.decoder_channels) < 1 or not 0 <= self.dropout < 1 or self.limb_weight < 0:
            raise KinectDataError("channels must be positive, dropout in [0, 1) and limb_weight at least 0")
        if self.feedback not in ("predicted", "teacher"):
            raise KinectDataError(f"feedback must be predicted or teacher, not {self.feedback!r}")
        if min(self.sequence, self.batch_size, self.epochs, self.units) < 1 or (self.stride or 1) < 1:
            raise KinectDataError("sequence, stride, batch size, epochs and units must be positive")
        if self.device not in ("auto", "cpu", "cuda"):
            raise KinectDataError(f"device must be auto, cpu or cuda, not {self.device!r}")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def for_model(cls, model: str, **settings: Any) -> TrainConfig:
        """The settings of ``model`` (:data:`MODEL_DEFAULTS`), with ``settings`` (None: the default)."""
        if model not in MODEL_DEFAULTS:
            raise KinectDataError(f"model must be one of {', '.join(MODEL_DEFAULTS)}, not {model!r}")
        given = {k: v for k, v in settings.items() if v is not None}
        return cls(**{"model": model, **MODEL_DEFAULTS[model], **given})

    def resolved_device(self) -> torch.device:
        if self.device == "auto":
            return torch.device("cuda" if torch.cuda.is_available() else "cpu")
        if self.device == "cuda" and not torch.cuda.is_available():
            raise KinectDataError("--device cuda, but torch sees no CUDA device")
        return torch.device(self.device)


MODEL_DEFAULTS: dict[str, dict[str, Any]] = {
    "yalta": {},  # the dataclass defaults: Yalta et al.'s settings
    "cdhc": {
        "feedback": "teacher",
        "sequence": 300,
        "batch_size": 16,
        "epochs": 20,
        "lr": 2e-4,
        "noise_eta": 0.0,
        "clip_norm": 1.0,
    },
}
"""Each model's training defaults beyond the dataclass's. cdhc: the paper gives no schedule; these
follow DC-TTS, whose blocks it uses (Adam 2e-4, gradient norm clipped to 1), with 10 s sequences
(longer than the 265-frame receptive field), no gradient noise."""
