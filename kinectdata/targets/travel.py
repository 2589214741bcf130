"""The dancer's travel across the floor, drawn at generation: the other part of a dance the music does
not fix (the first is the turning, :mod:`kinectdata.targets.turning`).

Ballroom dancers travel: on tang2018's training dances the root lies 0.8 to 5.5 m from where the
dance began, 2.8 m in the median dance, averaged over the dance. A network trained to a pose loss
averages which way a dancer goes and stays where it starts (its root within a metre), and the
field's kinetic features are mostly that distance (the peers' acceleration slip makes a third of
them each joint's distance from the first frame's root: real dances with their travel taken out
score FID_k 344 against other real dances, 42 with it; docs/notebook/2026-12-real-dance-variety.md). So the travel is a
random process fitted on the training dancers (:func:`fit_travel`: the ``train`` command keeps it in
the run) and drawn wherever a run makes positions, while the network makes the rest.

The process: each horizontal axis's velocity (m/s), slowed to below :data:`CUTOFF_HZ` (what a
dancer's steps add to it faster is the network's to make), is the two-stage process of
:mod:`kinectdata.targets.slow_process` scaled to the dancers' root mean square, with their time
constant; the two axes are drawn independently. Its sum over frames, over fps, is added to the
root's travel: the body moves with it, after the turning, over the standing foot where the target
has both legs (:mod:`kinectdata.targets.foot_lock`: the standing foot stays planted, the swinging one
catches up, the other foot stands where the leg reaches no further, the knees bend to keep the
legs' lengths). Where the music is silent the velocity is held at 0 (the dancer stops with the
music). Drawn over as many frames as each training dance
has, it puts the dancer 1.2 to 5.6 m from the start on average (median 2.9 m; the dancers' 0.8 to
5.5, 2.8).

Nothing in that process pulls the dancer back, and a ballroom is a floor: on tang2018's three folds
the training dancers' roots stay 2.4 to 2.6 m on average over a dance from the mean of where they
stood, the unbounded process drawn from their starts over their dances 3.3 to 3.5 m, and the aist
protocol's kinetic features (whole songs, raw positions: the acceleration slip's third value is each
joint's distance from the origin) score that distance. So :func:`fit_travel`, given where each
training dance stood (its root anchor), also keeps the floor: its centre (the mean of the dancers'
roots, x and z in their world), its radius (the farthest a root was from it) and a pull towards the
centre, a first-order decay of the offset from it whose time constant is the one that gives the
dancers' mean squared distance from the centre, in expectation, from their own starts over their own
lengths (:func:`pull_time_constant`). A draw starts where the dance begins (a recording's root
anchor, x and z); a dance of no known place, or one that begins outside the floor (a recording from
another room), starts at the centre of a floor of its own. A pulled draw is held still in silence as
the unbounded one is.

Only 3-D position targets centred on their root (``--root-centre``) travel: the root's values are
its travel. :func:`travel_targets` moves a whole song, :class:`TravelStream` one frame at a time; on
the same draws they agree.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy.optimize import brentq
from scipy.signal import butter, lfilter, sosfiltfilt

from kinectdata.core.errors import ConfigError
from kinectdata.core.motion import true_runs
from kinectdata.targets.foot_lock import FootLock, legs_of
from kinectdata.targets.slow_process import fit_time_constant, pole_and_gain, two_stage
from kinectdata.targets.specs import TargetSpec
from kinectdata.targets.turning import turnable

__all__ = [
    "CUTOFF_HZ",
    "TravelProcess",
    "TravelStream",
    "draw_travel",
    "fit_travel",
    "floor_columns",
    "pull_time_constant",
    "slow_velocity",
    "travel_targets",
]

CUTOFF_HZ = 0.5
"""The travel's velocity is the root's, low-passed below this (Hz)."""
FIT_LAGS_S = 2.0
"""Its autocorrelation is fitted over lags up to this (seconds)."""
MIN_FRAMES_S = 4.0
"""A stretch of known root positions shorter than this (seconds) is not fitted on."""
PULL_RANGE_S = (1.0, 3600.0)
"""The pull's time constant is fitted within this range (seconds); dancers who stay nearer the centre
than an hour's pull would keep them are pulled at the shortest, farther ones not at all."""


