"""Dance with Melody reader (tang2018): values against computations done here on dances made in the
corpus's shape (tests/corpus_copies.py: a made-up body, no corpus values), detection, bad input."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from corpus_copies import tang2018_dance

import kinectdata as kd
from kinectdata.cli import main
from kinectdata.core.errors import FormatError
from kinectdata.formats import detect_format
from kinectdata.formats.tang2018 import _sniff

T = 60
START, END = 37, 37 + T + 3  # 60 frames over 63 song frames: 25 * 60 / 63 = 23.81 fps


def write_dance(folder: Path, doc: dict | list | str | None = None, config: dict | str | None = None) -> Path:
    """A ``DANCE_W_1``-like folder in ``folder``: skeletons.json (the made-up dance, or ``doc``; a
    str is written as is) and config.json (START, END, or ``config``; None writes none)."""
    folder.mkdir(parents=True, exist_ok=True)
    doc = tang2018_dance(T, seed=4) if doc is None else doc
    config = {"start_position": START, "end_position": END} if config is None else config
    path = folder / "skeletons.json"
    path.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    if config != "absent":
        (folder / "config.json").write_text(config if isinstance(config, str) else json.dumps(config))
    return path


def expected(doc: dict, start: int, end: int) -> dict[str, np.ndarray]:
    """What the reader must give, computed frame by frame and point by point from the file's lists."""
    frames = doc["length"]
    points = np.empty((frames, 25, 3))
    for k in range(frames):
        c = doc["center"][k]
        for j in range(23):
            points[k, j] = [(doc["skeletons"][k][j][i] + c[i]) / 100.0 for i in range(3)]
        points[k, 23] = [c[i] / 100.0 for i in range(3)]
        points[k, 24] = (points[k, 3] + points[k, 12]) / 2.0  # between the shoulders
    times = np.array([k * (end - start) / (25.0 * frames) for k in range(frames)])
    return {"positions": points, "times": times}


# -- values --------------------------------------------------------------------------------------


def test_positions_are_the_points_plus_center_in_metres_with_the_pelvis_and_neck(tmp_path):
    path = write_dance(tmp_path / "DANCE_W_1")
    doc = json.loads(path.read_text())
    motion = kd.read_motion(path)
    want = expected(doc, START, END)
    assert motion.joint_set.name == "tang2018" and motion.positions.shape == (T, 25, 3)
    np.testing.assert_allclose(motion.positions, want["positions"], rtol=0, atol=1e-12)
    assert motion.position_mask.all()
    names = motion.joint_set.names
    assert (names[23], names[24], names[3], names[12]) == ("pelvis", "neck", "right_shoulder", "left_shoulder")
    assert motion.joint_set.parents[23] < 0  # the root


def test_times_spread_the_frames_over_the_dances_span_in_its_song(tmp_path):
    motion = kd.read_motion(write_dance(tmp_path / "DANCE_W_1"))
    doc = json.loads((tmp_path / "DANCE_W_1" / "skeletons.json").read_text())
    np.testing.assert_allclose(motion.times, expected(doc, START, END)["times"], rtol=1e-12, atol=0)
    assert motion.metadata["nominal_fps"] == pytest.approx(25.0 * T / (END - START), rel=1e-12)
    assert motion.metadata["song_start_s"] == pytest.approx(START / 25.0, rel=1e-12)
    # the last frame ends the span one frame's length before the song's end_position
    assert motion.times[-1] + 1.0 / motion.metadata["nominal_fps"] == pytest.approx((END - START) / 25.0)


def test_a_dance_spanning_as_many_song_frames_as_it_has_is_at_25_fps(tmp_path):
    motion = kd.read_motion(write_dance(tmp_path / "d", config={"start_position": 0, "end_position": T}))
    np.testing.assert_allclose(motion.times, np.arange(T) / 25.0, rtol=1e-12)
    assert motion.metadata["song_start_s"] == 0.0


