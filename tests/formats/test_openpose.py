"""OpenPose JSON reader: layouts against keypoints written here, tracking, file variants, bad input."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import DATA as TEST_DATA

from kinectdata.core.errors import FormatError
from kinectdata.formats import detect_format, read_motion
from kinectdata.formats.openpose import LAYOUTS, read_openpose, to_mpi15

DATA = TEST_DATA / "openpose"
FPS = 30.0

# OpenPose's keypoint orders (output documentation), written out as the tests' expectation.
BODY25 = [
    "Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist", "MidHip", "RHip", "RKnee",
    "RAnkle", "LHip", "LKnee", "LAnkle", "REye", "LEye", "REar", "LEar", "LBigToe", "LSmallToe", "LHeel",
    "RBigToe", "RSmallToe", "RHeel",
]  # fmt: skip
COCO18 = [
    "Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist", "RHip", "RKnee", "RAnkle",
    "LHip", "LKnee", "LAnkle", "REye", "LEye", "REar", "LEar",
]  # fmt: skip
MPI15 = [
    "Head", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist", "RHip", "RKnee", "RAnkle",
    "LHip", "LKnee", "LAnkle", "Chest",
]  # fmt: skip
NAMES = {"body25": BODY25, "coco18": COCO18, "mpi15": MPI15}


def expected_mpi(kp: np.ndarray, layout: str) -> tuple[np.ndarray, np.ndarray]:
    """[15, 2] positions (NaN where not detected) and [15] confidence from [K, 3] keypoints, by name."""
    names = NAMES[layout]
    point = {n: kp[i, :2] for i, n in enumerate(names)}
    conf = {n: kp[i, 2] for i, n in enumerate(names)}
    if layout != "mpi15":
        point["Head"], conf["Head"] = point["Nose"], conf["Nose"]
        hips = ["MidHip"] if layout == "body25" else ["RHip", "LHip"]
        hip_centre = sum(point[h] for h in hips) / len(hips)
        point["Chest"] = (point["Neck"] + hip_centre) / 2
        conf["Chest"] = min(conf[n] for n in ["Neck", *hips])
    pos = np.array([point[n] for n in MPI15])
    c = np.array([conf[n] for n in MPI15])
    pos[c == 0] = np.nan
    return pos, c


def random_person(rng: np.random.Generator, n_keypoints: int, missing=()) -> np.ndarray:
    """[K, 3] keypoints as OpenPose writes them: pixels, c in (0, 1], 0 0 0 where not found."""
    kp = np.column_stack(
        [np.round(rng.uniform(0, 1920, n_keypoints), 3), np.round(rng.uniform(0, 1080, n_keypoints), 3)]
        + [np.round(rng.uniform(0.05, 1.0, n_keypoints), 6)]
    )
    kp[list(missing)] = 0.0
    return kp


def moving_person(rng: np.random.Generator, n_frames: int, n_keypoints: int) -> list[np.ndarray]:
    """[K, 3] keypoints per frame of one person moving a few pixels a frame (one track)."""
    start = random_person(rng, n_keypoints)
    out = []
    for _ in range(n_frames):
        kp = random_person(rng, n_keypoints)
        kp[:, :2] = start[:, :2] + np.round(rng.normal(0, 3.0, (n_keypoints, 2)), 3)
        out.append(kp)
    return out


def person_entry(kp: np.ndarray, person_id: int = -1) -> dict:
    return {
        "person_id": [person_id],
        "pose_keypoints_2d": [float(v) for v in kp.reshape(-1)],
        "face_keypoints_2d": [],
        "hand_left_keypoints_2d": [],
        "hand_right_keypoints_2d": [],
        "pose_keypoints_3d": [],
        "face_keypoints_3d": [],
        "hand_left_keypoints_3d": [],
        "hand_right_keypoints_3d": [],
    }


def frame_doc(people: list[np.ndarray], ids: list[int] | None = None) -> dict:
    ids = ids or [-1] * len(people)
    return {"version": 1.3, "people": [person_entry(kp, i) for kp, i in zip(people, ids)]}


def dumps(doc) -> str:
    return json.dumps(doc, separators=(",", ":"))  # OpenPose writes no spaces


def write_folder(folder: Path, docs: list[dict], numbers, stem: str = "dance", digits: int = 12) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for n, doc in zip(numbers, docs):
        (folder / f"{stem}_{n:0{digits}d}_keypoints.json").write_text(dumps(doc))
    return folder


# -- layouts and values ------------------------------------------------------------------------------


@pytest.mark.parametrize("layout", ["body25", "coco18", "mpi15"])
def test_layout_mapped_exactly(tmp_path, layout):
    rng = np.random.default_rng(1)
    K = len(NAMES[layout])
    names = NAMES[layout]
    hip = {"body25": "MidHip", "coco18": "LHip", "mpi15": "Chest"}[layout]
    people = moving_person(rng, 3, K)
    people[1][[names.index("RElbow"), names.index(hip)]] = 0.0  # Chest is lost with its hip
    people[2][[0, names.index("Neck")]] = 0.0
    folder = write_folder(tmp_path / "run", [frame_doc([p]) for p in people], [0, 1, 2])

    m = read_openpose(folder, video_fps=FPS)

    assert m.joint_set.name == "openpose_mpi" and list(m.joint_set.names) == MPI15
    assert m.metadata["layout"] == layout and m.positions.shape == (3, 15, 2)
    for f, kp in enumerate(people):
        pos, conf = expected_mpi(kp, layout)
        np.testing.assert_allclose(m.positions[f], pos, rtol=0, atol=1e-9)
        np.testing.assert_allclose(m.confidence[f], conf.astype(np.float32))
        assert (m.position_mask[f] == (conf > 0)).all()
    assert m.confidence.dtype == np.float32
    assert not m.position_mask[1, [MPI15.index("RElbow"), MPI15.index("Chest")]].any()
    assert not m.position_mask[2, [MPI15.index("Head"), MPI15.index("Neck")]].any()
    assert m.position_mask[2, MPI15.index("Chest")] == (layout == "mpi15")  # else derived from the Neck
    assert np.isnan(m.positions[1, MPI15.index("RElbow")]).all() and m.confidence[1, MPI15.index("RElbow")] == 0
    if layout != "mpi15":  # Head is the Nose, exactly as written
        np.testing.assert_array_equal(m.positions[0, 0], people[0][0, :2])
    positions, confidence = to_mpi15(np.stack(people), LAYOUTS[layout])  # the tracker sees NaN too
    np.testing.assert_array_equal(np.isnan(positions[..., 0]), confidence == 0)


def test_forced_layout(tmp_path):
    rng = np.random.default_rng(2)
    kp = random_person(rng, 18)
    folder = write_folder(tmp_path / "run", [frame_doc([kp])], [0])
    assert read_openpose(folder, video_fps=FPS, layout="coco18").metadata["layout"] == "coco18"
    name = "dance_000000000000_keypoints.json"
    check(folder, r"54 values \(COCO-18\); expected 75 \(BODY_25\) for layout='body25'", file=name, layout="body25")
    with pytest.raises(FormatError, match="unknown layout 'body_25'.*body25, coco18, mpi15"):
        read_openpose(folder, video_fps=FPS, layout="body_25")


def test_real_openpose_file():
    """SPIN's example OpenPose output (BODY_25, JSON 1.2 without person_id, face and hands too)."""
    path = DATA / "im1010_openpose.json"
    kp = np.array(json.loads(path.read_text())["people"][0]["pose_keypoints_2d"]).reshape(25, 3)

    m = read_motion(path, video_fps=FPS)

    assert m.metadata["format"] == "openpose" and m.metadata["layout"] == "body25"
    assert m.n_frames == 1 and m.times[0] == 0.0 and m.metadata["people"] == {"0": 1}
    np.testing.assert_array_equal(m.joint_positions("Head")[0], [66.4171, 47.0342])  # the Nose
    np.testing.assert_array_equal(m.joint_positions("LAnkle")[0], [118.893, 155.601])
    assert m.confidence[0, MPI15.index("Neck")] == np.float32(0.628322)
    assert not m.position_mask[0, [MPI15.index("RElbow"), MPI15.index("RWrist")]].any()  # written 0,0,0
    np.testing.assert_allclose(m.joint_positions("Chest")[0], (kp[1, :2] + kp[8, :2]) / 2, atol=1e-12)
    assert m.confidence[0, MPI15.index("Chest")] == np.float32(min(kp[1, 2], kp[8, 2]))
    assert m.position_mask[0].sum() == 13


