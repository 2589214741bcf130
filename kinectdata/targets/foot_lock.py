"""The standing foot planted while the body travels: what keeps a drawn travel
(:mod:`kinectdata.targets.travel`) from sliding the feet.

Added to the root alone, the travel shifts every joint, and both feet slide with it: on tang2018's
fold 1 the generated dances' foot contact score (PFC) was 1.81 x the real dancers' without the
drawn travel and 2.54 x with it (docs/notebook/2026-12-real-dance-variety.md). A dancer travels by
standing on one foot while the body moves over it and swinging the other to catch up. So each foot
keeps a **lag** (metres, horizontal): how far the foot is from where the frames put it.

- **Which foot stands**: the lower one, held until the other is lower by more than
  :data:`STANCE_MARGIN_M`; the weight then shifts to it over :data:`SHIFT_S` (``w``, the left foot's
  share of the standing, goes from 1 to 0 or back at that rate).
- Each frame, the foot's own horizontal step in the world (the network's, the turning's and the
  travel's together) is added to its lag by the foot's share of the standing: the foot that stands
  stays where it is.
- The swinging foot then catches up: its lag goes towards ``-LEAD_S * v`` by ``(1 - w) * r`` of the
  way, ``r = 1 - exp(-1 / (fps * CATCH_UP_S))``, within about :data:`CATCH_UP_S`; ``v`` is the root's
  horizontal velocity in the world (m/s, averaged over about :data:`VELOCITY_SMOOTHING_S`), so that
  the foot lands where the body will be :data:`LEAD_S` later, ahead of it, as a dancer's step does.
- The lag is never more than the leg can reach: the ankle stays within the thigh's and the shin's
  lengths of the hip.
- **A step at the leg's reach**: when the standing foot's lag reaches that bound, the dancer steps:
  the stance goes to the other foot (over :data:`SHIFT_S`) and the one that stood sets off to
  catch up. The heights are then read turned round, so that a step the network makes with its
  feet's heights still moves the stance from one foot to the other, and the next reach turns it back.

The foot (its ankle and the joints below it) is moved back by its lag, and the knee is placed again by
two-bone inverse kinematics, so that the thigh and the shin keep their lengths in every frame and the
knee bends the way it did (in the plane of the hip, the new ankle and the old knee).

Chosen on fold 1 of tang2018 (the adopted recipe's run, its travel drawn again per song):
PFC 2.67 x the real dancers' with the travel added to the root alone, 1.16 x with the standing foot
planted (1.04 x with a catch-up of 0.4 s, 0.90 x with the feet's heights 0.3 cm apart for 88 % of
the standing, where the jerk rose from 1.90 to 2.04 x); jerk 1.91 x and bone CV as without it.
Carrying the travel's step alone (not the foot's whole step) left PFC at 2.6-2.9 x: the network's
feet slide on their own, by less than the travel but as often.

The step at the leg's reach, on fold 1 (docs/notebook/2026-12-real-dance-variety.md, "The step at the
leg's reach"): three cdhc networks held their right foot 1-6 cm up through every song, stood on the
left one in 99-100 % of the frames and slid it from the leg's first reach on. With the step, the
weight shifted over :data:`SHIFT_S` (in one frame the yalta candidate's jerk rose from 1.89 to
2.74 x the dancers', over 0.15 s to 2.17 x), the cdhc candidate's PFC fell from 1.25 to 0.81 x, its
jerk rose from 1.09 to 1.15 x, and its nine fold runs' PFC fell in every one (1.16-2.10 ->
0.73-1.55 x).

The margin and the catch-up, on tang2018's fold 3 (docs/notebook/2026-12-real-dance-variety.md,
"The feet that glide"): the stance first followed the sigmoid of the feet's heights over 1 cm that
pivots the turning, and the networks hold their feet within a centimetre or two of each other, so
that in 29 % of the frames each foot stood about half and both slid half the body's travel; and the
swinging foot caught up within 0.2 s. Held until the other foot is 2 cm lower, and caught up
within 0.1 s, the seven yalta fold runs' FID_k on the aist protocol fell in every one (fold 3:
156 -> 115, 154 -> 135, 188 -> 148; folds 1 and 2: 3-6 %), the cdhc run's on fold 3 from 115 to 84,
PFC fell in every one (0.79-1.38 -> 0.71-1.20 x the dancers'), and the jerk rose by 0.03-0.12 x the
dancers'. The feet still moved along the floor at 0.70-0.77 x the dancers' mean squared speed (the
pelvis at 1.15 x): a foot that only catches up with the body never passes it. Landing 0.1 s of the
body's travel ahead took FID_k (aist) further down in all eight runs (fold 3: 115 -> 98, 135 -> 129,
148 -> 125, cdhc 84 -> 80; folds 1 and 2: 1-3 %), and the bailando protocol's too, PFC within
0.05 x and the jerk within 0.02 x of where it was; 0.2 s ahead was better on four runs and worse
on four, PFC and jerk higher in all eight.

A target without both feet, their knees and their hips among its positions is not changed
(:func:`legs_of` is None). :class:`FootLock` works one frame at a time, so that a whole song and a
live dance plant the same frames (and take the same steps).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from kinectdata.targets.specs import TargetSpec

__all__ = [
    "CATCH_UP_S",
    "LEAD_S",
    "SHIFT_S",
    "STANCE_MARGIN_M",
    "VELOCITY_SMOOTHING_S",
    "FootLock",
    "Leg",
    "legs_of",
    "move_feet",
]

CATCH_UP_S = 0.1
"""The swinging foot's lag behind the body shrinks with this time constant (seconds)."""
LEAD_S = 0.1
"""The swinging foot catches up with where the body will be this much later (seconds): it lands ahead."""
VELOCITY_SMOOTHING_S = 0.2
"""The root's velocity the lead follows is averaged over about this (seconds; a causal first-order
low-pass, so that a live dance leads as a whole song does)."""
STANCE_MARGIN_M = 0.02
"""The standing foot keeps the weight until the other foot is this much lower (metres): feet at
about one height do not share it."""
SHIFT_S = 0.15
"""The stance moves from one foot to the other over this (seconds): the weight shifts, the swinging
foot sets off and the standing one stops within it, not in one frame."""
UP = 1  # y up


