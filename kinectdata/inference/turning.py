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

A travel fitted with its floor (:mod:`kinectdata.targets.travel`) is pulled towards the floor's
centre from where the dance starts: in ``evaluate`` the recording's root anchor (the kind is told,
:meth:`TurnedKind.know_place`), in ``generate`` the start's anchor (a recording's; the floor rule's
dance starts at the floor's centre), in ``live`` the centre.

A run trained with ``by_metre`` also keeps each metre's processes (``drawn_by_metre``): a song whose
metre is known (given, listed in the recordings manifest, found by the build or estimated from the
music, as its bar features are) is drawn its metre's where the run has them, else the pooled ones.

A run that kept its network's sway along the floor (``train --sway``, :mod:`kinectdata.targets.sway`)
scales the network's root x and z by it before the turning (:func:`run_sway`); it is part of every
free run as the drawn processes are.

Runs that reset their state every L frames (``evaluate``'s "with reset" figures, the yalta paper's
table) are not turned: those figures measure the network's prediction from true poses.

A run that learnt its poses facing one way (``train --facing``, :mod:`kinectdata.targets.facing`)
starts every free run from its first pose turned to face that way (:func:`faced_first_pose`), and its
frames are turned back by as much (:func:`~kinectdata.targets.facing.turn_about_root`), so that the
dance goes on from the way the first pose stood.
"""

from __future__ import annotations

import zlib
from typing import Any

import numpy as np

from kinectdata.core.errors import ConfigError
from kinectdata.features.silence import silence_features, silent_frames
from kinectdata.inference.smoothing import run_smoothing, smooth_motion
from kinectdata.inference.style_tempo import on_song_clock, run_style_tempo
from kinectdata.targets.facing import faced, trunk_pairs, turn_about_root
from kinectdata.targets.normalization import Normalizer
from kinectdata.targets.specs import TargetSpec
from kinectdata.targets.sway import SwayGain, calm_sway
from kinectdata.targets.travel import TravelProcess, TravelStream, draw_travel, travel_targets
from kinectdata.targets.turning import TurningProcess, TurningStream, draw_turning_speed, turn_targets

__all__ = [
    "DrawnStream",
    "TurnedKind",
    "drawn_line",
    "faced_first_pose",
    "live_turning",
    "run_faces",
    "run_sway",
    "run_travel",
    "run_turning",
    "travel_generator",
    "turn_song",
    "with_turning",
]


def _by_metre(config: dict[str, Any], drawn: str, beats_per_bar: int | None) -> dict[str, Any] | None:
    """The ``drawn`` process's record for a song of ``beats_per_bar``: its metre's (``drawn_by_metre``)
    where the run fitted one, else the pooled one; None where the run keeps no pooled one (trained
    without it, or left out by the caller: ``--no-turning``, ``--no-travel``)."""
    doc = config.get(drawn)
    if doc is None or beats_per_bar is None:
        return doc
    return (config.get("drawn_by_metre") or {}).get(str(int(beats_per_bar)), {}).get(drawn, doc)


def run_turning(config: dict[str, Any], beats_per_bar: int | None = None) -> TurningProcess | None:
    """The turning process a run's ``config.json`` keeps for a song of ``beats_per_bar`` (None:
    the metre unknown, the pooled one), or None (a run trained without one)."""
    doc = _by_metre(config, "turning", beats_per_bar)
    return None if doc is None else TurningProcess.from_dict(doc)


def run_travel(config: dict[str, Any], beats_per_bar: int | None = None) -> TravelProcess | None:
    """The travel process a run's ``config.json`` keeps for a song of ``beats_per_bar``, as
    :func:`run_turning`, or None (a run trained without one)."""
    doc = _by_metre(config, "travel", beats_per_bar)
    return None if doc is None else TravelProcess.from_dict(doc)


def run_sway(config: dict[str, Any]) -> SwayGain | None:
    """The gain a run's ``config.json`` keeps for its network's sway along the floor, or None (a run
    trained without it, or left out by the caller: ``evaluate``'s ``sway=False``)."""
    doc = config.get("sway")
    return None if doc is None else SwayGain.from_dict(doc)


def drawn_line(config: dict[str, Any], beats_per_bar: int | None = None) -> str:
    """What a run draws at generation, for a printout: its processes' lines (a song of
    ``beats_per_bar``'s; None: the pooled ones, and the metres the run has its own for), or that it
    draws none."""
    drawn = (run_sway(config), run_turning(config, beats_per_bar), run_travel(config, beats_per_bar))
    lines = [p.describe() for p in drawn if p]
    if not lines:
        return "no turning or travel drawn"
    metres = sorted(int(m) for m in config.get("drawn_by_metre") or {})
    if beats_per_bar is not None and str(int(beats_per_bar)) in (config.get("drawn_by_metre") or {}):
        lines.append(f"those of the training dances of {int(beats_per_bar)} beats a bar")
    elif metres:
        lines.append(f"songs of {' or '.join(map(str, metres))} beats a bar are drawn their metre's")
    return "; ".join(lines)


def run_faces(config: dict[str, Any]) -> bool:
    """Whether a run learnt its poses facing one way: trained with ``facing`` and its turning drawn,
    on targets that can be turned (as the training loop decides)."""
    train = config.get("train", {})
    if not (train.get("facing") and train.get("turning", True)) or not config["dataset"].get("root_centre"):
        return False
    try:
        trunk_pairs(TargetSpec.from_dict(config["dataset"]["target"]))
    except ConfigError:
        return False
    return True


def faced_first_pose(config: dict[str, Any], pose: np.ndarray) -> tuple[np.ndarray, float]:
    """A free run's first pose [D] (normalised, filled) turned to face the way the run's training
    poses faced, and the heading (rad) it was turned from; the pose as it is and 0 for a run that
    did not learn facing one way (:func:`run_faces`)."""
    pose = np.asarray(pose)
    if not run_faces(config):
        return pose, 0.0
    spec = TargetSpec.from_dict(config["dataset"]["target"])
    norm = Normalizer.from_dict(config["dataset"]["normalisation"])
    turned, heading = faced(norm.invert(pose[None].astype(np.float64), spec)[0], spec)
    return norm.apply(turned[None])[0].astype(pose.dtype), float(heading)


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
    start: np.ndarray | None = None,
) -> np.ndarray:
    """Denormalised targets [T, D] of ``spec`` at ``fps``, of the frames whose features are
    ``features`` [T, *F], turned by a speed drawn from ``rng`` and then moved by a ``travel`` drawn
    from ``travel_rng`` (either process None: not drawn) from ``start`` ([3] where the dance stands,
    a root anchor, metres; None: no known place), both still where the features are ``silence``
    [*F] (:func:`~kinectdata.features.silence.silence_features`)."""
    live = ~silent_frames(features, silence)
    if process is not None:
        values = turn_targets(values, spec, draw_turning_speed(process, live, fps, rng), fps, process)
    if travel is not None:
        floor = None if start is None else np.asarray(start, np.float64)[[0, 2]]
        values = travel_targets(values, spec, draw_travel(travel, live, fps, travel_rng or rng, floor), fps)
    return values


