"""What a model declares so that training, evaluation, generation, export and the sweep stay one
loop each: the :class:`ModelKind` protocol.

A kind is one object per model (registered with :func:`kinectdata.models.registry.register_model`).
It says:

- **who it is**: ``name`` (the ``--model`` choice, ``config.json``'s ``train.model``) and a
  one-line ``description``;
- **its settings**: ``settings_type``, a frozen dataclass of the model's own settings with the
  model's defaults; its ``__post_init__`` raises :class:`~kinectdata.core.errors.ConfigError` for
  a bad value. Field metadata ``help``, ``choices``, ``min``/``max`` (with ``min_open``/
  ``max_open``) describe the setting for the command line. ``training_defaults`` are the training
  loop's settings (``sequence``, ``batch_size``, ``epochs``, ``lr``, ...) where this model's
  differ from :class:`kinectdata.training.config.TrainConfig`'s base defaults; ``paper``, the
  published settings, the loop's and the model's (``train-baseline --paper``), over the loop's
  base defaults, not over ``training_defaults`` (what it does not name is the base's);
- **what it needs of a dataset**: :meth:`ModelKind.check_dataset` raises ConfigError with the
  reason (feature shape, target layout, normalisation); the registry adds the dataset's name and
  which ``--model`` or ``--pipeline`` to use;
- **its network**: :meth:`network_config` (JSON-able, kept in ``config.json``), :meth:`build`,
  ``network_type`` (the class :meth:`build` returns), :meth:`init_output` (the output layer
  starting at the mean pose);
- **training**: :meth:`fill_previous` (what a masked previous pose becomes), :meth:`predict` (a
  training batch through the network: its feedback), :meth:`predict_free` (that and the network's
  own free run through the window, for kinds with ``runs_free_in_training``), :meth:`loss`, :meth:`free_batch` (a
  validation batch free-running), :meth:`describe` and :meth:`loss_name` (the loss figure's
  title and axis);
- **running free**: :meth:`free_run` over a whole recording, given its first true pose (:meth:`free_runs`
  over several at once);
  ``resets`` says whether it can zero a state every training sequence (evaluation's "with reset");
- **draws**: :meth:`takes_draws` says whether a network of a configuration draws something in
  generation (a phrase code, :mod:`kinectdata.models.latent`): then :meth:`free_run`,
  :meth:`free_runs` and :meth:`stream` take which draw (``draw``, ``draws``: ``generate``'s and
  ``live``'s ``--seed``), and another draw makes another dance to the same music;
- **streaming**: ``streams`` says whether it has a network stepping one frame at a time with
  its state passed in and out (:meth:`stream`, the :class:`Stream` contract); ``engines`` maps the
  inference engines that run that stream (``torch``, ``onnxruntime``) to their weight precisions;
  ``exports`` the file formats it writes it as (``torchscript``, ``onnx``), ``state_names``
  naming the state tensors in those files, :meth:`export_metadata` what it adds to their
  metadata, and ``run_exports`` the files training writes into the run folder at the end (file
  name -> format);
- **the sweep**: ``sweep``, the variants of a published table (:class:`Sweep`), or None.

Tensors: audio features ``[B, L, *F]`` (``F`` the dataset's ``feature_shape``), poses and masks
``[B, L, D]`` (``D`` the target's size) with ``previous[:, t]`` the pose of frame t-1; numpy
recordings ``[T, *F]`` and ``[T, D]``. Subclassing :class:`ModelKind` inherits the defaults below
(no state to reset, no stream, nothing exported, no sweep).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from kinectdata.core.errors import ConfigError
from kinectdata.models.losses import rhythm_weight_settings

PAPER_LOOP: dict[str, Any] = {
    "sequence": 150,
    "stride": None,
    "batch_size": 50,
    "epochs": 10,
    "lr": 1e-4,
    "noise_eta": 0.01,
    "noise_gamma": 0.55,
    "clip_norm": None,
    "free_weight": 0.0,
    **dict.fromkeys(rhythm_weight_settings(), 0.0),
    "keep_energy_weight": 0.0,
    "song_starts": False,
    "turning": False,
    "travel": False,
    "facing": False,
    "by_metre": False,
    "component_floor": False,
    "sway": False,
    "smooth_hz": None,
    "style_tempo": None,
    "silence_share": 0.0,
    "keep": "last",
    "context": 0,
    "precision": "float32",
}
"""Yalta et al.'s training loop: sequences of 150 (not overlapping), batches of 50, 10 epochs, Adam
1e-4, annealed gradient noise, the teacher-forced (or fed-back) loss alone, the last epoch kept;
the base of every model's loop settings (``TrainConfig``'s ``LOOP_DEFAULTS``)."""


INPUTS = ("music-and-poses", "music")
"""What a bundled model's decoder is given (its ``inputs`` setting): the music and the previous
poses (the papers') or the music only."""


def check_inputs(inputs: str, prefix: str = "") -> None:
    """Raise :class:`ConfigError` unless ``inputs`` is one of :data:`INPUTS` (``prefix`` starts the message)."""
    if inputs not in INPUTS:
        raise ConfigError(f"{prefix}inputs must be one of {', '.join(INPUTS)}, not {inputs!r}")


@dataclass(frozen=True)
class Sweep:
    """A published table that ``kinectdata sweep`` reproduces for a model.

    Attributes:
        title: what the table is (e.g. "Yalta et al. (2016) Tables 3-5").
        base: the settings every variant starts from (training loop or model settings).
        variants: variant name -> the settings it changes from ``base``.
        paper: variant name -> the published figures: SMAPE % without reset, with reset, training
            minutes, forward ms per frame (a variant without figures is left out).
        paper_note: where the published figures come from (hardware, data).
        shown: the model settings the table's title names with their values (the same in every variant).
    """

    title: str
    base: Mapping[str, Any]
    variants: Mapping[str, Mapping[str, Any]]
    paper: Mapping[str, tuple[float, float, float, float]] = field(default_factory=dict)
    paper_note: str = ""
    shown: tuple[str, ...] = ()


class Stream(Protocol):
    """A network one frame at a time, its state passed in and out (an ``nn.Module``).

    ``initial_state()`` gives the state at the start (a tuple of tensors); ``forward(features [*F],
    previous [D], *state)`` returns ``(pose [D], *new state)``. One unbatched frame per call."""

    def initial_state(self) -> tuple[Any, ...]: ...

    def __call__(self, features: Any, previous: Any, *state: Any) -> tuple[Any, ...]: ...


def run_batches(lengths: list[int], max_frames: int = 20_000, max_batch: int = 32) -> list[list[int]]:
    """Indices of recordings grouped to run free together: similar lengths together (little
    padding), at most ``max_batch`` per group and, past the first, at most ``max_frames`` padded
    frames (batch x longest), so that memory stays bounded whatever the split holds."""
    groups: list[list[int]] = []
    for i in sorted(range(len(lengths)), key=lambda k: lengths[k]):
        group = groups[-1] if groups else None
        if group is not None and len(group) < max_batch and (len(group) + 1) * lengths[i] <= max_frames:
            group.append(i)
        else:
            groups.append([i])
    return groups


def in_run_batches(run: Callable[..., list], audios: list, first_poses: list, draws: list[int] | None = None) -> list:
    """``run(audios, first_poses) -> outputs`` (a network stepping recordings as one batch) over
    :func:`run_batches` groups; the outputs in the order given. With ``draws`` (one per recording),
    ``run(audios, first_poses, draws)``."""
    out: list[Any] = [None] * len(audios)
    for group in run_batches([len(a) for a in audios]):
        given = [[audios[i] for i in group], [first_poses[i] for i in group]]
        for i, result in zip(group, run(*given, *([] if draws is None else [[draws[i] for i in group]]))):
            out[i] = result
    return out


@runtime_checkable
class ModelKind(Protocol):
    """A model as training, evaluation, generation and export see it (see the module docstring)."""

    name: str
    description: str = ""
    settings_type: type
    training_defaults: Mapping[str, Any] = {}
    resets: bool = False
    streams: bool = False
    engines: Mapping[str, tuple[str, ...]] = {}
    exports: tuple[str, ...] = ()
    run_exports: Mapping[str, str] = {}
    state_names: tuple[str, ...] = ()
    sweep: Sweep | None = None
    runs_free_in_training: bool = False
    paper: Mapping[str, Any] = {}

    @property
    def network_type(self) -> type:
        """The class of the networks :meth:`build` returns."""
        raise NotImplementedError(f"the {self.name} model does not define network_type")

    def check_dataset(self, manifest: dict[str, Any]) -> None:
        """ConfigError saying why a dataset (its manifest) does not fit the model; None if it does."""

    def network_config(self, settings: Any, manifest: dict[str, Any]) -> dict[str, Any]:
        """The network's configuration (JSON-able) from the model's settings and the dataset's manifest."""
        raise NotImplementedError(f"the {self.name} model does not define network_config")

    def build(self, config: dict[str, Any]) -> Any:
        """A network (``nn.Module``) from :meth:`network_config`'s dict, at its initial weights."""
        raise NotImplementedError(f"the {self.name} model does not define build")

    def context_frames(self, config: dict[str, Any]) -> int:
        """Frames before an output that it depends on, for a network of :meth:`network_config`'s
        ``config`` (default 0: a recurrent network's state carries everything). Training windows
        get this many frames of real input before the frames their losses count
        (``TrainConfig.context``): without them every output near a window's start sees the zero
        padding of its left edge, which a network can read as a clock."""
        return 0

    def with_song_starts(self, config: dict[str, Any], lead: int) -> dict[str, Any]:
        """The network config of a run whose training windows also start up to ``lead`` frames
        before their songs, silence there (``TrainConfig.song_starts``): a kind whose generation
        should hear that silence before each song records it here (default: unchanged)."""
        return config

    def fill_previous(self, previous: Any, mask: Any, start_pose: Any) -> Any:
        """What masked previous poses become, ``[..., D]`` tensors or arrays (default: as stored)."""
        return previous

    def predict(self, net: Any, audio: Any, previous: Any, settings: Any, context: int = 0) -> Any:
        """Poses ``[B, L - context, D]`` of frames ``context``.. of a training batch: ``audio [B, L,
        *F]``, ``previous [B, L, D]`` (the true poses before each frame), the first ``context``
        frames input only (``TrainConfig.context``: a kind may skip work for them); ``net`` may be
        wrapped in DistributedDataParallel."""
        raise NotImplementedError(f"the {self.name} model does not define predict")

    def predict_free(self, net: Any, audio: Any, previous: Any, settings: Any, context: int = 0) -> tuple[Any, Any]:
        """``(poses, free poses)`` of frames ``context``.. of a training batch: :meth:`predict`'s
        poses and the network running on its own outputs through the window from ``previous[:,
        0]``, differentiable (the free-running rhythm loss: ``TrainConfig.free_weight``). Only for
        kinds with ``runs_free_in_training``."""
        raise NotImplementedError(f"the {self.name} model does not run free in training")

    def loss(self, net: Any, pred: Any, pose: Any, mask: Any, settings: Any) -> Any:
        """The scalar training loss of predictions against the true poses, over ``mask``'s valid values."""
        raise NotImplementedError(f"the {self.name} model does not define loss")

    def free_batch(self, net: Any, audio: Any, previous: Any, pred: Any, settings: Any) -> np.ndarray:
        """Poses ``[B, L, D]`` free-running over each window of a validation batch from its first
        previous pose (``pred``: :meth:`predict`'s, for models whose training already runs free).
        Default: :meth:`free_runs` over the windows."""
        windows, previous = audio.cpu().numpy(), previous.cpu().numpy()
        return np.stack(self.free_runs(net, [np.concatenate([a[:1], a]) for a in windows], [p[0] for p in previous]))

    def init_output(self, net: Any, start_pose: list[float]) -> None:
        """Start the output layer at the mean training pose ``[D]`` (default: leave it)."""

    def takes_draws(self, config: Mapping[str, Any]) -> bool:
        """Whether a network of this configuration draws in generation (then :meth:`free_run`,
        :meth:`free_runs` and :meth:`stream` take ``draw``/``draws``, from row 0 without them).
        Default: no, and those methods take no draw."""
        return False

    def free_run(self, net: Any, audio: np.ndarray, first_pose: np.ndarray, reset_every: int | None = None) -> Any:
        """Poses ``[T-1, D]`` (numpy) for frames 1..T-1 of features ``[T, *F]``, starting from the
        pose ``[D]`` of frame 0 and then fed the model's own outputs; with ``reset_every`` = L (only
        for models that reset) the state is zeroed every L frames."""
        raise NotImplementedError(f"the {self.name} model does not define free_run")

    def free_runs(
        self, net: Any, audios: list[np.ndarray], first_poses: list[np.ndarray], reset_every: int | None = None
    ) -> list[np.ndarray]:
        """:meth:`free_run` for several recordings (``audios[i]`` [T_i, *F], ``first_poses[i]``
        [D]) -> per recording [T_i - 1, D]. Default: one after the other; a model whose network
        steps a batch about as fast as one recording runs them together (:func:`in_run_batches`)."""
        return [self.free_run(net, a, p, reset_every) for a, p in zip(audios, first_poses)]

    def stream(self, net: Any, precision: str = "float32") -> Stream:
        """The network one frame at a time (:class:`Stream`) with weights of ``precision``."""
        raise NotImplementedError(f"the {self.name} model does not stream")

    def example_frame(self, net: Any) -> tuple[Any, Any]:
        """Zero features ``[*F]`` and a zero pose ``[D]`` (tensors) to trace the stream with (export)."""
        raise NotImplementedError(f"the {self.name} model does not stream")

    def stream_state_names(self, config: Mapping[str, Any]) -> tuple[str, ...]:
        """The names of the stream's state tensors for a network configuration (default: the
        kind's ``state_names``; a model whose state depends on its configuration overrides this)."""
        return tuple(self.state_names)

    def export_metadata(self, config: dict[str, Any]) -> dict[str, Any]:
        """What the model adds to an exported file's metadata, from its network configuration
        (an ``inputs`` entry is merged into the inputs' shapes)."""
        return {}

    def describe(self, settings: Any) -> str:
        """A few words on the settings, for the loss figure's title."""
        return self.name

    def loss_name(self, settings: Any) -> str:
        """The loss and its units, for the loss figure's axis."""
        return "training loss"
