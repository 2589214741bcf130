"""The two bundled models as :class:`~kinectdata.models.kind.ModelKind` s, with their settings.

- ``yalta`` (:class:`YaltaKind`): the DCNN + deep LSTM of Yalta et al. (2016)
  (:mod:`.yalta`): STFT inputs [T, 1, 129, 5], MSE, the previous pose its own output or the true
  one (``feedback``); resets, streams (torch in float32 or float16, ONNX Runtime), exports
  TorchScript and ONNX, writes ``stream.ts`` at the end of training; the sweep of the paper's
  Tables 3-5.
- ``cdhc`` (:class:`CdhcKind`): the CDHC encoder-decoder of Lee et al. (2018) (:mod:`.cdhc`):
  mel inputs [T, F], teacher forcing, L1 + limb-length loss, autoregressive generation; streams
  (torch and ONNX Runtime, float32: one cache per highway block), no state to reset, exports ONNX.

Declarations only at import: the networks (and torch) are imported when a kind is used, so the
registry and the command line's choices load without torch.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinectdata.core.errors import ConfigError
from kinectdata.models.kind import INPUTS, PAPER_LOOP, ModelKind, Sweep, check_inputs, in_run_batches
from kinectdata.models.losses import masked_mse, masked_velocity_l1, masked_velocity_mse

YALTA_ACTIVATIONS = ("tanh", "relu", "elu")
STYLE_PATHS = ("lstm", "convs")
FEEDBACKS = ("predicted", "teacher")
PREDICTS = ("pose", "change")


REAL_DANCE_LOOP: dict[str, Any] = {
    "sequence": 300,
    "stride": 75,
    "batch_size": 8,
    "epochs": 12,
    "lr": 1e-3,
    "noise_eta": 0.0,
    "clip_norm": 1.0,
    "free_weight": 1.0,
    "posture_weight": 3.0,
    "silence_share": 0.2,
    "keep": "best",
    "context": None,
    "song_starts": True,
}
"""The loop for real dance on a CPU (docs/training.md, "Learning real dance"), both models'
default: windows of 10 s every 2.5 s, many small steps (batches of 8, Adam 1e-3, the gradient's norm
clipped to 1, no gradient noise), the free-running rhythm loss beside the model's own, a fifth of
the windows silenced, the epoch whose free-running validation motion is most like the real
motion kept, and each window preceded by the model's own context (its receptive field) of real
input that no loss counts, windows from each song's start among them (silence before the song in
their context)."""


def _inputs_field(default: str):
    """Both models' ``inputs`` setting (:data:`INPUTS`)."""
    return field(
        default=default,
        metadata={
            "help": "what the decoder is given: the music and the previous poses (the paper's) or the music only "
            "(each pose a function of the music so far: no feedback to drift on or settle into).",
            "choices": INPUTS,
        },
    )


def _side_planes(manifest: dict[str, Any]) -> int:
    """How many of a dataset's last feature channels are constant planes (0: none): the parts at the
    end of its stack whose output is one value per plane (the style input's, the metre input's, the
    pulse's clocks with ``planes``)."""
    from kinectdata.features import StackConfig, feature_config

    described = manifest.get("config", {}).get("features")
    if described is None:  # a manifest that does not say its features (a test's): nothing bypasses
        return 0
    features = feature_config(described)
    parts = features.parts if isinstance(features, StackConfig) else (features,)
    side = 0
    for part in reversed(parts):
        if getattr(part, "planes", None) is None:
            break
        side += part.output_shape[0]
    return side if side < features.output_shape[0] else 0


