"""Does a 3-D recording look like a human body in metres, upright, at its frame rate?

Formats that do not say their unit (BVH, a new CSV dialect, declared arrays) or their up axis are
easy to read wrongly, and nothing fails: a dancer in centimetres read as metres is a 170 m giant,
one with z up lies on their back, one at 120 fps read as 30 dances four times too slowly. These
checks look at the body itself (`kinectdata info` prints them):

- :func:`bone_lengths`: each bone's median length (metres, over the frames where both its joints
  are valid);
- :func:`unit_doubt`: the body's extent, the median over frames of its bounding box's diagonal,
  should be 0.3-3.5 m (a person spans 1-2.5 m); 100 or 1000 times that says centimetres or
  millimetres read as metres, and 1/100 or 1/1000 the reverse;
- :func:`up_axis_doubt`: the head should be above the feet along the recording's up axis (y, or the
  file's ``gravity_axis``): with the joint set's ``head`` and foot roles, the median head-to-feet
  vector must point most along +up; without them, the body's longest principal axis (a dancer is
  taller than wide) must be the up axis;
- :func:`speed_doubt`: the 99th percentile of the joints' speeds should stay under 20 m/s (a
  dancer's hands reach 5-8 m/s): beyond, the stated frame rate is too high (a 30 fps file read at
  300) or the unit too large; and over a take of 10 s or more it should reach 0.8 m/s (real dance:
  2.5-7.2 m/s on the tang2018 corpus, 43 ballroom dances, so that a rate 10 times too low falls
  below it in every one): below, if the take is of dance, the stated rate is too low (a 25 fps file
  read at 2.5) or the unit too small.
"""

from __future__ import annotations

import numpy as np

from kinectdata.core.motion import Motion

MAX_CHECKED_COORDINATE = 1e150
"""Coordinates beyond this (and non-finite ones) are left out of the checks: no unit read wrongly
makes them (a body in micrometres read as metres is 10^6), and squaring them would overflow. The
checks must still see a body 1000 times too large, so this is not align's 1 km limit."""
BODY_EXTENT_M = (0.3, 3.5)
"""Plausible range of a body's extent in metres (its bounding box diagonal, median over frames)."""
MAX_SPEED_M_S = 20.0
"""Joint speeds (99th percentile) above this are no dancer's."""
MIN_DANCE_SPEED_M_S = 0.8
"""Joint speeds (99th percentile) below this, over :data:`MIN_SLOW_TAKE_S` or more, are no dance's."""
MIN_SLOW_TAKE_S = 10.0
_AXES = "xyz"
_SAMPLE_FRAMES = 2000  # the checks look at this many frames, evenly spread, of a long recording


def plausible_mask(motion: Motion) -> np.ndarray:
    """[T, J] bool: positions marked valid whose coordinates are finite and within
    :data:`MAX_CHECKED_COORDINATE` (what the checks below use)."""
    with np.errstate(invalid="ignore"):
        inside = (np.abs(motion.positions) <= MAX_CHECKED_COORDINATE).all(axis=-1)
    return motion.position_mask & inside


def _sampled(motion: Motion) -> np.ndarray:
    """Frame indices the checks use: all, or :data:`_SAMPLE_FRAMES` evenly spread."""
    n = motion.n_frames
    return np.arange(n) if n <= _SAMPLE_FRAMES else np.linspace(0, n - 1, _SAMPLE_FRAMES).round().astype(int)


def bone_lengths(motion: Motion) -> dict[str, float]:
    """``{"Parent-Child": metres}``: each bone's median length over the frames where both its joints
    are valid (bones never seen whole are left out)."""
    js = motion.joint_set
    valid = plausible_mask(motion)
    out = {}
    for parent, child in js.bones():
        both = valid[:, parent] & valid[:, child]
        if both.any():
            lengths = np.linalg.norm(motion.positions[both, child] - motion.positions[both, parent], axis=-1)
            out[f"{js.names[parent]}-{js.names[child]}"] = float(np.median(lengths))
    return out


def body_extent(motion: Motion) -> float | None:
    """Metres: the median over frames of the diagonal of the valid joints' bounding box; None when
    no frame has two valid joints."""
    extents = []
    usable = plausible_mask(motion)
    for t in _sampled(motion):
        valid = motion.positions[t, usable[t]]
        if len(valid) >= 2:
            extents.append(float(np.linalg.norm(valid.max(axis=0) - valid.min(axis=0))))
    return float(np.median(extents)) if extents else None


