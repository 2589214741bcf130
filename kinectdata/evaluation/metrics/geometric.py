"""Geometric ("manual") motion features: the 32 numbers per sequence behind FID_g and Div_g.

Boolean relations between body parts (Müller et al. 2005, "Efficient content-based retrieval of
motion capture data"), in the form of the AIST++ API's ``aist_plusplus/features/manual.py`` that
mint and Bailando (``utils/features/manual_new.py``) use: each of the 32 relations is evaluated on
frames 1..T-1 and the feature is the fraction of frames where it holds.

The peers' particulars, kept so that the numbers are theirs:

- the thresholds scale with three lengths of the SMPL template, not of the body measured:
  humerus :data:`HUMERUS_M`, shoulder width :data:`SHOULDER_WIDTH_M`, hip width :data:`HIP_WIDTH_M`;
- velocities are displacements per frame times 120 (their ``time_per_frame = 1/120``) although
  AIST++ motion is 60 fps; ``peer_velocity=False`` uses the true frame rate instead;
- y is up and the floor is the lowest joint of the current frame;
- the relations "moves along" use three of their four named joints (the fourth is ignored), so
  relations 5 and 6, which name a wrist fourth, measure the chest moving away from the belly.

Joint names are the AIST++ ones for the SMPL-24 order (``root`` is the pelvis, ``belly`` spine1,
``spine`` spine2, ``chest`` spine3, ``ltoes`` the left foot...). Equality with the peers' code:
tests/evaluation/test_field_metrics.py on ``shared/fixtures/metrics``.
"""

from __future__ import annotations

import numpy as np

from kinectdata.core.errors import KinectDataError

HUMERUS_M = 0.2568381092115207
"""SMPL template left shoulder to left elbow, metres (the peers' ``hl``)."""
SHOULDER_WIDTH_M = 0.39084835854945527
"""SMPL template shoulder to shoulder, metres (``sw``)."""
HIP_WIDTH_M = 0.11924706586886204
"""SMPL template hip to hip, metres (``hw``)."""
PEER_VELOCITY_RATE_HZ = 120.0
"""The peers' velocity scale: displacement per frame times 120, whatever the frame rate."""

JOINTS = (
    "root", "lhip", "rhip", "belly", "lknee", "rknee", "spine", "lankle", "rankle", "chest", "ltoes", "rtoes",
    "neck", "linshoulder", "rinshoulder", "head", "lshoulder", "rshoulder", "lelbow", "relbow", "lwrist", "rwrist",
    "lhand", "rhand",
)  # fmt: skip
"""The SMPL-24 joints in order, by the names the relations below use."""

_LENGTHS = {"hl": HUMERUS_M, "sw": SHOULDER_WIDTH_M, "hw": HIP_WIDTH_M}

