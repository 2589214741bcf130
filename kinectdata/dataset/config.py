"""What decides a dataset's contents: :class:`BuildConfig`, made from a named pipeline with
:meth:`BuildConfig.from_pipeline` (the command line and the quickstart both go through it)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from kinectdata.core.errors import ConfigError
from kinectdata.dataset.pipelines import PIPELINES
from kinectdata.features import PRESETS, FeatureConfig, feature_config
from kinectdata.targets.normalization import METHODS
from kinectdata.targets.specs import GENERIC_TARGETS, GenericTarget, TargetSpec, load_target_spec

DEFAULT_PIPELINE = "yalta2016"
TEMPO_PITCHES = ("turntable", "kept")
"""How a tempo copy's song is played faster (:attr:`BuildConfig.tempo_pitch`)."""


@dataclass(frozen=True)
class BuildConfig:
    """Everything that decides a dataset's contents (stored verbatim in its manifest).

    Attributes:
        features: the feature configuration (:class:`~kinectdata.features.StftConfig` or
            :class:`~kinectdata.features.MelConfig`; its ``to_dict()`` is accepted too).
        target: the target spec (:class:`~kinectdata.targets.specs.TargetSpec`, or its ``to_dict()``),
            or a :class:`~kinectdata.targets.specs.GenericTarget` (``positions``, ``full``), made
            into a spec for the recordings' joint set when the build reads them.
        fps: motion frames per second.
        sample_rate: Hz of the audio the features are computed from.
        normalisation: ``maxabs`` (Yalta et al.), ``minmax`` or ``none`` (targets already in
            range, e.g. the listen_to_dance spec's 0..1).
        root_centre: root-centre positions before normalising.
        split_ratios: (train, val, test) shares for recordings without an explicit split.
        seed: for drawn splits and augmentation noise.
        augment_snr: SNRs in dB of the noisy copies added to the training split (none: no copies).
        augment_tempo: tempo factors of the stretched copies added to the training split (none: no
            copies): each training dance with its song played r times as fast, as a turntable plays
            it (tempo and pitch both by r; the song read at ``sample_rate / r`` Hz and taken as
            ``sample_rate``), the motion's times divided by r, the offset too; 0.5-2, not 1.
        tempo_pitch: how a tempo copy's song is played faster: ``turntable`` (above: its pitch moves
            with its tempo) or ``kept`` (:func:`~kinectdata.align.stretch.stretch_audio`, SoX's
            ``tempo`` or librosa's phase vocoder: the same notes, r times as fast, as the tempo
            control of ``evaluate`` plays its songs).
        shard_size_mb: a new shard starts before one would exceed this (uncompressed MB).
        compression: None, "gzip" or "lzf" for the shard datasets.
        max_gap, min_coverage: alignment options (see :func:`kinectdata.align.recipe.align`).
        clean: clean every skeleton before it is aligned (``build-dataset --clean``): the settings of
            :class:`kinectdata.cleaning.CleanConfig` that differ from its defaults (``{}``: the
            default stages), or None (no cleaning); a recordings manifest entry's own ``clean`` wins.
    """

    features: FeatureConfig
    target: TargetSpec | GenericTarget
    fps: float = 30.0
    sample_rate: int = 16000
    normalisation: str = "maxabs"
    root_centre: bool = False
    split_ratios: tuple[float, float, float] = (0.8, 0.1, 0.1)
    seed: int = 0
    augment_snr: tuple[float, ...] = ()
    augment_tempo: tuple[float, ...] = ()
    tempo_pitch: str = "turntable"
    shard_size_mb: float = 256.0
    compression: str | None = None
    max_gap: float = 0.2
    min_coverage: float = 0.9
    clean: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        if self.clean is not None:
            from kinectdata.cleaning import CleanConfig

            object.__setattr__(self, "clean", CleanConfig.from_settings(self.clean, "clean").settings())
        if isinstance(self.features, dict):
            try:
                object.__setattr__(self, "features", feature_config(self.features))
            except ValueError as exc:
                raise ConfigError(f"invalid feature configuration: {exc}") from None
        if isinstance(self.target, dict):
            generic = self.target.get("generic")
            target = GenericTarget(generic) if generic is not None else TargetSpec.from_dict(self.target)
            object.__setattr__(self, "target", target)
        object.__setattr__(self, "split_ratios", tuple(self.split_ratios))
        object.__setattr__(self, "augment_snr", tuple(self.augment_snr))
        object.__setattr__(self, "augment_tempo", tuple(float(r) for r in self.augment_tempo))
        wrong = [r for r in self.augment_tempo if not 0.5 <= r <= 2 or r == 1]
        if wrong:
            raise ConfigError(f"augment_tempo: {wrong[0]:g} is not a tempo factor from 0.5 to 2 other than 1")
        if self.tempo_pitch not in TEMPO_PITCHES:
            raise ConfigError(f"tempo_pitch must be one of {', '.join(TEMPO_PITCHES)}, not {self.tempo_pitch!r}")
        if self.normalisation not in METHODS:
            raise ConfigError(f"normalisation must be one of {', '.join(METHODS)}, not {self.normalisation!r}")
        if self.compression not in (None, "gzip", "lzf"):
            raise ConfigError(f"compression must be none, gzip or lzf, not {self.compression!r}")
        if len(self.split_ratios) != 3:
            raise ConfigError(f"split_ratios must be three shares (train, val, test), not {list(self.split_ratios)}")
        feats = self.features
        if feats.sample_rate != self.sample_rate:
            raise ConfigError(
                f"the {feats.extractor} features are defined at {feats.sample_rate} Hz "
                f"({feats.slice_samples}-sample slices); building at {self.sample_rate} Hz needs a feature "
                "configuration for that rate"
            )
        period = self.sample_rate / self.fps
        if abs(feats.slice_samples - period) > 1:
            raise ConfigError(
                f"the features take {feats.slice_samples}-sample slices, one frame at "
                f"{self.sample_rate / feats.slice_samples:.0f} fps; at {self.fps:g} fps a frame is {period:.1f} "
                "samples: use a feature configuration with slices of one frame"
            )

    @classmethod
    def from_pipeline(cls, name: str = DEFAULT_PIPELINE, **overrides: Any) -> BuildConfig:
        """The configuration of a named pipeline (:data:`~kinectdata.dataset.pipelines.PIPELINES`),
        with ``overrides``: any field, where ``features`` may be a preset name
        (:data:`~kinectdata.features.PRESETS`) and ``target`` a shipped spec name or a spec file.
        None values are ignored (an option left at its default). ConfigError for an unknown
        pipeline, preset or field."""
        if name not in PIPELINES:
            raise ConfigError(f"unknown pipeline {name!r}; known: {', '.join(sorted(PIPELINES))}")
        given = {k: v for k, v in overrides.items() if v is not None}
        unknown = sorted(set(given) - {f.name for f in dataclasses.fields(cls)})
        if unknown:
            raise ConfigError(f"BuildConfig has no field {', '.join(unknown)}")
        chosen = PIPELINES[name]
        features = given.pop("features", chosen["features"])
        if isinstance(features, str):
            if features not in PRESETS:
                raise ConfigError(f"unknown feature preset {features!r}; known: {', '.join(sorted(PRESETS))}")
            features = PRESETS[features]
        target = given.pop("target", chosen["target"])
        if isinstance(target, str):
            target = GenericTarget(target) if target in GENERIC_TARGETS else load_target_spec(target)
        given.setdefault("normalisation", chosen["normalisation"])
        return cls(features=features, target=target, **given)

    @property
    def feature_config(self) -> FeatureConfig:
        """The feature configuration (the same object as :attr:`features`)."""
        return self.features

    @property
    def feature_shape(self) -> tuple[int, ...]:
        """One frame's input shape, e.g. ``(1, 129, 5)`` (STFT) or ``(80,)`` (mel)."""
        return self.features.output_shape

    def to_dict(self) -> dict[str, Any]:
        """The manifest's ``config``: every field as JSON values (features and target as dicts)."""
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d["features"], d["target"] = self.features.to_dict(), self.target.to_dict()
        d["split_ratios"], d["augment_snr"] = list(self.split_ratios), list(self.augment_snr)
        d["augment_tempo"] = list(self.augment_tempo)
        if not d["augment_tempo"]:  # the configuration of every dataset built before tempo copies existed
            del d["augment_tempo"]
        if d["tempo_pitch"] == "turntable":  # and before the pitch could be kept
            del d["tempo_pitch"]
        if d["clean"] is None:  # and before cleaning existed
            del d["clean"]
        return d

    def unit_config(self, noisy: bool) -> dict[str, Any]:
        """The part of the configuration a work file depends on (the seed only for noisy copies)."""
        keys = ("features", "target", "fps", "sample_rate", "root_centre", "max_gap", "min_coverage")
        keys += ("seed",) if noisy else ()
        keys += ("clean",) if self.clean is not None else ()
        return {k: self.to_dict()[k] for k in keys}

    def __repr__(self) -> str:
        snr = f", augment_snr={list(self.augment_snr)}" if self.augment_snr else ""
        snr += f", augment_tempo={list(self.augment_tempo)}" if self.augment_tempo else ""
        snr += f", tempo_pitch={self.tempo_pitch}" if self.tempo_pitch != "turntable" else ""
        return (
            f"BuildConfig({self.features.extractor} features {list(self.feature_shape)}, target {self.target.name} "
            f"[{getattr(self.target, 'dim', 'for the recordings joint set')}], {self.normalisation}, {self.fps:g} fps, "
            f"{self.sample_rate} Hz{snr})"
        )
