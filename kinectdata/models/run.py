"""Run folders: what training writes and what evaluation, generation and export read.

A run folder holds ``config.json`` (the training configuration, the model's and what it needs
to know of the dataset: features, target spec, normalisation, frame and sample rate), the
latest ``checkpoint.pt`` (model, optimiser, random generators, history; rewritten atomically
each epoch), ``log.csv``, ``loss.png``, and at the end ``model.pt`` and the files the model's
``run_exports`` name (the yalta model's ``stream.ts``: the streaming network as TorchScript, for
robots). Checkpoints hold only tensors and plain values and are loaded with
``torch.load(..., weights_only=True)``: nothing is unpickled.
"""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import torch

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import KinectDataError
from kinectdata.dataset.verify import read_manifest as read_dataset_manifest
from kinectdata.models.registry import DEFAULT_MODEL, load_network

CONFIG = "config.json"
CHECKPOINT = "checkpoint.pt"
MODEL = "model.pt"
STREAM = "stream.ts"
LOG = "log.csv"


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
    """The model a run trained (runs from before there were several hold no name: :data:`DEFAULT_MODEL`)."""
    return run_config["train"].get("model", DEFAULT_MODEL)


def load_model(run: str | Path) -> tuple[torch.nn.Module, dict[str, Any]]:
    """The trained network of a run (evaluation mode, CPU) and the run's configuration."""
    config = read_config(run)
    state = load_checkpoint(Path(run) / MODEL)
    if "model" not in state or "model" not in config:
        raise KinectDataError(f"{Path(run) / MODEL}: does not match {Path(run) / CONFIG} (no model in one of them)")
    where = f"{Path(run) / MODEL}: does not match the model of {Path(run) / CONFIG}"
    net = load_network(model_name(config), config["model"], state["model"], where)
    return net.eval(), config