@dataclass(frozen=True)
class PhraseCodeSettings:
    """Both models' phrase code (:mod:`kinectdata.models.latent`): a small latent vector per phrase,
    inferred from the dancer's poses in training (with a KL term towards N(0, I)) and drawn in
    generation (``generate``'s and ``live``'s ``--seed``), so that the dance can choose among
    figures the music does not fix. Off (``latent_dims`` 0) by default."""

    latent_dims: int = field(
        default=0,
        metadata={
            "help": "size of a phrase code: inferred from the dancer's poses in training, drawn in generation, so "
            "that the dance can choose among figures the music does not fix (0: none).",
            "min": 0,
        },
    )
    phrase_seconds: float = field(
        default=2.0,
        metadata={"help": "with --latent-dims: seconds per phrase of the code.", "min": 0, "min_open": True},
    )
    latent_weight: float = field(
        default=0.01,
        metadata={"help": "with --latent-dims: weight of the phrase code's KL divergence (nats per phrase).", "min": 0},
    )
    free_nats: float = field(
        default=0.5,
        metadata={"help": "with --latent-dims: nats per dimension of the code that its KL term forgives.", "min": 0},
    )

    def __post_init__(self) -> None:
        if self.latent_dims < 0 or not self.phrase_seconds > 0 or self.latent_weight < 0 or self.free_nats < 0:
            raise ConfigError(
                "latent_dims, latent_weight and free_nats must be at least 0 and phrase_seconds positive, not "
                f"{self.latent_dims}, {self.latent_weight}, {self.free_nats}, {self.phrase_seconds}"
            )

    def phrase_config(self, manifest: dict[str, Any]) -> dict[str, Any]:
        """The network config's phrase code entries (none without one): its size, and its phrase in
        frames at the dataset's rate."""
        if not self.latent_dims:
            return {}
        frames = max(1, round(self.phrase_seconds * float(manifest["config"]["fps"])))
        return {"latent_dims": self.latent_dims, "phrase_frames": frames}

    def with_kl(self, loss, net):
        """``loss`` plus the KL term of the network's last posterior pass (unchanged without one)."""
        from kinectdata.models.latent import kl_term

        if getattr(net, "phrase_code", None) is None or net.latent_kl is None or not self.latent_weight:
            return loss
        return loss + self.latent_weight * kl_term(net.latent_kl.float(), self.free_nats)


@dataclass(frozen=True)
class YaltaSettings(PhraseCodeSettings):
    """The yalta model's settings (defaults: the recipe for real dance; the paper's best,
    ELU, 500 units and its own previous output fed back, with ``--paper``)."""

    units: int = field(default=128, metadata={"help": "LSTM units per layer (the paper: 250, 500, 1000).", "min": 1})
    activation: str = field(
        default="elu", metadata={"help": "activation after each convolution and fc1.", "choices": YALTA_ACTIVATIONS}
    )
    feedback: str = field(
        default="teacher",
        metadata={
            "help": "previous pose fed to the decoder in training: the model's own output (the paper) or the true one.",
            "choices": FEEDBACKS,
        },
    )
    velocity_weight: float = field(
        default=0.0,
        metadata={
            "help": "weight of a loss on the frame-to-frame changes added to the pose loss (0: the paper's MSE).",
            "min": 0,
        },
    )
    inputs: str = _inputs_field("music-and-poses")
    style_path: str = field(
        default="lstm",
        metadata={
            "help": "where the constant planes after the spectra (the song's style, the pulse's clocks) enter: "
            "beside the audio code before LSTM4-6, or through the convolutions as the spectra do.",
            "choices": STYLE_PATHS,
        },
    )

    def __post_init__(self) -> None:
        check_inputs(self.inputs)
        if self.style_path not in STYLE_PATHS:
            raise ConfigError(f"style_path must be one of {', '.join(STYLE_PATHS)}, not {self.style_path!r}")
        if self.feedback not in FEEDBACKS:
            raise ConfigError(f"feedback must be predicted or teacher, not {self.feedback!r}")
        if self.activation not in YALTA_ACTIVATIONS:
            raise ConfigError(f"activation must be one of {', '.join(YALTA_ACTIVATIONS)}, not {self.activation!r}")
        if not isinstance(self.units, int) or self.units < 1:
            raise ConfigError(f"units must be a positive integer, not {self.units!r}")
        if not self.velocity_weight >= 0:
            raise ConfigError("velocity_weight must be at least 0")
        super().__post_init__()