@dataclass(frozen=True)
class TravelProcess:
    """The travel drawn at generation (module docstring).

    Attributes:
        rms_speed: each horizontal axis's velocity's stationary root mean square, m/s.
        time_constant: each of the two low-pass stages' time constant, seconds.
        recordings, frames: what it was fitted on (0: given, not fitted).
        centre: the floor's centre, (x, z) metres in the training dancers' world; None: no floor
            (fitted without root anchors, or a run from before floors), the travel unbounded.
        radius: the farthest a training dancer's root was from the centre, metres.
        pull: the pull's time constant, seconds (the offset from the centre decays as
            ``exp(-t / pull)`` where the drawn velocity adds nothing); None: not pulled.
    """

    rms_speed: float
    time_constant: float
    recordings: int = 0
    frames: int = 0
    centre: tuple[float, float] | None = None
    radius: float | None = None
    pull: float | None = None

    def __post_init__(self) -> None:
        if not (self.rms_speed >= 0 and math.isfinite(self.rms_speed)):
            raise ConfigError(f"travel: rms_speed must be a finite number >= 0 m/s, not {self.rms_speed}")
        if not (self.time_constant > 0 and math.isfinite(self.time_constant)):
            raise ConfigError(f"travel: time_constant must be a finite number > 0 s, not {self.time_constant}")
        if self.pull is not None and not (self.pull > 0 and math.isfinite(self.pull)):
            raise ConfigError(f"travel: pull must be a finite number > 0 s, not {self.pull}")
        if self.pull is not None and (self.centre is None or self.radius is None):
            raise ConfigError("travel: a pull needs the floor's centre and radius")
        if self.centre is not None and not (len(self.centre) == 2 and all(math.isfinite(c) for c in self.centre)):
            raise ConfigError(f"travel: the floor's centre must be two finite numbers (x, z metres), not {self.centre}")
        if self.radius is not None and not (self.radius >= 0 and math.isfinite(self.radius)):
            raise ConfigError(f"travel: the floor's radius must be a finite number >= 0 m, not {self.radius}")

    def describe(self) -> str:
        """One line for a printout."""
        fitted = f", fitted on {self.recordings} training recordings" if self.recordings else ""
        floor = ""
        if self.pull is not None:
            x, z = self.centre  # type: ignore[misc]
            floor = (
                f", pulled towards the floor's centre (x {x:.2f}, z {z:.2f} m; radius {self.radius:.1f} m) "
                f"over {self.pull:.0f} s"
            )
        return (
            f"travel drawn at generation: {self.rms_speed:.2f} m/s root mean square along each horizontal axis, "
            f"correlated over {self.time_constant:.2f} s (two stages){floor}, over the standing foot "
            f"(a step where the leg reaches no further){fitted}"
        )

    def start_offset(self, start: np.ndarray | None) -> np.ndarray:
        """[2] where a dance starting at ``start`` ([2] x, z metres; None: no known place) stands from
        the floor's centre: 0 when there is no place, no pull, or the start is outside the floor."""
        if start is None or self.pull is None:
            return np.zeros(2)
        offset = np.asarray(start, np.float64)[:2] - np.asarray(self.centre, np.float64)
        if not np.isfinite(offset).all() or float(np.hypot(*offset)) > self.radius:  # type: ignore[operator]
            return np.zeros(2)
        return offset

    def to_dict(self) -> dict[str, Any]:
        doc: dict[str, Any] = {
            "rms_speed": self.rms_speed,
            "time_constant": self.time_constant,
            "recordings": self.recordings,
            "frames": self.frames,
        }
        if self.centre is not None:  # a run from before floors keeps the record it had
            doc["centre"] = [float(c) for c in self.centre]
            doc["radius"] = self.radius
        if self.pull is not None:
            doc["pull"] = self.pull
        return doc

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> TravelProcess:
        try:
            centre = doc.get("centre")
            return cls(
                float(doc["rms_speed"]),
                float(doc["time_constant"]),
                int(doc.get("recordings", 0)),
                int(doc.get("frames", 0)),
                None if centre is None else (float(centre[0]), float(centre[1])),
                None if doc.get("radius") is None else float(doc["radius"]),
                None if doc.get("pull") is None else float(doc["pull"]),
            )
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise ConfigError(f"travel: not a travel process record ({exc})") from None


