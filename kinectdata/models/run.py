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

import hashlib
import io
import json
from pathlib import Path
from typing import Any

import numpy as np
import torch

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import KinectDataError
from kinectdata.dataset.verify import read_manifest as read_dataset_manifest
from kinectdata.dataset.verify import verified_manifest
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


def read_manifest(dataset: str | Path, *, verify: bool = True, checksums: bool = True) -> dict[str, Any]:
    """A dataset folder's manifest.json, checked against ``schemas/dataset-manifest.schema.json``,
    and with ``verify`` the whole folder against it (:func:`~kinectdata.dataset.verify.verify_dataset`:
    shards present, sizes, layout, accounts, and SHA-256 unless ``checksums`` is False), so that
    nothing trains on or is scored against a damaged or mixed folder; errors name the file."""
    if verify:
        return verified_manifest(dataset, checksums=checksums)
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


DIGEST = "sha256"
"""The checkpoint key holding the SHA-256 of everything else in it (:func:`state_digest`)."""


def save_checkpoint(path: Path, state: dict[str, Any]) -> None:
    """Write a checkpoint atomically (tensors and plain values only), with the SHA-256 of its
    content under :data:`DIGEST`, so that a damaged one is refused instead of trained on."""
    buffer = io.BytesIO()
    torch.save({**state, DIGEST: state_digest(state)}, buffer)
    with atomic_output(path) as tmp:
        tmp.write_bytes(buffer.getvalue())


def load_checkpoint(path: Path) -> dict[str, Any]:
    """A checkpoint written by :func:`save_checkpoint`, its digest checked (checkpoints written
    before digests, without one, are read as they are).

    Raises:
        KinectDataError: no such file, not a checkpoint, or its content differs from its digest.
    """
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except FileNotFoundError as exc:
        raise KinectDataError(f"{path}: no checkpoint") from exc
    except Exception as exc:  # a damaged or foreign file: never unpickled
        # torch's message advises weights_only=False, i.e. running the file's code: not repeated here
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        reason = "it holds objects other than tensors and plain values" if "weights_only" in str(exc) else first
        raise KinectDataError(f"{path}: not a readable kinectdata checkpoint ({reason}); it was not loaded") from exc
    if not isinstance(state, dict):
        raise KinectDataError(f"{path}: not a kinectdata checkpoint (holds a {type(state).__name__}, not a dict)")
    said = state.pop(DIGEST, None)
    if said is not None and said != state_digest(state):
        raise KinectDataError(
            f"{path}: damaged: its content differs from the SHA-256 written with it; it was not loaded "
            "(train again, or resume from a copy)"
        )
    return state


def state_digest(value: Any) -> str:
    """SHA-256 over a checkpoint's content: tensors by dtype, shape and bytes, containers in order
    (dicts by key), other values by ``repr``; independent of how torch lays out the file."""
    digest = hashlib.sha256()

    def walk(v: Any) -> None:
        if isinstance(v, torch.Tensor):
            t = v.detach().cpu().contiguous()
            digest.update(f"T{t.dtype}{tuple(t.shape)}".encode())
            digest.update(t.reshape(-1).view(torch.uint8).numpy().tobytes() if t.numel() else b"")
        elif isinstance(v, np.ndarray):  # repr would abbreviate a long array
            a = np.ascontiguousarray(v)
            digest.update(f"A{a.dtype.str}{a.shape}".encode())
            digest.update(a.tobytes() if a.dtype != object else repr(a.tolist()).encode())
        elif isinstance(v, dict):
            digest.update(b"{")
            for key in sorted(v, key=repr):
                digest.update(repr(key).encode())
                walk(v[key])
            digest.update(b"}")
        elif isinstance(v, (list, tuple)):
            digest.update(b"[")
            for item in v:
                walk(item)
            digest.update(b"]")
        else:
            digest.update(repr(v).encode())

    walk(value)
    return digest.hexdigest()


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
