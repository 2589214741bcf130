"""Features made of other features: each part's frame stacked on the first axis (``stack`` extractor).

A spectrum and the pulse (:mod:`.rhythm`) together: ``yalta2016`` STFT [1, 129, 5] and the pulse
as a [1, 129, 5] plane make a [2, 129, 5] input (two channels of the DCNN's first convolution);
``listen_to_dance`` log-mel [80] and a pulse [73] make a [153] vector. The parts' shapes must
agree beyond their first axis. A frame reads the union of its parts' spans and is padded where
any part's is.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from kinectdata.core.errors import ConfigError

__all__ = ["StackConfig", "stack_features"]


@dataclass(frozen=True)
class StackConfig:
    """Parts whose features are stacked, in order (each a feature configuration)."""

    extractor: ClassVar[str] = "stack"

    parts: tuple[Any, ...]

    def __post_init__(self) -> None:
        if len(self.parts) < 2:
            raise ConfigError("stacked features need at least two parts")
        shapes = [tuple(p.output_shape) for p in self.parts]
        if len({s[1:] for s in shapes}) != 1:
            raise ConfigError(f"stacked features' parts must agree beyond their first axis, got {shapes}")
        rates = {(p.sample_rate, p.slice_samples) for p in self.parts}
        if len(rates) != 1:
            raise ConfigError(f"stacked features' parts must share sample rate and slice, got {sorted(rates)}")
        if any(isinstance(p, StackConfig) for p in self.parts):
            raise ConfigError("stacked features cannot hold stacked features")

    @property
    def sample_rate(self) -> int:
        return self.parts[0].sample_rate

    @property
    def slice_samples(self) -> int:
        return self.parts[0].slice_samples

    @property
    def needs_metre(self) -> bool:
        """True when a part's output depends on the song's beats per bar."""
        return any(getattr(p, "needs_metre", False) for p in self.parts)

    @property
    def needs_style(self) -> bool:
        """True when a part's output depends on the song's dance style."""
        return any(getattr(p, "needs_style", False) for p in self.parts)

    @property
    def output_shape(self) -> tuple[int, ...]:
        first = tuple(self.parts[0].output_shape)
        return (sum(p.output_shape[0] for p in self.parts), *first[1:])

    @property
    def span(self) -> tuple[int, int]:
        return min(p.span[0] for p in self.parts), max(p.span[1] for p in self.parts)

    def new_state(self, live: bool = False) -> tuple[Any, ...] | None:
        """Each part's fresh stream state (``kinectdata.features.feature_state``), or None when no
        part has one."""
        from kinectdata.features import feature_state

        states = tuple(feature_state(p, live) for p in self.parts)
        return None if all(s is None for s in states) else states

    def to_dict(self) -> dict[str, Any]:
        return {"extractor": self.extractor, "parts": [p.to_dict() for p in self.parts]}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> StackConfig:
        from kinectdata.features import feature_config

        unknown = sorted(set(d) - {"extractor", "parts"})
        if unknown or not isinstance(d.get("parts"), list):
            raise ConfigError(f"a stacked features configuration holds a list of parts, got keys {sorted(d)}")
        return cls(tuple(feature_config(p) for p in d["parts"]))


def stack_features(
    samples: np.ndarray,
    starts: np.ndarray,
    config: StackConfig,
    *,
    beats_per_bar: int | None = None,
    style: str | None = None,
    state: tuple[Any, ...] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``(features float32 [N, *config.output_shape], padded bool [N])``: each part's features
    (:func:`kinectdata.features.compute_features`, given the song's ``beats_per_bar``, its ``style`` and its own
    part of a stream's ``state``, :meth:`StackConfig.new_state`) concatenated on the first feature axis."""
    from kinectdata.features import compute_features

    states = state or (None,) * len(config.parts)
    made = [
        compute_features(samples, starts, part, beats_per_bar=beats_per_bar, style=style, state=part_state)
        for part, part_state in zip(config.parts, states)
    ]
    features = np.concatenate([f for f, _ in made], axis=1)
    padded = np.logical_or.reduce([p for _, p in made])
    return features, padded