def test_non_finite_values_and_nulls_make_the_point_invalid_and_what_is_made_from_it(tmp_path):
    doc = tang2018_dance(T, seed=5)
    text = json.dumps(doc)
    doc["skeletons"][4][3][0] = float("nan")  # frame 4, the right shoulder: the neck is lost with it
    doc["skeletons"][6][9][1] = float("inf")
    doc["skeletons"][7][20][2] = None  # a JSON null
    doc["center"][9][1] = float("-inf")  # frame 9's pelvis: every point is relative to it
    path = write_dance(tmp_path / "d", doc)
    assert "NaN" in path.read_text() and "null" in path.read_text()
    motion = kd.read_motion(path)
    invalid = {(k, j) for k, j in zip(*np.nonzero(~motion.position_mask))}
    assert invalid == {(4, 3), (4, 24), (6, 9), (7, 20)} | {(9, j) for j in range(25)}
    assert np.isnan(motion.positions[~motion.position_mask]).all()
    clean = kd.read_motion(write_dance(tmp_path / "clean", text))
    np.testing.assert_array_equal(motion.positions[motion.position_mask], clean.positions[motion.position_mask])


# -- detection -----------------------------------------------------------------------------------


def test_a_skeletons_json_is_detected_as_written_or_indented(tmp_path):
    path = write_dance(tmp_path / "DANCE_C_2")
    assert detect_format(path) == "tang2018"
    doc = json.loads(path.read_text())
    path.write_text(json.dumps(doc, indent=2))
    assert detect_format(path) == "tang2018"
    assert kd.read_motion(path).n_frames == T


def test_other_json_files_are_not_claimed(tmp_path):
    from test_azure_json import make_body, make_doc
    from test_openpose import frame_doc, random_person

    rng = np.random.default_rng(3)
    azure = tmp_path / "body_tracking.json"
    azure.write_text(json.dumps(make_doc([(1000, [make_body(rng, 1)[0]]), (34333, [make_body(rng, 1)[0]])])))
    openpose = tmp_path / "frame_openpose.json"
    openpose.write_text(json.dumps(frame_doc([random_person(rng, 25)])))
    arrays = tmp_path / "keypoints.json"
    arrays.write_text(json.dumps({"keypoints3d": rng.normal(size=(3, 17, 3)).tolist()}))
    center_first = tmp_path / "skeletons.json"  # the corpus's keys in another order: not its files
    center_first.write_text(json.dumps({"center": [[0, 0, 0]] * 2, "length": 2, "skeletons": [[[0, 0, 0]] * 23] * 2}))
    for path in (azure, openpose, arrays, center_first):
        assert not _sniff(path, path.read_bytes()[:4096]), path.name
    assert detect_format(azure) == "azure_json"
    assert detect_format(openpose) == "openpose"
    with pytest.raises(FormatError, match="cannot tell the recording format"):
        detect_format(arrays)


def test_info_prints_the_format_and_the_dances_own_rate(tmp_path):
    path = write_dance(tmp_path / "DANCE_R_4")
    result = CliRunner().invoke(main, ["info", str(path)])
    assert result.exit_code == 0, result.output
    assert re.search(r"^format\s+tang2018$", result.output, re.M), result.output
    assert re.search(r"^joint set\s+tang2018 \(25 joints, 3-D\)$", result.output, re.M), result.output
    assert f"{T} over {(END - START) / 25 - (END - START) / (25 * T):.3f} s; {25 * T / (END - START):.2f} fps" in (
        result.output
    )


# -- bad input: one line naming the file and the place ---------------------------------------------


def _frames_of(points: int = 23) -> list:
    doc = tang2018_dance(4, seed=1)
    doc["skeletons"][2] = doc["skeletons"][2][:points]
    return doc


BAD_SKELETONS = [
    ("a frame of 22 points", _frames_of(22), r"skeletons\.json, frame 2: 'skeletons' is not \[23, 3\] numbers here$"),
    (
        "a point of text",
        {**tang2018_dance(4, seed=1), "skeletons": [[[0, 0, 0]] * 23] * 3 + [[[0, "x", 0]] * 23]},
        r"skeletons\.json, frame 3: 'skeletons' is not \[23, 3\] numbers here$",
    ),
    (
        "a center of 2 numbers",
        {**tang2018_dance(4, seed=1), "center": [[0, 0, 0], [0, 0], [0, 0, 0], [0, 0, 0]]},
        r"skeletons\.json, frame 1: 'center' is not \[3\] numbers here$",
    ),
    (
        "center longer than skeletons",
        {**tang2018_dance(4, seed=1), "center": [[0, 0, 0]] * 5},
        r"skeletons\.json: 5 center frames for 4 skeleton frames$",
    ),
    ("length disagreeing", {**tang2018_dance(4, seed=1), "length": 5}, r"skeletons\.json: length says 5 frames, "),
    ("no center", {"length": 4, "skeletons": [[[0, 0, 0]] * 23] * 4}, r"skeletons\.json: no 'center' key"),
    ("one frame", tang2018_dance(1, seed=1), r"skeletons\.json: 1 frame\(s\); a dance has at least 2$"),
    ("no frames", {"length": 0, "center": [], "skeletons": []}, r"skeletons\.json: 0 frame\(s\); a dance has "),
    ("not JSON", '{"length": 4, "center": [[1, 2', r"skeletons\.json: not JSON \(.*line 1 column"),
    ("a JSON list", [[[0, 0, 0]] * 23] * 4, r"skeletons\.json: a list; a Dance with Melody skeletons\.json is an "),
    ("a digit string too long for Python", '{"length": 1' + "0" * 5000 + "}", r"skeletons\.json: not JSON \("),
    (
        "a number beyond float64",
        json.dumps(tang2018_dance(4, seed=1)).replace('"center": [[', '"center": [[1' + "0" * 400 + ", ", 1),
        r"skeletons\.json, frame 0: 'center' is not \[3\] numbers here$",
    ),
]  # fmt: skip


