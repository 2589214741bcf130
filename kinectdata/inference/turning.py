"""A run's turning and travel drawn at generation (:mod:`kinectdata.targets.turning`,
:mod:`kinectdata.targets.travel`), wherever it makes positions.

``train`` fits the processes on the training dancers and keeps them in the run's ``config.json``
(``turning``, ``travel``; absent: the run draws none, as runs trained before them). The network makes
every frame as it would without them; the turning is then added to the denormalised targets, and
the travel after it, both held still where the music is silent
(:func:`kinectdata.features.silence.silent_frames`):

- a whole song (``evaluate``'s free runs through :class:`TurnedKind`, ``generate``): draws per frame
  from generators seeded by ``seed`` and, in ``evaluate``, by the song's features too (each song its
  own turning and travel, the same whichever control or order it comes in); the travel's generator
  is the turning's seed with a 1 after it, so that a run with both turns as one with the turning alone;
- one frame at a time (``live``): :func:`live_turning`, seeded by ``seed`` alone; on the same audio
  and seed its frames are ``generate``'s.

Runs that reset their state every L frames (``evaluate``'s "with reset" figures, the yalta paper's
table) are not turned: those figures measure the network's prediction from true poses.
"""

from __future__ import annotations

import zlib
from typing import Any

import numpy as np

from kinectdata.features.silence import silence_features, silent_frames
from kinectdata.targets.normalization import Normalizer
from kinectdata.targets.specs import TargetSpec
from kinectdata.targets.travel import TravelProcess, TravelStream, draw_travel, travel_targets
from kinectdata.targets.turning import TurningProcess, TurningStream, draw_turning_speed, turn_targets

__all__ = [
    "DrawnStream",
    "TurnedKind",
    "drawn_line",
    "live_turning",
    "run_travel",
    "run_turning",
    "travel_generator",
    "turn_song",
    "with_turning",
]


def run_turning(config: dict[str, Any]) -> TurningProcess | None:
    """The turning process a run's ``config.json`` keeps, or None (a run trained without one)."""
    doc = config.get("turning")
    return None if doc is None else TurningProcess.from_dict(doc)


def run_travel(config: dict[str, Any]) -> TravelProcess | None:
    """The travel process a run's ``config.json`` keeps, or None (a run trained without one)."""
    doc = config.get("travel")
    return None if doc is None else TravelProcess.from_dict(doc)


def drawn_line(config: dict[str, Any]) -> str:
    """What a run draws at generation, for a printout: its processes' lines, or that it draws none."""
    lines = [p.describe() for p in (run_turning(config), run_travel(config)) if p is not None]
    return "; ".join(lines) if lines else "no turning or travel drawn"


def turn_song(
    values: np.ndarray,
    features: np.ndarray,
    silence: np.ndarray,
    spec: TargetSpec,
    fps: float,
    process: TurningProcess | None,
    rng: np.random.Generator,
    travel: TravelProcess | None = None,
    travel_rng: np.random.Generator | None = None,
) -> np.ndarray:
    """Denormalised targets [T, D] of ``spec`` at ``fps``, of the frames whose features are
    ``features`` [T, *F], turned by a speed drawn from ``rng`` and then moved by a ``travel`` drawn
    from ``travel_rng`` (either process None: not drawn), both still where the features are
    ``silence`` [*F] (:func:`~kinectdata.features.silence.silence_features`)."""
    live = ~silent_frames(features, silence)
    if process is not None:
        values = turn_targets(values, spec, draw_turning_speed(process, live, fps, rng), fps, process)
    if travel is not None:
        values = travel_targets(values, spec, draw_travel(travel, live, fps, travel_rng or rng))
    return values


def song_generator(seed: int, features: np.ndarray) -> np.random.Generator:
    """The turning's draws of one song in ``evaluate``: seeded by ``seed`` and a CRC-32 of its features."""
    return np.random.default_rng([int(seed), zlib.crc32(np.ascontiguousarray(features).tobytes())])