# -- frames, times and file variants -----------------------------------------------------------------


def test_numeric_order_gaps_and_times(tmp_path):
    rng = np.random.default_rng(3)
    numbers = [8, 9, 10, 12, 30]  # unpadded: the lexical order would be 10, 12, 30, 8, 9
    people = moving_person(rng, len(numbers), 25)
    empty = 2  # frame 10: nobody seen
    docs = [frame_doc([] if i == empty else [p]) for i, p in enumerate(people)]
    folder = write_folder(tmp_path / "run", docs, numbers, stem="take2_cam1", digits=1)
    (folder / "notes.txt").write_text("not a keypoints file")

    m = read_openpose(folder, video_fps=25.0)

    np.testing.assert_allclose(m.times, (np.array(numbers) - 8) / 25.0)
    assert m.metadata["time_origin"] == {"value": 8, "unit": "frame"} and m.metadata["video_fps"] == 25.0
    assert m.metadata["people"] == {"0": 4}
    assert not m.position_mask[empty].any() and (m.confidence[empty] == 0).all()
    for i in (0, 1, 3, 4):
        np.testing.assert_allclose(m.positions[i], expected_mpi(people[i], "body25")[0], atol=1e-9)


def test_single_file_variants_match_the_folder(tmp_path):
    rng = np.random.default_rng(4)
    numbers = [3, 4, 6, 7]
    docs = [frame_doc([p]) for p in moving_person(rng, len(numbers), 25)]
    docs[2] = frame_doc([])
    folder = read_openpose(write_folder(tmp_path / "run", docs, numbers), video_fps=FPS)

    def keyed(key: str) -> list[dict]:
        out = [{key: n, **d} for n, d in zip(numbers, docs)]
        return [out[i] for i in (2, 0, 3, 1)]  # shuffled: the numbers order them

    variants = {
        "array.json": dumps(keyed("frame")),
        "wrapped.json": json.dumps({"video": "dance.mp4", "frames": keyed("frame_index")}, indent=2),
        "lines.jsonl": "\n".join(dumps(d) for d in keyed("frame_id")) + "\n",
        "lines.json": "\n".join(dumps(d) for d in keyed("frame")) + "\n\n",  # JSON Lines named .json
    }
    for name, text in variants.items():
        path = tmp_path / name
        path.write_text(text)
        m = read_motion(path, video_fps=FPS)
        assert m.metadata["format"] == "openpose", name
        np.testing.assert_array_equal(m.times, folder.times)
        np.testing.assert_array_equal(m.positions, folder.positions)
        np.testing.assert_array_equal(m.confidence, folder.confidence)
        assert m.metadata["time_origin"] == folder.metadata["time_origin"] == {"value": 3, "unit": "frame"}
        assert m.metadata["people"] == folder.metadata["people"] == {"0": 3}

    path = tmp_path / "positions.json"  # no frame keys: the position is the number
    path.write_text(dumps(docs))
    np.testing.assert_array_equal(read_openpose(path, video_fps=FPS).times, np.arange(4) / FPS)


