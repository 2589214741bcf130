"""Helpers shared by the tests (import as `from helpers import ...`)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from kinectdata.core.jointsets import load_joint_set
from kinectdata.core.motion import Motion


def random_motion(T: int = 40, seed: int = 0, untracked: float = 0.05, inferred: float = 0.1) -> Motion:
    """A Kinect v2 Motion with random positions, orientations and tracking, jittered 30 fps times."""
    rng = np.random.default_rng(seed)
    js = load_joint_set("kinect_v2")
    t = np.arange(T) / 30.0 + rng.normal(0, 0.002, T)
    t -= t[0]
    conf = rng.choice([0.0, 0.5, 1.0], size=(T, len(js)), p=[untracked, inferred, 1 - untracked - inferred])
    q = Rotation.random(T * len(js), random_state=seed).as_quat().reshape(T, len(js), 4)
    return Motion(t, rng.normal(0, 0.6, (T, len(js), 3)), js, position_mask=conf > 0, confidence=conf, orientations=q)


# yalta65, written out here as the tests' independent expectation of kinectdata/schemas/targets/yalta65.json
YALTA_POSITIONS = ["SpineBase", "HandLeft", "HandRight"]
YALTA_ORIENTATIONS = [
    "SpineBase",
    "SpineMid",
    "SpineShoulder",
    "Neck",
    "ShoulderLeft",
    "ElbowLeft",
    "WristLeft",
    "ShoulderRight",
    "ElbowRight",
    "WristRight",
    "HipLeft",
    "KneeLeft",
    "HipRight",
    "KneeRight",
]


def skip_unless_installed(missing: str | None, what: str) -> None:
    """Skip a test whose system dependency is missing here, but fail it under CI (``CI`` set), whose
    ``.ci/run`` installs that dependency: a broken install must not pass as a skipped test."""
    import os

    import pytest

    if missing is None:
        return
    message = f"{what} not usable here: {missing}"
    if os.environ.get("CI"):
        pytest.fail(f"{message} (CI installs it: .ci/run)")
    pytest.skip(message)