def travel_generator(seed: int, features: np.ndarray | None = None) -> np.random.Generator:
    """The travel's draws: the turning's seed (``seed``, and the song's features' CRC-32 in
    ``evaluate``) with a 1 after it."""
    if features is None:
        return np.random.default_rng([int(seed), 1])
    return np.random.default_rng([int(seed), zlib.crc32(np.ascontiguousarray(features).tobytes()), 1])


class TurnedKind:
    """A model kind whose free runs are turned and moved by its run's processes (every other attribute
    is the kind's own): what ``evaluate`` runs, so that every figure and control sees them."""

    def __init__(
        self,
        kind: Any,
        config: dict[str, Any],
        process: TurningProcess | None,
        seed: int = 0,
        travel: TravelProcess | None = None,
    ):
        self.kind, self.process, self.travel, self.seed = kind, process, travel, int(seed)
        self.spec = TargetSpec.from_dict(config["dataset"]["target"])
        self.norm = Normalizer.from_dict(config["dataset"]["normalisation"])
        self.fps = float(config["dataset"]["fps"])
        self.silence = silence_features(config["dataset"]["features"], self.fps)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.kind, name)

    def describe(self) -> str:
        """What is drawn, one line."""
        return "; ".join(p.describe() for p in (self.process, self.travel) if p is not None)

    def _turned(self, audio: np.ndarray, run: np.ndarray) -> np.ndarray:
        made = audio[len(audio) - len(run) :]  # a free run makes frames 1..T-1 of features [T]
        values = self.norm.invert(run, self.spec)
        turned = turn_song(
            values,
            made,
            self.silence,
            self.spec,
            self.fps,
            self.process,
            song_generator(self.seed, audio),
            self.travel,
            travel_generator(self.seed, audio),
        )
        return self.norm.apply(turned)

    def free_run(self, net: Any, audio: np.ndarray, first_pose: np.ndarray, reset_every: int | None = None) -> Any:
        run = self.kind.free_run(net, audio, first_pose, reset_every)
        return run if reset_every is not None else self._turned(np.asarray(audio), np.asarray(run))

    def free_runs(
        self, net: Any, audios: list[np.ndarray], first_poses: list[np.ndarray], reset_every: int | None = None
    ) -> list[np.ndarray]:
        runs = self.kind.free_runs(net, audios, first_poses, reset_every)
        if reset_every is not None:
            return runs
        return [self._turned(np.asarray(a), np.asarray(r)) for a, r in zip(audios, runs)]


def with_turning(kind: Any, config: dict[str, Any], seed: int = 0) -> Any:
    """``kind`` turned and moved by its run's processes (:class:`TurnedKind`), or ``kind`` itself when
    the run keeps neither."""
    process, travel = run_turning(config), run_travel(config)
    if process is None and travel is None:
        return kind
    return TurnedKind(kind, config, process, seed, travel)


class DrawnStream:
    """A run's turning and travel one frame at a time (either may be absent)."""

    def __init__(self, turning: TurningStream | None, travel: TravelStream | None):
        self.turning, self.travel = turning, travel

    def step(self, values: np.ndarray, live: bool) -> np.ndarray:
        if self.turning is not None:
            values = self.turning.step(values, live)
        if self.travel is not None:
            values = self.travel.step(values, live)
        return values


def live_turning(config: dict[str, Any], seed: int = 0) -> tuple[DrawnStream, np.ndarray] | None:
    """(the run's turning and travel one frame at a time, the features [*F] of a silent frame), or
    None when the run keeps neither process."""
    process, travel = run_turning(config), run_travel(config)
    if process is None and travel is None:
        return None
    data = config["dataset"]
    fps = float(data["fps"])
    spec = TargetSpec.from_dict(data["target"])
    turning = None if process is None else TurningStream(process, spec, fps, np.random.default_rng(int(seed)))
    moving = None if travel is None else TravelStream(travel, spec, fps, travel_generator(seed))
    return DrawnStream(turning, moving), silence_features(data["features"], fps)