# (relation, joints, threshold factor, length) or (relation, joints, (low, high) degrees).
# Relations, with a, b, c, d the joints in order and every test strict (>, or inside an open range):
#   plane:  d's signed distance from the plane through a, b, c (normal (c - a) x (b - a)) > threshold
#   nplane: d's distance from c along the direction b - a > threshold
#   angle:  the angle between b - a and d - c is inside (low, high) degrees
#   move:   the velocity of c relative to a, along b - a, > threshold (m/s)
#   nmove:  the velocity of d relative to a, along the normal (c - a) x (b - a), > threshold (m/s)
#   fast:   the speed of a > threshold (m/s)
RELATIONS: tuple[tuple, ...] = (
    ("nmove", ("neck", "rhip", "lhip", "rwrist"), 1.8, "hl"),
    ("nmove", ("neck", "lhip", "rhip", "lwrist"), 1.8, "hl"),
    ("nplane", ("chest", "neck", "neck", "rwrist"), 0.2, "hl"),
    ("nplane", ("chest", "neck", "neck", "lwrist"), 0.2, "hl"),
    ("move", ("belly", "chest", "chest"), 1.8, "hl"),  # the peers name rwrist fourth; it is ignored
    ("move", ("belly", "chest", "chest"), 1.8, "hl"),  # the peers name lwrist fourth; it is ignored
    ("angle", ("relbow", "rshoulder", "relbow", "rwrist"), (0, 110)),
    ("angle", ("lelbow", "lshoulder", "lelbow", "lwrist"), (0, 110)),
    ("nplane", ("lshoulder", "rshoulder", "lwrist", "rwrist"), 2.5, "sw"),
    ("move", ("lwrist", "rwrist", "rwrist"), 1.4, "hl"),
    ("move", ("rwrist", "root", "lwrist"), 1.4, "hl"),
    ("move", ("lwrist", "root", "rwrist"), 1.4, "hl"),
    ("fast", ("rwrist",), 2.5, "hl"),
    ("fast", ("lwrist",), 2.5, "hl"),
    ("plane", ("root", "lhip", "ltoes", "rankle"), 0.38, "hl"),
    ("plane", ("root", "rhip", "rtoes", "lankle"), 0.38, "hl"),
    ("nplane", ("zero", "y_unit", "y_min", "rankle"), 1.2, "hl"),
    ("nplane", ("zero", "y_unit", "y_min", "lankle"), 1.2, "hl"),
    ("nplane", ("lhip", "rhip", "lankle", "rankle"), 2.1, "hw"),
    ("angle", ("rknee", "rhip", "rknee", "rankle"), (0, 110)),
    ("angle", ("lknee", "lhip", "lknee", "lankle"), (0, 110)),
    ("fast", ("rankle",), 2.5, "hl"),
    ("fast", ("lankle",), 2.5, "hl"),
    ("angle", ("neck", "root", "rshoulder", "relbow"), (25, 180)),
    ("angle", ("neck", "root", "lshoulder", "lelbow"), (25, 180)),
    ("angle", ("neck", "root", "rhip", "rknee"), (50, 180)),
    ("angle", ("neck", "root", "lhip", "lknee"), (50, 180)),
    ("plane", ("rankle", "neck", "lankle", "root"), 0.5, "hl"),
    ("angle", ("neck", "root", "zero", "y_unit"), (70, 110)),
    ("nplane", ("zero", "minus_y_unit", "y_min", "rwrist"), -1.2, "hl"),
    ("nplane", ("zero", "minus_y_unit", "y_min", "lwrist"), -1.2, "hl"),
    ("fast", ("root",), 2.3, "hl"),
)


def geometric_features(positions: np.ndarray, fps: float = 60.0, peer_velocity: bool = True) -> np.ndarray:
    """The 32 geometric features of one sequence of SMPL-24 joints.

    Args:
        positions: [T, 24, 3] joint positions in metres, SMPL-24 order, y up, T >= 2.
        fps: frames per second; used only when ``peer_velocity`` is False.
        peer_velocity: velocities as the peers compute them (displacement per frame x 120).

    Returns:
        [32] float32 in 0..1: the fraction of frames 1..T-1 where each relation holds, in the order
        of :data:`RELATIONS`.
    """
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[1:] != (len(JOINTS), 3):
        raise KinectDataError(f"geometric features need [T, 24, 3] SMPL-24 positions, got shape {p.shape}")
    if p.shape[0] < 2:
        raise KinectDataError(f"geometric features need at least 2 frames, got {p.shape[0]}")
    if not np.all(np.isfinite(p)):
        frame = int(np.argmin(np.isfinite(p).all(axis=(1, 2))))
        raise KinectDataError(f"geometric features need finite positions; frame {frame} has a missing joint")
    if not peer_velocity and not fps > 0:
        raise KinectDataError(f"fps must be positive, got {fps}")
    rate = PEER_VELOCITY_RATE_HZ if peer_velocity else float(fps)
    now, before = _Frames(p[1:]), _Frames(p[:-1])
    with np.errstate(invalid="ignore", divide="ignore"):  # a zero-length direction: NaN, the relation is False
        holds = [_relation(spec, now, before, rate) for spec in RELATIONS]
    return np.mean(np.stack(holds, axis=1), axis=0).astype(np.float32)