@dataclass(frozen=True)
class Leg:
    """The columns of one leg in a target vector: each joint's x, y, z.

    Attributes:
        hip, knee, ankle: the chain the knee is placed again on.
        foot: the ankle and every joint below it (they move together with the lag).
    """

    hip: tuple[int, int, int]
    knee: tuple[int, int, int]
    ankle: tuple[int, int, int]
    foot: tuple[tuple[int, int, int], ...]


def _below(joints, index: int) -> list[int]:
    out, todo = [], [index]
    while todo:
        j = todo.pop()
        out.append(j)
        todo += [c for c, p in enumerate(joints.parents) if p == j]
    return out


def legs_of(spec: TargetSpec) -> tuple[Leg, Leg] | None:
    """The left and right legs of root-centred 3-D position targets ``spec``, or None when a foot,
    its knee or its hip is not among the positions. The ``left_foot`` / ``right_foot`` role is the
    ankle, or a leaf below it (Kinect's ``FootLeft``: its parent is then the ankle)."""
    joints = spec.joints
    if spec.dimensions != 3 or spec.root is None:
        return None

    def xyz(j: int) -> tuple[int, int, int]:
        s = spec.columns(joints.names[j], "position").start
        return s, s + 1, s + 2

    legs = []
    for side in ("left_foot", "right_foot"):
        foot = joints.role(side)
        if foot is None:
            return None
        has_children = any(p == foot for p in joints.parents)
        ankle = foot if has_children else joints.parents[foot]
        knee = joints.parents[ankle] if ankle >= 0 else -1
        hip = joints.parents[knee] if knee >= 0 else -1
        chain = [ankle, knee, hip]
        if min(chain) < 0 or any(joints.names[j] not in spec.positions or joints.names[j] == spec.root for j in chain):
            return None
        foot_joints = [j for j in _below(joints, ankle) if joints.names[j] in spec.positions]
        legs.append(Leg(xyz(hip), xyz(knee), xyz(ankle), tuple(xyz(j) for j in foot_joints)))
    return legs[0], legs[1]


def _reach(v: np.ndarray, lag: np.ndarray, reach: float) -> float:
    """The largest s in [0, 1] with |v - s (lag_x, 0, lag_z)| <= reach, for the ankle's offset ``v`` [3]
    from the hip."""
    lx, lz = float(lag[0]), float(lag[1])
    ll = lx * lx + lz * lz
    if ll == 0.0:
        return 1.0
    vl = float(v[0]) * lx + float(v[2]) * lz
    c = float(v @ v) - reach * reach
    if c >= 0:  # a straight leg (or rounding beyond it): the foot cannot stay behind
        return 0.0
    return min(1.0, (vl + math.sqrt(vl * vl - ll * c)) / ll)


def _place_knee(hip: np.ndarray, knee: np.ndarray, ankle: np.ndarray, moved: np.ndarray) -> np.ndarray:
    """[..., 3] the knee between ``hip`` and the ankle's new place ``moved`` (all [..., 3]), at the
    distances the old ``knee`` had from ``hip`` and ``ankle``, on the old knee's side."""
    thigh = np.linalg.norm(knee - hip, axis=-1, keepdims=True)
    shin = np.linalg.norm(ankle - knee, axis=-1, keepdims=True)
    line = moved - hip
    d = np.maximum(np.linalg.norm(line, axis=-1, keepdims=True), 1e-9)
    u = line / d
    along = (thigh**2 - shin**2 + d**2) / (2 * d)
    across = np.sqrt(np.maximum(thigh**2 - along**2, 0.0))
    side = knee - hip
    side = side - np.sum(side * u, axis=-1, keepdims=True) * u
    size = np.linalg.norm(side, axis=-1, keepdims=True)
    straight = np.cross(u, np.array([0.0, 1.0, 0.0]))  # a straight leg: bend it sideways of the step
    side = np.where(size > 1e-9, side, straight)
    side = side / np.maximum(np.linalg.norm(side, axis=-1, keepdims=True), 1e-12)
    return hip + along * u + across * side


