"""The network's own sway along the floor, brought to the dancers' at generation.

A run that draws its travel (:mod:`kinectdata.targets.travel`) trains its network on the root's place
less its slow part (:func:`kinectdata.training.augment.without_slow_travel`): the root's x and z are
the dancer's sway and steps about where the dance is going, in metres about 0. The cdhc model
sways there at the beat with 2 to 2.5 times the dancers' speed: on tang2018's fold 2 its root moved
along the floor at 0.22 m/s between 1 and 2 Hz on its training songs, the dancers' at 0.09
(docs/notebook/2026-12-real-dance-variety.md, "The root's sway at the beat, brought to the
dancers'"). The trunk rides on the root, so every trunk joint accelerates about twice as hard as
the dancers' do, and a style classifier that tells a cha-cha by its trunk's acceleration names
rumbas and waltzes cha-chas.

So the run measures, once trained, how fast its network's root moves along the floor in the beat's
band (:data:`BAND_HZ`) over its training songs, run whole, and how fast the dancers' roots move
there on the same songs (:func:`band_speed`), and keeps the ratio, never above 1
(:func:`fit_sway`). Wherever the run makes positions, the network's root x and z are scaled by it
before the drawn turning and travel (:func:`calm_sway`): a frame-by-frame product, so a live dance
scales each frame as ``generate`` scales the song.

On tang2018's folds the gain came out at 0.42-0.58; it brought the style named right to 10-12 of 12
songs (8-12 without) and the jerk down by a fifth to a third, and cost fold 3's aist FID_k figure:
one gain calms the network's 0.5-1 Hz root motion too, where it already moves less than the
dancers, along with its sway at the beat. So ``train --sway`` is off by default (docs/training.md,
"The network's sway brought to the dancers'").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.signal import butter, sosfiltfilt

from kinectdata.core.errors import ConfigError
from kinectdata.core.motion import true_runs
from kinectdata.targets.specs import TargetSpec
from kinectdata.targets.travel import floor_columns

__all__ = ["BAND_HZ", "SwayGain", "band_problem", "band_speed", "calm_sway", "fit_sway"]

BAND_HZ = (1.0, 4.0)
"""The beat's band (Hz): beats of 0.25 to 1 s. Below it lies the travel's (drawn below 0.5 Hz) and the
bar's; above it, the sensor's shake."""
ORDER = 2
"""The band-pass's order (a Butterworth run forwards and backwards: no delay)."""
MIN_FRAMES = 32
"""A stretch of known root positions shorter than this is not measured (the filter's edges)."""


def band_problem(band: tuple[float, float], fps: float) -> str:
    """Why roots at ``fps`` cannot be measured within ``band`` (Hz) ("" when they can)."""
    low, high = band
    if 0 < low < high < fps / 2:
        return ""
    return (
        f"measures the root's speed at {low:g}-{high:g} Hz, which a frame rate of {fps:g} fps cannot carry "
        f"(the band must lie within 0 and half the frame rate, {fps / 2:g} Hz)"
    )


def band_speed(tracks: Sequence[np.ndarray], fps: float, band: tuple[float, float] = BAND_HZ) -> tuple[float, int]:
    """How fast roots moved along the floor within ``band`` (Hz): the root mean square over frames of
    the horizontal velocity's length (m/s; both axes together), band-passed without delay, over every
    stretch of at least :data:`MIN_FRAMES` known positions of ``tracks`` (each [T_i, 2] metres, x and
    z, NaN where unknown). Returns (the speed, the frames measured); (NaN, 0) when none was."""
    why = band_problem(band, fps)
    if why:
        raise ConfigError(f"sway: {why}")
    low, high = band
    sos = butter(ORDER, [low, high], btype="band", fs=fps, output="sos")
    total, frames = 0.0, 0
    for track in tracks:
        track = np.asarray(track, np.float64)
        for first, last in true_runs(np.isfinite(track).all(axis=1)):
            if last + 1 - first < MIN_FRAMES:
                continue
            velocity = np.gradient(track[first : last + 1], axis=0) * fps
            passed = sosfiltfilt(sos, velocity, axis=0)
            total += float(np.sum(passed**2))
            frames += len(passed)
    return (math.sqrt(total / frames), frames) if frames else (math.nan, 0)


@dataclass(frozen=True)
class SwayGain:
    """What the network's root along the floor is scaled by at generation (module docstring).

    Attributes:
        gain: the factor, in (0, 1].
        network_speed, dancers_speed: their roots' speed along the floor within ``band``, m/s
            (:func:`band_speed`), on the songs it was fitted on.
        songs: how many songs.
        band: the band, Hz.
    """

    gain: float
    network_speed: float
    dancers_speed: float
    songs: int
    band: tuple[float, float] = BAND_HZ

    def __post_init__(self) -> None:
        if not (0 < self.gain <= 1 and math.isfinite(self.gain)):
            raise ConfigError(f"sway: the gain must be a number in (0, 1], not {self.gain}")

    def describe(self) -> str:
        """One line for a printout."""
        low, high = self.band
        return (
            f"the network's sway along the floor scaled by {self.gain:.2f} (at {low:g}-{high:g} Hz it moved "
            f"{self.network_speed:.3f} m/s on its {self.songs} training songs, the dancers {self.dancers_speed:.3f})"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "gain": self.gain,
            "network_speed": self.network_speed,
            "dancers_speed": self.dancers_speed,
            "songs": self.songs,
            "band": list(self.band),
        }

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> SwayGain:
        try:
            band = doc.get("band", BAND_HZ)
            return cls(
                float(doc["gain"]),
                float(doc["network_speed"]),
                float(doc["dancers_speed"]),
                int(doc["songs"]),
                (float(band[0]), float(band[1])),
            )
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise ConfigError(f"sway: not a sway record ({exc})") from None


def fit_sway(network: Sequence[np.ndarray], dancers: Sequence[np.ndarray], fps: float) -> SwayGain:
    """The gain that brings the network's root speed along the floor within :data:`BAND_HZ` to the
    dancers', never above 1: ``network`` and ``dancers``, per song, the root's [T_i, 2] x and z
    (metres; the network's sway about where it goes, the dancers' place, NaN where unknown).

    Raises:
        ConfigError: no stretch long enough to measure, in either.
    """
    made, made_frames = band_speed(network, fps)
    real, real_frames = band_speed(dancers, fps)
    if not (made_frames and real_frames):
        raise ConfigError(f"sway: no stretch of at least {MIN_FRAMES} known root positions to measure")
    gain = 1.0 if made <= real else max(real / made, 1e-6)
    return SwayGain(gain, made, real, len(network))


def calm_sway(values: np.ndarray, spec: TargetSpec, sway: SwayGain) -> np.ndarray:
    """Denormalised root-centred targets [T, D] (metres, y up) whose root x and z are scaled by
    ``sway.gain`` (one frame, [1, D], as a song's): a new float64 array."""
    out = np.array(values, np.float64)
    out[..., floor_columns(spec, "sway")] *= sway.gain
    return out
