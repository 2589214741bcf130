"""Training poses turned to face one way (kinectdata.training.augment.facing_windows): each frame
turned about the vertical through its root so that its hips' and shoulders' left-right axis lies
along +x, its shape, its heights and the root's travel kept; checked against scipy's rotations."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from kinectdata.core.errors import ConfigError
from kinectdata.core.jointsets import load_joint_set
from kinectdata.targets.normalization import Normalizer
from kinectdata.targets.specs import generic_target
from kinectdata.training.augment import Facing, facing_windows

SPEC = generic_target("positions", load_joint_set("tang2018"))


def manifest(spec=SPEC, centred=True, fps=1.0):
    """A manifest of ``spec``'s targets; at 1 fps the heading's 0.5-s average is one frame: unsmoothed."""
    norm = Normalizer("maxabs", np.full(spec.dim, 0.5), np.full(spec.dim, 0.1), np.full(spec.dim, 100))
    config = {"target": spec.to_dict(), "root_centre": centred, "fps": fps}
    return {"config": config, "normalisation": norm.to_dict()}


def body(frames: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(targets [frames, D] in metres, headings [frames] rad): one body whose left hip and shoulder
    lie at +x of their right ones, turned about y by a heading that changes every frame."""
    rng = np.random.default_rng(seed)
    names = SPEC.positions
    shape = {j: rng.uniform(-0.3, 0.3, 3) for j in names}
    for side, sign in (("left", 1), ("right", -1)):  # the trunk's pairs mirror each other across x = 0
        for part, height in (("hip", -0.05), ("shoulder", 0.45)):
            shape[f"{side}_{part}"] = np.array([sign * 0.15, height, 0.02])
    headings = rng.uniform(-np.pi, np.pi, frames)
    values = np.zeros((frames, SPEC.dim))
    for k, h in enumerate(headings):
        turn = Rotation.from_rotvec([0.0, -h, 0.0])  # about y: x towards z by h (y up, right-handed: -h)
        for j in names:
            values[k, SPEC.columns(j, "position")] = turn.apply(shape[j]) if j != SPEC.root else [1.0, 0.2, -0.5]
    return values, headings


def test_every_frame_comes_to_face_one_way_its_shape_kept():
    norm = Normalizer.from_dict(manifest()["normalisation"])
    values, _ = body(12)
    normalised = torch.tensor(norm.apply(values), dtype=torch.float32)
    batch = {
        "previous": normalised[None, :-2],
        "pose": normalised[None, 1:-1],
        "next": normalised[None, 2:],
        "mask": torch.ones(1, 10, SPEC.dim, dtype=torch.bool),
        "previous_mask": torch.ones(1, 10, SPEC.dim, dtype=torch.bool),
    }
    out = facing_windows(batch, Facing.of_dataset(manifest()))
    assert torch.equal(out["previous"][0, 1:], out["pose"][0, :-1]) and torch.equal(
        out["next"][0, :-1], out["pose"][0, 1:]
    )
    turned = norm.invert(out["pose"][0].double().numpy(), SPEC)
    for k in range(10):
        frame = turned[k].reshape(-1, 3)
        given = values[k + 1].reshape(-1, 3)
        assert np.allclose(frame[:, 1], given[:, 1], atol=1e-5)  # heights kept
        root = SPEC.positions.index(SPEC.root)
        assert np.allclose(frame[root], given[root], atol=1e-5)  # the root's travel kept
        others = [i for i in range(len(frame)) if i != root]
        d = np.linalg.norm(frame[others][:, None] - frame[others][None], axis=-1)
        assert np.allclose(d, np.linalg.norm(given[others][:, None] - given[others][None], axis=-1), atol=1e-4)
        hips = frame[SPEC.positions.index("left_hip")] - frame[SPEC.positions.index("right_hip")]
        assert hips[0] == pytest.approx(0.3, abs=1e-4) and hips[2] == pytest.approx(0.0, abs=1e-4)  # along +x


def test_a_frame_whose_trunk_is_unknown_is_left_as_it_is_and_bad_targets_are_refused():
    norm = Normalizer.from_dict(manifest()["normalisation"])
    values, _ = body(4, seed=1)
    normalised = torch.tensor(norm.apply(values), dtype=torch.float32)
    mask = torch.ones(1, 3, SPEC.dim, dtype=torch.bool)
    mask[0, 1, SPEC.columns("left_hip", "position")] = False
    batch = {"previous": normalised[None, :-1], "pose": normalised[None, 1:], "mask": mask,
             "previous_mask": torch.ones(1, 3, SPEC.dim, dtype=torch.bool)}  # fmt: skip
    out = facing_windows(batch, Facing.of_dataset(manifest()))
    assert torch.equal(out["pose"][0, 1], batch["pose"][0, 1])
    assert not torch.equal(out["pose"][0, 0], batch["pose"][0, 0])
    with pytest.raises(ConfigError, match="centred on their root"):
        Facing.of_dataset(manifest(centred=False))


def test_the_heading_is_smoothed_so_that_a_shaking_trunk_does_not_shake_the_body():
    """A body turning steadily, its heading read with noise (one hip shaking): turned by the smoothed
    heading, the far joints move a fraction as much as turned frame by frame; the steady turn is gone."""
    norm = Normalizer.from_dict(manifest()["normalisation"])
    frames = 90
    values, _ = body(1, seed=2)
    steady = np.zeros((frames, SPEC.dim))
    rng = np.random.default_rng(3)
    for k in range(frames):
        turn = Rotation.from_rotvec([0.0, -0.05 * k, 0.0])  # 1.5 rad/s at 30 fps
        for j in SPEC.positions:
            p = values[0, SPEC.columns(j, "position")]
            steady[k, SPEC.columns(j, "position")] = p if j == SPEC.root else turn.apply(p)
        hip = SPEC.columns("left_hip", "position")
        steady[k, hip] += [0.03 * rng.normal(), 0.0, 0.03 * rng.normal()]
    normalised = torch.tensor(norm.apply(steady), dtype=torch.float32)
    batch = {"previous": normalised[None, :-1], "pose": normalised[None, 1:],
             "mask": torch.ones(1, frames - 1, SPEC.dim, dtype=torch.bool),
             "previous_mask": torch.ones(1, frames - 1, SPEC.dim, dtype=torch.bool)}  # fmt: skip
    wrist = SPEC.columns("right_wrist", "position").start
    shakes = {}
    for fps in (1.0, 30.0):  # unsmoothed, then over 0.5 s (15 frames)
        out = facing_windows(batch, Facing.of_dataset(manifest(fps=fps)))
        metres = norm.invert(out["pose"][0].double().numpy(), SPEC)[:, [wrist, wrist + 2]]
        shakes[fps] = float(np.abs(np.diff(metres[10:-10], axis=0)).mean())
    turning = float(np.abs(np.diff(steady[11:-9, [wrist, wrist + 2]], axis=0)).mean())
    assert shakes[30.0] < 0.5 * shakes[1.0] and shakes[30.0] < 0.25 * turning