def move_feet(values: np.ndarray, legs: tuple[Leg, Leg], lags: np.ndarray) -> np.ndarray:
    """Targets [..., D] with each leg's foot moved back by its lag (``lags`` [..., 2, 2]: left, right;
    metres along x and z) and its knee placed again: a new array."""
    out = np.array(values, np.float64)
    lags = np.asarray(lags, np.float64)
    for k, leg in enumerate(legs):
        lag = lags[..., k, :]
        hip, knee, ankle = (out[..., list(c)] for c in (leg.hip, leg.knee, leg.ankle))
        for x, _, z in leg.foot:
            out[..., x] -= lag[..., 0]
            out[..., z] -= lag[..., 1]
        out[..., list(leg.knee)] = _place_knee(hip, knee, ankle, out[..., list(leg.ankle)])
    return out


class FootLock:
    """The feet's lags, one frame at a time (module docstring), for root-centred targets whose root's
    x and z are the columns ``root`` and whose legs are ``legs``, at ``fps``.

    ``lags(values)`` takes one frame's denormalised targets [D] (metres, y up; the root's values are
    its place in the world) and returns each foot's lag [2, 2] (left, right; x, z) in that frame, for
    :func:`move_feet`; ``step`` does both, ``plant`` a whole song.
    """

    def __init__(self, legs: tuple[Leg, Leg], root: Sequence[int], fps: float):
        self.legs = legs
        self.rate = 1.0 - math.exp(-1.0 / (float(fps) * CATCH_UP_S))
        self.state = np.zeros((2, 2))
        self.before: np.ndarray | None = None  # the feet's places in the world in the frame before [2, 2]
        self.shift = 1.0 / (float(fps) * SHIFT_S)
        self.left_stands: bool | None = None  # which foot has the weight (None before the first frame)
        self.share = 0.0  # the left foot's share of the standing, going towards ``left_stands`` by ``shift``
        self.turned = False  # steps at the leg's reach have turned the heights' reading round
        self.smoothing = 1.0 - math.exp(-1.0 / (float(fps) * VELOCITY_SMOOTHING_S))
        self.fps = float(fps)
        self.velocity = np.zeros(2)  # the root's horizontal velocity in the world (m/s), smoothed
        self.root_before: np.ndarray | None = None
        self._chains = [np.array([leg.hip, leg.knee, leg.ankle]) for leg in legs]
        self._places = np.array([[leg.ankle[0], leg.ankle[2]] for leg in legs])
        self._root = np.asarray(root)

    def lags(self, values: np.ndarray) -> np.ndarray:
        places = values[self._places] + values[self._root]
        steps = np.zeros((2, 2)) if self.before is None else places - self.before
        self.before = places
        root = values[self._root]
        if self.root_before is not None:
            self.velocity += self.smoothing * ((root - self.root_before) * self.fps - self.velocity)
        self.root_before = root.copy()
        ahead = -LEAD_S * self.velocity  # where the swinging foot's lag goes: the foot ahead of the body
        left, right = self.legs
        higher = float(values[left.ankle[UP]] - values[right.ankle[UP]])  # > 0: the left foot is higher
        if self.turned:
            higher = -higher
        if self.left_stands is None:
            self.left_stands = higher <= 0.0
            self.share = float(self.left_stands)
        elif (self.left_stands and higher > STANCE_MARGIN_M) or (not self.left_stands and higher < -STANCE_MARGIN_M):
            self.left_stands = not self.left_stands
        goal = float(self.left_stands)
        gap = goal - self.share
        self.share = goal if abs(gap) <= self.shift else self.share + math.copysign(self.shift, gap)
        step = False
        for k, stands in enumerate((self.share, 1.0 - self.share)):
            lag = self.state[k] + stands * steps[k]
            lag = lag + (1.0 - stands) * self.rate * (ahead - lag)
            hip, knee, ankle = values[self._chains[k]]
            reach = math.dist(knee, hip) + math.dist(ankle, knee)
            kept = _reach(ankle - hip, lag, reach)
            self.state[k] = lag * kept
            step |= stands > 0.5 and kept < 1.0
        if step and self.share == goal:  # the body is as far past the standing foot as the leg reaches
            self.left_stands = not self.left_stands
            self.turned = not self.turned
        return self.state.copy()

    def step(self, values: np.ndarray) -> np.ndarray:
        """One frame [D] with its standing foot planted: a new array."""
        values = np.asarray(values, np.float64)
        return move_feet(values, self.legs, self.lags(values))

    def plant(self, values: np.ndarray) -> np.ndarray:
        """Frames [T, D], each planted in turn: a new array."""
        values = np.asarray(values, np.float64)
        lags = np.array([self.lags(v) for v in values]).reshape(len(values), 2, 2)
        return move_feet(values, self.legs, lags)
