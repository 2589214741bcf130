"""A run's turning drawn at generation (:mod:`kinectdata.targets.turning`), wherever it makes positions.

``train`` fits the process on the training dancers and keeps it in the run's ``config.json``
(``turning``; absent: the run draws none, as runs trained before it). The network makes every frame
as it would without it; the turning is then added to the denormalised targets, held at 0 where the
music is silent (:func:`kinectdata.features.silence.silent_frames`):

- a whole song (``evaluate``'s free runs through :class:`TurnedKind`, ``generate``): one draw per
  frame from a generator seeded by ``seed`` and, in ``evaluate``, by the song's features too (each
  song its own turning, the same whichever control or order it comes in);
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
from kinectdata.targets.turning import TurningProcess, TurningStream, draw_turning_speed, turn_targets

__all__ = ["TurnedKind", "live_turning", "run_turning", "turn_song", "with_turning"]


def run_turning(config: dict[str, Any]) -> TurningProcess | None:
    """The turning process a run's ``config.json`` keeps, or None (a run trained without one)."""
    doc = config.get("turning")
    return None if doc is None else TurningProcess.from_dict(doc)


def turn_song(
    values: np.ndarray,
    features: np.ndarray,
    silence: np.ndarray,
    spec: TargetSpec,
    fps: float,
    process: TurningProcess,
    rng: np.random.Generator,
) -> np.ndarray:
    """Denormalised targets [T, D] of ``spec`` at ``fps``, of the frames whose features are
    ``features`` [T, *F], turned by a speed drawn from ``rng``, 0 where the features are ``silence``
    [*F] (:func:`~kinectdata.features.silence.silence_features`)."""
    speed = draw_turning_speed(process, ~silent_frames(features, silence), fps, rng)
    return turn_targets(values, spec, speed, fps, process)


def song_generator(seed: int, features: np.ndarray) -> np.random.Generator:
    """The draws of one song in ``evaluate``: seeded by ``seed`` and a CRC-32 of its features."""
    return np.random.default_rng([int(seed), zlib.crc32(np.ascontiguousarray(features).tobytes())])


class TurnedKind:
    """A model kind whose free runs are turned by its run's process (every other attribute is the
    kind's own): what ``evaluate`` runs, so that every figure and control sees the turning."""

    def __init__(self, kind: Any, config: dict[str, Any], process: TurningProcess, seed: int = 0):
        self.kind, self.process, self.seed = kind, process, int(seed)
        self.spec = TargetSpec.from_dict(config["dataset"]["target"])
        self.norm = Normalizer.from_dict(config["dataset"]["normalisation"])
        self.fps = float(config["dataset"]["fps"])
        self.silence = silence_features(config["dataset"]["features"], self.fps)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.kind, name)

    def _turned(self, audio: np.ndarray, run: np.ndarray) -> np.ndarray:
        made = audio[len(audio) - len(run) :]  # a free run makes frames 1..T-1 of features [T]
        values = self.norm.invert(run, self.spec)
        rng = song_generator(self.seed, audio)
        turned = turn_song(values, made, self.silence, self.spec, self.fps, self.process, rng)
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
    """``kind`` turned by its run's process (:class:`TurnedKind`), or ``kind`` itself when the run
    keeps none."""
    process = run_turning(config)
    return kind if process is None else TurnedKind(kind, config, process, seed)


def live_turning(config: dict[str, Any], seed: int = 0) -> tuple[TurningStream, np.ndarray] | None:
    """(the run's turning one frame at a time, the features [*F] of a silent frame), or None when the
    run keeps no turning process."""
    process = run_turning(config)
    if process is None:
        return None
    data = config["dataset"]
    fps = float(data["fps"])
    stream = TurningStream(process, TargetSpec.from_dict(data["target"]), fps, np.random.default_rng(int(seed)))
    return stream, silence_features(data["features"], fps)