_UNITS = {"hl": "humerus lengths", "sw": "shoulder widths", "hw": "hip widths"}


def describe_feature(index: int) -> str:
    """What geometric feature ``index`` (0-based, the order of :data:`RELATIONS`) counts, in words:
    the share of frames where the relation holds (velocities on the peers' scale, per frame x 120)."""
    relation, joints, *rest = RELATIONS[index]
    if relation == "angle":
        low, high = rest[0]
        return f"the angle between {joints[0]}->{joints[1]} and {joints[2]}->{joints[3]} within {low}-{high} degrees"
    threshold, unit = rest[0], _UNITS[rest[1]]
    if relation == "fast":
        return f"{joints[0]} faster than {threshold} {unit}/s"
    a, b, c, *d = joints
    if relation == "move":
        return f"{c} moving along {a}->{b}, relative to {a}, faster than {threshold} {unit}/s"
    if relation == "nmove":
        return f"{d[0]} moving across the plane of {a}, {b}, {c}, relative to {a}, faster than {threshold} {unit}/s"
    if relation == "nplane":
        return f"{d[0]} more than {threshold} {unit} beyond {c} along {a}->{b}"
    return f"{d[0]} more than {threshold} {unit} in front of the plane of {a}, {b}, {c}"


class _Frames:
    """Named points of [F, 24, 3] frames, with the peers' constant points."""

    def __init__(self, p: np.ndarray) -> None:
        self.p = p

    def __getitem__(self, name: str) -> np.ndarray:
        if name == "zero":
            return np.zeros((1, 3))
        if name == "y_unit":
            return np.array([[0.0, 1.0, 0.0]])
        if name == "minus_y_unit":
            return np.array([[0.0, -1.0, 0.0]])
        if name == "y_min":
            floor = np.zeros((self.p.shape[0], 3))
            floor[:, 1] = self.p[:, :, 1].min(axis=1)
            return floor
        return self.p[:, JOINTS.index(name)]


def _relation(spec: tuple, now: _Frames, before: _Frames, rate: float) -> np.ndarray:
    """[F] bool: the relation ``spec`` on each frame."""
    kind, joints = spec[0], spec[1]
    if kind == "angle":
        low, high = spec[2]
        a, b, c, d = (now[j] for j in joints)
        u, v = b - a, d - c
        cosine = np.sum(u * v, axis=-1) / (np.linalg.norm(u, axis=-1) * np.linalg.norm(v, axis=-1))
        angle = np.degrees(np.arccos(cosine))
        return (angle > low) & (angle < high)
    threshold = spec[2] * _LENGTHS[spec[3]]
    if kind == "fast":
        (a,) = joints
        return np.linalg.norm(now[a] - before[a], axis=-1) * rate > threshold
    if kind == "plane":
        a, b, c, d = (now[j] for j in joints)
        normal = np.cross(c - a, b - a)
        return _along(d - a, normal) > threshold
    if kind == "nplane":
        a, b, c, d = (now[j] for j in joints)
        return _along(d - c, b - a) > threshold
    if kind == "move":
        a, b, c = joints
        velocity = (now[c] - now[a]) - (before[c] - before[a])
        return _along(velocity, now[b] - now[a]) * rate > threshold
    if kind == "nmove":
        a, b, c, d = joints
        velocity = (now[d] - now[a]) - (before[d] - before[a])
        normal = np.cross(now[c] - now[a], now[b] - now[a])
        return _along(velocity, normal) * rate > threshold
    raise KinectDataError(f"unknown geometric relation {kind!r}")


def _along(vector: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """[F] the component of ``vector`` along ``direction`` (both [F, 3] or broadcastable)."""
    return np.sum(vector * direction, axis=-1) / np.linalg.norm(direction, axis=-1)
