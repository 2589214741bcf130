"""NTU RGB+D .skeleton reader: values against files written here from known arrays, and bad input."""

from __future__ import annotations

import re

import numpy as np
import pytest

from kinectdata.core.errors import FormatError
from kinectdata.formats import detect_format, read_motion
from kinectdata.formats.ntu import read_ntu

J = 25
LEAVES = [3, 15, 19, 21, 22, 23, 24]  # Head, feet, hand tips, thumbs: "0 0 0 0" orientation in NTU files
BODY_REST = "0 1 1 1 1 0 -0.4371323 -0.1682897 2"  # clippedEdges ... trackingState of a body line


def make_body(rng: np.random.Generator, states: np.ndarray | None = None) -> np.ndarray:
    """[25, 12] joint rows: x y z depthX depthY colorX colorY qw qx qy qz state, exactly representable."""
    rows = np.zeros((J, 12))
    rows[:, :3] = np.round(rng.uniform(-1.5, 4.0, (J, 3)), 6)
    rows[:, 3:7] = np.round(rng.uniform(0, 500, (J, 4)), 3)
    q = rng.normal(size=(J, 4))
    rows[:, 7:11] = q / np.linalg.norm(q, axis=1, keepdims=True)
    rows[LEAVES, 7:11] = 0.0
    rows[:, 11] = 2 if states is None else states
    return rows


def skeleton_text(frames: list[list[tuple[str, np.ndarray]]], joint_count: int = J) -> str:
    """Text of a .skeleton file; each frame is a list of (bodyID, [25, 12] rows)."""
    out = [str(len(frames))]
    for bodies in frames:
        out.append(str(len(bodies)))
        for body_id, rows in bodies:
            out.append(f"{body_id} {BODY_REST}")
            out.append(str(joint_count))
            for r in rows:
                out.append(" ".join(repr(float(v)) for v in r[:11]) + f" {int(r[11])}")
    return "\r\n".join(out) + "\r\n"  # the dataset's files have Windows line ends


def write(tmp_path, text: str, name: str = "S001C002P003R004A005.skeleton"):
    path = tmp_path / name
    path.write_text(text, newline="")
    return path


def joint_line(frame_bodies: list[int], frame: int, body: int, joint: int) -> int:
    """1-based line of a joint line, given the body count of each frame."""
    line = 2  # line 1 is the frame count
    for f, n in enumerate(frame_bodies):
        if f == frame:
            return line + 1 + body * (J + 2) + 2 + joint
        line += 1 + n * (J + 2)
    raise AssertionError


# -- values ----------------------------------------------------------------------------------------


def test_values_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    states = np.full(J, 2)
    states[[5, 6]] = 1
    states[[7]] = 0
    rows = [make_body(rng, states) for _ in range(3)]
    path = write(tmp_path, skeleton_text([[("72057594037931101", r)] for r in rows]))

    m = read_ntu(path)

    assert m.joint_set.name == "kinect_v2" and m.n_frames == 3
    np.testing.assert_array_equal(m.times, [0.0, 1 / 30, 2 / 30])
    expected = np.stack(rows)
    valid = states > 0
    np.testing.assert_array_equal(m.positions[:, valid], expected[:, valid, :3])
    assert np.isnan(m.positions[:, 7]).all()
    assert (m.position_mask == valid).all()
    np.testing.assert_array_equal(m.confidence[0], np.where(states == 2, 1.0, np.where(states == 1, 0.5, 0.0)))
    assert m.confidence.dtype == np.float32
    # file order w x y z -> x y z w
    has_q = np.ones(J, bool)
    has_q[LEAVES] = False
    has_q[7] = False  # untracked: its orientation is junk, masked like its position
    np.testing.assert_allclose(m.orientations[:, has_q], expected[:, has_q][..., [8, 9, 10, 7]], atol=1e-12)
    assert not m.orientation_mask[:, LEAVES].any() and not m.orientation_mask[:, 7].any()
    assert np.isnan(m.orientations[:, LEAVES]).all()
    assert m.orientation_mask[:, has_q].all()

    md = m.metadata
    assert md["format"] == "ntu" and md["nominal_fps"] == 30.0
    assert md["time_source"] == "frame index at nominal 30 fps"
    assert md["body"] == "72057594037931101"
    assert md["bodies"] == {"72057594037931101": 3}
    assert (md["setup"], md["camera"], md["performer"], md["replication"], md["action"]) == (1, 2, 3, 4, 5)


