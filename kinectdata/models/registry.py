"""The bundled models behind one small interface, by name: what training, evaluation and generation
need of a model, so that those stay one loop each.

- ``yalta``: the DCNN + deep LSTM of Yalta et al. (2016) (:mod:`.yalta`): STFT inputs
  [T, 1, 129, 5], MSE, the previous pose its own output (or the true one) as configured.
- ``cdhc``: the CDHC encoder-decoder of Lee et al. (2018) (:mod:`.cdhc`): mel inputs [T, F],
  teacher forcing (the true previous poses) in training, L1 + limb-length loss, autoregressive
  generation.

A kind builds its network from the training settings and the dataset's manifest, says what a
masked previous pose becomes, runs it on a training batch, scores that, sets the output layer to
start at the mean pose, and runs it free over a recording (given the true first pose, then its own
outputs).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from torch import nn

from kinectdata.core.errors import KinectDataError
from kinectdata.models.cdhc import CdhcConfig, CdhcNet, cdhc_loss, generate, init_output_bias
from kinectdata.models.losses import masked_mse
from kinectdata.models.yalta import YaltaConfig, YaltaNet, free_run
from kinectdata.targets.specs import TargetSpec


@dataclass(frozen=True)
class YaltaKind:
    """Yalta et al. (2016)."""

    name: str = "yalta"
    resets: bool = True  # free runs can zero the LSTM states every training sequence

    def config(self, train: Any, manifest: dict[str, Any]) -> YaltaConfig:
        shape = tuple(manifest["feature_shape"])
        if len(shape) != 3:
            raise KinectDataError(
                f"the yalta model takes STFT inputs [1, 129, 5]; this dataset's are {list(shape)} "
                "(a listen-to-dance dataset: use --model cdhc)"
            )
        return YaltaConfig(
            output_dim=manifest["target_dim"], units=train.units, activation=train.activation, input_shape=shape
        )

    def build(self, config: dict[str, Any]) -> YaltaNet:
        return YaltaNet(YaltaConfig.from_dict(config))

    def fill_previous(self, previous, mask, start_pose):
        """Masked previous poses stay as the dataset stores them (0: the centre of -0.9..0.9)."""
        return previous

    def predict(self, net: YaltaNet, audio, previous, feedback: str) -> torch.Tensor:
        """[B, L, D] from a batch: ``previous`` [B, L, D] the true poses before each frame."""
        return net(audio, previous if feedback == "teacher" else previous[:, 0], feedback)

    def loss(self, net: YaltaNet, pred, pose, mask, train: Any) -> torch.Tensor:
        return masked_mse(pred, pose, mask)

    def init_output(self, net: YaltaNet, start_pose: list[float]) -> None:
        with torch.no_grad():  # outputs start at the mean pose, not 0: maxabs targets are far from centred
            net.fc2.bias.copy_(torch.tensor(start_pose))

    def free_run(self, net: YaltaNet, audio: np.ndarray, first_pose: np.ndarray, reset_every: int | None = None):
        return free_run(net, audio, first_pose, reset_every)


@dataclass(frozen=True)
class CdhcKind:
    """Lee et al. (2018), "Listen to Dance"."""

    name: str = "cdhc"
    resets: bool = False  # no state to reset: the receptive field is fixed

    def config(self, train: Any, manifest: dict[str, Any]) -> CdhcConfig:
        shape = tuple(manifest["feature_shape"])
        if len(shape) != 1:
            raise KinectDataError(
                f"the cdhc model takes per-frame feature vectors [F] (mel bands); this dataset's are {list(shape)} "
                "(a yalta2016 dataset: use --model yalta)"
            )
        spec = TargetSpec.from_dict(manifest["config"]["target"])
        if spec.orientations:
            raise KinectDataError(f"the cdhc model regresses coordinates and limb lengths; {spec.name} has quaternions")
        if manifest["normalisation"]["method"] != "none" or spec.position_scale != "recording_minmax":
            raise KinectDataError(
                f"the cdhc model's sigmoid output covers 0..1: it needs targets scaled into 0..1 per recording "
                f"(position_scale recording_minmax, normalisation none, as --pipeline listen-to-dance builds); "
                f"this dataset's are {spec.position_scale} and {manifest['normalisation']['method']}"
            )
        if manifest["config"].get("root_centre"):
            raise KinectDataError(
                "the cdhc model's limb loss measures limbs between its output coordinates; root-centred "
                "coordinates put the root in another frame of reference than its children: build without --root-centre"
            )
        index = {j: i for i, j in enumerate(spec.positions)}
        return CdhcConfig(
            output_dim=manifest["target_dim"],
            input_dim=shape[0],
            channels=train.channels,
            decoder_channels=train.decoder_channels,
            dropout=train.dropout,
            coordinates=spec.dimensions * len(spec.positions),
            joint_dims=spec.dimensions,
            limbs=tuple((index[j], index[p]) for j, p in spec.limb_pairs()),
        )

    def build(self, config: dict[str, Any]) -> CdhcNet:
        return CdhcNet(CdhcConfig.from_dict(config))

    def fill_previous(self, previous, mask, start_pose):
        """Masked previous values (stored as 0, a real coordinate in 0..1) become the mean training
        pose's, so teacher forcing never shows a joint jumping to the image's corner."""
        if isinstance(previous, torch.Tensor):
            start = torch.as_tensor(start_pose, dtype=previous.dtype, device=previous.device)
            return torch.where(mask, previous, start)
        return np.where(mask, previous, np.asarray(start_pose, dtype=np.asarray(previous).dtype))

    def predict(self, net: CdhcNet, audio, previous, feedback: str) -> torch.Tensor:
        return net(audio, previous)  # teacher forcing: the true pose of each previous frame

    def loss(self, net: CdhcNet, pred, pose, mask, train: Any) -> torch.Tensor:
        return cdhc_loss(pred, pose, mask, net.config, train.limb_weight)[0]

    def init_output(self, net: CdhcNet, start_pose: list[float]) -> None:
        init_output_bias(net, np.asarray(start_pose))

    def free_run(self, net: CdhcNet, audio: np.ndarray, first_pose: np.ndarray, reset_every: int | None = None):
        """Poses [T-1, D] of frames 1..T-1 from the audio of those frames, starting from the true
        pose of frame 0 (``reset_every`` does not apply)."""
        return generate(net, audio[1:], first_pose)


MODELS: dict[str, YaltaKind | CdhcKind] = {"yalta": YaltaKind(), "cdhc": CdhcKind()}


def model_kind(name: str) -> YaltaKind | CdhcKind:
    """The model registered under ``name``; KinectDataError listing the known ones otherwise."""
    try:
        return MODELS[name]
    except KeyError:
        raise KinectDataError(f"unknown model {name!r}; known: {', '.join(MODELS)}") from None


def model_for_features(features: dict[str, Any]) -> str:
    """The bundled model of a dataset's features: ``cdhc`` for mel inputs, ``yalta`` otherwise."""
    return "cdhc" if features.get("extractor") == "mel" else "yalta"


def load_network(model: str, config: dict[str, Any], state: dict[str, Any], where: str) -> nn.Module:
    """A network of the named kind with a state dict; KinectDataError starting with ``where`` if
    they disagree."""
    try:
        net = model_kind(model).build(config)
        net.load_state_dict(state)
    except (KeyError, TypeError, ValueError, RuntimeError, KinectDataError) as exc:
        raise KinectDataError(f"{where} ({model} model: {exc})") from exc
    return net
