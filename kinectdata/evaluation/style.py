"""Is a generated dance recognisably its song's style? A classifier fitted on the real training
dances names the style of each generated one (docs/metrics.md, "Style").

The features of a dance (:func:`style_features`) are the field's, on SMPL-24 joints in metres:
the 72 kinetic features (each joint's mean squared horizontal and vertical speed and its mean
acceleration, :func:`~kinectdata.evaluation.metrics.kinetic.kinetic_features`, with the physical
acceleration: the peers' slip makes that feature the distance from where the sensor stood) as
their logarithms, and the 32 geometric ones (the share of frames where each of Müller's relations
holds, :func:`~kinectdata.evaluation.metrics.geometric.geometric_features`). The classifier
(:class:`StyleClassifier`) standardises them by the training dances and names the style whose
training dances' mean is nearest (Euclidean: a nearest-centroid classifier; with 27 waltzes and 2
cha-chas among tang2018's training dances, the nearest single dance would favour the majority).
Its leave-one-out accuracy on the training dances says how well the features tell the styles apart
in real dance; on tang2018's 33 training dances it is 32 of 33 (the nearest single dance: 31).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.metrics.geometric import geometric_features
from kinectdata.evaluation.metrics.kinetic import kinetic_features

LOG_FLOOR = 1e-6
"""Added to the kinetic features before their logarithm ((m/s)^2 and m/s^2): a joint that never moves."""


def style_features(positions: np.ndarray, fps: float) -> np.ndarray:
    """[104] float64: the logarithms of the 72 physical kinetic features and the 32 geometric
    features of one dance, ``positions`` [T, 24, 3] SMPL-24 joints in metres, y up, at ``fps``."""
    kinetic = kinetic_features(positions, fps, up_axis=1, peer_acceleration=False)
    geometric = geometric_features(positions, fps)
    return np.concatenate([np.log(np.asarray(kinetic, np.float64) + LOG_FLOOR), np.asarray(geometric, np.float64)])


@dataclass(frozen=True)
class StyleClassifier:
    """The style whose real training dances' mean is nearest (module docstring).

    Attributes:
        names: the training dances, [N].
        styles: their styles, [N].
        features: [N, F] their :func:`style_features`.
    """

    names: tuple[str, ...]
    styles: tuple[str, ...]
    features: np.ndarray

    def __post_init__(self) -> None:
        n = len(self.names)
        if n < 2 or len(self.styles) != n or np.shape(self.features)[0] != n:
            raise KinectDataError(
                f"a style classifier needs at least 2 training dances, each with its style and features; got "
                f"{n} dances, {len(self.styles)} styles and {np.shape(self.features)[0]} feature rows"
            )
        if not np.isfinite(self.features).all():
            raise KinectDataError("a style classifier's training features must be finite")

    def _scaled(self, x: np.ndarray, fit_rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        fit = self.features[fit_rows]
        mean, spread = fit.mean(axis=0), fit.std(axis=0)
        spread = np.where(spread > 0, spread, 1.0)  # a feature that never varies counts for nothing
        return (fit - mean) / spread, (np.atleast_2d(x) - mean) / spread

    def _nearest(self, x: np.ndarray, fit_rows: np.ndarray) -> list[tuple[str, str]]:
        fitted, asked = self._scaled(x, fit_rows)
        styles = np.array(self.styles)[fit_rows]
        held = sorted(set(styles))
        centres = np.stack([fitted[styles == s].mean(axis=0) for s in held])
        to_centre = ((asked[:, None, :] - centres[None]) ** 2).sum(axis=-1)
        to_dance = ((asked[:, None, :] - fitted[None]) ** 2).sum(axis=-1)
        dances = np.array(self.names)[fit_rows]
        return [(held[int(c)], str(dances[int(d)])) for c, d in zip(to_centre.argmin(axis=1), to_dance.argmin(axis=1))]

    def predict(self, features: np.ndarray) -> list[tuple[str, str]]:
        """(the style named, the nearest single training dance) of each row of ``features`` [M, F]."""
        return self._nearest(np.asarray(features, np.float64), np.ones(len(self.names), bool))

    def leave_one_out(self) -> int:
        """How many training dances the others name correctly (each left out of the fit in turn)."""
        right = 0
        for i in range(len(self.names)):
            rows = np.ones(len(self.names), bool)
            rows[i] = False
            right += self._nearest(self.features[i], rows)[0][0] == self.styles[i]
        return right


@dataclass(frozen=True)
class StyleReport:
    """The style of each generated dance as the classifier names it.

    Attributes:
        songs: per generated dance, (its song's style, the style named, the nearest training dance).
        held: the styles the training dances hold, with how many dances each.
        leave_one_out: training dances named right when left out, and how many there are.
        heard: per generated dance, the style its run heard in the music (a run whose features hear
            it, :mod:`kinectdata.features.style_input`); empty otherwise.
        real: per generated dance, the style the classifier names its song's real dance (where the
            split has it): what a run that danced as the dancers did would be named; empty otherwise.
    """

    songs: dict[str, tuple[str, str, str]]
    held: dict[str, int]
    leave_one_out: tuple[int, int]
    heard: dict[str, str] = field(default_factory=dict)
    real: dict[str, str] = field(default_factory=dict)

    @property
    def counted(self) -> list[str]:
        """The dances whose song's style some training dance holds (no other can be named right)."""
        return [name for name, (style, _, _) in self.songs.items() if style in self.held]

    @property
    def right(self) -> int:
        return sum(self.songs[n][0] == self.songs[n][1] for n in self.counted)

    @property
    def by_style(self) -> dict[str, tuple[int, int]]:
        """Per style of the counted songs: (dances named right, dances). One dance for every song,
        named the majority's style, scores the majority's share overall and 0 in every other style."""
        out: dict[str, tuple[int, int]] = {}
        for n in self.counted:
            style, said, _ = self.songs[n]
            right, total = out.get(style, (0, 0))
            out[style] = (right + (style == said), total + 1)
        return dict(sorted(out.items()))

    @property
    def heard_right(self) -> int | None:
        """Counted dances whose music the run heard as their song's style (None: it heard none)."""
        return sum(self.heard.get(n) == self.songs[n][0] for n in self.counted) if self.heard else None

    @property
    def danced_as_heard(self) -> int | None:
        """Counted dances named the style their run heard (None: it heard none). A run that dances
        what it hears names at most :attr:`heard_right` right: the rest is the hearing's."""
        return sum(self.heard.get(n) == self.songs[n][1] for n in self.counted) if self.heard else None

    def hearing(self) -> str:
        """How often the music was heard as its song's style and the dances follow what was heard
        ("" for a run that hears no style)."""
        if not self.heard:
            return ""
        n = len(self.counted)
        return (
            f"the music heard as its style in {self.heard_right} of {n}, "
            f"danced as heard in {self.danced_as_heard} of {n}"
        )

    @property
    def real_right(self) -> int | None:
        """Counted dances whose song's real dance the classifier names right (None: no real dance
        given): how many a run that danced as the dancers did would have right."""
        return sum(self.real.get(n) == self.songs[n][0] for n in self.counted) if self.real else None

    def dancers(self) -> str:
        """How many of the songs' real dances are named right ("" when none was given)."""
        if not self.real:
            return ""
        return f"the real dances of these songs named right in {self.real_right} of {len(self.counted)}"

    def verdict(self) -> str:
        named = ", ".join(f"{n} {style} -> {said}" for n, (style, said, _) in self.songs.items())
        per_style = ", ".join(f"{style} {r} of {t}" for style, (r, t) in self.by_style.items())
        right, n = self.leave_one_out
        heard = f"; {self.hearing()}" if self.heard else ""
        real = f"; {self.dancers()}" if self.real else ""
        return (
            f"dances in their song's style: {self.right} of {len(self.counted)} ({named}; by style {per_style}; "
            f"the nearest style's mean in the kinetic and geometric features of the {n} training dances, which "
            f"names {right} of them right when each is left out{real}{heard})"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "songs": {n: {"style": s, "named": said, "nearest": near} for n, (s, said, near) in self.songs.items()},
            "held": self.held,
            "counted": self.counted,
            "right": self.right,
            "by_style": {style: {"right": r, "dances": t} for style, (r, t) in self.by_style.items()},
            "leave_one_out": {"right": self.leave_one_out[0], "dances": self.leave_one_out[1]},
            "heard": self.heard,
            "heard_right": self.heard_right,
            "danced_as_heard": self.danced_as_heard,
            "hearing": self.hearing(),
            "real": self.real,
            "real_right": self.real_right,
            "dancers": self.dancers(),
            "verdict": self.verdict(),
        }


