"""Training configuration and run folders.

A run folder holds ``config.json`` (the training configuration, the model's and what it needs
to know of the dataset: features, target spec, normalisation, frame and sample rate), the
latest ``checkpoint.pt`` (model, optimiser, random generators, history; rewritten atomically
each epoch), ``log.csv``, ``loss.png``, and at the end ``model.pt`` and ``stream.ts`` (the
streaming network as TorchScript, for robots). Checkpoints hold only tensors and plain values
and are loaded with ``torch.load(..., weights_only=True)``: nothing is unpickled.
"""

from __future__ import annotations

import io
import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import torch

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import KinectDataError
from kinectdata.dataset.verify import read_manifest as read_dataset_manifest
from kinectdata.models.registry import load_network

CONFIG = "config.json"
CHECKPOINT = "checkpoint.pt"
MODEL = "model.pt"
STREAM = "stream.ts"
LOG = "log.csv"


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


def write_json(path: Path, doc: Any) -> None:
    """Write ``doc`` as indented JSON, atomically."""
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(doc, indent=2) + "\n")


def _read_json(folder: str | Path, name: str, what: str) -> dict[str, Any]:
    path = Path(folder) / name
    try:
        return json.loads(path.read_text())
    except OSError as exc:
        raise KinectDataError(f"{folder}: not {what} (no readable {name}: {exc.strerror or exc})") from exc
    except ValueError as exc:
        raise KinectDataError(f"{path}: not valid JSON ({exc})") from exc


def read_config(run: str | Path) -> dict[str, Any]:
    """A run folder's config.json; errors name the file."""
    return _read_json(run, CONFIG, "a training run")


def read_manifest(dataset: str | Path) -> dict[str, Any]:
    """A dataset folder's manifest.json, checked against ``schemas/dataset-manifest.schema.json``;
    errors name the file."""
    return read_dataset_manifest(dataset)


def dataset_summary(dataset: Path, manifest: dict[str, Any]) -> dict[str, Any]:
    """What a run keeps of its dataset: enough to read features and write poses without it."""
    cfg = manifest["config"]
    return {
        "path": str(Path(dataset).resolve()),
        "build_key": manifest["build_key"],
        "fps": cfg["fps"],
        "sample_rate": cfg["sample_rate"],
        "features": cfg["features"],
        "target": cfg["target"],
        "root_centre": cfg["root_centre"],
        "normalisation": manifest["normalisation"],
        "feature_shape": manifest["feature_shape"],
        "target_dim": manifest["target_dim"],
        "skeleton": manifest.get("skeleton", {}),  # bone offsets for drawing generated poses (none before v0.1 builds)
    }


MODEL_INTERFACE = ("fps", "sample_rate", "features", "feature_shape", "target", "root_centre", "normalisation")
"""What a dataset must share with a run's for the run's scores on it to mean anything."""


def interface_mismatch(run_config: dict[str, Any], dataset: Path, manifest: dict[str, Any]) -> list[str]:
    """The :data:`MODEL_INTERFACE` keys in which a dataset differs from the run's own."""
    summary = dataset_summary(dataset, manifest)
    return [k for k in MODEL_INTERFACE if summary[k] != run_config["dataset"][k]]


def save_checkpoint(path: Path, state: dict[str, Any]) -> None:
    """Write a checkpoint atomically (tensors and plain values only)."""
    buffer = io.BytesIO()
    torch.save(state, buffer)
    with atomic_output(path) as tmp:
        tmp.write_bytes(buffer.getvalue())


def load_checkpoint(path: Path) -> dict[str, Any]:
    try:
        return torch.load(path, map_location="cpu", weights_only=True)
    except FileNotFoundError as exc:
        raise KinectDataError(f"{path}: no checkpoint") from exc
    except Exception as exc:  # a damaged or foreign file: never unpickled
        # torch's message advises weights_only=False, i.e. running the file's code: not repeated here
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        reason = "it holds objects other than tensors and plain values" if "weights_only" in str(exc) else first
        raise KinectDataError(f"{path}: not a readable kinectdata checkpoint ({reason}); it was not loaded") from exc


def model_name(run_config: dict[str, Any]) -> str:
    """The model a run trained (runs from before the cdhc model hold no name: yalta)."""
    return run_config["train"].get("model", "yalta")


def load_model(run: str | Path) -> tuple[torch.nn.Module, dict[str, Any]]:
    """The trained network of a run (evaluation mode, CPU) and the run's configuration."""
    config = read_config(run)
    state = load_checkpoint(Path(run) / MODEL)
    if "model" not in state or "model" not in config:
        raise KinectDataError(f"{Path(run) / MODEL}: does not match {Path(run) / CONFIG} (no model in one of them)")
    where = f"{Path(run) / MODEL}: does not match the model of {Path(run) / CONFIG}"
    net = load_network(model_name(config), config["model"], state["model"], where)
    return net.eval(), config