def features_key(features: np.ndarray) -> int:
    """A song's features [T, *F] as ``evaluate`` knows the song by: their bytes' CRC-32."""
    return zlib.crc32(np.ascontiguousarray(features).tobytes())


def song_generator(seed: int, features: np.ndarray) -> np.random.Generator:
    """The turning's draws of one song in ``evaluate``: seeded by ``seed`` and a CRC-32 of its features."""
    return np.random.default_rng([int(seed), features_key(features)])


def travel_generator(seed: int, features: np.ndarray | None = None) -> np.random.Generator:
    """The travel's draws: the turning's seed (``seed``, and the song's features' CRC-32 in
    ``evaluate``) with a 1 after it."""
    if features is None:
        return np.random.default_rng([int(seed), 1])
    return np.random.default_rng([int(seed), features_key(features), 1])


class TurnedKind:
    """A model kind whose free runs are turned and moved by its run's processes, then smoothed as the
    run says (:mod:`kinectdata.inference.smoothing`; every other attribute is the kind's own): what
    ``evaluate`` runs, so that every figure and control sees them. A song it is told is played at
    another tempo (:meth:`know_played`, :mod:`kinectdata.inference.style_tempo`) is danced by the
    network on the played features and warped back onto the song's clock before all that, as
    ``generate`` does. What it is told of a song (its metre, its played features) holds for the
    song's opening too: a control that cuts a song to another's length dances that song's music as
    the song is danced."""

    def __init__(
        self,
        kind: Any,
        config: dict[str, Any],
        process: TurningProcess | None,
        seed: int = 0,
        travel: TravelProcess | None = None,
    ):
        self.kind, self.process, self.travel, self.seed = kind, process, travel, int(seed)
        self.config = config
        self.spec = TargetSpec.from_dict(config["dataset"]["target"])
        self.norm = Normalizer.from_dict(config["dataset"]["normalisation"])
        self.fps = float(config["dataset"]["fps"])
        self.silence = silence_features(config["dataset"]["features"], self.fps)
        self.metres: dict[int, int] = {}  # a song's features' CRC-32 -> its beats per bar
        self.played: dict[int, tuple[np.ndarray, float]] = {}  # a song's features' CRC-32 -> (played, factor)
        self.places: dict[int, np.ndarray] = {}  # a song's features' CRC-32 -> where its dance starts [3]
        self.songs: dict[int, np.ndarray] = {}  # a song's features' CRC-32 -> the features, for its openings
        self.smooth_hz = run_smoothing(config)
        self.sway = run_sway(config)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.kind, name)

    def describe(self) -> str:
        """What is drawn, one line (:func:`drawn_line`)."""
        return drawn_line(self.config)

    def know_metre(self, features: np.ndarray, beats_per_bar: int | None) -> None:
        """Draw the song whose features are ``features`` [T, *F] (the whole song, as a free run is
        given it) with its metre's processes, where the run has them; None: the pooled ones."""
        key = self._know(features)
        if beats_per_bar is None:
            self.metres.pop(key, None)
        else:
            self.metres[key] = int(beats_per_bar)

    def know_place(self, features: np.ndarray, anchor: np.ndarray | None) -> None:
        """Start the travel of the song whose features are ``features`` [T, *F] at ``anchor`` ([3]
        metres, the recording's root anchor: its travel is pulled towards the floor's centre from
        there); None: no known place (the floor's centre). Nothing to tell a run that draws no travel."""
        if self.travel is None:
            return
        key = self._know(features)
        if anchor is None:
            self.places.pop(key, None)
        else:  # a place not on the floor (or not finite) starts at the centre: TravelProcess.start_offset
            self.places[key] = np.asarray(anchor, np.float64)

    def know_played(self, features: np.ndarray, played: np.ndarray, factor: float) -> None:
        """Dance the song whose features are ``features`` [T, *F] from ``played`` [T', *F], the
        features of its music played ``factor`` times as fast (:mod:`kinectdata.inference.style_tempo`),
        the network's frames warped back onto the song's T frames."""
        self.played[self._know(features)] = (played, float(factor))

    def _know(self, features: np.ndarray) -> int:
        key = features_key(features)
        self.songs[key] = np.asarray(features)
        return key

    def _song_key(self, audio: np.ndarray) -> int:
        """The key of the song ``audio`` [T, *F] is: its own when told of, else that of a song told of
        whose opening it is (a control's cut), else its own."""
        key = features_key(audio)
        if key in self.songs:
            return key
        for known, whole in self.songs.items():
            if (
                len(audio) < len(whole)
                and whole.shape[1:] == audio.shape[1:]
                and np.array_equal(whole[: len(audio)], audio)
            ):
                return known
        return key

    def _played(self, audio: np.ndarray) -> tuple[np.ndarray, float] | None:
        """(played features, factor) for ``audio`` [T, *F], a song told played or its opening (the
        played frames that cover it), or None: danced as it is."""
        if not self.played:
            return None
        key = self._song_key(audio)
        found = self.played.get(key)
        if found is None or len(self.songs[key]) == len(audio):
            return found
        played, factor = found
        frames = int(np.ceil((len(audio) - 1) / factor)) + 2  # the played frames that cover the opening
        return played[:frames], factor

    def _network_runs(
        self, net: Any, audios: list[np.ndarray], firsts: list[np.ndarray], reset_every: int | None
    ) -> list[np.ndarray]:
        """The network's free runs [T-1, D] of songs [T, *F] from their first poses, each song told
        played at another tempo danced on its played features and warped back onto its clock."""
        played = [self._played(np.asarray(a)) for a in audios]
        inputs = [a if p is None else p[0] for a, p in zip(audios, played)]
        runs = self.kind.free_runs(net, inputs, firsts, reset_every)
        return [
            r if p is None else on_song_clock(np.asarray(r), f, p[1], len(a))
            for r, p, f, a in zip(runs, played, firsts, audios)
        ]

    def _turned(self, audio: np.ndarray, run: np.ndarray, heading: float = 0.0) -> np.ndarray:
        made = audio[len(audio) - len(run) :]  # a free run makes frames 1..T-1 of features [T]
        key = self._song_key(audio) if (self.metres or self.places) else None
        metre = self.metres.get(key) if self.metres else None
        process, travel = self.process, self.travel
        if metre is not None:
            process = run_turning(self.config, metre) if process is not None else None
            travel = run_travel(self.config, metre) if travel is not None else None
        values = self.norm.invert(run, self.spec)
        if self.sway is not None:
            values = calm_sway(values, self.spec, self.sway)
        if heading:  # the run faced one way: back to where its first pose stood
            values = turn_about_root(values, self.spec, heading)
        turned = turn_song(
            values,
            made,
            self.silence,
            self.spec,
            self.fps,
            process,
            song_generator(self.seed, audio),
            travel,
            travel_generator(self.seed, audio),
            self.places.get(key) if self.places else None,
        )
        if self.smooth_hz is not None:
            turned = smooth_motion(turned, self.spec, self.fps, self.smooth_hz)
        return self.norm.apply(turned)

    def _back(self, run: Any, heading: float) -> Any:
        """A reset run (not turned) back to where its first pose stood, when that pose was faced."""
        if not heading:
            return run
        values = turn_about_root(self.norm.invert(np.asarray(run), self.spec), self.spec, heading)
        return self.norm.apply(values).astype(np.asarray(run).dtype)

    def free_run(self, net: Any, audio: np.ndarray, first_pose: np.ndarray, reset_every: int | None = None) -> Any:
        first, heading = faced_first_pose(self.config, first_pose)
        run = self._network_runs(net, [audio], [first], reset_every)[0]
        if reset_every is not None:
            return self._back(run, heading)
        return self._turned(np.asarray(audio), np.asarray(run), heading)

    def free_runs(
        self, net: Any, audios: list[np.ndarray], first_poses: list[np.ndarray], reset_every: int | None = None
    ) -> list[np.ndarray]:
        started = [faced_first_pose(self.config, p) for p in first_poses]
        runs = self._network_runs(net, audios, [p for p, _ in started], reset_every)
        if reset_every is not None:
            return [self._back(r, h) for r, (_, h) in zip(runs, started)]
        return [self._turned(np.asarray(a), np.asarray(r), h) for a, r, (_, h) in zip(audios, runs, started)]