def test_body_choice_and_gaps(tmp_path):
    rng = np.random.default_rng(2)
    a = [make_body(rng) for _ in range(5)]
    b = [make_body(rng) for _ in range(5)]
    frames = [
        [("11", a[0])],
        [("11", a[1]), ("22", b[1])],
        [],  # nobody in view
        [("22", b[3])],
        [("22", b[4]), ("11", a[4])],
    ]
    path = write(tmp_path, skeleton_text(frames), name="dance.skeleton")

    m = read_ntu(path)  # 22 is in 3 frames, 11 in 3: tie -> the first to appear
    assert m.metadata["body"] == "11"
    assert m.metadata["bodies"] == {"11": 3, "22": 3}
    assert "setup" not in m.metadata

    frames[0].append(("22", b[0]))
    path = write(tmp_path, skeleton_text(frames), name="dance.skeleton")
    m = read_ntu(path)  # now 22 is the longest tracked
    assert m.metadata["body"] == "22" and m.n_frames == 5
    present = [True, True, False, True, True]
    assert (m.position_mask.all(axis=1) == present).all() and not m.position_mask[2].any()
    assert (m.confidence[2] == 0).all() and not m.orientation_mask[2].any()
    for f in (0, 1, 3, 4):
        np.testing.assert_array_equal(m.positions[f], b[f][:, :3])

    m = read_ntu(path, body="11")
    assert m.metadata["body"] == "11"
    assert list(m.position_mask.all(axis=1)) == [True, True, False, False, True]
    np.testing.assert_array_equal(m.positions[4], a[4][:, :3])  # second body of its frame
    np.testing.assert_array_equal(m.times, np.arange(5) / 30)


def test_read_motion_detects_by_extension(tmp_path):
    rng = np.random.default_rng(3)
    path = write(tmp_path, skeleton_text([[("5", make_body(rng))], [("5", make_body(rng))]]))
    assert detect_format(path) == "ntu"
    m = read_motion(path)
    assert m.metadata["format"] == "ntu" and m.n_frames == 2
    other = write(tmp_path, path.read_text(), name="renamed.txt")
    from kinectdata.formats.ntu import _sniff

    assert _sniff(other, other.read_bytes()[:4096])
    assert not _sniff(other, b"time,x,y\n0,1,2\n")


# -- bad input -------------------------------------------------------------------------------------


def check(path, line: int | None, *words: str, body: str | None = None) -> FormatError:
    with pytest.raises(FormatError) as info:
        read_ntu(path, body=body)
    msg = str(info.value)
    assert path.name in msg
    if line is not None:
        assert info.value.line == line and f"line {line}" in msg
    for w in words:
        assert re.search(w, msg), (w, msg)
    return info.value


@pytest.fixture
def good(tmp_path):
    """Lines of a valid two-frame file, one body per frame (57 lines; joint lines 5-29 and 33-57)."""
    rng = np.random.default_rng(4)
    return skeleton_text([[("7", make_body(rng))], [("7", make_body(rng))]]).splitlines()


def test_empty_file(tmp_path):
    check(write(tmp_path, ""), 1, "empty")
    check(write(tmp_path, "\n  \n"), 1, "empty")


def test_truncated(tmp_path, good):
    assert len(good) == 57
    path = write(tmp_path, "\n".join(good[:-3]) + "\n")
    err = check(path, 55, "end of file", "25 joint lines", "truncated")  # the line after the last
    assert err.frame == 1
    check(write(tmp_path, "\n".join(good[:29]) + "\n"), 30, "end of file", "body count")
    check(write(tmp_path, "\n".join(good[:30]) + "\n"), 31, "end of file", "body line")


def test_non_numeric_token(tmp_path, good):
    line = joint_line([1, 1], 1, 0, 4)
    tokens = good[line - 1].split()
    tokens[2] = "0.12a"
    good[line - 1] = " ".join(tokens)
    err = check(write(tmp_path, "\n".join(good)), line, "'0.12a' is not a number")
    assert err.frame == 1


def test_wrong_token_count(tmp_path, good):
    line = joint_line([1, 1], 0, 0, 10)
    good[line - 1] += " 1"
    check(write(tmp_path, "\n".join(good)), line, "12 values", "found 13")