YALTA_SWEEP = Sweep(
    title="Yalta et al. (2016) Tables 3-5",
    base={"activation": "elu", "units": 500, "sequence": 150},
    variants={
        "TanH": {"activation": "tanh"},
        "ReLU": {"activation": "relu"},
        "ELU": {},
        "250 units": {"units": 250},
        "1000 units": {"units": 1000},
        "50 steps": {"sequence": 50},
        "100 steps": {"sequence": 100},
    },
    paper={  # SMAPE % without reset, with reset, training minutes, forward ms/frame
        "TanH": (19.73, 20.34, 1182.79, 9.16),
        "ReLU": (19.67, 20.27, 1152.02, 8.54),
        "ELU": (18.57, 19.20, 1139.81, 10.94),
        "250 units": (19.76, 20.28, 663.99, 10.16),
        "1000 units": (17.81, 18.53, 1305.85, 14.97),
        "50 steps": (22.99, 23.73, 247.19, 10.94),
        "100 steps": (19.16, 20.01, 774.75, 10.94),
    },
    paper_note="GTX Titan X, about 15 Latin songs",
    shown=("feedback",),
)
"""The paper's Tables 3-5: each variant changes one thing of the base (ELU, 500 units, sequences of 150)."""


class YaltaKind(ModelKind):
    """Yalta et al. (2016)."""

    name = "yalta"
    description = "the DCNN + deep LSTM of Yalta et al. (2016)"
    settings_type = YaltaSettings
    # bfloat16: its four convolutions are four fifths of a training step; in bfloat16 a step took
    # 0.65 x the time, the whole gradient within 0.2 % of float32's (docs/benchmarks.md, bench_model)
    training_defaults: dict[str, Any] = {**REAL_DANCE_LOOP, "precision": "bfloat16"}
    paper: dict[str, Any] = {
        **PAPER_LOOP,
        "units": 500,
        "feedback": "predicted",
        "velocity_weight": 0.0,
        "inputs": "music-and-poses",
    }
    """Yalta et al. (2016): ELU, 500 units, its own outputs fed back, MSE, Adam 1e-4, sequences of
    150, batches of 50, 10 epochs, gradient noise (eta 0.01 from the authors' later code, gamma
    0.55 Neelakantan et al.'s)."""
    resets = True  # free runs can zero the LSTM states every training sequence
    streams = True
    engines = {"torch": ("float32", "float16"), "onnxruntime": ("float32",)}
    exports = ("torchscript", "onnx")
    run_exports = {"stream.ts": "torchscript"}  # the streaming LSTM for robots
    state_names = ("h1", "c1", "h2", "c2")
    sweep = YALTA_SWEEP
    runs_free_in_training = True

    @property
    def network_type(self) -> type:
        from kinectdata.models.yalta import YaltaNet

        return YaltaNet

    def check_dataset(self, manifest: dict[str, Any]) -> None:
        shape = list(manifest["feature_shape"])
        if len(shape) != 3 or shape[1:] != [129, 5]:
            raise ConfigError(f"the yalta model takes STFT inputs [1, 129, 5]; this dataset's are {shape}")

    def network_config(self, settings: YaltaSettings, manifest: dict[str, Any]) -> dict[str, Any]:
        from kinectdata.models.yalta import YaltaConfig

        return YaltaConfig(
            output_dim=manifest["target_dim"],
            units=settings.units,
            activation=settings.activation,
            input_shape=tuple(manifest["feature_shape"]),
            inputs=settings.inputs,
            side_channels=_side_planes(manifest) if settings.style_path == "lstm" else 0,
            **settings.phrase_config(manifest),
        ).to_dict()

    def build(self, config: dict[str, Any]):
        from kinectdata.models.yalta import YaltaConfig, YaltaNet

        return YaltaNet(YaltaConfig.from_dict(config))

    def predict(self, net, audio, previous, settings: YaltaSettings, context: int = 0):
        """[B, L - context, D] from a batch: ``previous`` [B, L, D] the true poses before each frame
        (the LSTMs' state carries the context: every frame is stepped; a phrase code is inferred
        from them)."""
        posterior = settings.latent_dims > 0
        return net(audio, previous, settings.feedback, posterior=posterior)[:, context:]

    def predict_free(self, net, audio, previous, settings: YaltaSettings, context: int = 0):
        """The configured feedback's poses and the free run, on one pass of the audio path."""
        posterior = settings.latent_dims > 0
        if settings.feedback == "predicted":  # its training already runs free
            poses = net(audio, previous, "predicted", posterior=posterior)[:, context:]
            return poses, poses
        poses, free = net(audio, previous, "teacher", free=True, posterior=posterior)
        return poses[:, context:], free[:, context:]

    def loss(self, net, pred, pose, mask, settings: YaltaSettings):
        """MSE (and the velocity term), and a phrase code's KL term from the last :meth:`predict`."""
        loss = masked_mse(pred, pose, mask)
        if settings.velocity_weight > 0:
            loss = loss + settings.velocity_weight * masked_velocity_mse(pred, pose, mask)
        return settings.with_kl(loss, net)

    def free_batch(self, net, audio, previous, pred, settings: YaltaSettings) -> np.ndarray:
        """Predicted feedback already runs free in training: its predictions are the free run."""
        free = pred if settings.feedback == "predicted" else net(audio, previous[:, 0], "predicted")
        return free.cpu().numpy()

    def init_output(self, net, start_pose: list[float]) -> None:
        import torch

        with torch.no_grad():  # outputs start at the mean pose, not 0: maxabs targets are far from centred
            net.fc2.bias.copy_(torch.tensor(start_pose))

    def takes_draws(self, config) -> bool:
        return _has_phrase_code(config)

    def free_run(self, net, audio: np.ndarray, first_pose: np.ndarray, reset_every: int | None = None, draw: int = 0):
        from kinectdata.models.yalta import free_run

        return free_run(net, audio, first_pose, reset_every, draw)

    def free_runs(self, net, audios, first_poses, reset_every: int | None = None, draws: list[int] | None = None):
        from kinectdata.models.yalta import free_runs

        return in_run_batches(lambda a, p, *d: free_runs(net, a, p, reset_every, *d), audios, first_poses, draws)

    def stream(self, net, precision: str = "float32", draw: int = 0):
        from kinectdata.models.yalta import PhrasedStreamingYalta, StreamingYalta

        if getattr(net, "phrase_code", None) is not None:
            return PhrasedStreamingYalta(net.eval(), precision, draw)
        return StreamingYalta(net.eval(), precision)

    def stream_state_names(self, config):
        """The LSTMs' states, and a phrase code's frame count."""
        return (*self.state_names, *(("phrase_frame",) if _has_phrase_code(config) else ()))

    def example_frame(self, net):
        import torch

        return torch.zeros(*net.config.input_shape), torch.zeros(net.config.output_dim)

    def export_metadata(self, config: dict[str, Any]) -> dict[str, Any]:
        return {
            "model": "yalta2016",
            "inputs": {
                "features": list(config["input_shape"]),
                **{name: [3, config["units"]] for name in self.state_names},
                **({"phrase_frame": [1]} if _has_phrase_code(config) else {}),
            },
            "activation": config["activation"],
            "units": config["units"],
            **_phrase_metadata(config),
        }

    def describe(self, settings: YaltaSettings) -> str:
        return f"{settings.units} units, {settings.activation}, {settings.feedback} feedback"

    def loss_name(self, settings: YaltaSettings) -> str:
        velocity = f" + {settings.velocity_weight:g} x velocity MSE" if settings.velocity_weight else ""
        return f"mean squared error (normalised targets){velocity}"


