"""Turning about the vertical, drawn at generation: the part of a dance the music does not fix.

The dancers of a real corpus turn all the time (on tang2018, 44 % of their joints' mean squared
speed), but when and which way they turn keeps no time with the music: the signed turning speed's
mean per phase of the beat or the bar explains no more of it than shifted phases do
(docs/notebook/2026-11-real-dance.md, "Whether the music can tell a turn"). A network trained to a pose loss averages
such turns away and faces one way. So the turning is a random process fitted on the training
dancers (:func:`fit_turning`: the ``train`` command keeps it in the run) and drawn wherever a run
makes positions (``evaluate``, ``generate``, ``live``), while the network makes the rest.

The process: the turning speed ``w_t`` (rad/s) is white Gaussian noise through two equal
first-order low-pass stages (:mod:`kinectdata.targets.slow_process`), scaled so its stationary root
mean square is ``rms_speed``; its autocorrelation is ``(1 + t / tau) exp(-t / tau)``. Where the
music is silent the speed is held at 0 (the dancer stops with the music). The heading ``h_t`` is the
speed's sum over frames divided by fps. Two stages, not one: one renews the acceleration every
frame and adds jerk (docs/notebook/2026-11-real-dance.md, "Tried since, on the folds: turning drawn
at generation").

A frame is turned by ``h_t`` about the vertical (y up; positive from x towards z, as
:func:`kinectdata.evaluation.metrics.turning.turning_rates` counts it): each joint's offset from the
root turns, and the root travels so that the **pivot** stays where it was between frames: a point
that slides between the two feet by their heights (``sigmoid((y_right - y_left) / 0.01 m)`` on the
left one: 88 % on the lower foot when they are 2 cm apart), as a dancer turns on the standing foot;
the root when the target has no feet. Turned about the root, both feet slide (foot contact 4 x the
real dancers' on tang2018); about the standing foot, they do not.

Only 3-D position targets centred on their root (``--root-centre``) are turned: the root's values are
its travel, the other joints' their offsets from it. :func:`turn_targets` turns a whole song,
:class:`TurningStream` one frame at a time; on the same draws they agree.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from kinectdata.core.errors import ConfigError
from kinectdata.targets.slow_process import fit_time_constant, pole_and_gain, two_stage
from kinectdata.targets.specs import TargetSpec

__all__ = [
    "PIVOT_SOFTNESS_M",
    "TurningProcess",
    "TurningStream",
    "draw_turning_speed",
    "fit_turning",
    "left_standing",
    "turnable",
    "turn_targets",
]

PIVOT_SOFTNESS_M = 0.01
"""The feet's height difference (metres) over which the pivot slides from one foot to the other."""
FIT_LAGS_S = 2.0
"""The autocorrelation of the dancers' turning speed is fitted over lags up to this (seconds)."""
UP, ACROSS = 1, (0, 2)  # y up; the horizontal axes x and z


@dataclass(frozen=True)
class TurningProcess:
    """The turning drawn at generation (module docstring).

    Attributes:
        rms_speed: the turning speed's stationary root mean square, rad/s.
        time_constant: each of the two low-pass stages' time constant, seconds.
        pivot: the joints the turn pivots about: the left and right foot, or the root alone.
        recordings, frames: what it was fitted on (0: given, not fitted).
        mean_abs_speed: the fitted dancers' mean absolute turning speed, rad/s (NaN: given).
    """

    rms_speed: float
    time_constant: float
    pivot: tuple[str, ...]
    recordings: int = 0
    frames: int = 0
    mean_abs_speed: float = math.nan

    def __post_init__(self) -> None:
        if not (self.rms_speed >= 0 and math.isfinite(self.rms_speed)):
            raise ConfigError(f"turning: rms_speed must be a finite number >= 0 rad/s, not {self.rms_speed}")
        if not (self.time_constant > 0 and math.isfinite(self.time_constant)):
            raise ConfigError(f"turning: time_constant must be a finite number > 0 s, not {self.time_constant}")
        if len(self.pivot) not in (1, 2):
            raise ConfigError(f"turning: the pivot is one joint (the root) or two (the feet), not {list(self.pivot)}")

    def describe(self) -> str:
        """One line for a printout."""
        about = "the standing foot" if len(self.pivot) == 2 else "the root"
        fitted = f", fitted on {self.recordings} training recordings" if self.recordings else ""
        return (
            f"turning drawn at generation: speed {self.rms_speed:.2f} rad/s root mean square, "
            f"correlated over {self.time_constant:.2f} s (two stages), about {about}{fitted}"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "rms_speed": self.rms_speed,
            "time_constant": self.time_constant,
            "pivot": list(self.pivot),
            "recordings": self.recordings,
            "frames": self.frames,
            "mean_abs_speed": None if math.isnan(self.mean_abs_speed) else self.mean_abs_speed,
        }

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> TurningProcess:
        try:
            mean_abs = doc.get("mean_abs_speed")
            return cls(
                float(doc["rms_speed"]),
                float(doc["time_constant"]),
                tuple(str(j) for j in doc["pivot"]),
                int(doc.get("recordings", 0)),
                int(doc.get("frames", 0)),
                math.nan if mean_abs is None else float(mean_abs),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"turning: not a turning process record ({exc})") from None


