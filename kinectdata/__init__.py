"""kinectdata: music-driven dance research, from Kinect-class skeleton recordings and their music to
datasets, reference models and their evaluation.

``import kinectdata as kd`` gives the main verbs of the data path (docs/api.md); each loads its
module on first use, so the import itself stays cheap (no torch, h5py or pandas):

- read: :func:`read_motion`, :class:`Motion`, :func:`load_joint_set`, :func:`load_audio`;
- align: :func:`align_motion` (``kinectdata.align.recipe.align``), :func:`align_files`,
  :class:`AlignedRecording` (``.load(path)``);
- features: :class:`StftConfig`, :class:`MelConfig`, :data:`FEATURE_PRESETS`,
  :func:`recording_features` (per motion frame, rates checked), :func:`compute_features`,
  :func:`song_descriptors` and :class:`MusicStyleClassifier` (a song's dance style from its music);
- targets: :class:`TargetSpec`, :func:`load_target_spec`, :func:`extract_targets`, :class:`Normalizer`;
- dataset: :func:`prepare_corpus` (a corpus recipe), :func:`write_folds` (cross-validation
  manifests), :class:`BuildConfig`
  (``.from_pipeline(name, **overrides)``), :func:`build_dataset`, :func:`verify_dataset`,
  :class:`WindowDataset`;
- models, training, evaluation, generation: :func:`register_model`, :class:`TrainConfig`,
  :func:`train`, :func:`evaluate`, :func:`generate`, :func:`export_run`, :func:`load_model`;
  dancing live: :class:`LiveDancer`, :func:`run_live` (sources and sinks in ``kinectdata.live``),
  :func:`humanoid_mapping` (a joint set as Unity humanoid bones for VMC);
- errors: :class:`KinectDataError`, :class:`InputError`, :class:`ConfigError`,
  :class:`KinectDataWarning`.
"""

from __future__ import annotations

import importlib
from typing import Any

from kinectdata.core.version import __version__

_API = {
    # read
    "read_motion": ("kinectdata.formats", "read_motion"),
    "write_motion": ("kinectdata.apps.convert", "write_motion"),
    "convert": ("kinectdata.apps.convert", "convert"),
    "clean_motion": ("kinectdata.cleaning", "clean_motion"),
    "CleanConfig": ("kinectdata.cleaning", "CleanConfig"),
    "Motion": ("kinectdata.core.motion", "Motion"),
    "load_joint_set": ("kinectdata.core.jointsets", "load_joint_set"),
    "load_audio": ("kinectdata.align.audio", "load_audio"),
    # align
    "align_motion": ("kinectdata.align.recipe", "align"),  # "align" is the subpackage kinectdata.align
    "align_files": ("kinectdata.align.recipe", "align_files"),
    "AlignedRecording": ("kinectdata.align.aligned", "AlignedRecording"),
    # features
    "StftConfig": ("kinectdata.features", "StftConfig"),
    "MelConfig": ("kinectdata.features", "MelConfig"),
    "FEATURE_PRESETS": ("kinectdata.features", "PRESETS"),
    "compute_features": ("kinectdata.features", "compute_features"),
    "recording_features": ("kinectdata.features.recording", "recording_features"),
    "song_descriptors": ("kinectdata.features.music_style", "song_descriptors"),
    "MusicStyleClassifier": ("kinectdata.features.music_style", "MusicStyleClassifier"),
    # targets
    "TargetSpec": ("kinectdata.targets.specs", "TargetSpec"),
    "load_target_spec": ("kinectdata.targets.specs", "load_target_spec"),
    "extract_targets": ("kinectdata.targets.specs", "extract_targets"),
    "Normalizer": ("kinectdata.targets.normalization", "Normalizer"),
    # dataset
    "prepare_corpus": ("kinectdata.dataset.recipes", "prepare_corpus"),
    "write_folds": ("kinectdata.dataset.folds", "write_folds"),
    "BuildConfig": ("kinectdata.dataset.config", "BuildConfig"),
    "PIPELINES": ("kinectdata.dataset.pipelines", "PIPELINES"),
    "build_dataset": ("kinectdata.dataset.build", "build_dataset"),
    "verify_dataset": ("kinectdata.dataset.verify", "verify_dataset"),
    "WindowDataset": ("kinectdata.dataset.windows", "WindowDataset"),
    # models, training, evaluation, generation (need torch)
    "register_model": ("kinectdata.models.registry", "register_model"),
    "load_model": ("kinectdata.models.run", "load_model"),
    "TrainConfig": ("kinectdata.training.config", "TrainConfig"),
    "train": ("kinectdata.training.train", "train"),
    "evaluate": ("kinectdata.evaluation.evaluate", "evaluate"),
    "generate": ("kinectdata.inference.generate", "generate"),
    "export_run": ("kinectdata.inference.export", "export_run"),
    "StartPose": ("kinectdata.inference.start", "StartPose"),
    "LiveDancer": ("kinectdata.live.session", "LiveDancer"),
    "run_live": ("kinectdata.live.session", "run_live"),
    "humanoid_mapping": ("kinectdata.live.humanoid", "humanoid_mapping"),
    # the field's metrics of two sets of dance (numpy only)
    "load_dance_set": ("kinectdata.evaluation.motion_sets", "load_dance_set"),
    "motion_as_dance": ("kinectdata.evaluation.motion_sets", "motion_as_dance"),
    "score_sets": ("kinectdata.evaluation.field_scores", "score_sets"),
    "get_protocol": ("kinectdata.evaluation.protocols", "get_protocol"),
    # errors
    "KinectDataError": ("kinectdata.core.errors", "KinectDataError"),
    "InputError": ("kinectdata.core.errors", "InputError"),
    "ConfigError": ("kinectdata.core.errors", "ConfigError"),
    "KinectDataWarning": ("kinectdata.core.errors", "KinectDataWarning"),
}

__all__ = ["__version__", *_API]


def __getattr__(name: str) -> Any:
    if name in _API:
        module, attribute = _API[name]
        value = getattr(importlib.import_module(module), attribute)
        globals()[name] = value  # later look-ups skip this function
        return value
    raise AttributeError(f"module 'kinectdata' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_API))