@dataclass(frozen=True)
class CdhcSettings(PhraseCodeSettings):
    """The cdhc model's settings (defaults: the recipe for real dance, 128 channels, no dropout;
    the paper's widths and DC-TTS's dropout with ``--paper``).

    No dropout by default: with it, the free run the rhythm loss trains on moved by the dropout's
    noise alone (on tang2018 at 0.46 x the real energy in training mode, 1e-10 x in evaluation
    mode: docs/notebook/2026-11-real-dance.md)."""

    channels: int = field(default=128, metadata={"help": "width of the audio and skeleton encoders.", "min": 1})
    decoder_channels: int = field(default=128, metadata={"help": "width of the fused code and the decoder.", "min": 1})
    dropout: float = field(
        default=0.0,
        metadata={"help": "dropout after each highway block (the paper's 0.05).", "min": 0, "max": 1, "max_open": True},
    )
    limb_weight: float = field(
        default=1.0, metadata={"help": "weight of the limb-length loss added to the L1 loss.", "min": 0}
    )
    velocity_weight: float = field(
        default=0.0,
        metadata={
            "help": "weight of an L1 loss on the frame-to-frame changes added to the loss (0: the paper's).",
            "min": 0,
        },
    )
    predicts: str = field(
        default="change",
        metadata={
            "help": "on normalised targets, the decoder predicts each pose (the paper's) or its change from the "
            "previous pose (a residual output: the paper's stays at the mean pose on real dance).",
            "choices": PREDICTS,
        },
    )
    inputs: str = _inputs_field("music")
    leak: float = field(
        default=0.05,
        metadata={
            "help": "with --predicts change: the share of the previous pose's distance from the mean training pose "
            "taken back every frame (0: a pure sum of changes, which drifts off the body over a song).",
            "min": 0,
            "max": 1,
        },
    )

    def __post_init__(self) -> None:
        if not 0 <= self.leak <= 1:
            raise ConfigError(f"leak must be in 0..1, not {self.leak}")
        check_inputs(self.inputs)
        if self.predicts not in PREDICTS:
            raise ConfigError(f"predicts must be one of {', '.join(PREDICTS)}, not {self.predicts!r}")
        if min(self.channels, self.decoder_channels) < 1 or not 0 <= self.dropout < 1 or self.limb_weight < 0:
            raise ConfigError("channels must be positive, dropout in [0, 1) and limb_weight at least 0")
        if not self.velocity_weight >= 0:
            raise ConfigError("velocity_weight must be at least 0")
        super().__post_init__()


