"""Audio features for the network input, and a small registry of extractors by name (lhotse-style).

An extractor is a callable ``(samples, starts, config, *, chunk_frames=...) -> (features, padded)``:
``samples`` [S] mono float audio, ``starts`` [N] int64 slice starts (may run off either end),
``features`` float32 [N, ...] and ``padded`` bool [N] (see :func:`stft_features`). Built in:

- ``"stft"``: :func:`kinectdata.features.stft.stft_features` with a :class:`StftConfig`
  (presets ``"yalta2016"``, ``"motion_dance"``), the Yalta et al. pipeline;
- ``"mel"``: :func:`kinectdata.features.mel.mel_features` with a :class:`MelConfig` (preset
  ``"listen_to_dance"``), the Lee et al. pipeline;
- ``"rhythm"``: :func:`kinectdata.features.rhythm.rhythm_features` with a :class:`RhythmConfig`:
  the music's pulse at 43 tempi, computed causally from its onsets;
- ``"stack"``: :func:`kinectdata.features.stack.stack_features`, parts stacked on their first
  axis (presets ``"yalta2016_rhythm"``: the STFT and the pulse as two channels [2, 129, 5];
  ``"listen_to_dance_rhythm"``: log-mel, the saliences of the pulse's tempi and its metrical levels [153];
  ``"listen_to_dance_rhythm_bars"``: the same with the bar and two bars in the song's metre;
  ``"listen_to_dance_rhythm_counted"``: those levels counted from the beat); ``"listen_to_dance_pulse"``:
  that pulse alone, without the log-mel bands [73].

All presets are in :data:`PRESETS`. A configuration's dict names its extractor
(``"extractor"``; a dict without one is an STFT configuration, as datasets before the mel
features stored them): :func:`feature_config` reads it back, :func:`compute_features` runs it.
Register another extractor with the decorator ``@register_extractor("name")`` or the call
``register_extractor("name", fn)``; look one up with ``get_extractor(name)``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

from kinectdata.core.errors import ConfigError, KinectDataError
from kinectdata.features.mel import MelConfig, mel_features
from kinectdata.features.metre_input import MetreInputConfig, metre_input_features
from kinectdata.features.rhythm import RhythmConfig, rhythm_features
from kinectdata.features.stack import StackConfig, stack_features
from kinectdata.features.stft import PRESETS as STFT_PRESETS
from kinectdata.features.stft import StftConfig, stft_features
from kinectdata.features.style_input import StyleInputConfig, style_input_features

__all__ = [
    "PRESETS",
    "FeatureConfig",
    "MelConfig",
    "MetreInputConfig",
    "RhythmConfig",
    "StackConfig",
    "StftConfig",
    "compute_features",
    "extractor_names",
    "feature_config",
    "feature_state",
    "get_extractor",
    "mel_features",
    "needs_metre",
    "needs_style",
    "song_style",
    "style_input_of",
    "register_extractor",
    "stft_features",
]

FeatureConfig = StftConfig | MelConfig | RhythmConfig | MetreInputConfig | StyleInputConfig | StackConfig
LISTEN_TO_DANCE_PULSE = RhythmConfig(
    tempo_range_bpm=(15.0, 240.0),
    n_tempi=65,
    window_s=12.0,
    decay_s=4.0,
    levels=(1, 2, 3, 4),
    beat_range_bpm=(40.0, 240.0),
    harmonic_weight=1.0,
    tempo_phases=False,
)
"""The pulse the cdhc model is given: the saliences of tempi down to 15 BPM (two bars of 4 at 120
BPM) over 12 s of onsets, and the predominant pulse at the beat, two beats and bars of 3 and 4:
[73]. Its decoder reads each frame's features through convolutions: given the 43 tempi with their
phases it kept one tempo's phase, the same period for every song (each tempo's phase is a clock at
that tempo whatever the music); with the levels it moved alive and human for both seeds tried, and
without the tempi's phases (``tempo_phases=False``) the only clocks it is given are the song's own
beat and bar. The beat is picked with the salience at twice each tempo added (``harmonic_weight``):
without it, at twice the music's beat almost as often as at the beat (docs/notebook/2026-11-real-dance.md, "How the
recipe was found"; ``python -m benchmarks.bench_pulse``)."""
LISTEN_TO_DANCE_BAR_PULSE = dataclasses.replace(LISTEN_TO_DANCE_PULSE, levels=(1, 2), bar_levels=(1, 2))
"""The same pulse with the bar and two bars counted in the song's metre (``compute_features(...,
beats_per_bar=)``) instead of bars of 3 and 4 beats: [73]. On Dance with Melody (388 of its 564
training windows waltzes) the cdhc model given fixed levels danced the training cha-chas at 3
beats, and given these at their bar; on the test dances it did not do better (docs/notebook/2026-11-real-dance.md,
"The bar in each song's metre"), so it is a preset to choose, not the default."""
LISTEN_TO_DANCE_COUNTED_PULSE = dataclasses.replace(LISTEN_TO_DANCE_BAR_PULSE, counted_levels=True)
"""The same pulse with the two beats, the bar and two bars counted from the beat (``counted_levels``:
clocks that turn once per level whatever the downbeats sound like; the tempogram's phase at a bar's
tempo hardly turns where the downbeats are not louder, and the cdhc network, the same at every
instant, cannot divide a beat's clock into bars itself): [73]."""
LISTEN_TO_DANCE_CLOCKS = dataclasses.replace(LISTEN_TO_DANCE_BAR_PULSE, levels=(1,), saliences=False)
"""The bar pulse's clocks alone: the beat, the bar and two bars in the song's metre, each ``s* cos``,
``s* sin`` [6], without the sound, the tempi's saliences (``saliences=False``) or the two beats'
clock. The cdhc network given the log-mel bands too danced most held-out waltzes at a period of its
own, between their two beats and their bar; given the clocks with the two beats', at the two beats;
given these and the style (``listen_to_dance_clocks_style``), at their bar, and met goals a, b, c and e
in 3 of 6 fold runs (the real-dance recipe's features: 3 of 7), losing another goal in the others: a
choice, not the default (docs/notebook/2026-12-real-dance-variety.md, "The sound or the clock" and
"The bar's clocks over seeds")."""
YALTA_CLOCK_PLANES = dataclasses.replace(LISTEN_TO_DANCE_CLOCKS, unit_levels=True, planes=(129, 5))
"""The pulse's clocks at the beat, the bar and two bars in the song's metre at unit amplitude (the
cdhc model's candidate clocks on the folds), each value a constant [129, 5] plane [6, 129, 5]: for
the yalta model, whose side channels take them past its convolutions beside the audio code."""
LISTEN_TO_DANCE_HELD_PULSE = dataclasses.replace(
    LISTEN_TO_DANCE_BAR_PULSE, levels=(1,), unit_levels=True, beat_hold=1.0
)
"""The bar pulse with its clocks at unit amplitude, without the two beats' clock, and the beat held
(``beat_hold=1.0``): over tang2018's 36 training and validation songs the beat picked is librosa's
in 71 % of the frames (67.5 % held at 0.3) and moves 3.2 times a minute (13.2 at
0.3): [71]. The features of the cdhc candidates c1-c4 on the folds
(docs/notebook/2026-12-real-dance-variety.md, "The root at the bar's rate, and the bent knee back")."""
PRESETS: dict[str, FeatureConfig] = {
    **STFT_PRESETS,
    "listen_to_dance": MelConfig(),
    "yalta2016_rhythm": StackConfig((STFT_PRESETS["yalta2016"], RhythmConfig(columns=5))),
    "motion_dance_rhythm": StackConfig((STFT_PRESETS["motion_dance"], RhythmConfig(columns=5))),
    "listen_to_dance_rhythm": StackConfig((MelConfig(), LISTEN_TO_DANCE_PULSE)),
    "listen_to_dance_rhythm_bars": StackConfig((MelConfig(), LISTEN_TO_DANCE_BAR_PULSE)),
    "listen_to_dance_rhythm_counted": StackConfig((MelConfig(), LISTEN_TO_DANCE_COUNTED_PULSE)),
    "listen_to_dance_pulse": LISTEN_TO_DANCE_COUNTED_PULSE,
    "yalta2016_rhythm_metre": StackConfig(
        (STFT_PRESETS["yalta2016"], RhythmConfig(columns=5), MetreInputConfig(planes=(129, 5)))
    ),
    "listen_to_dance_rhythm_bars_metre": StackConfig((MelConfig(), LISTEN_TO_DANCE_BAR_PULSE, MetreInputConfig())),
    "yalta2016_rhythm_style": StackConfig(
        (STFT_PRESETS["yalta2016"], RhythmConfig(columns=5), StyleInputConfig(planes=(129, 5)))
    ),
    "listen_to_dance_rhythm_bars_style": StackConfig((MelConfig(), LISTEN_TO_DANCE_BAR_PULSE, StyleInputConfig())),
    "yalta2016_rhythm_clocks_style": StackConfig(
        (STFT_PRESETS["yalta2016"], RhythmConfig(columns=5), YALTA_CLOCK_PLANES, StyleInputConfig(planes=(129, 5)))
    ),
    "listen_to_dance_clocks": LISTEN_TO_DANCE_CLOCKS,
    "listen_to_dance_clocks_style": StackConfig((LISTEN_TO_DANCE_CLOCKS, StyleInputConfig())),
    "listen_to_dance_rhythm_held_style": StackConfig((MelConfig(), LISTEN_TO_DANCE_HELD_PULSE, StyleInputConfig())),
}
"""Feature configurations by name: ``yalta2016``, ``motion_dance`` (STFT), ``listen_to_dance``
(mel), and each with the music's pulse stacked on (``_rhythm``; ``listen_to_dance_rhythm_bars``:
its bar levels in the song's metre), and each of those with the song's metre as input
(``_metre``: :mod:`.metre_input`, one value per bar length of 3 and 4 beats) or its dance style
(``_style``: :mod:`.style_input`, one value per style of the training songs, at most 4; a dataset
build fits the classifier that hears it); ``listen_to_dance_clocks`` (``_style``): the pulse's clocks at
the beat, the bar and two bars alone, without the sound (:data:`LISTEN_TO_DANCE_CLOCKS`);
``yalta2016_rhythm_clocks_style``: the yalta model's spectra and pulse, the clocks and the style as
constant planes (:data:`YALTA_CLOCK_PLANES`) that its side channels take past the convolutions;
``listen_to_dance_rhythm_held_style``: the log-mel bands, the pulse with its beat held
(:data:`LISTEN_TO_DANCE_HELD_PULSE`) and the style."""
_CONFIG_TYPES = {
    "stft": StftConfig,
    "mel": MelConfig,
    "rhythm": RhythmConfig,
    "metre": MetreInputConfig,
    "style": StyleInputConfig,
    "stack": StackConfig,
}