def test_one_frame_file_takes_its_number_from_the_name(tmp_path):
    path = tmp_path / "dance_000000000042_keypoints.json"
    path.write_text(dumps(frame_doc([random_person(np.random.default_rng(5), 25)])))
    m = read_openpose(path, video_fps=FPS)
    assert m.n_frames == 1 and m.metadata["time_origin"] == {"value": 42, "unit": "frame"}


# -- several people --------------------------------------------------------------------------------

TEMPLATE = {  # a standing person facing the camera, in heights from the mid-hip (x right, y down)
    "Nose": (0.0, -0.47), "Neck": (0.0, -0.36), "RShoulder": (-0.1, -0.35), "RElbow": (-0.14, -0.2),
    "RWrist": (-0.16, -0.06), "LShoulder": (0.1, -0.35), "LElbow": (0.14, -0.2), "LWrist": (0.16, -0.06),
    "MidHip": (0.0, 0.0), "RHip": (-0.06, 0.0), "RKnee": (-0.07, 0.24), "RAnkle": (-0.07, 0.47),
    "LHip": (0.06, 0.0), "LKnee": (0.07, 0.24), "LAnkle": (0.07, 0.47), "REye": (-0.02, -0.49),
    "LEye": (0.02, -0.49), "REar": (-0.04, -0.48), "LEar": (0.04, -0.48), "LBigToe": (0.09, 0.5),
    "LSmallToe": (0.1, 0.5), "LHeel": (0.06, 0.49), "RBigToe": (-0.09, 0.5), "RSmallToe": (-0.1, 0.5),
    "RHeel": (-0.06, 0.49),
}  # fmt: skip