@pytest.mark.parametrize(("doc", "message"), [p[1:] for p in BAD_SKELETONS], ids=[p[0] for p in BAD_SKELETONS])
def test_a_bad_skeletons_json_is_one_line_naming_the_file_and_frame(tmp_path, doc, message):
    path = write_dance(tmp_path / "DANCE_W_3", doc)
    with pytest.raises(FormatError) as err:
        kd.read_motion(path, format="tang2018")
    assert re.match(re.escape(str(path.parent)) + "/" + message, str(err.value)), str(err.value)
    assert "\n" not in str(err.value)


BAD_CONFIGS = [
    ("absent", "absent", r"missing: the dance's start and end in its song are in config\.json$"),
    ("end before start", {"start_position": 80, "end_position": 40}, r"end_position 40 is not after start_position 8"),
    ("end at start", {"start_position": 40, "end_position": 40}, r"end_position 40 is not after start_position 40$"),
    ("text start", {"start_position": "156", "end_position": 400}, r"start_position must be a song frame .*not '156'$"),
    ("no end", {"start_position": 3}, r"end_position must be a song frame .*not None$"),
    ("negative start", {"start_position": -1, "end_position": 400}, r"start_position must be a song frame .*not -1$"),
    ("a huge end", '{"start_position": 0, "end_position": 1' + "0" * 400 + "}", r"end_position .*not 1000+\.\.\.$"),
    ("NaN", '{"start_position": NaN, "end_position": 400}', r"start_position must be a song frame .*not nan$"),
    ("a list", "[0, 400]", r"start_position must be a song frame .*not None$"),
    ("not JSON", "start 0 end 400", r"not JSON \("),
]  # fmt: skip


@pytest.mark.parametrize(("config", "message"), [p[1:] for p in BAD_CONFIGS], ids=[p[0] for p in BAD_CONFIGS])
def test_a_bad_config_json_is_one_line_naming_it(tmp_path, config, message):
    path = write_dance(tmp_path / "DANCE_C_6", config=config)
    with pytest.raises(FormatError) as err:
        kd.read_motion(path, format="tang2018")
    config_path = path.with_name("config.json")
    assert re.match(re.escape(f"{config_path}: ") + message, str(err.value)), str(err.value)


def test_the_cli_reports_a_bad_dance_in_one_line(tmp_path):
    path = write_dance(tmp_path / "DANCE_T_5", _frames_of(22))
    result = CliRunner().invoke(main, ["info", str(path)])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert result.output.strip() == f"Error: {path}, frame 2: 'skeletons' is not [23, 3] numbers here"
    (tmp_path / "DANCE_T_5" / "config.json").unlink()
    result = CliRunner().invoke(main, ["info", str(path), "--format", "tang2018"])
    assert result.exit_code == 1 and len(result.output.strip().splitlines()) == 1
    assert str(tmp_path / "DANCE_T_5" / "config.json") in result.output


def test_formats_lists_the_reader_as_found_by_content():
    result = CliRunner().invoke(main, ["formats"])
    assert result.exit_code == 0, result.output
    line = next(line for line in result.output.splitlines() if line.split()[:1] == ["tang2018"])
    assert "by content" in line and "config.json beside it" in line
    assert any(line.split()[:3] == ["tang2018", "25", "joints,"] for line in result.output.splitlines())