Extractor = Callable[..., Any]

_EXTRACTORS: dict[str, Extractor] = {}


def register_extractor(name: str, fn: Extractor | None = None, *, replace: bool = False):
    """Register ``fn`` under ``name``; without ``fn``, return a decorator that does.

    Raises ValueError if ``name`` is taken by another callable (unless ``replace=True``);
    registering the same callable again is a no-op. Returns ``fn`` (so the decorator keeps it).
    """
    if not isinstance(name, str) or not name:
        raise ConfigError(f"extractor name must be a non-empty string, got {name!r}")

    def add(f: Extractor) -> Extractor:
        if not callable(f):
            raise TypeError(f"extractor {name!r} must be callable, got {type(f).__name__}")
        old = _EXTRACTORS.get(name)
        if old is not None and old is not f and not replace:
            raise ConfigError(f"extractor {name!r} is already registered ({old!r}); pass replace=True")
        _EXTRACTORS[name] = f
        return f

    return add if fn is None else add(fn)


def get_extractor(name: str) -> Extractor:
    """The extractor registered under ``name``; KeyError listing the known names otherwise."""
    try:
        return _EXTRACTORS[name]
    except KeyError:
        raise KeyError(f"unknown feature extractor {name!r}; known: {', '.join(extractor_names())}") from None