def body(rng: np.random.Generator, centre, height: float) -> np.ndarray:
    """[25, 3] BODY_25 keypoints of a person at ``centre`` (pixels), a few pixels of noise."""
    xy = np.array([TEMPLATE[n] for n in BODY25]) * height + centre + rng.normal(0, 2.0, (25, 2))
    return np.column_stack([np.round(xy, 3), np.round(rng.uniform(0.3, 1.0, 25), 6)])


def scene(rng: np.random.Generator, n_frames: int = 60, passer=range(20, 40)):
    """Two dancers (list order swapped every frame) and a passer-by walking behind them."""
    t = np.arange(n_frames) / FPS
    a = [body(rng, (700 + 120 * np.sin(2 * np.pi * s), 650), 500) for s in t]
    b = [body(rng, (1250 - 120 * np.sin(2 * np.pi * s), 660 + 20 * np.cos(4 * np.pi * s)), 480) for s in t]
    c = {f: body(rng, (200 + 25 * (f - passer[0]), 300), 220) for f in passer}
    people = [[b[f], a[f]] if f % 2 else [a[f], b[f]] for f in range(n_frames)]
    for f in passer:
        people[f].insert(f % 3, c[f])
    return people, a, b, c


def assert_track(m, frames: dict[int, np.ndarray], n_frames: int):
    for f in range(n_frames):
        if f in frames:
            np.testing.assert_allclose(m.positions[f], expected_mpi(frames[f], "body25")[0], atol=1e-9)
        else:
            assert not m.position_mask[f].any()


def test_tracking_follows_swapped_dancers_and_a_passer_by(tmp_path):
    rng = np.random.default_rng(6)
    people, a, b, c = scene(rng)
    folder = write_folder(tmp_path / "run", [frame_doc(p) for p in people], range(60))

    m = read_openpose(folder, video_fps=FPS)

    assert m.metadata["people"] == {"0": 60, "1": 60, "2": 20}
    assert m.metadata["person"] == "0" and m.metadata["person_ids"].startswith("tracked")  # tie: the first
    assert_track(m, dict(enumerate(a)), 60)
    assert_track(read_openpose(folder, video_fps=FPS, person="1"), dict(enumerate(b)), 60)
    assert_track(read_openpose(folder, video_fps=FPS, person="2"), c, 60)  # absent frames fully masked

    with pytest.raises(FormatError) as info:
        read_openpose(folder, video_fps=FPS, person="3")
    assert "run" in str(info.value) and re.search(
        r"'3'.*0 \(60 frames\), 1 \(60 frames\), 2 \(20 frames\)", str(info.value)
    )