def style_report(
    training: Sequence[tuple[str, str, np.ndarray]],
    generated: Sequence[tuple[str, str, np.ndarray]],
    heard: dict[str, str] | None = None,
    real: Sequence[tuple[str, np.ndarray]] = (),
) -> StyleReport:
    """Name the style of each generated dance by the real training dances.

    Args:
        training: (name, style, :func:`style_features`) of each real training dance.
        generated: (name, its song's style, :func:`style_features`) of each generated dance.
        heard: the style the run heard in each generated dance's music, where it hears one.
        real: (name, :func:`style_features`) of the real dance of a generated dance's song, where
            there is one: named by the same classifier, the figure a run can be held to.
    """
    classifier = StyleClassifier(
        tuple(n for n, _, _ in training), tuple(s for _, s, _ in training), np.stack([f for _, _, f in training])
    )
    named = classifier.predict(np.stack([f for _, _, f in generated])) if generated else []
    songs = {n: (style, said, near) for (n, style, _), (said, near) in zip(generated, named)}
    held = dict(sorted(Counter(classifier.styles).items()))
    real = [(n, f) for n, f in real if n in songs]
    real_named = classifier.predict(np.stack([f for _, f in real])) if real else []
    return StyleReport(
        songs,
        held,
        (classifier.leave_one_out(), len(classifier.names)),
        dict(heard or {}),
        {n: said for (n, _), (said, _) in zip(real, real_named)},
    )