def unit_doubt(motion: Motion) -> str | None:
    """A sentence when the body's extent (:func:`body_extent`) is not a person's in metres, else None."""
    if motion.joint_set.dimensions != 3:
        return None
    extent = body_extent(motion)
    lo, hi = BODY_EXTENT_M
    if extent is None or lo <= extent <= hi:
        return None
    for factor, unit, reverse in (
        (100, "centimetres", False),
        (1000, "millimetres", False),
        (1 / 100, "centimetres", True),
        (1 / 1000, "millimetres", True),
    ):
        if lo * factor <= extent <= hi * factor:
            if reverse:
                return (
                    f"the body spans {extent:.4g} m, a person 1-2.5 m: metres read as {unit}? (the values look "
                    f"{round(1 / factor)} times too small)"
                )
            return (
                f"the body spans {extent:.4g} m, a person 1-2.5 m: {unit} read as metres? (read the file with its "
                f"unit: BVH --unit {'cm' if factor == 100 else 'mm'}, an array schema's unit, a CSV dialect's "
                "position unit)"
            )
    return f"the body spans {extent:.4g} m, a person 1-2.5 m: is the unit right?"


def up_axis(motion: Motion) -> int:
    """Index (0, 1, 2) of the recording's up axis: its ``gravity_axis`` metadata (HTR), else y."""
    declared = str(motion.metadata.get("gravity_axis", "y")).strip().lower()
    return _AXES.index(declared[-1]) if declared and declared[-1] in _AXES else 1


def up_axis_doubt(motion: Motion) -> str | None:
    """A sentence when the head is not above the feet along the up axis (see the module), else None."""
    if motion.joint_set.dimensions != 3:
        return None
    up = up_axis(motion)
    js = motion.joint_set
    head, feet = js.role("head"), [j for j in (js.role("left_foot"), js.role("right_foot")) if j is not None]
    frames = _sampled(motion)
    usable = plausible_mask(motion)
    if head is not None and feet:
        ok = usable[frames, head] & usable[frames][:, feet].all(axis=1)
        if not ok.any():
            return None
        rows = frames[ok]
        rise = np.median(motion.positions[rows, head] - motion.positions[rows][:, feet].mean(axis=1), axis=0)
        axis = int(np.argmax(np.abs(rise)))
        if axis == up and rise[axis] > 0:
            return None
        where = f"{'above' if rise[axis] > 0 else 'below'} the feet along {_AXES[axis]}"
        return (
            f"the head is {where} ({rise[axis]:+.2f}), but the up axis is {_AXES[up]}: the floor is not below the "
            "feet (are the file's axes or the up axis right?)"
        )
    centred = [motion.positions[t, usable[t]] for t in frames]
    centred = [p - p.mean(axis=0) for p in centred if len(p) >= 3]
    if not centred:
        return None
    points = np.concatenate(centred)
    _, _, vt = np.linalg.svd(points, full_matrices=False)
    axis = int(np.argmax(np.abs(vt[0])))
    if axis == up:
        return None
    return (
        f"the body is longest along {_AXES[axis]}, but the up axis is {_AXES[up]}: a dancer lying down, or the "
        "file's axes are not the expected ones"
    )


def speed_doubt(motion: Motion) -> str | None:
    """A sentence when the joints move faster than a dancer can, or slower than dance does over a
    long take (see the module), else None."""
    if motion.joint_set.dimensions != 3 or motion.n_frames < 2:
        return None
    usable = plausible_mask(motion)
    both = usable[1:] & usable[:-1]
    if not both.any():
        return None
    dt = np.diff(motion.times)[:, None]
    steps = np.diff(np.where(usable[..., None], motion.positions, 0.0), axis=0)  # no step from or to a bad value
    speeds = (np.linalg.norm(steps, axis=-1) / dt)[both]
    fast = float(np.percentile(speeds, 99))
    if fast > MAX_SPEED_M_S:
        return (
            f"joints move at {fast:.3g} m/s (99th percentile), no dancer's speed (hands reach 5-8 m/s): is the "
            "stated frame rate too high (a 30 fps file read at 300?), or the unit too large?"
        )
    if fast < MIN_DANCE_SPEED_M_S and motion.duration >= MIN_SLOW_TAKE_S:
        return (
            f"joints move at most {fast:.2g} m/s (99th percentile), slower than dance (2.5-7 m/s in real dances): "
            "if this is dance, is the stated frame rate too low (a 25 fps file read at 2.5?), or the unit too "
            "small? (A take of someone standing still reads so too.)"
        )
    return None