@pytest.mark.parametrize(("missing", "same_track"), [(29, True), (30, False)])
def test_track_ends_after_one_second_unseen(tmp_path, missing, same_track):
    rng = np.random.default_rng(7)
    n = 10 + missing + 10
    seen = [f for f in range(n) if not 10 <= f < 10 + missing]
    people = {f: body(rng, (900, 600), 500) for f in seen}
    folder = write_folder(tmp_path / "run", [frame_doc([people[f]]) for f in seen], seen)
    m = read_openpose(folder, video_fps=FPS)
    # last seen at frame 9; back at 9 + missing + 1: (missing + 1) / 30 s later
    assert m.metadata["people"] == ({"0": 20} if same_track else {"0": 10, "1": 10})


def test_person_ids_written_by_openpose_are_used(tmp_path):
    rng = np.random.default_rng(8)
    people, a, b, _ = scene(rng, passer=range(0))
    # ids say the opposite of the geometry from frame 30 on: the written ids win
    ids = [[5, 7] if (f % 2 == 0) == (f < 30) else [7, 5] for f in range(60)]
    folder = write_folder(tmp_path / "run", [frame_doc(p, i) for p, i in zip(people, ids)], range(60))

    m = read_openpose(folder, video_fps=FPS, person="5")

    assert m.metadata["people"] == {"5": 60, "7": 60} and m.metadata["person"] == "5"
    assert m.metadata["person_ids"] == "person_id as written by OpenPose"
    assert_track(m, {f: a[f] if f < 30 else b[f] for f in range(60)}, 60)


# -- format detection ------------------------------------------------------------------------------


def test_detection(tmp_path):
    rng = np.random.default_rng(9)
    docs = [frame_doc([p]) for p in moving_person(rng, 3, 25)]
    folder = write_folder(tmp_path / "run", docs, range(3))
    assert detect_format(folder) == "openpose"
    assert read_motion(folder, video_fps=FPS).n_frames == 3

    (tmp_path / "frames.json").write_text(dumps(docs))
    (tmp_path / "frames.jsonl").write_text("\n".join(dumps(d) for d in docs))
    (tmp_path / "wrapped.json").write_text(dumps({"frames": docs}))
    (tmp_path / "nobody.json").write_text(dumps({"version": 1.3, "people": []}))
    for name in ("frames.json", "frames.jsonl", "wrapped.json", "nobody.json"):
        assert detect_format(tmp_path / name) == "openpose", name

    azure = {  # keys sorted, as the Azure Kinect offline processor writes them
        "bone_list": [["PELVIS", "SPINE_NAVEL"]],
        "frames": [{"bodies": [{"body_id": 1, "joint_orientations": [[1, 0, 0, 0]] * 2,
                                "joint_positions": [[0, 0, 2000]] * 2}],
                    "frame_id": 0, "num_bodies": 1, "timestamp_usec": 0}],
        "joint_names": ["PELVIS", "SPINE_NAVEL"],
        "k4abt_sdk_version": "1.1.2",
        "source_file": "take.mkv",
    }  # fmt: skip
    (tmp_path / "take.json").write_text(json.dumps(azure, indent=4))
    assert detect_format(tmp_path / "take.json") == "azure_json"

    empty = tmp_path / "empty_folder"
    empty.mkdir()
    with pytest.raises(FormatError, match="cannot tell the recording format"):
        detect_format(empty)


# -- bad input -------------------------------------------------------------------------------------


def check(path: Path, *words: str, file: str | None = None, frame: int | None = None, line: int | None = None, **opts):
    """The FormatError reading ``path`` raises: it names ``file`` (default: path) and the place."""
    opts.setdefault("video_fps", FPS)
    with pytest.raises(FormatError) as info:
        read_openpose(path, **opts)
    err, msg = info.value, str(info.value)
    assert Path(err.path).name == (file or path.name) and (file or path.name) in msg, msg
    if frame is not None:
        assert err.frame == frame and f"frame {frame}" in msg, msg
    if line is not None:
        assert err.line == line and f"line {line}" in msg, msg
    for w in words:
        assert re.search(w, msg), (w, msg)
    return err


@pytest.fixture
def run(tmp_path):
    """A folder of four frames (numbers 0, 1, 2, 5), two people each."""
    rng = np.random.default_rng(10)
    docs = [frame_doc([random_person(rng, 25), random_person(rng, 25)]) for _ in range(4)]
    return write_folder(tmp_path / "run", docs, [0, 1, 2, 5])


