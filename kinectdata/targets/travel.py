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
catches up, the knees bend to keep the legs' lengths). Where the music is silent the velocity
is held at 0 (the dancer stops with the music). Drawn over as many frames as each training dance
has, it puts the dancer 1.2 to 5.6 m from the start on average (median 2.9 m; the dancers' 0.8 to
5.5, 2.8).

Only 3-D position targets centred on their root (``--root-centre``) travel: the root's values are
its travel. :func:`travel_targets` moves a whole song, :class:`TravelStream` one frame at a time; on
the same draws they agree.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.signal import butter, sosfiltfilt

from kinectdata.core.errors import ConfigError
from kinectdata.targets.foot_lock import FootLock, legs_of
from kinectdata.targets.slow_process import fit_time_constant, pole_and_gain, two_stage
from kinectdata.targets.specs import TargetSpec
from kinectdata.targets.turning import turnable

__all__ = ["CUTOFF_HZ", "TravelProcess", "TravelStream", "draw_travel", "fit_travel", "slow_velocity", "travel_targets"]

CUTOFF_HZ = 0.5
"""The travel's velocity is the root's, low-passed below this (Hz)."""
FIT_LAGS_S = 2.0
"""Its autocorrelation is fitted over lags up to this (seconds)."""
MIN_FRAMES_S = 4.0
"""A stretch of known root positions shorter than this (seconds) is not fitted on."""


@dataclass(frozen=True)
class TravelProcess:
    """The travel drawn at generation (module docstring).

    Attributes:
        rms_speed: each horizontal axis's velocity's stationary root mean square, m/s.
        time_constant: each of the two low-pass stages' time constant, seconds.
        recordings, frames: what it was fitted on (0: given, not fitted).
    """

    rms_speed: float
    time_constant: float
    recordings: int = 0
    frames: int = 0

    def __post_init__(self) -> None:
        if not (self.rms_speed >= 0 and math.isfinite(self.rms_speed)):
            raise ConfigError(f"travel: rms_speed must be a finite number >= 0 m/s, not {self.rms_speed}")
        if not (self.time_constant > 0 and math.isfinite(self.time_constant)):
            raise ConfigError(f"travel: time_constant must be a finite number > 0 s, not {self.time_constant}")

    def describe(self) -> str:
        """One line for a printout."""
        fitted = f", fitted on {self.recordings} training recordings" if self.recordings else ""
        return (
            f"travel drawn at generation: {self.rms_speed:.2f} m/s root mean square along each horizontal axis, "
            f"correlated over {self.time_constant:.2f} s (two stages), over the standing foot{fitted}"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "rms_speed": self.rms_speed,
            "time_constant": self.time_constant,
            "recordings": self.recordings,
            "frames": self.frames,
        }

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> TravelProcess:
        try:
            return cls(
                float(doc["rms_speed"]),
                float(doc["time_constant"]),
                int(doc.get("recordings", 0)),
                int(doc.get("frames", 0)),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"travel: not a travel process record ({exc})") from None


def slow_velocity(track: np.ndarray, fps: float) -> list[np.ndarray]:
    """The horizontal velocity (m/s) of a root's travel ``track`` [T, 2] (metres, NaN where unknown),
    low-passed below :data:`CUTOFF_HZ` (a zero-phase second-order Butterworth filter), for each
    stretch of known positions at least :data:`MIN_FRAMES_S` long: a list of [T_i, 2]."""
    track = np.asarray(track, np.float64)
    known = np.isfinite(track).all(axis=1)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], known.astype(np.int8), [0]])))
    sos = butter(2, CUTOFF_HZ / (fps / 2), output="sos")
    out = []
    for start, end in zip(edges[::2], edges[1::2]):
        if end - start >= max(MIN_FRAMES_S * fps, 16):
            velocity = np.gradient(track[start:end], axis=0) * fps
            out.append(sosfiltfilt(sos, velocity, axis=0))
    return out


