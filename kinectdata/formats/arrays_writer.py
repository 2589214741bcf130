"""Writing a 3-D Motion as joint arrays with their array schema (the reader: :mod:`.arrays`).

``dance.npz`` holds ``positions`` [T, J, 3] float64 metres, y up (NaN where a joint has no value),
``times`` [T] seconds, ``confidence`` [T, J] float32 and, where the recording has them,
``orientations`` [T, J, 4] unit quaternions x, y, z, w (NaN where none). Beside it
``dance.schema.json`` (``schemas/array-schema.schema.json``) says so, so that the arrays read back
with ``--schema dance.schema.json`` and no code; a joint set kinectdata does not ship is written
as ``dance.joints.json`` beside them and named by the schema. All three files appear together or
not at all.
"""

from __future__ import annotations

import json
import re
from contextlib import ExitStack
from pathlib import Path

import numpy as np

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import KinectDataError
from kinectdata.core.jointsets import is_shipped
from kinectdata.core.motion import Motion
from kinectdata.formats.writers import register_writer

SCHEMA_SUFFIX = ".schema.json"
JOINTS_SUFFIX = ".joints.json"


def companions(path: str | Path) -> tuple[Path, Path]:
    """The array schema and joint-set files written beside ``path`` (``dance.npz``:
    ``dance.schema.json``, ``dance.joints.json``)."""
    path = Path(path)
    stem = path.name[: -len(path.suffix)] if path.suffix else path.name
    return path.with_name(stem + SCHEMA_SUFFIX), path.with_name(stem + JOINTS_SUFFIX)


@register_writer(
    "arrays",
    extensions=(".npz",),
    description="Joint arrays (.npz) with their array schema (.schema.json) beside them",
)
def write_arrays(motion: Motion, path: str | Path) -> Path:
    """Write ``motion`` (3-D) as ``path`` (``.npz``) and its array schema beside it, atomically.

    Returns:
        The ``.npz`` path; the schema is :func:`companions`' first.

    Raises:
        KinectDataError: a 2-D joint set (joint arrays hold 3-D joints).
    """
    path = Path(path)
    js = motion.joint_set
    if js.dimensions != 3:
        raise KinectDataError(f"{path}: joint arrays hold 3-D joints; joint set {js.name!r} is {js.dimensions}-D")
    schema_path, joints_path = companions(path)
    shipped = is_shipped(js)
    arrays = {
        "positions": np.where(motion.position_mask[..., None], motion.positions, np.nan),
        "times": motion.times,
        "confidence": motion.confidence.astype(np.float32),
    }
    if motion.has_orientations:
        arrays["orientations"] = np.where(motion.orientation_mask[..., None], motion.orientations, np.nan)
    source = motion.metadata.get("source")
    schema = {
        "name": re.sub(r"[^A-Za-z0-9_.-]", "_", schema_path.name[: -len(SCHEMA_SUFFIX)]) or "arrays",
        "description": f"{path.name}: {motion.n_frames} frames of {js.name} joints in metres, y up"
        + (f", from {Path(str(source)).name}" if source else ""),
        "joint_set": js.name if shipped else joints_path.name,
        "positions": "positions",
        "time": {"key": "times", "unit": "s"},
        "unit": "m",
        "up": "y",
        "confidence": "confidence",
        **({"orientations": "orientations"} if "orientations" in arrays else {}),
    }
    with ExitStack() as stack:  # every file renamed into place only when all were written
        if not shipped:
            tmp = stack.enter_context(atomic_output(joints_path))
            tmp.write_text(json.dumps(js.to_dict(), indent=1) + "\n", encoding="utf-8")
        tmp = stack.enter_context(atomic_output(schema_path))
        tmp.write_text(json.dumps(schema, indent=1) + "\n", encoding="utf-8")
        tmp = stack.enter_context(atomic_output(path))
        with open(tmp, "wb") as f:  # a file object: np.savez would add ".npz" to a name
            np.savez(f, **arrays)
    return path