def turnable(spec: TargetSpec, root_centred: bool) -> str:
    """Why targets of ``spec`` cannot be turned ("" when they can): only 3-D positions centred on a
    root that is among them."""
    if spec.dimensions != 3 or not spec.positions:
        return "the target has no 3-D joint positions"
    if not root_centred or spec.root is None or spec.root not in spec.positions:
        return "the target is not centred on its root (build with --root-centre)"
    return ""


def _pivot(spec: TargetSpec) -> tuple[str, ...]:
    roles = spec.joints.roles
    feet = roles.get("left_foot"), roles.get("right_foot")
    if all(f is not None and f in spec.positions and f != spec.root for f in feet):
        return feet  # type: ignore[return-value]
    return (spec.root,)  # type: ignore[return-value]


def fit_turning(rates: Sequence[np.ndarray], fps: float, spec: TargetSpec) -> TurningProcess:
    """The turning process of dancers whose turning speeds are ``rates``.

    Args:
        rates: per recording, its turning speed per frame [T_i], rad/s (NaN where unknown), e.g.
            :func:`kinectdata.evaluation.metrics.turning.turning_rates` of its joints about the root.
        fps: frames per second.
        spec: the target (its feet give the pivot).

    Returns:
        The process whose speed has the dancers' mean absolute speed (as a Gaussian's: root mean
        square = mean absolute x sqrt(pi / 2), which the per-frame estimate's rare spikes do not
        inflate) and whose autocorrelation over lags up to :data:`FIT_LAGS_S` is nearest theirs
        (least squares over the time constant).

    Raises:
        ConfigError: no finite rate to fit.
    """
    finite = [np.asarray(r, np.float64)[np.isfinite(r)] for r in rates]
    values = np.concatenate(finite) if finite else np.zeros(0)
    if values.size < 3:
        raise ConfigError("turning: no turning speed to fit (fewer than 3 frames with a known turn)")
    mean_abs = float(np.abs(values).mean())
    tau = fit_time_constant(rates, fps, FIT_LAGS_S)
    return TurningProcess(
        rms_speed=mean_abs * math.sqrt(math.pi / 2),
        time_constant=tau,
        pivot=_pivot(spec),
        recordings=sum(1 for r in finite if r.size),
        frames=int(values.size),
        mean_abs_speed=mean_abs,
    )


def draw_turning_speed(process: TurningProcess, live: np.ndarray, fps: float, rng: np.random.Generator) -> np.ndarray:
    """[T] turning speed (rad/s) of T frames, 0 where ``live`` [T] (bool) is False (silence): one
    standard normal draw per frame from ``rng``, as :class:`TurningStream` draws them."""
    live = np.asarray(live, bool)
    return process.rms_speed * two_stage(rng.standard_normal(len(live)), live, process.time_constant, fps)


@dataclass(frozen=True)
class _Columns:
    xz: np.ndarray  # [J-1, 2] the x and z columns of every joint but the root
    root: tuple[int, int, int]  # the root's x, y, z columns
    feet: tuple[tuple[int, int, int], ...]  # each pivot foot's x, y, z columns (none: the root)


def _columns(spec: TargetSpec, process: TurningProcess) -> _Columns:
    why = turnable(spec, root_centred=True)
    if why:
        raise ConfigError(f"turning: {why}")

    def xyz(joint: str) -> tuple[int, int, int]:
        if joint not in spec.positions:
            raise ConfigError(f"turning: its pivot {joint!r} is not among the target's joints")
        s = spec.columns(joint, "position").start
        return s, s + 1, s + 2

    others = [xyz(j) for j in spec.positions if j != spec.root]
    feet = tuple(xyz(j) for j in process.pivot) if len(process.pivot) == 2 else ()
    return _Columns(np.array([(c[0], c[2]) for c in others], np.int64).reshape(-1, 2), xyz(spec.root), feet)


