"""Tests of the synthetic OpenPose output (kinectdata.synth.openpose): the projection against an
independent camera matrix, the keypoint table against the documented offsets, the detector's
statistics, the passer-by, the files, their atomic writing, the command line and the reader."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from scipy import stats
from scipy.spatial.transform import Rotation

from kinectdata.cli import main
from kinectdata.synth import dance, make_body, synthesize_openpose, synthesize_recording, write_openpose_recording
from kinectdata.synth import openpose as op

# OpenPose's BODY_25 order and the Kinect v2 joint of each directly mapped keypoint, written out
# here as the tests' own expectation.
BODY_25 = [
    "Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist", "MidHip", "RHip", "RKnee",
    "RAnkle", "LHip", "LKnee", "LAnkle", "REye", "LEye", "REar", "LEar", "LBigToe", "LSmallToe", "LHeel",
    "RBigToe", "RSmallToe", "RHeel",
]  # fmt: skip
FROM_KINECT = {
    "Neck": "SpineShoulder", "MidHip": "SpineBase",
    "RShoulder": "ShoulderRight", "RElbow": "ElbowRight", "RWrist": "WristRight",
    "LShoulder": "ShoulderLeft", "LElbow": "ElbowLeft", "LWrist": "WristLeft",
    "RHip": "HipRight", "RKnee": "KneeRight", "RAnkle": "AnkleRight",
    "LHip": "HipLeft", "LKnee": "KneeLeft", "LAnkle": "AnkleLeft",
}  # fmt: skip
K = np.array([[1060.0, 0.0, 959.5], [0.0, 1060.0, 539.5], [0.0, 0.0, 1.0]])
"""The documented colour camera as an intrinsic matrix (OpenCV axes: x right, y down, z forward)."""
KINECT_TO_OPENCV = np.diag([-1.0, -1.0, 1.0])  # Kinect x points to the sensor's left, y up
SD_PX = 2.0


def _project(points: np.ndarray) -> np.ndarray:
    """Pixels of Kinect camera-space points [..., 3] through K [R | 0], by homogeneous division."""
    h = points @ KINECT_TO_OPENCV.T @ K.T
    return h[..., :2] / h[..., 2:]


def _kp(name: str) -> int:
    return BODY_25.index(name)


@pytest.fixture(scope="module")
def rec():
    return synthesize_recording(seed=7, duration_s=12.0)


@pytest.fixture(scope="module")
def video(rec):
    return synthesize_openpose(rec)


@pytest.fixture(scope="module")
def written(rec, tmp_path_factory):
    return write_openpose_recording(rec, tmp_path_factory.mktemp("openpose"), "s7")


def _exact_dance(rec, times):
    """The noise-free dance evaluated directly at ``times`` (recording clock): the session's dance
    seed is the third child of its seed (see synthesize_recording)."""
    tr = rec.truth
    return dance(
        seed=np.random.SeedSequence(rec.options["seed"]).spawn(5)[2],
        times_s=times + tr["offset_s"],
        beat_times_s=np.array(tr["beat_times_s"]),
        music_start_s=tr["music_start_s"],
        clap_time_s=tr["clap_time_audio_s"],
        tempo_bpm=tr["tempo_bpm"],
    )


def _read_frames(folder, stem, n):
    return [json.loads((folder / f"{stem}_{k:012d}_keypoints.json").read_text()) for k in range(n)]


# -- geometry ----------------------------------------------------------------------------------
def test_projection_matches_a_camera_matrix_and_keeps_handedness():
    cam = op.PinholeCamera()
    rng = np.random.default_rng(0)
    points = np.column_stack([rng.uniform(-1.5, 1.5, 200), rng.uniform(-1, 1, 200), rng.uniform(0.5, 5, 200)])
    assert np.allclose(cam.project(points), _project(points), atol=1e-9)
    # A person facing the sensor has their right at Kinect +x: it must land on the image's left.
    right_hand, left_hand = cam.project(np.array([[0.3, 0.0, 2.5], [-0.3, 0.0, 2.5]]))
    assert right_hand[0] < 959.5 < left_hand[0]
    assert cam.project(np.array([0.0, 0.5, 2.0]))[1] < 539.5  # up is up
    assert np.isnan(cam.project(np.array([0.1, 0.1, -1.0]))).all()  # behind the camera
    assert cam.inside(np.array([[0.0, 0.0], [1919.0, 1079.0]])).all()
    assert not cam.inside(np.array([[-1.0, 5.0], [5.0, 1080.0], [np.nan, 3.0]])).any()


def test_dancer_right_side_is_on_the_image_left(rec, video):
    true = video.dancer_true
    for r, left in (("RShoulder", "LShoulder"), ("RHip", "LHip"), ("REar", "LEar")):
        assert (true[:, _kp(r), 0] < true[:, _kp(left), 0]).all()
    standing = video.times + rec.truth["offset_s"] < rec.truth["music_start_s"]
    assert standing.sum() > 30
    assert (true[standing, _kp("RWrist"), 0] < true[standing, _kp("LWrist"), 0]).all()
    assert (true[:, _kp("Nose"), 1] < true[:, _kp("Neck"), 1]).all()  # image y grows downwards
    assert (true[:, _kp("Neck"), 1] < true[:, _kp("MidHip"), 1]).all()


def test_keypoints_follow_the_kinect_joints_at_the_video_times(rec, video):
    assert op.BODY_25 == tuple(BODY_25)
    assert np.allclose(video.times, np.arange(video.n_frames) / 30.0)
    assert video.times[-1] <= rec.motion.times[-1] < video.times[-1] + 1 / 30
    exact = _exact_dance(rec, video.times)
    for name, joint in FROM_KINECT.items():
        error = np.abs(video.dancer_true[:, _kp(name)] - _project(exact.joint_positions(joint)))
        assert error.max() < 0.5, name  # the cubic spline through the sensor frames
    # While the dancer stands before the music the body faces the sensor (-z) squarely.
    standing = video.times + rec.truth["offset_s"] < rec.truth["music_start_s"] - 0.2
    head = exact.joint_positions("Head")[standing]
    face = {
        "Nose": (0, -0.02, -0.10),
        "REye": (0.032, 0.03, -0.08),
        "LEye": (-0.032, 0.03, -0.08),
        "REar": (0.075, 0, 0.01),
        "LEar": (-0.075, 0, 0.01),
    }
    for name, offset in face.items():
        assert np.abs(video.dancer_true[standing, _kp(name)] - _project(head + offset)).max() < 0.5, name


def test_face_and_foot_offsets_turn_with_the_body():
    body = make_body(1.70)
    names = body.joint_set.names
    pos = body.rest_positions + [0.0, 0.0, 2.5]
    for side in ("Left", "Right"):  # feet pointing straight forward (-z), flat
        pos[names.index(f"Foot{side}")] = pos[names.index(f"Ankle{side}")] + [0.0, 0.0, -0.1]
    p = {n: pos[i] for i, n in enumerate(names)}
    expected = {  # camera axes for a person facing the sensor: right +x, up +y, forward -z
        "Nose": p["Head"] + [0, -0.02, -0.10],
        "REye": p["Head"] + [0.032, 0.03, -0.08],
        "LEar": p["Head"] + [-0.075, 0, 0.01],
        "RBigToe": p["FootRight"] + [-0.02, 0, -0.06],
        "RSmallToe": p["FootRight"] + [0.035, 0, -0.03],
        "RHeel": p["AnkleRight"] + [0, -0.07, 0.05],
        "LBigToe": p["FootLeft"] + [0.02, 0, -0.06],
        "LSmallToe": p["FootLeft"] + [-0.035, 0, -0.03],
        "LHeel": p["AnkleLeft"] + [0, -0.07, 0.05],
        **{k: p[v] for k, v in FROM_KINECT.items()},
    }
    points, seen = op.body25_points(pos[None], names)
    for name, where in expected.items():
        assert np.allclose(points[0, _kp(name)], where, atol=1e-12), name
    assert seen.all()
    # Turned 90 degrees to face camera -x (the image's right): the right side faces the camera,
    # the left eye and ear are behind the head; every offset turns with the body.
    turn = Rotation.from_euler("y", np.pi / 2)
    root = pos[names.index("SpineBase")]
    turned, seen = op.body25_points((turn.apply(pos - root) + root)[None], names)
    assert np.allclose(turned[0], turn.apply(points[0] - root) + root, atol=1e-12)
    assert {BODY_25[k] for k in np.flatnonzero(~seen[0])} == {"LEye", "LEar"}


# -- detections --------------------------------------------------------------------------------
def test_detection_noise_and_confidence(video):
    found = video.dancer[..., 2] > 0
    residual = (video.dancer[..., :2] - video.dancer_true)[found]
    assert residual.shape[0] > 5000
    assert np.abs(residual.std(axis=0) - SD_PX).max() < 0.08
    assert np.abs(residual.mean(axis=0)).max() < 0.1
    c = video.dancer[..., 2][found]
    assert c.min() >= 0.4 and c.max() <= 0.95
    assert stats.kstest(c, stats.uniform(0.4, 0.55).cdf).pvalue > 1e-3
    assert video.info["noise_sd_px"] == SD_PX and video.info["detector"]["confidence_range"] == [0.4, 0.95]


def test_missed_keypoints_rate_bursts_and_frames(video):
    model = op.DetectorModel()
    # Documented: 2 % isolated misses, bursts of 3..8 frames (mean 5.5) starting at 0.6 % per frame.
    documented = 1 - (1 - 0.02) * (1 - 0.006 * 5.5)
    assert model.miss_rate == pytest.approx(documented, abs=0.002)
    assert video.info["miss_rate"] == model.miss_rate
    detected = video.dancer_detected
    true = video.dancer_true[detected]
    inside = (true[..., 0] >= 0) & (true[..., 0] < 1920) & (true[..., 1] >= 0) & (true[..., 1] < 1080)
    kept = video.dancer[detected]
    missed = (kept[..., 2] == 0) & inside
    assert np.array_equal(kept[kept[..., 2] == 0], np.zeros(((kept[..., 2] == 0).sum(), 3)))  # OpenPose's 0,0,0
    assert missed.sum() / inside.sum() == pytest.approx(documented, abs=0.015)
    assert video.info["dancer_missed_fraction"] == pytest.approx(missed.sum() / inside.sum(), abs=1e-12)
    runs = []
    for column in missed.T:
        edges = np.diff(np.r_[0, column.astype(int), 0])
        runs += list(np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1))
    runs = np.array(runs)
    assert (runs == 1).sum() > 50 and (runs >= 3).sum() > 20  # isolated misses and bursts
    # Whole frames without the dancer: rare, listed in the truth.
    absent = np.flatnonzero(~detected)
    assert 1 <= absent.size <= 0.03 * video.n_frames
    assert video.info["dancer"]["missing_frames"] == absent.tolist()
    assert all(video.people(k) == [] or len(video.people(k)) == 1 for k in absent)


def test_passer_by_crosses_for_the_documented_span(rec, video):
    info = video.info["passer_by"]
    frames = np.flatnonzero(video.passer_detected)
    assert frames[0] == info["first_frame"] and frames[-1] == info["last_frame"]
    assert np.array_equal(frames, np.arange(frames[0], frames[-1] + 1))  # one crossing
    assert info["start_s"] == pytest.approx(frames[0] / 30) and info["end_s"] == pytest.approx(frames[-1] / 30)
    # In view while both the neck and the hip centre are on the image: a path of 2 Z (cx + 0.5) / f
    # metres at the walking speed, give or take the body's lean and swing.
    in_view_s = 2 * info["depth_m"] * 960 / 1060 / info["speed_m_s"]
    assert (frames.size - 1) / 30 == pytest.approx(in_view_s, abs=0.25)
    dancer_depth = np.median(rec.true_motion.positions[..., 2])
    assert abs(info["depth_m"] - dancer_depth) > 0.5
    assert info["nearer_than_dancer"] == (info["depth_m"] < dancer_depth)
    neck_x = video.passer_true[frames, _kp("Neck"), 0]
    step = np.diff(neck_x)
    assert (step < 0).all() if info["walks"] == "right_to_left" else (step > 0).all()
    # Sometimes listed first, only where both are present; the dancer is in clearly more frames.
    first = np.array(info["listed_first_frames"])
    assert first.size > 0 and video.passer_detected[first].all() and video.dancer_detected[first].all()
    assert video.dancer_detected.sum() > 2 * frames.size
    for k in frames:
        people = video.people(k)
        order = [np.array_equal(p, video.passer[k]) for p in people]
        assert order[0] == (k in first) and sum(order) == 1


def test_deterministic_from_the_seed(rec, video):
    again = synthesize_openpose(rec)
    for name in ("dancer", "passer", "dancer_detected", "passer_detected", "passer_first"):
        assert np.array_equal(getattr(again, name), getattr(video, name)), name
    assert again.info == video.info and video.info["seed"] == 7
    other = synthesize_openpose(rec, seed=8)
    assert not np.array_equal(other.dancer, video.dancer)
    assert np.array_equal(other.dancer_true, video.dancer_true)  # the same dancer, other detections
    slower = synthesize_openpose(rec, video_fps=25.0)
    assert slower.n_frames == int(rec.motion.times[-1] * 25) + 1


def test_rejects_what_it_cannot_use(rec):
    from dataclasses import replace

    from kinectdata.core.errors import KinectDataError

    with pytest.raises(KinectDataError, match="video_fps"):
        synthesize_openpose(rec, video_fps=0.0)
    with pytest.raises(KinectDataError, match="true_motion"):
        synthesize_openpose(replace(rec, true_motion=None))
    with pytest.raises(KinectDataError, match="audio_format"):
        write_openpose_recording(rec, "unused", "s7", audio_format="mp3")


# -- files -------------------------------------------------------------------------------------
def test_files_in_openpose_format(rec, video, written, tmp_path):
    folder = written["openpose"]
    assert folder.name == "s7_openpose" and written["audio"].name == "s7.flac"
    names = sorted(p.name for p in folder.iterdir())
    assert names == [f"s7_{k:012d}_keypoints.json" for k in range(video.n_frames)]
    text = (folder / names[0]).read_text()
    assert text.startswith('{"version":1.3,"people":[{"person_id":[-1],"pose_keypoints_2d":[') and "\n" not in text
    keys = [
        "person_id", "pose_keypoints_2d", "face_keypoints_2d", "hand_left_keypoints_2d", "hand_right_keypoints_2d",
        "pose_keypoints_3d", "face_keypoints_3d", "hand_left_keypoints_3d", "hand_right_keypoints_3d",
    ]  # fmt: skip
    for k, doc in enumerate(_read_frames(folder, "s7", video.n_frames)):
        assert list(doc) == ["version", "people"] and doc["version"] == 1.3
        expected = video.people(k)
        assert len(doc["people"]) == len(expected)
        for person, kp in zip(doc["people"], expected):
            assert list(person) == keys and person["person_id"] == [-1]
            assert all(person[key] == [] for key in keys[2:])
            values = np.array(person["pose_keypoints_2d"]).reshape(25, 3)
            assert np.allclose(values, kp, rtol=1e-5, atol=1e-6)  # six significant digits
    truth = json.loads(written["truth"].read_text())
    assert truth["offset_s"] == rec.truth["offset_s"] and truth["format"] == "openpose"
    assert truth["files"] == {"audio": "s7.flac", "openpose": "s7_openpose", "truth": "s7.truth.json"}
    section = truth["openpose"]
    assert section["n_frames"] == video.n_frames and section["video_fps"] == 30.0
    assert section["image_size_px"] == [1920, 1080] and section["camera"]["focal_px"] == 1060.0
    assert section["file_pattern"].format(frame=3) == names[3]
    assert section["passer_by"] == json.loads(json.dumps(video.info["passer_by"]))
    assert "--format openpose --video-fps 30.0" in truth["command"] and "--name s7" in truth["command"]
    again = write_openpose_recording(rec, tmp_path, "s7")
    assert again["truth"].read_bytes() == written["truth"].read_bytes()
    assert again["audio"].read_bytes() == written["audio"].read_bytes()
    for name in names:
        assert (again["openpose"] / name).read_bytes() == (folder / name).read_bytes()


def test_folder_is_written_atomically(rec, video, tmp_path, monkeypatch):
    calls = []
    real = op.frame_json

    def failing(people):
        calls.append(1)
        if len(calls) == 20:
            raise RuntimeError("disk full")
        return real(people)

    monkeypatch.setattr(op, "frame_json", failing)
    with pytest.raises(RuntimeError, match="disk full"):
        op.write_openpose_folder(video, tmp_path / "s7_openpose", "s7")
    assert list(tmp_path.iterdir()) == []  # neither the folder nor the staging folder
    # A failed rewrite leaves the complete earlier folder as it was.
    monkeypatch.setattr(op, "frame_json", real)
    op.write_openpose_folder(video, tmp_path / "s7_openpose", "s7")
    before = {p.name: p.read_bytes() for p in (tmp_path / "s7_openpose").iterdir()}
    calls.clear()
    monkeypatch.setattr(op, "frame_json", failing)
    with pytest.raises(RuntimeError):
        op.write_openpose_folder(video, tmp_path / "s7_openpose", "s7")
    assert [p.name for p in tmp_path.iterdir()] == ["s7_openpose"]
    assert {p.name: p.read_bytes() for p in (tmp_path / "s7_openpose").iterdir()} == before


def test_cli_writes_folder_audio_and_truth(tmp_path):
    def run(*args):
        return CliRunner().invoke(main, ["synth", str(tmp_path), "--seed", "3", "--duration", "8", *args])

    result = run("--format", "openpose", "--video-fps", "25")
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "synth_003.flac",
        "synth_003.truth.json",
        "synth_003_openpose",
    ]
    truth = json.loads((tmp_path / "synth_003.truth.json").read_text())
    files = sorted((tmp_path / "synth_003_openpose").iterdir())
    assert len(files) == truth["openpose"]["n_frames"] == int(truth["motion_duration_s"] * 25) + 1
    assert (
        truth["openpose"]["video_fps"] == 25.0 and files[-1].name == f"synth_003_{len(files) - 1:012d}_keypoints.json"
    )
    assert run("--format", "openpose", "--dialect", "kinectreader").exit_code == 2
    assert run("--video-fps", "25").exit_code == 2  # csv has no video
    assert run("--name", "plain").exit_code == 0  # csv stays the default
    assert (tmp_path / "plain.csv").is_file() and not (tmp_path / "plain_openpose").exists()


# -- the reader --------------------------------------------------------------------------------
def test_reader_follows_the_dancer(video, written):
    from kinectdata.formats import openpose as _reader  # noqa: F401  (registers the reader)
    from kinectdata.formats import read_motion

    motion = read_motion(written["openpose"], format="openpose", video_fps=30.0)
    assert motion.joint_set.name == "openpose_mpi" and motion.n_frames == video.n_frames
    assert np.allclose(motion.times, video.times)
    # The noise-free MPI joints: Head <- Nose, Chest = midpoint of Neck and MidHip.
    mpi = ["Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist"]
    mpi += ["RHip", "RKnee", "RAnkle", "LHip", "LKnee", "LAnkle"]
    true = np.concatenate(
        [
            video.dancer_true[:, [_kp(n) for n in mpi]],
            video.dancer_true[:, [_kp("Neck"), _kp("MidHip")]].mean(1)[:, None],
        ],
        axis=1,
    )
    kept = video.dancer[..., 2] > 0
    expected_mask = np.concatenate(
        [kept[:, [_kp(n) for n in mpi]], (kept[:, _kp("Neck")] & kept[:, _kp("MidHip")])[:, None]], axis=1
    )
    expected_mask &= video.dancer_detected[:, None]
    assert np.array_equal(motion.position_mask, expected_mask)
    error = (motion.positions - true)[expected_mask]
    assert np.abs(error).max() < 5 * SD_PX
    assert np.sqrt(np.mean(error[:, 0] ** 2)) < 1.1 * SD_PX