def fit_travel(tracks: Sequence[np.ndarray], fps: float) -> TravelProcess:
    """The travel process of dancers whose roots travelled along ``tracks`` (each [T_i, 2] horizontal
    positions, metres, NaN where unknown): the root mean square of their slow velocity
    (:func:`slow_velocity`) over both axes, and the time constant whose autocorrelation over lags up
    to :data:`FIT_LAGS_S` is nearest theirs.

    Raises:
        ConfigError: no stretch of known positions long enough to fit.
    """
    velocities = [v for track in tracks for v in slow_velocity(track, fps)]
    if not velocities:
        raise ConfigError(f"travel: no stretch of at least {MIN_FRAMES_S:g} s of known root positions to fit")
    series = [v[:, axis] for v in velocities for axis in (0, 1)]
    values = np.concatenate(series)
    return TravelProcess(
        rms_speed=float(np.sqrt(np.mean(values**2))),
        time_constant=fit_time_constant(series, fps, FIT_LAGS_S),
        recordings=len(tracks),
        frames=int(sum(len(v) for v in velocities)),
    )


def draw_travel(process: TravelProcess, live: np.ndarray, fps: float, rng: np.random.Generator) -> np.ndarray:
    """[T, 2] horizontal displacement (metres) of T frames from where the dance starts, the velocity
    0 where ``live`` [T] (bool) is False: two standard normal draws per frame from ``rng`` (x, then
    z), as :class:`TravelStream` draws them."""
    live = np.asarray(live, bool)
    velocity = process.rms_speed * two_stage(rng.standard_normal((len(live), 2)), live, process.time_constant, fps)
    return np.cumsum(velocity, axis=0) / fps


def _root_columns(spec: TargetSpec) -> list[int]:
    why = turnable(spec, root_centred=True)
    if why:
        raise ConfigError(f"travel: {why}")
    start = spec.columns(spec.root, "position").start
    return [start, start + 2]


def travel_targets(values: np.ndarray, spec: TargetSpec, displacement: np.ndarray, fps: float) -> np.ndarray:
    """Denormalised root-centred targets [T, D] (metres, y up) at ``fps`` moved by ``displacement``
    [T, 2] (metres along x and z from where the song began; :func:`draw_travel`), the standing foot
    planted where ``spec`` has both legs (:mod:`kinectdata.targets.foot_lock`): a new array."""
    out = np.array(values, np.float64)
    out[:, _root_columns(spec)] += np.asarray(displacement, np.float64)
    lock = _foot_lock(spec, fps)
    return out if lock is None else lock.plant(out)


def _foot_lock(spec: TargetSpec, fps: float) -> FootLock | None:
    legs = legs_of(spec)
    return None if legs is None else FootLock(legs, _root_columns(spec), fps)


class TravelStream:
    """:func:`draw_travel` and :func:`travel_targets` one frame at a time, for a live dance: after T
    steps the frames equal the whole song's from a generator seeded the same."""

    def __init__(self, process: TravelProcess, spec: TargetSpec, fps: float, rng: np.random.Generator):
        self.process, self.fps, self.rng = process, float(fps), rng
        self.columns = _root_columns(spec)
        self.b, self.gain = pole_and_gain(process.time_constant, self.fps)
        self.u = np.zeros(2)
        self.v = np.zeros(2)
        self.place = np.zeros(2)
        self.feet = _foot_lock(spec, self.fps)

    def step(self, values: np.ndarray, live: bool) -> np.ndarray:
        e = self.rng.standard_normal(2)
        self.u = self.b * self.u + (1 - self.b) * e
        self.v = self.b * self.v + (1 - self.b) * self.u if live else np.zeros(2)  # v is 0 after a silence
        self.place = self.place + self.process.rms_speed * self.gain * self.v / self.fps
        out = np.array(values, np.float64)
        out[self.columns] += self.place
        return out if self.feet is None else self.feet.step(out)
