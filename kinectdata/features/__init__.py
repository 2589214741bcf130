"""Audio features for the network input, and a small registry of extractors by name (lhotse-style).

An extractor is a callable ``(samples, starts, config, *, chunk_frames=...) -> (features, padded)``:
``samples`` [S] mono float audio, ``starts`` [N] int64 slice starts (may run off either end),
``features`` float32 [N, ...] and ``padded`` bool [N] (see :func:`stft_features`). Built in:

- ``"stft"``: :func:`kinectdata.features.stft.stft_features` with a :class:`StftConfig`
  (presets in :data:`PRESETS`: ``"yalta2016"``, ``"motion_dance"``).

Register another one with the decorator ``@register_extractor("mel")`` or the call
``register_extractor("mel", fn)``; look one up with ``get_extractor(name)``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from kinectdata.features.stft import PRESETS, StftConfig, stft_features

__all__ = ["PRESETS", "StftConfig", "extractor_names", "get_extractor", "register_extractor", "stft_features"]

Extractor = Callable[..., Any]

_EXTRACTORS: dict[str, Extractor] = {}


def register_extractor(name: str, fn: Extractor | None = None, *, replace: bool = False):
    """Register ``fn`` under ``name``; without ``fn``, return a decorator that does.

    Raises ValueError if ``name`` is taken by another callable (unless ``replace=True``);
    registering the same callable again is a no-op. Returns ``fn`` (so the decorator keeps it).
    """
    if not isinstance(name, str) or not name:
        raise ValueError(f"extractor name must be a non-empty string, got {name!r}")

    def add(f: Extractor) -> Extractor:
        if not callable(f):
            raise TypeError(f"extractor {name!r} must be callable, got {type(f).__name__}")
        old = _EXTRACTORS.get(name)
        if old is not None and old is not f and not replace:
            raise ValueError(f"extractor {name!r} is already registered ({old!r}); pass replace=True")
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


register_extractor("stft", stft_features)
