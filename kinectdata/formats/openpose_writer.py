"""Writing a 2-D ``openpose_mpi`` Motion as OpenPose JSON Lines (the reader: :mod:`.openpose`).

One line per frame, ``{"version": 1.3, "frame": k, "people": [{"person_id": [0],
"pose_keypoints_2d": [x, y, c] * 15}]}``, the 15 keypoints in the MPI-15 order (the joint set's
order), so the reader detects the ``mpi15`` layout; a joint without a value is written as OpenPose
writes an undetected keypoint, ``0, 0, 0``. The frame number is the frame's index; the frame rate
is not in the format (give it to the reader as ``video_fps``).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import KinectDataError
from kinectdata.core.motion import Motion
from kinectdata.formats.writers import register_writer


def openpose_loses(motion: Motion) -> list[str]:
    """What of ``motion`` OpenPose JSON cannot carry, each a short phrase (:mod:`.writers`)."""
    lost = ["the frame times (OpenPose JSON numbers frames: read it back with --video-fps)"]
    if motion.has_orientations:
        lost.append("the orientations")
    return lost


@register_writer(
    "openpose", extensions=(".jsonl",), loses=openpose_loses, description="OpenPose JSON Lines (2-D MPI-15)"
)
def write_openpose_jsonl(motion: Motion, path: str | Path, *, digits: int = 6) -> Path:
    """Write ``motion`` (joint set ``openpose_mpi``) to ``path`` atomically; values rounded to ``digits``
    decimals. Returns the path."""
    path = Path(path)
    if motion.joint_set.name != "openpose_mpi":
        raise KinectDataError(f"{path}: OpenPose JSON holds openpose_mpi joints, not {motion.joint_set.name}")
    values = np.zeros((motion.n_frames, motion.n_joints, 3))
    values[..., :2] = np.where(motion.position_mask[..., None], motion.positions, 0.0)
    values[..., 2] = np.where(motion.position_mask, np.maximum(motion.confidence, 1e-3), 0.0)  # c > 0: detected
    values = np.round(values, digits)
    lines = [
        json.dumps(
            {"version": 1.3, "frame": k, "people": [{"person_id": [0], "pose_keypoints_2d": frame.ravel().tolist()}]}
        )
        for k, frame in enumerate(values)
    ]
    with atomic_output(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    return path