def slow_velocity(track: np.ndarray, fps: float) -> list[np.ndarray]:
    """The horizontal velocity (m/s) of a root's travel ``track`` [T, 2] (metres, NaN where unknown),
    low-passed below :data:`CUTOFF_HZ` (a zero-phase second-order Butterworth filter), for each
    stretch of known positions at least :data:`MIN_FRAMES_S` long: a list of [T_i, 2]."""
    track = np.asarray(track, np.float64)
    sos = butter(2, CUTOFF_HZ / (fps / 2), output="sos")
    out = []
    for first, last in true_runs(np.isfinite(track).all(axis=1)):
        if last + 1 - first >= max(MIN_FRAMES_S * fps, 16):
            velocity = np.gradient(track[first : last + 1], axis=0) * fps
            out.append(sosfiltfilt(sos, velocity, axis=0))
    return out


def fit_travel(
    tracks: Sequence[np.ndarray], fps: float, anchors: Sequence[np.ndarray | None] | None = None
) -> TravelProcess:
    """The travel process of dancers whose roots travelled along ``tracks`` (each [T_i, 2] horizontal
    positions, metres, NaN where unknown): the root mean square of their slow velocity
    (:func:`slow_velocity`) over both axes, and the time constant whose autocorrelation over lags up
    to :data:`FIT_LAGS_S` is nearest theirs. Given where each dance stood (``anchors``, each [2] x and
    z metres in one world, added to its track), the floor too (module docstring): its centre, its
    radius and the pull (:func:`pull_time_constant`); left out when an anchor is missing.

    Raises:
        ConfigError: no stretch of known positions long enough to fit.
    """
    velocities = [v for track in tracks for v in slow_velocity(track, fps)]
    if not velocities:
        raise ConfigError(f"travel: no stretch of at least {MIN_FRAMES_S:g} s of known root positions to fit")
    series = [v[:, axis] for v in velocities for axis in (0, 1)]
    values = np.concatenate(series)
    process = TravelProcess(
        rms_speed=float(np.sqrt(np.mean(values**2))),
        time_constant=fit_time_constant(series, fps, FIT_LAGS_S),
        recordings=len(tracks),
        frames=int(sum(len(v) for v in velocities)),
    )
    known = anchors is not None and all(a is not None and np.isfinite(np.asarray(a)[:2]).all() for a in anchors)
    if not known:
        return process
    starts = [np.asarray(a, np.float64)[:2] for a in anchors]  # type: ignore[union-attr]
    world = [np.asarray(t, np.float64) + s for t, s in zip(tracks, starts)]
    stood = np.concatenate([w[np.isfinite(w).all(axis=1)] for w in world])
    if not len(stood):
        return process
    centre = stood.mean(axis=0)
    distance = np.hypot(*(stood - centre).T)
    pull = pull_time_constant(
        process, [s - centre for s in starts], [len(t) for t in tracks], float(np.mean(distance**2)), fps
    )
    return replace(process, centre=(float(centre[0]), float(centre[1])), radius=float(distance.max()), pull=pull)


def pull_time_constant(
    process: TravelProcess, offsets: Sequence[np.ndarray], lengths: Sequence[int], mean_square: float, fps: float
) -> float | None:
    """The pull's time constant (seconds, within :data:`PULL_RANGE_S`) under which ``process``'s
    draws from ``offsets`` (each [2] metres from the floor's centre) over ``lengths`` frames lie, in
    expectation, ``mean_square`` (m^2) from the centre on average over all their frames; None when
    even the longest leaves them nearer (no pull needed). Exact, not sampled: per axis the offset is
    ``a^(t+1) P0`` plus the velocity's response, whose variance from a standing start is the running
    sum of its squared impulse response."""
    n = max(lengths)
    b, gain = pole_and_gain(process.time_constant, fps)
    impulse = np.zeros(n)
    impulse[0] = 1.0
    velocity = gain * lfilter([(1 - b) ** 2], [1.0, -2 * b, b * b], impulse)  # one axis, unit rms
    start_square = [float(np.dot(o, o)) for o in offsets]
    frames = np.arange(1, n + 1)

    def excess(log_tau: float) -> float:
        a = math.exp(-1 / (fps * math.exp(log_tau)))
        response = process.rms_speed / fps * lfilter([1.0], [1.0, -a], velocity)
        spread = 2 * np.cumsum(response**2)  # both axes
        decay = a ** (2 * frames)
        total = sum(spread[:m].sum() + p * decay[:m].sum() for m, p in zip(lengths, start_square))
        return total / sum(lengths) - mean_square

    low, high = (math.log(t) for t in PULL_RANGE_S)
    if excess(high) <= 0:
        return None
    if excess(low) >= 0:
        return PULL_RANGE_S[0]
    return float(math.exp(brentq(excess, low, high, xtol=1e-4)))