def frame_file(run: Path, number: int) -> Path:
    return run / f"dance_{number:012d}_keypoints.json"


def edit(run: Path, number: int, person: int, change) -> str:
    """Apply ``change(pose_keypoints_2d)`` to one person of one frame file; the file's name."""
    path = frame_file(run, number)
    doc = json.loads(path.read_text())
    change(doc["people"][person]["pose_keypoints_2d"])
    path.write_text(dumps(doc))  # Python's json writes NaN and Infinity tokens
    return path.name


def test_invalid_json_names_file_and_line(run, tmp_path):
    path = frame_file(run, 2)
    text = json.dumps(json.loads(path.read_text()), indent=1).splitlines()
    assert text[1] == ' "version": 1.3,'
    text[1] = text[1].rstrip(",")  # the comma missing is found on line 3
    path.write_text("\n".join(text))
    check(run, "invalid JSON", file=path.name, line=3)

    lines = tmp_path / "frames.jsonl"
    lines.write_text('{"people":[]}\n\n{"people":[]}\n{"people":[}\n')
    check(lines, "invalid JSON", line=4)
    array = tmp_path / "frames.json"
    array.write_text('[\n{"people":[]},\n{"people":[]]\n]')
    check(array, "invalid JSON", line=3)
    pretty = tmp_path / "pretty.json"
    pretty.write_text('{\n "people": []\n}\n{"oops"')  # not JSON Lines: the first line is no document
    check(pretty, "invalid JSON: Extra data", line=4)


@pytest.mark.parametrize(
    ("change", "words"),
    [
        (lambda kp: kp.__setitem__(7, float("nan")), ["keypoint 2 is not finite"]),
        (lambda kp: kp.__setitem__(9, float("inf")), ["keypoint 3 is not finite"]),
        (lambda kp: kp.pop(), ["has 74 values but earlier people have 75 \\(BODY_25\\)"]),
        (lambda kp: kp.__setitem__(5, 2.5), ["keypoint 1 has confidence 2.5, outside 0..2"]),
        (lambda kp: kp.__setitem__(2, -0.1), ["keypoint 0 has confidence -0.1"]),
        (lambda kp: kp.__setitem__(0, "12.5"), ["must hold numbers, found '12.5'"]),
        (lambda kp: kp.__setitem__(0, None), ["must hold numbers, found None"]),
        (
            lambda kp: kp.__setitem__(slice(None), kp[:54]),
            [r"54 values \(COCO-18\) but earlier people have 75 \(BODY_25\): mixed layouts"],
        ),
    ],
)
def test_bad_keypoints_name_file_frame_and_person(run, change, words):
    name = edit(run, 5, 1, change)
    check(run, r"people\[1\]\.pose_keypoints_2d", *words, file=name, frame=5)


def test_bad_values_in_a_single_file(tmp_path):
    rng = np.random.default_rng(11)
    docs = [frame_doc([random_person(rng, 15)]) for _ in range(3)]
    docs[1]["people"][0]["pose_keypoints_2d"][2] = 2.5
    path = tmp_path / "frames.jsonl"
    path.write_text("\n".join(dumps(d) for d in docs))
    check(path, r"people\[0\]\.pose_keypoints_2d keypoint 0 has confidence 2.5", frame=1, line=2)
    path = tmp_path / "frames.json"
    path.write_text(dumps([{"frame": 10 + i, **d} for i, d in enumerate(docs)]))
    check(path, "confidence 2.5", frame=11)


def test_confidences_a_little_above_one_are_clipped_and_counted(tmp_path):
    """Real OpenPose writes confidences up to about 1.4: the recording is read, c clipped to 1."""
    rng = np.random.default_rng(12)
    docs = [frame_doc([random_person(rng, 15)], ids=[0]) for _ in range(4)]  # one tracked person
    for frame, j, c in ((0, 3, 1.00081), (2, 7, 1.4), (3, 3, 1.2)):
        docs[frame]["people"][0]["pose_keypoints_2d"][3 * j + 2] = c
    path = tmp_path / "frames.jsonl"
    path.write_text("\n".join(dumps(d) for d in docs))
    motion = read_openpose(path, video_fps=30)
    assert motion.metadata["confidences_clipped"] == 3
    assert motion.confidence.max() <= 1.0
    from click.testing import CliRunner

    from kinectdata.cli import main

    shown = CliRunner().invoke(main, ["info", str(path), "--video-fps", "30"]).output
    assert "confidences     3 above 1 (as OpenPose writes at times), clipped to 1" in shown


