"""A run's turning and travel drawn at generation, end to end on the sample sessions built
root-centred: train fits them into config.json (or, asked not to, keeps none), generate draws them
(a rigid turn of each frame about the vertical, then a move of the body across the floor over the
standing foot, seeded), live draws them frame by frame as generate does, evaluate says so and --no-turning and
--no-travel leave the network's motion alone."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import REPO, TINY_TRAINING

pytest.importorskip("torch")

from kinectdata.cli import main  # noqa: E402
from kinectdata.inference.export import stream_metadata  # noqa: E402
from kinectdata.inference.generate import generate  # noqa: E402
from kinectdata.live import sources  # noqa: E402
from kinectdata.live.clock import VirtualClock  # noqa: E402
from kinectdata.live.session import LiveDancer, run_live  # noqa: E402
from kinectdata.training.config import TrainConfig  # noqa: E402
from kinectdata.training.train import train  # noqa: E402

SONG = REPO / "sample_data" / "synth_001.flac"


def test_train_fits_the_training_dancers_turning_into_the_run(centred_run, tmp_path):
    run, dataset = centred_run
    turning = json.loads((run / "config.json").read_text())["turning"]
    assert turning["pivot"] == ["FootLeft", "FootRight"] and turning["recordings"] == 1
    assert turning["rms_speed"] == pytest.approx(turning["mean_abs_speed"] * math.sqrt(math.pi / 2))
    assert 0 < turning["rms_speed"] < 20 and 0 < turning["time_constant"] < 10
    off = TrainConfig(**{**TINY_TRAINING, "epochs": 1, "turning": False})
    train(dataset, tmp_path / "off", off)
    assert "turning" not in json.loads((tmp_path / "off" / "config.json").read_text())
    assert TrainConfig("yalta", paper=True).turning is False  # the papers drew no turning
    travel = json.loads((run / "config.json").read_text())["travel"]
    assert travel["recordings"] == 1 and 0 < travel["rms_speed"] < 2 and 0 < travel["time_constant"] < 10
    no_travel = TrainConfig(**{**TINY_TRAINING, "epochs": 1, "travel": False})
    train(dataset, tmp_path / "still", no_travel)
    assert "travel" not in json.loads((tmp_path / "still" / "config.json").read_text())
    assert TrainConfig("yalta", paper=True).travel is False
    shutil.copytree(run, tmp_path / "resumed")  # a resumed run keeps the process it was started with
    train(dataset, tmp_path / "resumed", TrainConfig(**{**TINY_TRAINING, "epochs": 2}), resume=True)
    resumed = json.loads((tmp_path / "resumed" / "config.json").read_text())
    assert resumed["turning"] == turning and resumed["travel"] == travel


def test_generate_turns_each_frame_rigidly_about_the_vertical_and_is_seeded(centred_run):
    run, _ = centred_run
    still, timing_still = generate(run, SONG, turning=False, travel=False)
    turned, timing = generate(run, SONG, travel=False)
    again, _ = generate(run, SONG, travel=False)
    other, _ = generate(run, SONG, seed=1, travel=False)
    assert timing_still["turning"] == "none drawn" and "about the standing foot" in timing["turning"]
    np.testing.assert_array_equal(turned.positions, again.positions)
    assert not np.allclose(turned.positions, other.positions)
    p, q = still.positions, turned.positions
    np.testing.assert_allclose(q[..., 1], p[..., 1], atol=1e-9)  # heights kept
    for k in (0, len(p) // 2, len(p) - 1):  # each frame's shape kept: the distances between its joints
        dp = np.linalg.norm(p[k][:, None] - p[k][None], axis=-1)
        np.testing.assert_allclose(np.linalg.norm(q[k][:, None] - q[k][None], axis=-1), dp, atol=1e-9)
    assert np.abs(q - p).max() > 1e-3  # and it does turn


def test_the_travel_moves_the_body_over_the_standing_foot_and_the_turning_is_drawn_as_without_it(centred_run):
    run, _ = centred_run
    still, _ = generate(run, SONG, turning=False, travel=False)
    moved, timing = generate(run, SONG, turning=False)
    assert "travel drawn at generation" in timing["turning"] and "over the standing foot" in timing["turning"]
    config = json.loads((run / "config.json").read_text())
    lock = {
        "catch_up_s": 0.1,
        "lead_s": 0.1,
        "velocity_smoothing_s": 0.2,
        "stance_margin_m": 0.02,
        "shift_s": 0.15,
        "steps_at_reach": True,
    }
    assert stream_metadata(config)["foot_lock"] == lock
    assert stream_metadata({**config, "travel": None})["foot_lock"] is None
    names = list(still.joint_set.names)
    legs = [names.index(f"{j}{s}") for j in ("Knee", "Ankle", "Foot") for s in ("Left", "Right")]
    body = [j for j in range(len(names)) if j not in legs]
    shift = moved.positions[:, body] - still.positions[:, body]  # [T, J - 6, 3]
    np.testing.assert_allclose(shift[..., 1], 0.0, atol=1e-9)  # no joint rises or falls
    np.testing.assert_allclose(shift, np.broadcast_to(shift[:, :1], shift.shape), atol=1e-9)  # all alike
    assert np.abs(shift[:, 0, [0, 2]]).max() > 0.01  # and it does move
    for upper, lower in (("Hip", "Knee"), ("Knee", "Ankle"), ("Ankle", "Foot")):  # the legs keep their bones
        for side in ("Left", "Right"):
            a, b = names.index(upper + side), names.index(lower + side)
            before, after = (np.linalg.norm(m.positions[:, a] - m.positions[:, b], axis=-1) for m in (still, moved))
            np.testing.assert_allclose(after, before, atol=1e-6)
    # the turning's draws do not depend on whether the travel is drawn after it
    turned_only, _ = generate(run, SONG, travel=False)
    both, _ = generate(run, SONG)
    from_turning = turned_only.positions[:, body] - still.positions[:, body]
    np.testing.assert_allclose(both.positions[:, body] - shift - still.positions[:, body], from_turning, atol=1e-6)


def test_the_travel_starts_where_the_dance_stands_and_is_pulled_towards_the_floors_centre(centred_run):
    """The run keeps its training dancer's floor; a dance started off its centre is the same draw
    as one started at it, less a pull towards the centre along the offset (never across it), and a
    dance started outside the floor (a recording from another room) is drawn as one at the centre."""
    from kinectdata.inference.start import StartPose
    from kinectdata.inference.turning import TurnedKind, with_turning
    from kinectdata.models.registry import model_kind
    from kinectdata.targets.travel import TravelProcess

    run, dataset = centred_run
    config = json.loads((run / "config.json").read_text())
    floor = TravelProcess.from_dict(config["travel"])
    assert floor.pull is not None and "pulled towards the floor's centre" in floor.describe()
    pose = np.asarray(config["dataset"]["start_pose"], np.float32)
    cx, cz = floor.centre

    def root_travel(x: float) -> np.ndarray:
        motion, _ = generate(run, SONG, start=StartPose(pose, np.array([x, 0.9, cz])), turning=False)
        root = motion.positions[:, motion.joint_set.index("SpineBase")][:, [0, 2]]
        return root - root[0]

    at_centre, off_centre, outside = (root_travel(cx + d) for d in (0.0, floor.radius / 2, floor.radius + 1))
    np.testing.assert_allclose(outside, at_centre, atol=1e-9)
    pull = off_centre - at_centre
    np.testing.assert_allclose(pull[:, 1], 0.0, atol=1e-9)  # along the offset (+x) only
    assert pull[:, 0].max() <= 1e-9 and pull[:, 0].min() < -1e-4 and np.diff(pull[:, 0]).max() <= 1e-9
    assert pull[:, 0].min() > -floor.radius / 2  # towards the centre, never past it
    # evaluate tells its kind where each song's dancer stood: the recording's root anchor
    from kinectdata.evaluation.evaluate import _tell_kind, split_recordings
    from kinectdata.models.run import model_name, read_manifest

    kind = with_turning(model_kind(model_name(config)), config)
    assert isinstance(kind, TurnedKind)
    manifest = read_manifest(dataset, checksums=False)
    recordings = split_recordings(dataset, manifest, "test")
    _tell_kind(kind, recordings, {}, manifest, config, None)
    assert [p.tolist() for p in kind.places.values()] == [r["info"]["root_anchor"] for r in recordings]


def test_live_draws_the_turning_frame_by_frame_as_generate_does(centred_run):
    run, _ = centred_run
    clock = VirtualClock(100.0)
    dancer = LiveDancer(run, "torch", seed=3)
    assert "turning drawn at generation" in dancer.turning_line and "travel drawn" in dancer.turning_line

    class Kept:
        def __init__(self):
            self.positions = []

        def send(self, pose):
            self.positions.append(pose.positions)

    kept = Kept()
    run_live(dancer, sources.FileSource(SONG, dancer.sample_rate, 80, clock), [kept], clock)
    expected, _ = generate(run, SONG, seed=3)
    np.testing.assert_allclose(np.stack(kept.positions), expected.positions, atol=1e-6, equal_nan=True)


@pytest.mark.slow
def test_evaluate_says_what_it_drew_and_no_turning_leaves_the_network_alone(centred_run, tmp_path):
    run, dataset = centred_run
    args = ["evaluate", "--run", str(run), "--data", str(dataset), "--split", "test", "--bootstrap", "0"]
    drawn = CliRunner().invoke(main, [*args, "--out", str(tmp_path / "a")])
    assert drawn.exit_code == 0, drawn.output
    assert "turning drawn at generation: speed" in drawn.output and "fitted on 1 training recordings" in drawn.output
    plain = CliRunner().invoke(main, [*args, "--out", str(tmp_path / "b"), "--no-turning"])
    assert plain.exit_code == 0, plain.output
    assert "turning drawn" not in plain.output and "travel drawn at generation" in plain.output
    neither = CliRunner().invoke(main, [*args, "--out", str(tmp_path / "c"), "--no-turning", "--no-travel"])
    assert neither.exit_code == 0, neither.output
    seeded = CliRunner().invoke(main, [*args, "--out", str(tmp_path / "d"), "--seed", "1"])
    assert seeded.exit_code == 0, seeded.output
    assert "drawn with seed 0" in drawn.output and "drawn with seed 1" in seeded.output
    results = [json.loads((tmp_path / x / "results.json").read_text()) for x in "abcd"]
    assert results[2]["turning"] is None and results[0]["turning"].startswith("turning drawn")
    assert "travel drawn" in results[0]["turning"]
    # heights are the network's either way; the horizontal places are not
    assert results[0]["smape"]["without_reset"] != results[2]["smape"]["without_reset"]
    # another seed, other draws of the same network: other places, the same description
    assert (results[0]["draw_seed"], results[3]["draw_seed"]) == (0, 1)
    assert results[3]["turning"] == results[0]["turning"]
    assert results[0]["smape"]["without_reset"] != results[3]["smape"]["without_reset"]


def test_a_facing_run_dances_on_from_its_first_pose_whichever_way_that_pose_faces(centred_run, tmp_path):
    """A run that learnt its poses facing one way, started from a first pose turned by an angle about
    the vertical, makes the dance it makes from the unturned pose, turned by that angle: it sees the
    same faced pose either way. And its mean pose, the start, faces the way it learnt (its hips along
    +x)."""
    from kinectdata.inference.start import StartPose
    from kinectdata.targets.facing import heading, turn_about_root
    from kinectdata.targets.normalization import Normalizer
    from kinectdata.targets.specs import TargetSpec

    _, dataset = centred_run
    run = tmp_path / "facing"
    train(dataset, run, TrainConfig(**{**TINY_TRAINING, "epochs": 1, "facing": True}))
    config = json.loads((run / "config.json").read_text())
    spec = TargetSpec.from_dict(config["dataset"]["target"])
    norm = Normalizer.from_dict(config["dataset"]["normalisation"])
    mean = norm.invert(np.asarray(config["dataset"]["start_pose"])[None], spec)[0]
    assert heading(mean, spec) == pytest.approx(0.0, abs=1e-6)
    made = {}
    for angle in (0.0, 1.1):
        pose = norm.apply(turn_about_root(mean, spec, angle)[None])[0].astype(np.float32)
        motion, _ = generate(run, SONG, start=StartPose(pose), turning=False, travel=False)
        made[angle] = motion.positions - motion.positions[:, [motion.joint_set.index("SpineBase")]]
    cos, sin = math.cos(1.1), math.sin(1.1)
    x, z = made[0.0][..., 0], made[0.0][..., 2]
    np.testing.assert_allclose(made[1.1][..., 0], cos * x - sin * z, atol=1e-4)
    np.testing.assert_allclose(made[1.1][..., 2], sin * x + cos * z, atol=1e-4)
    np.testing.assert_allclose(made[1.1][..., 1], made[0.0][..., 1], atol=1e-4)