def draw_travel(
    process: TravelProcess, live: np.ndarray, fps: float, rng: np.random.Generator, start: np.ndarray | None = None
) -> np.ndarray:
    """[T, 2] horizontal displacement (metres) of T frames from where the dance starts, held still
    where ``live`` [T] (bool) is False: two standard normal draws per frame from ``rng`` (x, then z),
    as :class:`TravelStream` draws them. ``start``: [2] where the dance starts (x, z metres, a root
    anchor's), for a process pulled towards its floor's centre (:meth:`TravelProcess.start_offset`)."""
    live = np.asarray(live, bool)
    velocity = process.rms_speed * two_stage(rng.standard_normal((len(live), 2)), live, process.time_constant, fps)
    if process.pull is None:
        return np.cumsum(velocity, axis=0) / fps
    a = math.exp(-1 / (fps * process.pull))
    offset = process.start_offset(start)
    place, held, done = np.empty_like(velocity), offset, 0
    for first, last in true_runs(live):  # held still in silence, pulled while the music plays
        place[done:first] = held
        steps = velocity[first : last + 1] / fps
        place[first : last + 1] = lfilter([1.0], [1.0, -a], steps, axis=0, zi=a * held[None])[0]
        held, done = place[last], last + 1
    place[done:] = held
    return place - offset


def floor_columns(spec: TargetSpec, owner: str = "travel") -> list[int]:
    """The root's x and z columns of a 3-D target centred on its root: its travel along the floor.

    Raises:
        ConfigError: targets whose root is not their travel (the message starts with ``owner``).
    """
    why = turnable(spec, root_centred=True)
    if why:
        raise ConfigError(f"{owner}: {why}")
    start = spec.columns(spec.root, "position").start
    return [start, start + 2]


def travel_targets(values: np.ndarray, spec: TargetSpec, displacement: np.ndarray, fps: float) -> np.ndarray:
    """Denormalised root-centred targets [T, D] (metres, y up) at ``fps`` moved by ``displacement``
    [T, 2] (metres along x and z from where the song began; :func:`draw_travel`), the standing foot
    planted where ``spec`` has both legs (:mod:`kinectdata.targets.foot_lock`): a new array."""
    out = np.array(values, np.float64)
    out[:, floor_columns(spec)] += np.asarray(displacement, np.float64)
    lock = _foot_lock(spec, fps)
    return out if lock is None else lock.plant(out)


def _foot_lock(spec: TargetSpec, fps: float) -> FootLock | None:
    legs = legs_of(spec)
    return None if legs is None else FootLock(legs, floor_columns(spec), fps)


class TravelStream:
    """:func:`draw_travel` and :func:`travel_targets` one frame at a time, for a live dance: after T
    steps the frames equal the whole song's from a generator seeded the same and the same ``start``."""

    def __init__(
        self,
        process: TravelProcess,
        spec: TargetSpec,
        fps: float,
        rng: np.random.Generator,
        start: np.ndarray | None = None,
    ):
        self.process, self.fps, self.rng = process, float(fps), rng
        self.columns = floor_columns(spec)
        self.b, self.gain = pole_and_gain(process.time_constant, self.fps)
        self.a = 1.0 if process.pull is None else math.exp(-1 / (self.fps * process.pull))
        self.u = np.zeros(2)
        self.v = np.zeros(2)
        self.offset = process.start_offset(start)
        self.place = self.offset.copy()  # from the floor's centre (from the start when unbounded)
        self.feet = _foot_lock(spec, self.fps)

    def step(self, values: np.ndarray, live: bool) -> np.ndarray:
        e = self.rng.standard_normal(2)
        self.u = self.b * self.u + (1 - self.b) * e
        self.v = self.b * self.v + (1 - self.b) * self.u if live else np.zeros(2)  # v is 0 after a silence
        if live:
            self.place = self.a * self.place + self.process.rms_speed * self.gain * self.v / self.fps
        out = np.array(values, np.float64)
        out[self.columns] += self.place - self.offset
        return out if self.feet is None else self.feet.step(out)
