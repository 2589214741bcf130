"""Training settings: :class:`TrainConfig`, the training loop's settings and the model's own.

The loop's settings (:data:`LOOP_DEFAULTS`) are the same for every model; each model
(:class:`~kinectdata.models.kind.ModelKind`) changes their defaults (``training_defaults``) and
brings its own settings (``settings_type``, e.g. the yalta model's ``units``, ``activation``,
``feedback``; the cdhc model's ``channels``, ``decoder_channels``, ``dropout``, ``limb_weight``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from kinectdata.core.errors import ConfigError, KinectDataError
from kinectdata.dataset.layout import BALANCE_FIELDS
from kinectdata.models.kind import PAPER_LOOP
from kinectdata.models.losses import RhythmWeights, rhythm_weight_settings
from kinectdata.models.registry import DEFAULT_MODEL, make_settings, model_kind

LOOP_DEFAULTS: dict[str, Any] = {
    **PAPER_LOOP,
    "seed": 0,
    "device": "auto",
    "max_minutes": None,
    "previous_noise": 0.0,
    "balance": None,
    "weight_average": 0.0,
    "mirror_share": 0.0,
    "turning": True,
    "travel": True,
    # the body's terms of the free-running loss, in it before they were settings (RhythmWeights)
    "bone_weight": 10.0,
    "world_speed_weight": 1.0,
    "foot_weight": 10.0,
}
"""The training loop's settings and their base defaults (Yalta et al.'s; a model's
``training_defaults`` change them)."""

KEEPS = ("last", "best")
PRECISIONS = ("float32", "bfloat16")
ADDED_OFF = {
    "free_weight": 0.0,
    "silence_share": 0.0,
    "keep": "last",
    "predicts": "pose",
    "style_path": "convs",
    "inputs": "music-and-poses",
    **dict.fromkeys(rhythm_weight_settings(), 0.0),
    "posture_weight": 10.0,  # the posture term was always on; its weight was 10 before it was a setting
    "bone_weight": 10.0,  # so were the bone, world speed and foot terms, at these weights
    "world_speed_weight": 1.0,
    "foot_weight": 10.0,
    "keep_energy_weight": 0.0,
    "song_starts": False,
    "context": 0,
    "balance": None,
    "weight_average": 0.0,
    "mirror_share": 0.0,
    "turning": False,
    "travel": False,
    "facing": False,
    "by_metre": False,
    "component_floor": False,
    "sway": False,
    "smooth_hz": None,
    "style_tempo": None,
    "precision": "float32",
}
"""Loop (and model) settings added after runs were written: a run's config.json without them trained without
them, whatever today's defaults are (resuming it goes on as it started)."""

FLAT_BEFORE = ("units", "activation", "feedback", "channels", "decoder_channels", "dropout", "limb_weight")
"""The model settings every run's ``config.json`` held side by side before each model had its own:
reading such a run keeps its model's and ignores the other model's."""


_WEIGHTS = ("free_weight", "keep_energy_weight", *rhythm_weight_settings())
"""The loop's loss weights: each at least 0."""
_SWITCHES = ("song_starts", "turning", "travel", "facing", "by_metre", "component_floor", "sway")
"""The loop's settings that are true or false."""


