"""Per-component normalisation of target vectors into -0.9..0.9, fitted on a training split.

Fitting is streamable: compute :class:`NormStats` per recording (``NormStats.from_arrays``),
``merge`` those of the training split, then ``Normalizer.fit(stats, method)``. Every method is
``y = (x - offset) * scale`` per component, computed in float64 and stored as float32:

- ``maxabs`` (Yalta et al. 2016, the default): ``offset = 0``, ``scale = 0.9 / max|x|``;
- ``minmax`` (the authors' later code): ``offset = (min + max) / 2``, ``scale = 1.8 / (max - min)``,
  i.e. ``y = -0.9 + 1.8 * (x - min) / (max - min)``;
- ``none``: ``offset = 0``, ``scale = 1``: the values as they are, for targets that are in range
  by construction (the ``listen_to_dance`` spec's 0..1 coordinates, which a sigmoid output layer
  must reach: their expected range, :attr:`Normalizer.bounds`, is 0..1).

Degenerate components get ``scale = 1``: one with no valid training value (``offset = 0``; listed
in :attr:`Normalizer.degenerate`), a constant one under minmax (``offset`` = the constant, so it
maps to 0.0) and one whose training values are all 0 under maxabs. Values of other splits may
fall outside -0.9..0.9; they are not clipped (:func:`count_out_of_range` counts them).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from kinectdata.core.errors import ConfigError

if TYPE_CHECKING:
    from kinectdata.targets.specs import TargetSpec

LIMIT = 0.9
"""Training values are mapped into [-LIMIT, LIMIT]."""
METHODS = ("maxabs", "minmax", "none")
FORMULA = "y = (x - offset) * scale"


def _floats(a: np.ndarray) -> list[float | None]:
    """JSON-able list: NaN (an empty component's min/max) becomes None."""
    return [None if np.isnan(v) else float(v) for v in a]


def _array(values: Sequence[float | None]) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in values], dtype=np.float64)


@dataclass(frozen=True, eq=False)
class NormStats:
    """Per-component count, min and max of the valid values of target vectors.

    Attributes:
        count: [D] int64, number of valid values.
        min, max: [D] float64 over the valid values; NaN where ``count`` is 0.
        names: component names (``TargetSpec.component_names()``), or None.
    """

    count: np.ndarray
    min: np.ndarray
    max: np.ndarray
    names: tuple[str, ...] | None = None

    @property
    def dim(self) -> int:
        return int(self.count.shape[0])

    @classmethod
    def from_arrays(
        cls, values: np.ndarray, mask: np.ndarray | None = None, names: Sequence[str] | None = None
    ) -> NormStats:
        """Stats of values [N, D] (a recording's targets) where mask [N, D] is True (default: finite)."""
        values = np.asarray(values, dtype=np.float64)
        if values.ndim != 2:
            raise ConfigError(f"values must be [N, D], got shape {values.shape}")
        mask = np.isfinite(values) if mask is None else np.asarray(mask, dtype=bool)
        if mask.shape != values.shape:
            raise ConfigError(f"mask must have the shape of values {values.shape}, got {mask.shape}")
        count = mask.sum(axis=0).astype(np.int64)
        lo = np.where(mask, values, np.inf).min(axis=0, initial=np.inf)
        hi = np.where(mask, values, -np.inf).max(axis=0, initial=-np.inf)
        empty = count == 0
        lo[empty] = np.nan
        hi[empty] = np.nan
        return cls(count, lo, hi, _names(names, values.shape[1]))

    @classmethod
    def empty(cls, dim: int, names: Sequence[str] | None = None) -> NormStats:
        """Stats of no values (the identity of :meth:`merge`)."""
        return cls(np.zeros(dim, np.int64), np.full(dim, np.nan), np.full(dim, np.nan), _names(names, dim))

    def merge(self, *others: NormStats) -> NormStats:
        """Stats of the union of the values behind self and others (same dimension and names)."""
        count, lo, hi = self.count.copy(), self.min.copy(), self.max.copy()
        for o in others:
            if o.dim != self.dim or (self.names is not None and o.names is not None and o.names != self.names):
                raise ConfigError("cannot merge stats of different target layouts (dimension or component names)")
            count += o.count
            lo = np.fmin(lo, o.min)  # fmin/fmax ignore the NaN of empty components
            hi = np.fmax(hi, o.max)
        names = self.names if self.names is not None else next((o.names for o in others if o.names), None)
        return NormStats(count, lo, hi, names)

    def negated(self, components: np.ndarray) -> NormStats:
        """Stats of the values with the selected components [D] bool negated (min and max swap)."""
        flip = np.asarray(components, bool)
        lo = np.where(flip, -self.max, self.min)
        hi = np.where(flip, -self.min, self.max)
        return NormStats(self.count.copy(), lo, hi, self.names)

    @classmethod
    def merge_all(cls, stats: Iterable[NormStats]) -> NormStats:
        """Merge of a non-empty sequence of stats (e.g. one per training recording)."""
        stats = list(stats)
        if not stats:
            raise ConfigError("merge_all needs at least one NormStats")
        return stats[0].merge(*stats[1:])

    def to_dict(self) -> dict[str, Any]:
        """JSON-able dict (min/max of empty components are null)."""
        return {
            "count": [int(c) for c in self.count],
            "min": _floats(self.min),
            "max": _floats(self.max),
            "names": None if self.names is None else list(self.names),
        }

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any]) -> NormStats:
        names = doc.get("names")
        return cls(
            np.array(doc["count"], dtype=np.int64),
            _array(doc["min"]),
            _array(doc["max"]),
            None if names is None else tuple(names),
        )


def _names(names: Sequence[str] | None, dim: int) -> tuple[str, ...] | None:
    if names is None:
        return None
    names = tuple(names)
    if len(names) != dim:
        raise ConfigError(f"{len(names)} component names for {dim} components")
    return names