class CdhcKind(ModelKind):
    """Lee et al. (2018), "Listen to Dance"."""

    name = "cdhc"
    description = "the CDHC encoder-decoder of Lee et al. (2018)"
    settings_type = CdhcSettings
    # ~8 times the yalta model's steps per epoch on a CPU: its kept epochs in 25 minutes were 13-38.
    # The jitter term: from the music alone its motion jittered at 3.4-5.9 x the real dancers' jerk on
    # held-out dances, 1.8-4.6 x with it (pooled over three folds 2.07 x -> 1.06 x:
    # docs/notebook/2026-11-real-dance.md).
    # The bones' jitter term: its spine jumped in length between frames where the real dancers' did not,
    # and the peers' geometric features (FID_g) strayed with it (docs/notebook/2026-11-real-dance.md).
    # The periodogram term: with it the model's period followed the song's tempo and its music (goals
    # b and c) in all four fold runs, without it in 3 and 2 of 4 (docs/notebook/2026-11-real-dance.md).
    # Facing one way and the draws by metre: its body kept its width under the drawn turning (the
    # turning 15 % -> 37 % of the energy) and the Latin songs their style; with them it met every goal
    # the folds score on fold 1 and goals b and e on fold 2, where the defaults without them met none
    # (docs/notebook/2026-12-real-dance-variety.md).
    # The slow motion's speed, the weights averaged and the energy in the keep rule: it moved at two
    # thirds of the dancers' energy with the jerk and the feet within bounds on folds 1 and 2; twice
    # the jitter term took back the jerk the style input brought (2.63 x -> 1.93 x on fold 1), with
    # goals b, c and e met there (docs/notebook/2026-12-real-dance-variety.md).
    # The spans term: a seed bent its right knee under 110 degrees in half its frames, and every
    # held-out dance was named a cha-cha; with it that seed met goals b, c and e on fold 1
    # (docs/notebook/2026-12-real-dance-variety.md).
    # The 6 Hz low-pass: its free-running motion shook at 2.02-2.31 x the dancers' jerk on two fold runs
    # that met every other goal but the listening; low-passed, 1.32-1.56 x, with no other goal moved
    # (docs/notebook/2026-12-real-dance-variety.md).
    training_defaults = {
        **REAL_DANCE_LOOP,
        "epochs": 40,
        "low_energy_weight": 2.0,
        "weight_average": 0.995,
        "keep_energy_weight": 0.5,
        "jitter_weight": 2.0,
        "bone_jitter_weight": 1.0,
        "span_weight": 10.0,
        "periodogram_weight": 1.0,
        "facing": True,
        "by_metre": True,
        "smooth_hz": 6.0,
        "style_tempo": 0.08,
    }
    paper = {
        **PAPER_LOOP,
        "channels": 256,
        "decoder_channels": 128,
        "dropout": 0.05,
        "velocity_weight": 0.0,
        "predicts": "pose",
        "inputs": "music-and-poses",
        "sequence": 300,
        "batch_size": 16,
        "epochs": 20,
        "lr": 2e-4,
        "noise_eta": 0.0,
        "clip_norm": 1.0,
    }
    """The paper gives no schedule; these follow DC-TTS, whose blocks it uses (Adam 2e-4, gradient
    norm clipped to 1), with 10 s sequences (longer than the 265-frame receptive field), no
    gradient noise, teacher forcing and the paper's widths (256 channels, a 128-channel decoder);
    the rest is Yalta et al.'s loop (:data:`PAPER_LOOP`): no context before each window, no weights
    averaged, no drawn turning or low-pass, the last epoch kept."""
    resets = False  # no state to reset: the receptive field is fixed
    streams = True
    engines = {"torch": ("float32",), "onnxruntime": ("float32",)}
    exports = ("onnx",)  # its stream carries one cache per block: TorchScript's scripting takes no such list
    runs_free_in_training = True

    def stream_state_names(self, config):
        """One cache per highway block, [1, channels, (k - 1) x dilation] (its last inputs): the audio
        encoder's, the skeleton encoder's, the decoder's."""
        return tuple(name for name, _ in _cdhc_caches(config))

    def export_metadata(self, config: dict[str, Any]) -> dict[str, Any]:
        from kinectdata.models.cdhc import CdhcConfig

        net = CdhcConfig.from_dict(config)
        return {
            "model": "cdhc",
            "inputs": dict(_cdhc_caches(config)),
            "receptive_field_frames": net.receptive_field,
            "output": net.output,
            # the state at a song's start: zeros, then this many frames of zero features stepped through
            "start_silence_frames": net.start_silence,
            **_phrase_metadata(config),
        }

    @property
    def network_type(self) -> type:
        from kinectdata.models.cdhc import CdhcNet

        return CdhcNet

    def check_dataset(self, manifest: dict[str, Any]) -> None:
        from kinectdata.targets.specs import TargetSpec

        shape = list(manifest["feature_shape"])
        if len(shape) != 1:
            raise ConfigError(
                f"the cdhc model takes per-frame feature vectors [F] (mel bands); this dataset's are {shape}"
            )
        spec = TargetSpec.from_dict(manifest["config"]["target"])
        if spec.orientations:
            raise ConfigError(f"the cdhc model regresses coordinates and limb lengths; {spec.name} has quaternions")
        method = manifest["normalisation"]["method"]
        if method == "none" and spec.position_scale != "recording_minmax":
            raise ConfigError(
                "the cdhc model's output covers 0..1 for targets left unnormalised (the paper's per-video min-max "
                f"coordinates, position_scale recording_minmax) or -0.9..0.9 for normalised ones (maxabs, minmax); "
                f"this dataset's are {spec.position_scale} and {method}"
            )
        if manifest["config"].get("root_centre") and spec.limbs and spec.root in spec.positions:
            raise ConfigError(
                "the cdhc model's limb loss measures limbs between its output coordinates; root-centred "
                "coordinates put the root in another frame of reference than its children: build without --root-centre"
            )

    def network_config(self, settings: CdhcSettings, manifest: dict[str, Any]) -> dict[str, Any]:
        from kinectdata.models.cdhc import CdhcConfig
        from kinectdata.targets.specs import TargetSpec

        spec = TargetSpec.from_dict(manifest["config"]["target"])
        index = {j: i for i, j in enumerate(spec.positions)}
        if manifest["normalisation"]["method"] == "none":
            output = "sigmoid"
        elif settings.inputs == "music":
            output = "linear"
        else:
            output = "residual" if settings.predicts == "change" else "linear"
        return CdhcConfig(
            output_dim=manifest["target_dim"],
            input_dim=manifest["feature_shape"][0],
            channels=settings.channels,
            decoder_channels=settings.decoder_channels,
            dropout=settings.dropout,
            coordinates=spec.dimensions * len(spec.positions),
            joint_dims=spec.dimensions,
            limbs=tuple((index[j], index[p]) for j, p in spec.limb_pairs()),
            output=output,
            leak=settings.leak if output == "residual" else 0.0,
            inputs=settings.inputs,
            **settings.phrase_config(manifest),
        ).to_dict()

    def build(self, config: dict[str, Any]):
        from kinectdata.models.cdhc import CdhcConfig, CdhcNet

        return CdhcNet(CdhcConfig.from_dict(config))

    def context_frames(self, config: dict[str, Any]) -> int:
        """The receptive field but the output's own frame (264 at the default sizes)."""
        from kinectdata.models.cdhc import CdhcConfig

        return CdhcConfig.from_dict(config).receptive_field - 1

    def with_song_starts(self, config: dict[str, Any], lead: int) -> dict[str, Any]:
        """A music-only network generates each song after the ``lead`` frames of silence its
        training windows had before it (``start_silence``): without them its first second burst at
        2-19 x the real dancers' speed on the folds (docs/notebook/2026-11-real-dance.md). A network fed its own
        poses starts as before."""
        return {**config, "start_silence": lead} if config.get("inputs") == "music" else config

    def fill_previous(self, previous, mask, start_pose):
        """Masked previous values (stored as 0, a real coordinate in 0..1) become the mean training
        pose's, so teacher forcing never shows a joint jumping to the image's corner."""
        if isinstance(previous, np.ndarray):
            return np.where(mask, previous, np.asarray(start_pose, dtype=previous.dtype))
        import torch

        start = torch.as_tensor(start_pose, dtype=previous.dtype, device=previous.device)
        return torch.where(mask, previous, start)

    def predict(self, net, audio, previous, settings: CdhcSettings, context: int = 0):
        """Teacher forcing (the true pose of each previous frame); the context's frames computed
        only as far as later frames read them. A phrase code is inferred from the true poses."""
        return net(audio, previous, skip=context, posterior=True)

    def predict_free(self, net, audio, previous, settings: CdhcSettings, context: int = 0):
        return net(audio, previous, free=True, skip=context, posterior=True)

    def loss(self, net, pred, pose, mask, settings: CdhcSettings):
        """The L1 and limb loss (and the velocity term), and a phrase code's KL term from the last
        :meth:`predict` (kept on the network)."""
        from kinectdata.models.cdhc import cdhc_loss

        loss = cdhc_loss(pred, pose, mask, net.config, settings.limb_weight)[0]
        if settings.velocity_weight > 0:
            loss = loss + settings.velocity_weight * masked_velocity_l1(pred, pose, mask)
        return settings.with_kl(loss, net)

    def init_output(self, net, start_pose: list[float]) -> None:
        from kinectdata.models.cdhc import init_output_bias

        init_output_bias(net, np.asarray(start_pose))

    def takes_draws(self, config) -> bool:
        return _has_phrase_code(config)

    def free_run(self, net, audio: np.ndarray, first_pose: np.ndarray, reset_every: int | None = None, draw: int = 0):
        """Poses [T-1, D] of frames 1..T-1 from the audio of those frames, starting from the true
        pose of frame 0 (``reset_every`` does not apply); a phrase code drawn from row ``draw`` on."""
        from kinectdata.models.cdhc import generate

        return generate(net, audio[1:], first_pose, draw)

    def free_runs(self, net, audios, first_poses, reset_every: int | None = None, draws: list[int] | None = None):
        from kinectdata.models.cdhc import generate_many

        return in_run_batches(
            lambda a, p, *d: generate_many(net, [x[1:] for x in a], p, *d), audios, first_poses, draws
        )

    def stream(self, net, precision: str = "float32", draw: int = 0):
        from kinectdata.models.cdhc import FrameCdhc

        if precision != "float32":
            raise ConfigError(f"the cdhc model streams float32 weights only, not {precision}")
        return FrameCdhc(net, draw)

    def example_frame(self, net):
        import torch

        return torch.zeros(net.config.input_dim), torch.zeros(net.config.output_dim)

    def describe(self, settings: CdhcSettings) -> str:
        return f"cdhc, {settings.channels}/{settings.decoder_channels} channels, L1 + {settings.limb_weight:g} limb"

    def loss_name(self, settings: CdhcSettings) -> str:
        velocity = f" + {settings.velocity_weight:g} x velocity L1" if settings.velocity_weight else ""
        return f"L1 + {settings.limb_weight:g} x limb-length L1{velocity} (0..1 targets)"