def test_body_line_token_count(tmp_path, good):
    good[2] = "7 0 1 1"
    check(write(tmp_path, "\n".join(good)), 3, "10 values", "found 4")


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_non_finite(tmp_path, good, value):
    line = joint_line([1, 1], 1, 0, 0)
    tokens = good[line - 1].split()
    tokens[1] = value
    good[line - 1] = " ".join(tokens)
    check(write(tmp_path, "\n".join(good)), line, "not finite")


def test_wrong_joint_count(tmp_path):
    rng = np.random.default_rng(5)
    text = skeleton_text([[("7", make_body(rng)[:24])]], joint_count=24)
    check(write(tmp_path, text), 4, "joint count 24, expected 25")


@pytest.mark.parametrize(
    ("first", "line", "words"),
    [("-2", 1, ["frame count", "'-2'"]), ("2.5", 1, ["frame count"]), ("1000000", 1, ["1000000", "truncated"])],
)
def test_bad_frame_count(tmp_path, good, first, line, words):
    good[0] = first
    check(write(tmp_path, "\n".join(good)), line, *words)


def test_absurd_body_count(tmp_path, good):
    good[1] = "7"
    check(write(tmp_path, "\n".join(good)), 2, "body count 7")
    good[1] = "-1"
    check(write(tmp_path, "\n".join(good)), 2, "body count")


def test_a_wrong_body_count_is_named_on_its_own_line(tmp_path):
    """A body count that disagrees with the bodies written after it is reported at the count's line
    (where the mistake is), not at the next frame's line where reading first goes wrong."""
    rng = np.random.default_rng(7)
    frames = [[("7", make_body(rng)), ("9", make_body(rng))], [("7", make_body(rng))], [("7", make_body(rng))]]
    lines = skeleton_text(frames).splitlines()
    count_lines = [2, 2 + 1 + 2 * (J + 2), 2 + 2 + 3 * (J + 2)]  # 1-based line of each frame's body count
    assert [lines[i - 1] for i in count_lines] == ["2", "1", "1"]
    over = list(lines)
    over[count_lines[1] - 1] = "2"  # frame 1 announces 2 bodies, holds 1: the next line is frame 2's count
    err = check(
        write(tmp_path, "\n".join(over)), count_lines[1], "body count 2 is more than the 1 body", str(count_lines[2])
    )
    assert err.frame == 1
    under = list(lines)
    under[count_lines[0] - 1] = "1"  # frame 0 announces 1 body, holds 2
    err = check(write(tmp_path, "\n".join(under)), count_lines[0], "body count 1 is fewer than the bodies", "body line")
    assert err.frame == 0
    last = list(lines)
    last[count_lines[2] - 1] = "0"  # the last frame announces none, one follows
    err = check(write(tmp_path, "\n".join(last)), count_lines[2], "body count 0 is fewer")
    assert err.frame == 2


def test_zero_frames_and_no_bodies(tmp_path):
    check(write(tmp_path, "0\n"), 1, "no frames")
    check(write(tmp_path, "2\n0\n0\n"), None, "no body appears in any of the 2 frames")


def test_trailing_content(tmp_path, good):
    check(write(tmp_path, "\n".join(good + ["", "1"])), len(good) + 2, "after the last of the 2 frames")


def test_unknown_body(tmp_path, good):
    err = check(write(tmp_path, "\n".join(good)), None, "no body with id '8'", r"7 \(2 frames\)", body="8")
    assert err.line is None


def test_duplicate_body_in_frame(tmp_path):
    rng = np.random.default_rng(6)
    text = skeleton_text([[("7", make_body(rng)), ("7", make_body(rng))]])
    check(write(tmp_path, text), 30, "appears twice")


def test_bad_quaternion_norm(tmp_path, good):
    line = joint_line([1, 1], 1, 0, 1)
    tokens = good[line - 1].split()
    tokens[7:11] = ["0.5", "0.5", "0.5", "0.2"]
    good[line - 1] = " ".join(tokens)
    check(write(tmp_path, "\n".join(good)), line, "norm", "not 1")


def test_bad_tracking_state(tmp_path, good):
    line = joint_line([1, 1], 0, 0, 2)
    good[line - 1] = good[line - 1].rsplit(" ", 1)[0] + " 3"
    check(write(tmp_path, "\n".join(good)), line, "tracking state 3")


def test_binary_file(tmp_path):
    path = tmp_path / "x.skeleton"
    path.write_bytes(b"\xff\xfe\x00\x01garbage")
    check(path, None, "not a UTF-8 text file")
