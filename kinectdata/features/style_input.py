"""The song's dance style as a network input (``style`` extractor): one value per style, 1.0 at the
song's style, on every frame where music sounds.

Why: the spectra and the pulse say when to move, not which dance the song asks for; a network
trained mostly on waltzes then dances one average dance for every song (:mod:`.music_style`).

Which style: the caller's (``style=``: a dataset build gives a training song its manifest's
style), else the one :attr:`StyleInputConfig.classifier` hears in ``samples``, which must then be
the whole song (``generate``, ``evaluate`` and a build's other songs estimate it first, as they do the
metre). The classifier is fitted by a dataset build on its training songs
(:func:`kinectdata.dataset.song_styles.fit_style_inputs`) and travels in the configuration, so a
trained run hears the style of any song the same way.

Output per motion frame: ``[slots]``, 1.0 at the style's place among the classifier's styles
(sorted) and 0 elsewhere, or with ``planes`` = (rows, columns) ``[slots, rows, columns]``, each
value a constant plane. ``slots`` is fixed before the fit, so the input's shape is known before the
songs are heard. A frame whose own slice of audio is digital silence gives zeros, as the metre input
(:mod:`.metre_input`) does.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from kinectdata.core.errors import ConfigError
from kinectdata.features.config_dict import checked_planes
from kinectdata.features.metre_input import on_sounding_frames, sounding_slices
from kinectdata.features.music_style import MusicStyleClassifier, TooLittleMusic

__all__ = ["NO_STYLE", "StyleInputConfig", "style_input_features"]

NO_STYLE = ""
"""The style of a song none could be heard in (no whole song, too few beats): the input all zeros."""


@dataclass(frozen=True)
class StyleInputConfig:
    """The style as input (module docstring).

    Attributes:
        slots: the most styles it can name (outputs per frame).
        classifier: the fitted music style classifier (None before a dataset build fits it).
        sample_rate: Hz. slice_samples: samples per motion frame's slice (as the parts it is
            stacked with).
        planes: None for a vector per frame; (rows, columns) for constant planes.
    """

    extractor: ClassVar[str] = "style"
    needs_style: ClassVar[bool] = True

    slots: int = 4
    classifier: MusicStyleClassifier | None = None
    sample_rate: int = 16000
    slice_samples: int = 534
    planes: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.slots, int) or self.slots < 1:
            raise ConfigError(f"style input: slots must be at least 1, got {self.slots!r}")
        if self.classifier is not None and len(self.classifier.styles) > self.slots:
            raise ConfigError(
                f"style input: the training songs hold {len(self.classifier.styles)} styles "
                f"({', '.join(self.classifier.styles)}), more than its {self.slots} slots"
            )
        if self.sample_rate < 1 or self.slice_samples < 1:
            raise ConfigError("style input: sample_rate and slice_samples must be positive")
        if self.planes is not None:
            object.__setattr__(self, "planes", checked_planes(self.planes, "style input"))

    @property
    def output_shape(self) -> tuple[int, ...]:
        return (self.slots, *self.planes) if self.planes else (self.slots,)

    @property
    def span(self) -> tuple[int, int]:
        """Samples a frame reads relative to its start: its own slice."""
        return 0, self.slice_samples

    @property
    def styles(self) -> tuple[str, ...]:
        """The styles it names, in slot order (none before the fit)."""
        return () if self.classifier is None else self.classifier.styles

    def style_of(self, samples: np.ndarray) -> str:
        """The style the classifier hears in a whole song's mono ``samples`` [S] at ``sample_rate``."""
        if self.classifier is None:
            raise ConfigError(
                "style input: no music style classifier yet (a dataset build fits it on its training songs)"
            )
        return self.classifier.style_of(samples, self.sample_rate)

    def to_dict(self) -> dict[str, Any]:
        return {
            "extractor": self.extractor,
            "slots": self.slots,
            "classifier": None if self.classifier is None else self.classifier.to_dict(),
            "sample_rate": self.sample_rate,
            "slice_samples": self.slice_samples,
            "planes": None if self.planes is None else list(self.planes),
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> StyleInputConfig:
        if d.get("extractor", cls.extractor) != cls.extractor:
            raise ConfigError(f"not a style input configuration (extractor {d['extractor']!r})")
        unknown = sorted(set(d) - {"extractor", "slots", "classifier", "sample_rate", "slice_samples", "planes"})
        if unknown:
            raise ConfigError(f"unknown StyleInputConfig keys: {unknown}")
        kw = {k: v for k, v in d.items() if k != "extractor"}
        if kw.get("classifier") is not None:
            kw["classifier"] = MusicStyleClassifier.from_dict(kw["classifier"])
        if kw.get("planes") is not None:
            kw["planes"] = tuple(kw["planes"])
        return cls(**kw)


def style_input_features(
    samples: np.ndarray, starts: np.ndarray, config: StyleInputConfig, *, style: str | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """``(features float32 [N, *config.output_shape], padded bool [N])`` of mono ``samples`` [S] for
    the frames starting at sample ``starts`` [N]: the one-hot of ``style`` (None: the classifier's
    style of ``samples``, the whole song) among the classifier's styles where the frame's slice is
    not digital silence (all zeros for a style it does not name, or music too short or beatless to
    tell); padded where the slice runs off the audio."""
    x = np.asarray(samples)
    starts = np.asarray(starts, np.int64)
    ends = starts + config.slice_samples
    sounding = sounding_slices(x, starts, config.slice_samples)
    if style is None and sounding.any():  # digital silence has no style to hear
        try:
            style = config.style_of(x)
        except TooLittleMusic:  # too few beats to tell (noise, a short clip): no style
            style = None
    one_hot = np.zeros(config.slots, np.float32)
    if style in config.styles:
        one_hot[config.styles.index(style)] = 1.0
    return on_sounding_frames(one_hot, sounding, config.planes), ends > x.size