def _cdhc_caches(config: Mapping[str, Any]) -> list[tuple[str, list[int]]]:
    """(name, shape) of each cache of the cdhc stream, in :class:`~kinectdata.models.cdhc.FrameCdhc`'s order."""
    from kinectdata.models.cdhc import CdhcConfig

    net = CdhcConfig.from_dict(dict(config))
    k = net.kernel_size - 1
    parts = (
        ("audio", net.channels, net.encoder_dilations),
        ("skeleton", net.channels, net.encoder_dilations),
        ("decoder", net.decoder_channels, net.decoder_dilations),
    )
    caches = [(f"{part}{i}", [1, width, k * d]) for part, width, dilations in parts for i, d in enumerate(dilations)]
    return caches + ([("phrase_frame", [1])] if net.latent_dims else [])


def _has_phrase_code(config: Mapping[str, Any]) -> bool:
    """Whether a network config (either model's) has a phrase code (``--latent-dims``): then its
    kind takes draws, and its stream carries the frame count ``phrase_frame``."""
    return bool(config.get("latent_dims"))


def _phrase_metadata(config: Mapping[str, Any]) -> dict[str, Any]:
    """What a program stepping an exported stream with a phrase code needs to know of it: the state
    ``phrase_frame`` starts at draw x ``phrase_frames`` (draw 0: 0) and the stream returns it one
    more every frame; phrase i takes row (draw + i) mod ``latent_draws`` of the table in the file."""
    if not _has_phrase_code(config):
        return {}
    return {
        "phrase_code": {
            "phrase_frames": config["phrase_frames"],
            "latent_draws": config.get("latent_draws", 64),
            "start": "phrase_frame = draw x phrase_frames; the stream returns it plus one",
        }
    }
