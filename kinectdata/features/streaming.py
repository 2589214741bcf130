"""Per-frame features of streamed audio: blocks in, frame features out as soon as they are complete.

The dataset builder and ``generate`` read audio in blocks (:class:`~kinectdata.align.audio.AudioReader`);
:class:`StreamingFeatures` holds only the samples that frames still need, so memory stays
bounded, and its output equals the extractor's (:func:`~kinectdata.features.compute_features`) on
the whole audio.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from kinectdata.core.errors import ConfigError

from . import FeatureConfig, compute_features, feature_state, needs_style


class StreamingFeatures:
    """Feeds streamed audio blocks to a feature extractor, keeping only the samples still needed.

    ``starts`` [N] are absolute sample indices of the frames' slices; a frame is computed as soon
    as the samples it reads (``config.span`` around its start) have arrived, the rest at
    :meth:`finish` (zero-padded and flagged past the end). ``beats_per_bar``: the song's metre, for
    features that count its bars (:func:`~kinectdata.features.needs_metre`). ``style``: the song's
    dance style, for features with a style input (:func:`~kinectdata.features.needs_style`: required
    there, since a block is not the whole song). ``live``: blocks of a
    frame or so, which keep what one call computed for the next (:func:`~kinectdata.features.feature_state`).
    """

    def __init__(
        self,
        starts: np.ndarray,
        config: FeatureConfig,
        sink: Callable[[int, np.ndarray, np.ndarray], None],
        beats_per_bar: int | None = None,
        live: bool = False,
        style: str | None = None,
    ):
        if style is None and needs_style(config):
            raise ConfigError(
                "streamed features with a style input need the song's style, heard from the whole song first"
            )
        self.starts, self.config, self.sink = starts, config, sink
        self.beats_per_bar, self.style = beats_per_bar, style
        self.lo, hi = config.span
        self.ends = starts + hi
        self.k = 0
        self.buffer = np.zeros(0, np.float32)
        self.buffer_start = 0
        self.state = feature_state(config, live)  # what frames that depend on earlier frames carry on

    def push(self, block: np.ndarray) -> None:
        self.buffer = np.concatenate([self.buffer, block])
        ready = int(np.searchsorted(self.ends, self.buffer_start + self.buffer.size, side="right"))
        if ready > self.k:
            self._emit(ready)
        keep_from = self.starts[self.k] + self.lo - self.buffer_start if self.k < self.starts.size else self.buffer.size
        keep_from = int(np.clip(keep_from, 0, self.buffer.size))
        self.buffer = self.buffer[keep_from:]
        self.buffer_start += keep_from

    def finish(self) -> None:
        if self.k < self.starts.size:
            self._emit(self.starts.size)

    def _emit(self, upto: int) -> None:
        _set_origin(self.state, self.buffer_start)
        feats, padded = compute_features(
            self.buffer,
            self.starts[self.k : upto] - self.buffer_start,
            self.config,
            beats_per_bar=self.beats_per_bar,
            style=self.style,
            state=self.state,
        )
        self.sink(self.k, feats, padded)
        self.k = upto


def _set_origin(state, origin: int) -> None:
    """Tell the pulse's kept onset spectra (:class:`~kinectdata.features.rhythm.OnsetSpectra`) in a
    stream state where the buffer passed next starts in the stream."""
    if isinstance(state, tuple):
        for part in state:
            _set_origin(part, origin)
    elif getattr(state, "spectra", None) is not None:
        state.spectra.origin = origin