def left_standing(left_height: np.ndarray | float, right_height: np.ndarray | float) -> np.ndarray:
    """The left foot's share of the standing (0..1, broadcast), from the feet's heights (metres, y
    up): ``sigmoid((y_right - y_left) / PIVOT_SOFTNESS_M)``, the lower foot stands."""
    diff = (np.asarray(left_height, np.float64) - np.asarray(right_height, np.float64)) / PIVOT_SOFTNESS_M
    return 1.0 / (1.0 + np.exp(np.clip(diff, -60, 60)))


def _stance(values: np.ndarray, cols: _Columns) -> np.ndarray:
    """[..., 2] the pivot's horizontal place in the unturned world, for targets [..., D]."""
    root = values[..., [cols.root[0], cols.root[2]]]
    if not cols.feet:
        return root
    (lx, ly, lz), (rx, ry, rz) = cols.feet
    left = left_standing(values[..., ly], values[..., ry])
    foot = left[..., None] * values[..., [lx, lz]] + (1 - left[..., None]) * values[..., [rx, rz]]
    return root + foot


def _rotate(xz: np.ndarray, cos: np.ndarray, sin: np.ndarray) -> np.ndarray:
    """``xz`` [..., 2] turned by the angle whose cosine and sine are given (broadcast on ``...``)."""
    x, z = xz[..., 0], xz[..., 1]
    return np.stack([cos * x - sin * z, sin * x + cos * z], axis=-1)


def turn_targets(
    values: np.ndarray, spec: TargetSpec, speed: np.ndarray, fps: float, process: TurningProcess
) -> np.ndarray:
    """Denormalised root-centred targets [T, D] (metres, y up) turned by the heading that ``speed``
    [T] (rad/s) sums to, about the process's pivot (module docstring); a new array. Frame 0's heading
    is ``speed[0] / fps``: pass the frames that follow a given pose, as a free run makes them."""
    cols = _columns(spec, process)
    values = np.asarray(values, np.float64)
    heading = np.cumsum(np.asarray(speed, np.float64)) / fps
    before = np.concatenate([[0.0], heading[:-1]])
    stance = _stance(values, cols)  # [T, 2]
    cos, sin = np.cos(heading), np.sin(heading)
    # the translation that keeps the pivot where the frame before put it: sum of (R(h_{t-1}) - R(h_t)) f_t
    shift = np.cumsum(_rotate(stance, np.cos(before), np.sin(before)) - _rotate(stance, cos, sin), axis=0)
    out = values.copy()
    out[:, cols.xz] = _rotate(values[:, cols.xz], cos[:, None], sin[:, None])
    rx, _, rz = cols.root
    out[:, [rx, rz]] = _rotate(values[:, [rx, rz]], cos, sin) + shift
    return out


class TurningStream:
    """:func:`draw_turning_speed` and :func:`turn_targets` one frame at a time, for a live dance.

    ``step(values, live)`` takes one frame's denormalised targets [D] and whether its music sounds,
    and returns them turned; after T steps the frames equal :func:`turn_targets` of the T frames with
    :func:`draw_turning_speed`'s speed from a generator seeded the same.
    """

    def __init__(self, process: TurningProcess, spec: TargetSpec, fps: float, rng: np.random.Generator):
        self.process, self.fps, self.rng = process, float(fps), rng
        self.cols = _columns(spec, process)
        self.b, self.gain = pole_and_gain(process.time_constant, self.fps)
        self.u = self.v = self.heading = 0.0
        self.shift = np.zeros(2)

    def step(self, values: np.ndarray, live: bool) -> np.ndarray:
        e = float(self.rng.standard_normal())
        self.u = self.b * self.u + (1 - self.b) * e
        self.v = self.b * self.v + (1 - self.b) * self.u if live else 0.0  # v is 0 after a silence
        before = self.heading
        self.heading = before + self.process.rms_speed * self.gain * self.v / self.fps
        values = np.asarray(values, np.float64)
        stance = _stance(values, self.cols)
        cos, sin = math.cos(self.heading), math.sin(self.heading)
        self.shift = self.shift + _rotate(stance, math.cos(before), math.sin(before)) - _rotate(stance, cos, sin)
        out = values.copy()
        out[self.cols.xz] = _rotate(values[self.cols.xz], cos, sin)
        rx, _, rz = self.cols.root
        out[[rx, rz]] = _rotate(values[[rx, rz]], cos, sin) + self.shift
        return out
