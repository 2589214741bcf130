"""The song's metre as a network input (``metre`` extractor): which of a few bar lengths the music
is in, one value per bar length, on every frame where music sounds.

Why: a waltz is in 3 and a cha-cha or a rumba in 4, and the dancers dance them differently (in
Dance with Melody the waltzers hold their partner and their arms still, the cha-cha and rumba
dancers' wrists move 7 to 10 times as fast); the pulse's levels count the bar in the song's metre
(:mod:`.rhythm`) but do not say which metre it is, and a network trained mostly on waltzes then
dances one average dance for every song (docs/notebook/2026-12-real-dance-variety.md). The metre is the song's
(``beats_per_bar`` given by the caller: a dataset build takes the recordings manifest's, else
estimates it from the music, as for the pulse's bar levels; ``generate`` and ``evaluate`` likewise).

Output per motion frame: ``[len(values)]``, 1.0 at the metre's bar length and 0 elsewhere (all 0
for a metre not among ``values``), or with ``planes`` = (rows, columns) ``[len(values), rows,
columns]``, each value a constant plane (to stack under an image-like input, e.g. the yalta
model's [2, 129, 5]). A frame whose own slice of audio is digital silence (every sample within
:data:`SILENT_BELOW` of 0) gives zeros: silence has no metre, and the silence a model is trained
and tested on stays the features of all-zero audio (:mod:`.silence`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from kinectdata.core.errors import ConfigError
from kinectdata.features.config_dict import checked_planes, config_from_dict, config_to_dict

__all__ = ["MetreInputConfig", "metre_input_features", "on_sounding_frames", "sounding_slices"]

SILENT_BELOW = 1e-6
"""A frame's slice is digital silence when no sample is further than this from 0 (full scale 1)."""


@dataclass(frozen=True)
class MetreInputConfig:
    """The metre as input (module docstring).

    Attributes:
        values: the bar lengths (in beats) given one output each.
        sample_rate: Hz. slice_samples: samples per motion frame's slice (as the parts it is
            stacked with).
        planes: None for a vector per frame; (rows, columns) for constant planes.
    """

    extractor: ClassVar[str] = "metre"
    needs_metre: ClassVar[bool] = True

    values: tuple[int, ...] = (3, 4)
    sample_rate: int = 16000
    slice_samples: int = 534
    planes: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        if not self.values or any(not isinstance(v, int) or v < 1 for v in self.values):
            raise ConfigError(f"metre input: values must be bar lengths of at least 1 beat, got {self.values!r}")
        if len(set(self.values)) != len(self.values):
            raise ConfigError(f"metre input: values must differ, got {self.values!r}")
        if self.sample_rate < 1 or self.slice_samples < 1:
            raise ConfigError("metre input: sample_rate and slice_samples must be positive")
        if self.planes is not None:
            object.__setattr__(self, "planes", checked_planes(self.planes, "metre input"))

    @property
    def output_shape(self) -> tuple[int, ...]:
        return (len(self.values), *self.planes) if self.planes else (len(self.values),)

    @property
    def span(self) -> tuple[int, int]:
        """Samples a frame reads relative to its start: its own slice."""
        return 0, self.slice_samples

    def to_dict(self) -> dict[str, Any]:
        return config_to_dict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> MetreInputConfig:
        return config_from_dict(cls, d, "a metre input")


def metre_input_features(
    samples: np.ndarray, starts: np.ndarray, config: MetreInputConfig, *, beats_per_bar: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """``(features float32 [N, *config.output_shape], padded bool [N])`` of mono ``samples`` [S] for
    the frames starting at sample ``starts`` [N]: the one-hot of ``beats_per_bar`` (None: 4) among
    ``config.values`` where the frame's slice is not digital silence; padded where the slice runs
    off the audio."""
    metre = 4 if beats_per_bar is None else int(beats_per_bar)
    if metre < 1:
        raise ConfigError(f"metre input: beats_per_bar must be at least 1, got {beats_per_bar!r}")
    x = np.asarray(samples)
    starts = np.asarray(starts, np.int64)
    ends = starts + config.slice_samples
    sounding = sounding_slices(x, starts, config.slice_samples)
    one_hot = np.array([1.0 if v == metre else 0.0 for v in config.values], np.float32)
    return on_sounding_frames(one_hot, sounding, config.planes), ends > x.size


def sounding_slices(samples: np.ndarray, starts: np.ndarray, slice_samples: int) -> np.ndarray:
    """[N] bool: the frames whose slice of ``samples`` [S] (``slice_samples`` from each of ``starts``
    [N]) is not digital silence (some sample further than :data:`SILENT_BELOW` from 0)."""
    x = np.asarray(samples)
    starts = np.asarray(starts, np.int64)
    # how many samples of each frame's slice are not digital silence, from a running count
    loud = np.abs(x.astype(np.float32, copy=False)) > SILENT_BELOW
    counts = np.concatenate([[0], np.cumsum(loud)])
    first, last = np.clip(starts, 0, x.size), np.clip(starts + slice_samples, 0, x.size)
    return counts[last] - counts[first] > 0


def on_sounding_frames(one_hot: np.ndarray, sounding: np.ndarray, planes: tuple[int, int] | None) -> np.ndarray:
    """float32 [N, K] (``planes`` None) or [N, K, rows, columns]: ``one_hot`` [K] on the frames where
    ``sounding`` [N] is True, zeros on the others; with ``planes``, each value a constant plane."""
    out = np.where(np.asarray(sounding)[:, None], np.asarray(one_hot, np.float32)[None], 0.0).astype(np.float32)
    if planes:
        out = np.broadcast_to(out[:, :, None, None], (*out.shape, *planes)).copy()
    return out
