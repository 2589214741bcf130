"""A run's generated motion low-passed before it leaves the model (``train --smooth-hz``).

A network trained frame by frame to regress poses shakes: its frames scatter about the motion it
means, and the scatter shows as jerk (on tang2018 the yalta model's free runs jerk 2.4-2.6 x as much as
the dancers'). A robot's servos and an avatar both want that shake gone, and so does a dance that
should look human. A run trained with ``smooth_hz`` keeps the cutoff in its ``config.json``
(``train.smooth_hz``; absent or None: no smoothing, as runs written before it) and every place that
makes positions from it, ``evaluate``'s free runs, ``generate`` and ``live``, passes the motion it
makes (after its drawn turning and travel) through the same causal filter:

- a Butterworth low-pass of order :data:`ORDER` at ``smooth_hz`` (``scipy.signal.butter``), run
  forwards only (``scipy.signal.sosfilt``), so that live can run it one frame at a time and get
  ``generate``'s frames: a delay of about ``sqrt(2) / (2 pi smooth_hz)`` seconds at low frequencies
  (38 ms at 6 Hz, about a frame at 30 fps);
- starting at rest on the first frame the model makes (that frame comes out as it went in), so that
  a dance does not rise from zero;
- per column: positions and limb lengths as they are; each quaternion first turned to the
  hemisphere of the one before it (q and -q are one rotation) and normalised again after.

The network is trained as without it: it feeds back its own unsmoothed poses, and the filter only
changes what the run hands out. Runs that reset their state every L frames (``evaluate``'s "with
reset" figures) are not smoothed, as they are not turned: those figures measure the network.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.signal import butter, sosfilt, sosfilt_zi

from kinectdata.core.errors import ConfigError
from kinectdata.core.quaternions import make_continuous
from kinectdata.targets.specs import TargetSpec

__all__ = [
    "NOT_SMOOTHED",
    "ORDER",
    "MotionSmoother",
    "check_cutoff",
    "run_smoothing",
    "smooth_motion",
    "smoothing_line",
]

ORDER = 2
"""The Butterworth filter's order: 12 dB per octave above the cutoff, little overshoot."""
NOT_SMOOTHED = "not smoothed"
""":func:`smoothing_line` of a run that does not smooth."""


def run_smoothing(config: dict[str, Any]) -> float | None:
    """The cutoff (Hz) a run's ``config.json`` smooths its generated motion at, or None."""
    cutoff = config.get("train", {}).get("smooth_hz")
    return None if cutoff is None else float(cutoff)


def smoothing_line(config: dict[str, Any]) -> str:
    """What a run does to its generated motion, for a printout (:data:`NOT_SMOOTHED` when nothing)."""
    cutoff = run_smoothing(config)
    if cutoff is None:
        return NOT_SMOOTHED
    return f"low-passed at {cutoff:g} Hz (causal Butterworth, order {ORDER})"


def check_cutoff(cutoff_hz: float, fps: float) -> None:
    """ConfigError unless ``cutoff_hz`` lies above 0 and below half the frame rate ``fps``."""
    if not 0 < cutoff_hz < fps / 2:
        raise ConfigError(
            f"smooth_hz must be above 0 and below half the frame rate ({fps / 2:g} Hz), not {cutoff_hz:g}"
        )


def _sections(cutoff_hz: float, fps: float) -> np.ndarray:
    check_cutoff(cutoff_hz, fps)
    return butter(ORDER, cutoff_hz, fs=fps, output="sos")


def _continuous(values: np.ndarray, spec: TargetSpec, before: np.ndarray | None) -> np.ndarray:
    """``values`` [T >= 1, D] as float64 with each quaternion track sign-continuous
    (:func:`~kinectdata.core.quaternions.make_continuous`), from the sign of ``before`` [D] when given."""
    out = np.array(values, dtype=np.float64)
    for cols in spec.quaternion_slices:
        track = out[:, cols] if before is None else np.concatenate([before[None, cols], out[:, cols]])
        out[:, cols] = make_continuous(track)[-len(out) :]
    return out


def _normalised(values: np.ndarray, spec: TargetSpec) -> np.ndarray:
    for cols in spec.quaternion_slices:
        norm = np.linalg.norm(values[..., cols], axis=-1, keepdims=True)
        values[..., cols] = values[..., cols] / np.where(norm > 0, norm, 1.0)
    return values


def smooth_motion(values: np.ndarray, spec: TargetSpec, fps: float, cutoff_hz: float) -> np.ndarray:
    """Denormalised targets [T, D] of ``spec`` at ``fps`` low-passed at ``cutoff_hz`` (Hz), causally,
    starting at rest on frame 0 (see the module docstring). Returns float64 [T, D]."""
    if len(values) == 0:
        return np.zeros(np.shape(values), np.float64)
    x = _continuous(values, spec, None)
    sos = _sections(cutoff_hz, fps)
    zi = sosfilt_zi(sos)[:, :, None] * x[0][None, None, :]
    return _normalised(sosfilt(sos, x, axis=0, zi=zi)[0], spec)


class MotionSmoother:
    """:func:`smooth_motion` one frame at a time (``live``): :meth:`step` on frames 0, 1, ... gives
    ``smooth_motion``'s frames."""

    def __init__(self, spec: TargetSpec, fps: float, cutoff_hz: float):
        self.spec = spec
        self.sos = _sections(cutoff_hz, fps)
        self.state: np.ndarray | None = None
        self.last: np.ndarray | None = None

    def step(self, value: np.ndarray) -> np.ndarray:
        """[D] denormalised targets of the next frame in, smoothed [D] (float64) out."""
        x = _continuous(np.asarray(value)[None], self.spec, self.last)
        self.last = x[0]
        if self.state is None:
            self.state = sosfilt_zi(self.sos)[:, :, None] * x[0][None, None, :]
        y, self.state = sosfilt(self.sos, x, axis=0, zi=self.state)
        return _normalised(y, self.spec)[0]