@dataclass(frozen=True, eq=False)
class Normalizer:
    """``y = (x - offset) * scale`` per component (see the module docstring for the methods).

    Attributes:
        method: ``"maxabs"`` or ``"minmax"``.
        scale, offset: [D] float64.
        count: [D] int64, valid training values per component (0: degenerate).
        names: component names, or None.
    """

    method: str
    scale: np.ndarray
    offset: np.ndarray
    count: np.ndarray
    names: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ConfigError(f"unknown normalisation method {self.method!r} (known: {', '.join(METHODS)})")
        for key in ("scale", "offset"):
            object.__setattr__(self, key, np.asarray(getattr(self, key), dtype=np.float64))
        object.__setattr__(self, "count", np.asarray(self.count, dtype=np.int64))
        if not (self.scale.shape == self.offset.shape == self.count.shape) or self.scale.ndim != 1:
            raise ConfigError("scale, offset and count must be [D] arrays of one length")
        object.__setattr__(self, "names", _names(self.names, self.dim))

    @property
    def dim(self) -> int:
        return int(self.scale.shape[0])

    @property
    def bounds(self) -> tuple[float, float]:
        """The range normalised values are expected in: -0.9..0.9, or 0..1 for ``none``."""
        return (0.0, 1.0) if self.method == "none" else (-LIMIT, LIMIT)

    @property
    def degenerate(self) -> tuple[int, ...]:
        """Indices of components with no valid training value (left unscaled)."""
        return tuple(int(i) for i in np.flatnonzero(self.count == 0))

    @classmethod
    def fit(cls, stats: NormStats, method: str = "maxabs") -> Normalizer:
        """The normaliser of a training split's (merged) stats."""
        if method not in METHODS:
            raise ConfigError(f"unknown normalisation method {method!r} (known: {', '.join(METHODS)})")
        D = stats.dim
        scale, offset = np.ones(D), np.zeros(D)
        ok = stats.count > 0
        lo, hi = stats.min[ok], stats.max[ok]
        if method == "none":
            pass
        elif method == "maxabs":
            m = np.maximum(np.abs(lo), np.abs(hi))
            scale[ok] = np.where(m > 0, LIMIT / np.where(m > 0, m, 1.0), 1.0)
        else:
            span = hi - lo
            scale[ok] = np.where(span > 0, 2 * LIMIT / np.where(span > 0, span, 1.0), 1.0)
            offset[ok] = np.where(span > 0, lo + span / 2, lo)
        return cls(method, scale, offset, stats.count.copy(), stats.names)

    def apply(self, values: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
        """Normalised float32 values [..., D]; 0.0 where mask (same shape) is False."""
        values = np.asarray(values, dtype=np.float64)
        self._check(values)
        y = (values - self.offset) * self.scale
        if mask is not None:
            y = np.where(mask, y, 0.0)
        return y.astype(np.float32)

    def invert(
        self, normalized: np.ndarray, spec: TargetSpec | None = None, *, mask: np.ndarray | None = None
    ) -> np.ndarray:
        """Float64 values [..., D] back in target units: the inverse of :meth:`apply`.

        Args:
            normalized: [..., D] (e.g. a model's output).
            spec: the TargetSpec of the layout; when given, each quaternion is rescaled to unit
                length (an all-zero quaternion, from masked entries under maxabs, stays zero).
            mask: [..., D] bool; where False the result is 0.0 (as :meth:`apply` stored it), which
                minmax needs for masked entries to come back as 0.0.
        """
        y = np.asarray(normalized, dtype=np.float64)
        self._check(y)
        x = y / self.scale + self.offset
        if mask is not None:
            x = np.where(mask, x, 0.0)
        if spec is not None:
            if spec.dim != self.dim or (self.names is not None and tuple(spec.component_names()) != self.names):
                raise ConfigError(f"target spec {spec.name!r} does not describe this normaliser's components")
            for s in spec.quaternion_slices:
                q = x[..., s]
                n = np.linalg.norm(q, axis=-1, keepdims=True)
                x[..., s] = np.where(n > 0, q / np.where(n > 0, n, 1.0), 0.0)
        return x

    def _check(self, a: np.ndarray) -> None:
        if a.shape[-1:] != (self.dim,):
            raise ConfigError(f"expected [..., {self.dim}] values, got shape {a.shape}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-able dict: method, formula, scale, offset, count (lists), names."""
        return {
            "method": self.method,
            "formula": FORMULA,
            "scale": [float(v) for v in self.scale],
            "offset": [float(v) for v in self.offset],
            "count": [int(c) for c in self.count],
            "names": None if self.names is None else list(self.names),
        }

    @classmethod
    def from_dict(cls, doc: Mapping[str, Any]) -> Normalizer:
        if doc.get("formula", FORMULA) != FORMULA:
            raise ConfigError(f"unsupported normaliser formula {doc['formula']!r} (expected {FORMULA!r})")
        names = doc.get("names")
        return cls(doc["method"], doc["scale"], doc["offset"], doc["count"], None if names is None else tuple(names))


def count_out_of_range(
    normalized: np.ndarray, mask: np.ndarray | None = None, bounds: tuple[float, float] = (-LIMIT, LIMIT)
) -> np.ndarray:
    """[D] int64: valid normalised values [N, D] outside ``bounds`` (values of other splits, unclipped)."""
    y = np.asarray(normalized)
    lo, hi = (np.asarray(b, dtype=y.dtype) for b in bounds)
    out = (y < lo) | (y > hi)
    if mask is not None:
        out &= np.asarray(mask, dtype=bool)
    return out.reshape(-1, y.shape[-1]).sum(axis=0).astype(np.int64)
