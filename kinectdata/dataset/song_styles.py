"""The music style classifier of a dataset whose features hear the song's style
(:mod:`kinectdata.features.style_input`), fitted on its training songs before any recording is prepared.

A training recording is given its manifest's ``style``; every other recording (validation, test)
the style its music sounds like to this classifier, as any song has at generation. The manifest's
labelled songs without a recording (:class:`~kinectdata.dataset.inputs.LabelledSong`) teach the
classifier too, those of a style some training recording dances (a style no training dance shows
cannot be danced, so it is not heard either). The fit is deterministic (the same songs give the same
classifier), so a resumed build keys its recordings as the first one did.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from kinectdata.align.aligned import audio_blocks
from kinectdata.align.audio import AudioReader
from kinectdata.core.errors import ConfigError, KinectDataError
from kinectdata.dataset.config import BuildConfig
from kinectdata.dataset.inputs import LabelledSong, RecordingEntry
from kinectdata.features import StackConfig, style_input_of
from kinectdata.features.music_style import MusicStyleClassifier, TooLittleMusic, song_descriptors
from kinectdata.features.style_input import StyleInputConfig

__all__ = ["fit_style_inputs", "song_samples"]


def song_samples(entry: RecordingEntry | LabelledSong, sample_rate: int) -> np.ndarray:
    """[S] float32: the whole song of a recording entry or a labelled song, mono at ``sample_rate`` Hz
    (its audio file, or an aligned file's audio)."""
    aligned = isinstance(entry, RecordingEntry) and entry.aligned
    blocks = audio_blocks(entry.recording) if aligned else AudioReader(entry.audio, sample_rate).blocks()
    return np.concatenate([np.zeros(0, np.float32), *blocks])


def fit_style_inputs(
    config: BuildConfig,
    training: Sequence[RecordingEntry],
    source: str | Path,
    songs: Sequence[LabelledSong] = (),
) -> BuildConfig:
    """``config`` with its style input's classifier fitted on the ``training`` recordings' songs and
    their manifest ``style``, and on the labelled ``songs`` of those styles (``config`` as it is when
    its features hear no style or their classifier is fitted already: a dataset built with another
    dataset's features hears as it does).

    Raises:
        ConfigError: a training recording has no ``style`` in the manifest.
        KinectDataError: a labelled song cannot be read, or a style has no training song that can
            be read and described (10 beats at least; names them). Other songs too short to describe
            are left out of the fit only.
    """
    part = style_input_of(config.feature_config)
    if part is None or part.classifier is not None:
        return config
    unlabelled = [e.name for e in training if not e.style]
    if unlabelled:
        raise ConfigError(
            f"{source}: the features hear the song's style, fitted on the training recordings' styles, but "
            f"{', '.join(unlabelled[:3])}{' ...' if len(unlabelled) > 3 else ''} give no 'style'"
        )
    described, styles, danced, untold = [], [], [], []
    for entry in training:
        try:
            described.append(song_descriptors(song_samples(entry, config.sample_rate), config.sample_rate))
            styles.append(entry.style)
            danced.append(True)
        except KinectDataError as exc:  # a song too short to describe is still told its style in training
            untold.append(f"{entry.name} ({exc})")
    missing = sorted({e.style for e in training} - set(styles))
    trained = {e.style for e in training}
    for song in (s for s in songs if s.style in trained):
        try:
            described.append(song_descriptors(song_samples(song, config.sample_rate), config.sample_rate))
        except TooLittleMusic:
            continue  # it teaches nothing; the training songs are enough
        except KinectDataError as exc:
            raise KinectDataError(f"{source}: song {song.name} ({song.audio}): {exc}") from exc
        styles.append(song.style)
        danced.append(False)
    if len(described) < 2 or missing:
        raise KinectDataError(
            f"{source}: the features hear the song's style, but too few training songs can be described to "
            f"learn {', '.join(missing) or 'the styles'} from: {'; '.join(untold[:3])}"
        )
    classifier = MusicStyleClassifier.fit(np.stack(described), styles, danced)
    fitted = dataclasses.replace(part, classifier=classifier)
    return dataclasses.replace(config, features=_with_part(config.feature_config, part, fitted))


def _with_part(features, old: StyleInputConfig, new: StyleInputConfig):
    if isinstance(features, StackConfig):
        return StackConfig(tuple(new if p is old else p for p in features.parts))
    return new