def with_turning(kind: Any, config: dict[str, Any], seed: int = 0) -> Any:
    """``kind`` turned and moved by its run's processes and smoothed as the run says (:class:`TurnedKind`),
    or ``kind`` itself when the run keeps neither process nor a sway gain, did not learn its poses facing one way, is
    not smoothed (:mod:`kinectdata.inference.smoothing`) and plays no song at its style's tempo
    (:mod:`kinectdata.inference.style_tempo`)."""
    process, travel = run_turning(config), run_travel(config)
    plain = run_smoothing(config) is None and run_style_tempo(config) is None and run_sway(config) is None
    if process is None and travel is None and not run_faces(config) and plain:
        return kind
    return TurnedKind(kind, config, process, seed, travel)


class DrawnStream:
    """A run's sway gain, turning and travel one frame at a time (any may be absent)."""

    def __init__(
        self,
        turning: TurningStream | None,
        travel: TravelStream | None,
        sway: tuple[SwayGain, TargetSpec] | None = None,
    ):
        self.turning, self.travel, self.sway = turning, travel, sway

    def step(self, values: np.ndarray, live: bool) -> np.ndarray:
        if self.sway is not None:
            values = calm_sway(np.asarray(values)[None], self.sway[1], self.sway[0])[0]
        if self.turning is not None:
            values = self.turning.step(values, live)
        if self.travel is not None:
            values = self.travel.step(values, live)
        return values


def live_turning(
    config: dict[str, Any], seed: int = 0, beats_per_bar: int | None = None
) -> tuple[DrawnStream, np.ndarray] | None:
    """(the run's sway gain, turning and travel one frame at a time, a song of ``beats_per_bar``'s
    (None: the pooled ones), the features [*F] of a silent frame), or None when the run keeps none."""
    process, travel, sway = run_turning(config, beats_per_bar), run_travel(config, beats_per_bar), run_sway(config)
    if process is None and travel is None and sway is None:
        return None
    data = config["dataset"]
    fps = float(data["fps"])
    spec = TargetSpec.from_dict(data["target"])
    turning = None if process is None else TurningStream(process, spec, fps, np.random.default_rng(int(seed)))
    moving = None if travel is None else TravelStream(travel, spec, fps, travel_generator(seed))
    calmed = None if sway is None else (sway, spec)
    return DrawnStream(turning, moving, calmed), silence_features(data["features"], fps)
