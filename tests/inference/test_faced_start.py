"""A run that learnt its poses facing one way starts its free runs from a faced first pose and turns
its dance back to where that pose stood (kinectdata.targets.facing, kinectdata.inference.turning):
the heading against the body's known turn (scipy's rotations), the faced pose against the training
loop's own facing (torch), and the free run's wiring through a stub network."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "training"))
from test_facing import SPEC, body, manifest  # noqa: E402

from kinectdata.inference.turning import TurnedKind, faced_first_pose, run_faces, with_turning  # noqa: E402
from kinectdata.targets.facing import faced, heading, turn_about_root  # noqa: E402
from kinectdata.targets.normalization import Normalizer  # noqa: E402
from kinectdata.training.augment import Facing, facing_windows  # noqa: E402


def _config(facing=True, turning=True, centred=True):
    m = manifest(centred=centred)
    dataset = {"target": SPEC.to_dict(), "normalisation": m["normalisation"], "root_centre": centred, "fps": 30.0,
               "features": {}}  # fmt: skip
    return {"train": {"facing": facing, "turning": turning}, "dataset": dataset}


def test_the_heading_is_the_turn_the_body_was_given_and_turning_back_restores_it():
    values, headings = body(20, seed=4)
    np.testing.assert_allclose(np.unwrap(heading(values, SPEC) - headings), 0.0, atol=1e-9)
    turned, found = faced(values, SPEC)
    np.testing.assert_allclose(heading(turned, SPEC), 0.0, atol=1e-9)
    np.testing.assert_allclose(turn_about_root(turned, SPEC, found), values, atol=1e-12)
    root = SPEC.columns(SPEC.root, "position")
    np.testing.assert_array_equal(turned[:, root], values[:, root])


def test_the_faced_pose_is_the_one_the_training_loop_learns_from():
    norm = Normalizer.from_dict(manifest()["normalisation"])
    values, _ = body(6, seed=5)
    normalised = torch.tensor(norm.apply(values), dtype=torch.float32)
    ones = torch.ones(1, 5, SPEC.dim, dtype=torch.bool)
    batch = {"previous": normalised[None, :-1], "pose": normalised[None, 1:], "mask": ones, "previous_mask": ones}
    trained = norm.invert(facing_windows(batch, Facing.of_dataset(manifest()))["pose"][0].double().numpy(), SPEC)
    np.testing.assert_allclose(faced(values[1:], SPEC)[0], trained, atol=1e-5)


class _Holds:
    """A stub network kind: its free run holds the first pose it is given, and remembers it."""

    name = "holds"

    def __init__(self):
        self.given = []

    def free_run(self, net, audio, first_pose, reset_every=None):
        self.given.append(np.array(first_pose))
        return np.repeat(np.asarray(first_pose)[None], len(audio) - 1, axis=0)

    def free_runs(self, net, audios, first_poses, reset_every=None):
        return [self.free_run(net, a, p, reset_every) for a, p in zip(audios, first_poses)]


def test_a_free_run_starts_faced_and_comes_back_to_where_its_first_pose_stood():
    config = _config()
    norm = Normalizer.from_dict(config["dataset"]["normalisation"])
    values, headings = body(1, seed=6)
    pose = norm.apply(values)[0].astype(np.float32)
    kind = _Holds()
    drawn = with_turning(kind, config)
    assert isinstance(drawn, TurnedKind)  # no turning or travel kept, but the run faces
    audio = np.ones((40, 1, 129, 5), np.float32)  # STFT frames (not silence: the run is not held still)
    run = drawn.free_run(None, audio, pose)
    given = norm.invert(kind.given[0][None].astype(np.float64), SPEC)[0]
    assert heading(given, SPEC) == pytest.approx(0.0, abs=1e-5)  # the network saw a faced pose
    np.testing.assert_allclose(norm.invert(np.asarray(run, np.float64), SPEC), np.repeat(values, 39, 0), atol=1e-4)
    (reset,) = drawn.free_runs(None, [audio], [pose], reset_every=10)
    np.testing.assert_allclose(norm.invert(np.asarray(reset, np.float64), SPEC), np.repeat(values, 39, 0), atol=1e-4)
    assert faced_first_pose(config, pose)[1] == pytest.approx(headings[0])


@pytest.mark.parametrize("changes", [{"facing": False}, {"turning": False}, {"centred": False}])
def test_a_run_that_did_not_learn_facing_starts_from_its_pose_as_it_is(changes):
    config = _config(**changes)
    pose = np.linspace(-0.5, 0.5, SPEC.dim).astype(np.float32)
    assert not run_faces(config)
    out, h = faced_first_pose(config, pose)
    assert h == 0.0 and np.array_equal(out, pose)
    assert with_turning(_Holds(), {**config, "turning": None, "travel": None}).__class__ is _Holds


def test_the_start_pose_of_a_facing_run_is_the_mean_of_faced_poses(tmp_path):
    """The mean pose of bodies facing every way has its hips at the body's axis; faced first, the
    hips keep their width (0.3 m) and the mean is the body's own shape."""
    import h5py

    from kinectdata.training.train import _start_pose

    m = manifest()
    norm = Normalizer.from_dict(m["normalisation"])
    values, _ = body(400, seed=7)
    with h5py.File(tmp_path / "train-00000.h5", "w") as f:
        f["current"] = norm.apply(values).astype(np.float32)
        f["mask"] = np.ones(values.shape, bool)
    listed = [{"split": "train", "shard": "train-00000.h5", "start": 0, "frames": 400}]
    manifest_doc = {**m, "target_dim": SPEC.dim, "recordings": listed}
    hips = SPEC.columns("left_hip", "position").start, SPEC.columns("right_hip", "position").start
    for faces, width in ((False, 0.0), (True, 0.3)):
        mean = norm.invert(np.asarray(_start_pose(tmp_path, manifest_doc, faces))[None], SPEC)[0]
        assert mean[hips[0]] - mean[hips[1]] == pytest.approx(width, abs=0.03)
    np.testing.assert_allclose(mean, faced(values[:1], SPEC)[0][0], atol=1e-4)