def extractor_names() -> list[str]:
    """The registered names, sorted."""
    return sorted(_EXTRACTORS)


def feature_config(d: dict[str, Any]) -> FeatureConfig:
    """The configuration object of a stored features dict (its ``"extractor"``, default ``stft``)."""
    name = d.get("extractor", "stft")
    if name not in _CONFIG_TYPES:
        raise ConfigError(f"unknown feature extractor {name!r}; known: {', '.join(sorted(_CONFIG_TYPES))}")
    return _CONFIG_TYPES[name].from_dict(d)


def compute_features(
    samples: np.ndarray,
    starts: np.ndarray,
    config: FeatureConfig,
    *,
    beats_per_bar: int | None = None,
    style: str | None = None,
    state: Any = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``(features [N, *config.output_shape] float32, padded [N] bool)`` with the config's extractor.

    ``beats_per_bar``: the song's metre, passed on to an extractor whose configuration
    :func:`needs_metre` (None there: the extractor's default, 4). ``style``: the song's dance style,
    passed on to one that :func:`needs_style` (None there: heard in ``samples``, which must then be
    the whole song). ``state``: for a configuration
    whose frames depend on the frames before them (:func:`feature_state`), what a stream of calls
    carries from one to the next (None: this call's frames are the first)."""
    extra: dict[str, Any] = {"beats_per_bar": beats_per_bar} if needs_metre(config) else {}
    if needs_style(config):
        extra["style"] = style
    if state is not None:
        extra["state"] = state
    return get_extractor(config.extractor)(samples, starts, config, **extra)


def feature_state(config: FeatureConfig, live: bool = False) -> Any:
    """A fresh state for a stream of :func:`compute_features` calls over consecutive frames, or None
    when every frame's features depend on its own samples alone (all but the pulse's counted levels
    and held beat: :class:`~kinectdata.features.rhythm.PulseCount`). ``live``: calls a frame or two apart, which may
    keep what one call computed for the next (the pulse's onset spectra) without changing the output."""
    new_state = getattr(config, "new_state", None)
    if new_state is None:
        return None
    return new_state(live) if live else new_state()  # a plugin's new_state may take no argument


def needs_metre(config: FeatureConfig) -> bool:
    """True when features of ``config`` depend on the song's beats per bar (the pulse's bar levels)."""
    return bool(getattr(config, "needs_metre", False))


def needs_style(config: FeatureConfig) -> bool:
    """True when features of ``config`` depend on the song's dance style (:mod:`.style_input`)."""
    return bool(getattr(config, "needs_style", False))


def style_input_of(config: FeatureConfig) -> StyleInputConfig | None:
    """The style input among ``config``'s parts (``config`` itself, or a part of a stack), or None."""
    parts = config.parts if isinstance(config, StackConfig) else (config,)
    return next((p for p in parts if isinstance(p, StyleInputConfig)), None)


def song_style(config: FeatureConfig, samples: np.ndarray | None, given: str | None = None) -> tuple[str | None, str]:
    """``(style, how it was found)`` of a song for features that hear its style: ``given`` (the
    caller's; it must be one the classifier names), else heard in the whole song's mono ``samples``
    [S] at the features' rate, else None (no audio, or too few beats to tell: the style input is
    then all zeros). ``(None, "")`` for features without a style input."""
    part = style_input_of(config)
    if part is None:
        return None, ""
    if given is not None:
        if given not in part.styles:
            raise ConfigError(f"style {given!r}: the run knows {', '.join(part.styles) or 'no style'}")
        return given, f"{given} (given)"
    if samples is None:
        return None, "none (no whole song to hear it from)"
    try:
        return (style := part.style_of(samples)), f"{style} (heard in the music)"
    except KinectDataError as exc:
        return None, f"none ({exc})"


register_extractor("stft", stft_features)
register_extractor("mel", mel_features)
register_extractor("rhythm", rhythm_features)
register_extractor("metre", metre_input_features)
register_extractor("style", style_input_features)
register_extractor("stack", stack_features)