@dataclass(frozen=True, init=False)
class TrainConfig:
    """Training settings: the loop's and the model's own.

    ``TrainConfig(model, **settings)`` takes the loop's settings and the model's by name (flat, as
    ``config.json`` holds them); what is not given takes the model's default: the recipe that learns
    real dance on a CPU (docs/training.md, "Learning real dance"). ``paper=True`` starts from the
    model's published settings instead (its kind's ``paper`` over the base defaults, none of the
    recipe's additions). ``settings=`` may give
    the model's settings as a whole (an instance of its ``settings_type`` or a mapping).
    Attribute access reaches the model's settings too (``config.units`` for the yalta model).

    Attributes:
        model: a registered model (:mod:`kinectdata.models.registry`: ``yalta``, ``cdhc``, ...).
        settings: the model's own settings (its ``settings_type``, validated by it).
        sequence: frames per training sequence; stride: frames between sequence starts
            (default: ``sequence``, non-overlapping).
        batch_size: sequences per batch. epochs: passes over the training split.
        lr: Adam's learning rate.
        noise_eta, noise_gamma: annealed Gaussian gradient noise, variance eta / (1 + t)^gamma
            at step t (Neelakantan et al. 2015); eta 0 turns it off.
        clip_norm: clip the gradient's global norm to this before the noise (None: no clipping).
        seed: every random choice (initialisation, batch order, noise).
        device: ``auto`` (CUDA when present, else CPU), ``cpu`` or ``cuda``.
        previous_noise: standard deviation of Gaussian noise added in training to the true previous
            poses a model is fed (normalised units; teacher feedback), so that it cannot just copy
            them and must take the motion from the music (0: none, the papers' training).
        max_minutes: a time budget for training (None: none). When it runs out the current epoch
            ends at the step it reached, is validated and logged, and the run finishes as if its
            epochs were done (``model.pt`` and the exports written).
        free_weight: weight of the free-running rhythm loss (0: none): in every training window the
            model also runs on its own outputs from the window's first true pose, and the spectra of
            its motion's frame-to-frame changes and their overall size are matched to the real
            motion's (:func:`~kinectdata.models.losses.masked_rhythm_loss`): how much and how often
            it moves, not when. Models whose kind ``runs_free_in_training``.
        posture_weight: weight of the posture term in the free-running loss
            (:func:`~kinectdata.models.losses.masked_posture_loss`: each coordinate's mean and spread
            over the window against the real one's). The yalta model follows the songs at 3 and
            played one period for all at 10 (2 seeds of 3); the cdhc model from the music alone
            moves at 10 and stands still at 3 (docs/notebook/2026-11-real-dance.md). Runs written before it had 10.
        jitter_weight: weight of the jitter term in the free-running loss
            (:func:`~kinectdata.models.losses.masked_jitter_loss`: the motion's accelerations and jerks
            against the real ones', an excess costing in proportion). Runs written before it had none.
        periodogram_weight: weight of the whole-window periodogram in the free-running loss
            (:func:`~kinectdata.models.losses.masked_periodogram_loss`: where the motion's periods lie,
            resolved to a fraction of the multi-resolution spectra's bins). Runs written before it had none.
        bone_jitter_weight: weight of the bones' jitter in the free-running loss
            (:func:`~kinectdata.models.losses.masked_bone_jitter_loss`: how fast each bone's length
            changes from frame to frame against the real one's, an excess costing in proportion).
            Runs written before it had none.
        low_energy_weight: weight of the slow motion's speed in the free-running loss
            (:func:`~kinectdata.models.losses.masked_low_band_energy_loss`: the motion below about
            1.5 Hz against the real one's, per 2 s). Runs written before it had none.
        span_weight: weight of the joints' bends in the free-running loss
            (:func:`~kinectdata.models.losses.masked_span_loss`: the mean and spread of each two-bone
            chain's span, hip to ankle, shoulder to wrist, against the real one's, in proportion).
            Runs written before it had none.
        bend_weight: weight of the joints' angles in the free-running loss
            (:func:`~kinectdata.models.losses.masked_bend_loss`: the mean and spread of the angle at
            each two-bone chain's middle joint, the knee, the elbow, against the real one's, in
            radians). Runs written before it had none.
        repetition_weight: weight of how the motion repeats in the free-running loss
            (:func:`~kinectdata.models.losses.masked_repetition_loss`: the autocorrelation of the
            joints' heights at lags of 0.2-4.5 s against the real one's, whatever the phase: at one
            bar or at two). Runs written before it had none.
        world_excess_weight: weight of the joints' excess speed in the world in the free-running
            loss (:func:`~kinectdata.models.losses.masked_world_speed_loss` with ``excess``: each
            joint's speed along each world axis per 2 s against the real one's, faster costing in
            proportion; the world speed term itself costs slower more). Runs written before it had
            none.
        world_jitter_weight: weight of the joints' excess acceleration in the world in the
            free-running loss (:func:`~kinectdata.models.losses.masked_world_jitter_loss`: the
            jitter term on each joint's position along each world axis, the root's travel added
            back: a trunk swaying faster than the dancers'). Runs written before it had none.
        root_band_weight: weight of the root's speed along the floor by band in the free-running
            loss (:func:`~kinectdata.models.losses.masked_root_band_loss`: at 0.5-1, 1-2 and 2-4 Hz,
            in metres per second, against the real one's, whatever the phase: the root swaying at the
            bar's rate rather than the beat's). Runs written before it had none.
        root_rise_weight: weight of the root's vertical speed by band in the free-running loss
            (:func:`~kinectdata.models.losses.masked_root_rise_loss`: at 0.5-1, 1-2, 2-4 and 4-8 Hz,
            in metres per second, against the real one's, whatever the phase: a waltz's rise and
            fall). Runs written before it had none.
        root_phase_weight: weight of the root's rise and fall out of phase in the free-running loss
            (:func:`~kinectdata.models.losses.masked_root_phase_loss`: one minus the correlation of
            the root's vertical velocity with the real one's in each of the rise term's bands,
            whatever the size: rising and falling when the dancer did, to the same music). Runs
            written before it had none.
        step_weight: weight of the feet's speed about the root in the free-running loss
            (:func:`~kinectdata.models.losses.masked_step_loss`: each foot joint's speed along
            each axis about the root over the window against the real one's, slower costing in
            proportion: a body carried along the floor with its feet still glides). Runs written
            before it had none.
        bone_weight: weight of the bones' stretch in the free-running loss
            (:func:`~kinectdata.models.losses.masked_bone_loss`; 10, as runs written before it had).
        world_speed_weight: weight of the joints' speed in the world in the free-running loss
            (:func:`~kinectdata.models.losses.masked_world_speed_loss`, slower costing more; 1, as
            runs written before it had).
        foot_weight: weight of the feet's sliding in the free-running loss
            (:func:`~kinectdata.models.losses.masked_foot_loss`: EDGE's foot contact score against
            the real one's; 10, as runs written before it had).
        song_starts: also train on each song's first frames: windows whose ``context`` runs before
            the recording's first frame, silence there (audio zeros; no pose, masked:
            :class:`~kinectdata.dataset.windows.WindowDataset`'s ``lead``). Without them a model
            with a context never trains on the first ``context`` frames of a song, which it is
            asked for whenever it generates one; a kind that takes it (the cdhc model given the
            music only: ``ModelKind.with_song_starts``) then hears as much silence before every
            song it generates. Runs written before it had none.
        silence_share: share of training windows whose music is silenced from a random frame on,
            the pose then held (:mod:`kinectdata.training.augment`): a model learns to stop in silence.
        keep: which epoch ``model.pt`` (and the exports) hold: ``last``, or ``best``, the epoch whose
            free-running validation rhythm loss (``val_rhythm`` in ``log.csv``) is lowest among those
            whose validation songs, run whole, move at 0.5-2 x the real energy (``val_energy``:
            :class:`kinectdata.training.whole_songs.WholeSongs`), or among all while none does.
        keep_energy_weight: with ``keep`` ``best``, how much an epoch's energy counts beside its
            rhythm loss: the epoch kept is the one whose rhythm loss times
            ``exp(keep_energy_weight * |ln val_energy|)`` is lowest (0: the loss alone). The
            validation loss moves by 5-15 % from epoch to epoch; with 0 the keep rule picks the
            stillest of the alive epochs whose loss is about the lowest. Runs written before it had
            none.
        context: frames of real input before each training and validation window that no loss
            counts, so that the window's first outputs see music, not the zero padding of its edge
            (None: the model's own, ``ModelKind.context_frames``: the cdhc model's receptive field
            but one, 264 frames; the yalta model's 0). The windows read are ``sequence + context``
            frames long.
        balance: draw each epoch's training windows so that every group of them has the same share:
            by ``recording``, or by a fact about the music the recordings manifest gives
            (``style``, ``beats_per_bar``; :data:`~kinectdata.dataset.layout.BALANCE_FIELDS`). The
            windows are drawn with replacement, as many as there are; None (or one group): each
            window once per epoch, shuffled.
        weight_average: the decay per step of an exponential moving average of the weights (0:
            none): with it, validation, the kept epoch, ``model.pt`` and the exports use the
            averaged weights, ``1 / (1 - weight_average)`` steps long (0.995: 200 steps), the
            optimiser going on with its own. Runs written before it had none.
        mirror_share: share of training windows danced by their dancer's mirror image
            (:func:`~kinectdata.training.augment.mirror_windows`: the body reflected across x = 0,
            its left and right swapped by the joint set's names), to the same music; 0: none.
            Runs written before it had none.
        turning: fit the training dancers' turning about the vertical and keep it in the run, to be
            drawn wherever the run makes positions (:mod:`kinectdata.targets.turning`; 3-D position
            targets centred on their root only, else none is kept: ``evaluate`` and ``generate`` say
            which). The
            papers' settings (``paper``) draw none. Runs written before it had none.
        travel: fit the training dancers' travel across the floor and keep it in the run, to be drawn
            wherever the run makes positions (:mod:`kinectdata.targets.travel`; the same targets as
            ``turning``, else none is kept). The papers' settings draw none. Runs written before it
            had none.
        facing: train on poses turned about the vertical to face one way, frame by frame
            (:func:`~kinectdata.training.augment.facing_windows`), for a run that draws its turning: the
            network makes the body, the drawn turning where it faces (a run that keeps no turning, its
            targets not 3-D positions centred on their root, trains as without it). Runs written
            before it had none.
        by_metre: also fit the turning and the travel on the training recordings of each metre
            (:func:`~kinectdata.training.turning.fit_dataset_by_metre`), kept in the run as
            ``drawn_by_metre``: a song is drawn its metre's processes where the run has them, else the
            pooled ones. Runs written before it had none.
        component_floor: the free-running loss's speed, jitter and bone terms floor each component
            at 1 % of its own mean over the batch, not of every component's
            (:func:`~kinectdata.models.losses.masked_energy_loss`'s ``component_floor``): on tang2018
            the root's sway along the floor, in normalised units, lies under the shared floor and
            costs nothing however fast it sways. Runs written before it had it off.
        sway: once trained, measure how fast the network's root moves along the floor in the beat's
            band over the training songs run whole, against the dancers' (:mod:`kinectdata.targets.sway`),
            and keep the ratio (never above 1) in the run as ``sway``: wherever the run makes
            positions, the network's root x and z are scaled by it before the drawn turning and
            travel. Only a run that draws its travel keeps one. Runs written before it had it off.
        smooth_hz: low-pass the motion the run makes (after its drawn turning and travel) at this
            cutoff, Hz, wherever it makes positions: ``evaluate``'s free runs (so the kept epoch's
            whole songs too), ``generate`` and ``live`` (:mod:`kinectdata.inference.smoothing`: a causal
            Butterworth of order 2, so live's frames are ``generate``'s); the network trains as
            without it. None (or 0, which turns a model's default off): not smoothed, as runs
            written before it.
        style_tempo: a share of the tempo (0.08: 8 %): a song further than that from its heard
            style's usual tempo is played to the network at the band's nearer edge, pitch kept, and
            its dance warped back onto the song's clock, wherever a whole song is danced: ``evaluate``
            and ``generate`` (:mod:`kinectdata.inference.style_tempo`; not ``live``, whose music arrives
            as it plays, nor the kept epoch's validation songs, danced as they are). Needs features
            that hear the style (``*_style``), from a build that kept each style's tempo; for others
            the run keeps None and ``train`` warns. None (or 0): every song at its own tempo, as runs
            written before it.
        precision: the training step's arithmetic (:data:`PRECISIONS`): ``float32``, or
            ``bfloat16``, the network's forward pass under ``torch.autocast`` (its losses, weights,
            optimiser, validation and every run made from it in float32; a model keeps what it
            must in float32: the yalta model its LSTMs, :class:`~kinectdata.models.yalta.YaltaNet`).
            Where the device has no native bfloat16 (a CPU without AVX-512 BF16, a GPU without
            bfloat16), ``train`` warns and trains in float32. Runs written before it had float32.
    """

    model: str
    sequence: int
    stride: int | None
    batch_size: int
    epochs: int
    lr: float
    noise_eta: float
    noise_gamma: float
    clip_norm: float | None
    seed: int
    device: str
    max_minutes: float | None
    previous_noise: float
    free_weight: float
    posture_weight: float
    jitter_weight: float
    periodogram_weight: float
    bone_jitter_weight: float
    low_energy_weight: float
    span_weight: float
    bend_weight: float
    repetition_weight: float
    world_excess_weight: float
    world_jitter_weight: float
    root_band_weight: float
    root_rise_weight: float
    root_phase_weight: float
    step_weight: float
    bone_weight: float
    world_speed_weight: float
    foot_weight: float
    song_starts: bool
    silence_share: float
    keep: str
    keep_energy_weight: float
    context: int | None
    balance: str | None
    weight_average: float
    mirror_share: float
    turning: bool
    travel: bool
    facing: bool
    by_metre: bool
    component_floor: bool
    sway: bool
    smooth_hz: float | None
    style_tempo: float | None
    precision: str
    settings: Any

    def __init__(self, model: str | None = None, *, settings: Any = None, paper: bool = False, **given: Any) -> None:
        kind = model_kind(model or DEFAULT_MODEL)
        clash = sorted({f.name for f in dataclasses.fields(kind.settings_type)} & {*LOOP_DEFAULTS, "model"})
        if clash:
            raise ConfigError(f"the {kind.name} model's settings {', '.join(clash)} clash with the training loop's")
        # the published settings start from the loop's base, not the model's real-dance recipe: what the
        # paper dict does not name is then the base's, never a recipe addition
        loop = dict(LOOP_DEFAULTS) if paper else {**LOOP_DEFAULTS, **kind.training_defaults}
        if paper:  # the published settings, under what is given
            loop.update({k: v for k, v in kind.paper.items() if k in loop})
            given = {**{k: v for k, v in kind.paper.items() if k not in loop}, **given}
        own = {k: v for k, v in given.items() if k not in loop}
        loop.update({k: v for k, v in given.items() if k in loop})
        for off in ("smooth_hz", "style_tempo"):  # 0 turns a model's default off (None would take the default)
            if loop[off] == 0:
                loop[off] = None
        object.__setattr__(self, "model", kind.name)
        for name, value in loop.items():
            object.__setattr__(self, name, value)
        object.__setattr__(self, "settings", make_settings(kind, settings, **own))
        self._validate()

    def _validate(self) -> None:
        if min(self.sequence, self.batch_size, self.epochs) < 1 or (self.stride or 1) < 1:
            raise ConfigError("sequence, stride, batch size and epochs must be positive")
        if self.lr <= 0 or self.noise_eta < 0 or self.noise_gamma < 0 or (self.clip_norm or 1) <= 0:
            raise ConfigError("lr and clip_norm must be positive, noise_eta and noise_gamma at least 0")
        if not self.previous_noise >= 0:
            raise ConfigError(f"previous_noise must be at least 0, not {self.previous_noise!r}")
        if not 0 <= self.weight_average < 1:
            raise ConfigError(f"weight_average must be in [0, 1), not {self.weight_average!r}")
        for name in _WEIGHTS:
            if not getattr(self, name) >= 0:
                raise ConfigError(f"{name} must be at least 0, not {getattr(self, name)!r}")
        for name in _SWITCHES:
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"{name} must be true or false, not {getattr(self, name)!r}")
        if self.by_metre and not (self.turning or self.travel):
            raise ConfigError("by_metre: a run that fits its drawn processes by metre must draw its turning or travel")
        if self.smooth_hz is not None and not (isinstance(self.smooth_hz, (int, float)) and self.smooth_hz > 0):
            raise ConfigError(f"smooth_hz must be a positive cutoff in Hz or None, not {self.smooth_hz!r}")
        if self.style_tempo is not None and not (
            isinstance(self.style_tempo, (int, float)) and 0 < self.style_tempo < 1
        ):
            raise ConfigError(
                f"style_tempo must be a share of the tempo in 0..1 (0.08: 8 %) or None, not {self.style_tempo!r}"
            )
        if self.facing and not self.turning:
            raise ConfigError("facing: a run that learns its poses facing one way must draw its turning (turning true)")
        if not 0 <= self.mirror_share <= 1:
            raise ConfigError(f"mirror_share must be in 0..1, not {self.mirror_share!r}")
        if not 0 <= self.silence_share <= 1:
            raise ConfigError(f"silence_share must be in 0..1, not {self.silence_share!r}")
        if self.context is not None and not (isinstance(self.context, int) and self.context >= 0):
            raise ConfigError(f"context must be a number of frames, at least 0, or None, not {self.context!r}")
        if self.balance == "none":  # the command line's word for None
            object.__setattr__(self, "balance", None)
        if self.balance is not None and self.balance not in BALANCE_FIELDS:
            raise ConfigError(f"balance must be one of {', '.join(BALANCE_FIELDS)} or None, not {self.balance!r}")
        if self.precision not in PRECISIONS:
            raise ConfigError(f"precision must be {' or '.join(PRECISIONS)}, not {self.precision!r}")
        if self.keep not in KEEPS:
            raise ConfigError(f"keep must be {' or '.join(KEEPS)}, not {self.keep!r}")
        if self.free_weight > 0 and not model_kind(self.model).runs_free_in_training:
            raise ConfigError(f"free_weight: the {self.model} model cannot run free in training")
        if self.max_minutes is not None and not self.max_minutes > 0:
            raise ConfigError(f"max_minutes must be positive, not {self.max_minutes!r}")
        if self.device not in ("auto", "cpu", "cuda"):
            raise ConfigError(f"device must be auto, cpu or cuda, not {self.device!r}")

    def __getattr__(self, name: str) -> Any:
        # only reached when normal lookup fails: the model's own settings by name
        if name.startswith("__") or name == "settings":
            raise AttributeError(name)
        settings = self.__dict__.get("settings")
        if settings is not None and name in {f.name for f in dataclasses.fields(settings)}:
            return getattr(settings, name)
        raise AttributeError(f"the {self.__dict__.get('model')} model's training settings have no {name!r}")

    def to_dict(self) -> dict[str, Any]:
        """The settings flat, as ``config.json`` holds them: ``model``, the loop's, the model's."""
        own = {f.name: getattr(self.settings, f.name) for f in dataclasses.fields(self.settings)}
        return {"model": self.model, **{k: getattr(self, k) for k in LOOP_DEFAULTS}, **own}

    def replace(self, **changes: Any) -> TrainConfig:
        """A copy with ``changes`` (loop or model settings by name). Another ``model`` keeps the
        loop's settings and starts from that model's own defaults."""
        model = changes.pop("model", self.model)
        if model != self.model:
            return TrainConfig(model, **{k: getattr(self, k) for k in LOOP_DEFAULTS}, **changes)
        return dataclasses.replace(self, **changes)

    def differences(self, other: TrainConfig) -> list[tuple[str, Any, Any]]:
        """(name, this value, ``other``'s value) of every setting in which the two differ."""
        mine, theirs = self.to_dict(), other.to_dict()
        return [(k, mine.get(k), theirs.get(k)) for k in {**mine, **theirs} if mine.get(k) != theirs.get(k)]

    @property
    def rhythm_weights(self) -> RhythmWeights:
        """The free-running loss's term weights as
        :func:`~kinectdata.models.losses.masked_rhythm_loss` takes them: each field of
        :class:`~kinectdata.models.losses.RhythmWeights` from the setting of its name with
        ``_weight`` (``posture`` from ``posture_weight``...)."""
        return RhythmWeights(*(getattr(self, name) for name in rhythm_weight_settings()))

    @classmethod
    def for_model(cls, model: str, paper: bool = False, **settings: Any) -> TrainConfig:
        """The settings of ``model`` (its defaults, or with ``paper`` its published ones), with
        ``settings`` (None: the default)."""
        return cls(model, paper=paper, **{k: v for k, v in settings.items() if v is not None})

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TrainConfig:
        """A run's ``train`` settings as ``config.json`` holds them, also as runs wrote them before
        (no ``model``: :data:`~kinectdata.models.registry.DEFAULT_MODEL`; every model's settings
        side by side: :data:`FLAT_BEFORE`). Settings added since take their defaults."""
        d = dict(d)
        kind = model_kind(d.pop("model", None) or DEFAULT_MODEL)
        own = {f.name for f in dataclasses.fields(kind.settings_type)}
        unknown = sorted(set(d) - set(LOOP_DEFAULTS) - own - set(FLAT_BEFORE))
        if unknown:
            raise ConfigError(f"unknown training settings {', '.join(unknown)} for the {kind.name} model")
        old = {k: v for k, v in ADDED_OFF.items() if k not in d and (k in LOOP_DEFAULTS or k in own)}
        return cls(kind.name, **old, **{k: v for k, v in d.items() if k in LOOP_DEFAULTS or k in own})

    def resolved_device(self):
        """The torch device to train on."""
        import torch

        if self.device == "auto":
            return torch.device("cuda" if torch.cuda.is_available() else "cpu")
        if self.device == "cuda" and not torch.cuda.is_available():
            raise KinectDataError("--device cuda, but torch sees no CUDA device")
        return torch.device(self.device)