def test_the_key_of_openpose_before_1_2_is_named(tmp_path):
    rng = np.random.default_rng(13)
    doc = frame_doc([random_person(rng, 15)])
    doc["people"][0]["pose_keypoints"] = doc["people"][0].pop("pose_keypoints_2d")
    path = tmp_path / "old.jsonl"
    path.write_text(dumps(doc))
    check(path, r"people\[0\] has 'pose_keypoints', the key of OpenPose before 1.2", line=1)


def test_structure_errors(tmp_path, run):
    cases = {
        "top.json": ({"video": "x.mp4"}, ["not OpenPose output"]),
        "frames.json": ({"frames": {"0": {}}}, ["'frames' must be a list"]),
        "nolist.json": ([{"people": {}}], ["needs a 'people' list"]),
        "noperson.json": ([{"people": [[1, 2, 3]]}], [r"people\[0\] must be an object"]),
        "badkey.json": ([{"frame": -1, "people": []}], ["'frame' must be a non-negative integer"]),
        "twice.json": ([{"frame": 4, "people": []}, {"frame": 4, "people": []}], ["frame number 4 appears twice"]),
        "none.json": ([], ["holds no frames"]),
        "nobody.json": ([{"people": []}] * 3, ["no body appears in any of the 3 frames"]),
    }
    for name, (doc, words) in cases.items():
        path = tmp_path / name
        path.write_text(dumps(doc))
        check(path, *words)
    empty = tmp_path / "empty.json"
    empty.write_text(" \n")
    check(empty, "empty", line=1)

    (run / "dance_5_keypoints.json").write_text(frame_file(run, 5).read_text())
    check(run, "frame number 5 also in dance_000000000005_keypoints.json", file="dance_5_keypoints.json")
    (run / "dance_5_keypoints.json").unlink()
    (run / "cam_keypoints.json").write_text('{"people":[]}')
    check(run, "no frame number in the file name", file="cam_keypoints.json")

    folder = tmp_path / "images"
    folder.mkdir()
    (folder / "frame_000.png").write_bytes(b"")
    check(folder, r"no \*_keypoints.json files")


def test_person_id_errors(run):
    def set_ids(number: int, ids):
        path = frame_file(run, number)
        doc = json.loads(path.read_text())
        for p, i in zip(doc["people"], ids):
            p["person_id"] = i
        path.write_text(dumps(doc))

    for n in (0, 1, 2, 5):
        set_ids(n, [[1], [2]])
    assert read_openpose(run, video_fps=FPS).metadata["people"] == {"1": 4, "2": 4}
    set_ids(2, [[3], [3]])
    check(run, r"people\[1\]\.person_id 3 appears twice", file=frame_file(run, 2).name, frame=2)
    set_ids(2, [[3], [-1]])
    check(
        run,
        r"people\[1\]\.person_id is -1 while other people carry OpenPose ids",
        file=frame_file(run, 2).name,
        frame=2,
    )
    set_ids(2, [[3], "x"])
    check(run, r"people\[1\]\.person_id must be \[integer\]", file=frame_file(run, 2).name, frame=2)


def test_video_fps_is_required(run):
    with pytest.raises(FormatError, match="no timestamps.*frame rate.*--video-fps") as info:
        read_openpose(run)
    assert info.value.path == str(run)
    with pytest.raises(FormatError, match="no timestamps"):
        read_motion(run)
    for bad in (0, -30, float("nan"), "fast"):
        with pytest.raises(FormatError, match="video_fps must be a positive number"):
            read_openpose(run, video_fps=bad)
