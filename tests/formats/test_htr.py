"""Tests of the HTR reader, against hand-computed values and a forward kinematics written here."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import DATA as TEST_DATA

from kinectdata.core.errors import FormatError
from kinectdata.formats import detect_format, read_motion, readers
from kinectdata.formats.htr import read_htr

DATA = TEST_DATA / "htr"
ORDERS = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"]


def htr_lines(
    names,
    parents,
    base,
    frames,
    *,
    order="ZYX",
    units="mm",
    angle_units="Degrees",
    scale=1.0,
    fps=30,
    first_frame=1,
    comments=False,
    num_segments=None,
    num_frames=None,
):
    """HTR text lines for segments ``names`` with ``parents`` (None = GLOBAL).

    ``base`` [J, 7]: Tx Ty Tz Rx Ry Rz BoneLength; ``frames`` [T, J, 7]: Tx Ty Tz Rx Ry Rz SF.
    """
    T, J = len(frames), len(names)
    lines = ["# Written by the kinectdata tests"] if comments else []
    lines += [
        "[Header]",
        "FileType htr",
        "DataType HTRS",
        "FileVersion 1",
        f"NumSegments {J if num_segments is None else num_segments}",
        f"NumFrames {T if num_frames is None else num_frames}",
        f"DataFrameRate {fps}",
        f"EulerRotationOrder {order}",
        f"CalibrationUnits {units}",
        f"RotationUnits {angle_units}",
        "GlobalAxisofGravity Y",
        "BoneLengthAxis Y",
        f"ScaleFactor {scale}",
        "[SegmentNames&Hierarchy]",
    ]
    if comments:
        lines.append("#CHILD\tPARENT")
    lines += [f"{n}\t{p or 'GLOBAL'}" for n, p in zip(names, parents)]
    lines.append("[BasePosition]")
    if comments:
        lines.append("#SegmentName Tx, Ty, Tz, Rx, Ry, Rz, BoneLength")
    lines += [n + "\t" + "\t".join(f"{v:.10g}" for v in base[j]) for j, n in enumerate(names)]
    for j, n in enumerate(names):
        lines.append(f"[{n}]")
        if comments:
            lines.append("#Fr\tTx\tTy\tTz\tRx\tRy\tRz\tSF")
        lines += [f"{first_frame + t}\t" + "\t".join(f"{v:.10g}" for v in frames[t, j]) for t in range(T)]
    lines.append("[EndOfFile]")
    return lines


def write(tmp_path, lines, name="take.htr", newline="\n"):
    path = tmp_path / name
    path.write_bytes((newline.join(lines) + newline).encode())
    return path


# -- independent forward kinematics --------------------------------------------------------------
def axis_matrix(axis, angle):
    c, s = np.cos(angle), np.sin(angle)
    return {
        "X": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
        "Y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
        "Z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]),
    }[axis]


def euler_matrix(order, rx_ry_rz_degrees):
    """Rotation matrix of HTR angles: the product of the axis rotations in the named order."""
    angle = dict(zip("XYZ", np.radians(rx_ry_rz_degrees)))
    return (
        axis_matrix(order[0], angle[order[0]])
        @ axis_matrix(order[1], angle[order[1]])
        @ axis_matrix(order[2], angle[order[2]])
    )


def homogeneous(rotation=None, translation=(0, 0, 0)):
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = np.eye(3) if rotation is None else rotation, translation
    return m


def forward_kinematics(names, parents, base, frames, order, to_m):
    """Global 4x4 transforms [T, J, 4, 4], one matrix product at a time."""
    T, J = frames.shape[:2]
    out = np.zeros((T, J, 4, 4))
    for t in range(T):
        done: dict[str, np.ndarray] = {}
        while len(done) < J:
            for j, n in enumerate(names):
                if n in done or (parents[j] is not None and parents[j] not in done):
                    continue
                local = (
                    homogeneous(translation=base[j, :3] * to_m)
                    @ homogeneous(translation=frames[t, j, :3] * to_m)
                    @ homogeneous(euler_matrix(order, base[j, 3:6]))
                    @ homogeneous(euler_matrix(order, frames[t, j, 3:6]))
                )
                done[n] = local if parents[j] is None else done[parents[j]] @ local
                out[t, j] = done[n]
    return out


def quat_from_matrix(m):
    """(x, y, z, w) of a rotation matrix (Shepperd's method, w >= 0 branch is enough for checks)."""
    w = np.sqrt(max(0.0, 1 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
    x = np.sqrt(max(0.0, 1 + m[0, 0] - m[1, 1] - m[2, 2])) / 2
    y = np.sqrt(max(0.0, 1 - m[0, 0] + m[1, 1] - m[2, 2])) / 2
    z = np.sqrt(max(0.0, 1 - m[0, 0] - m[1, 1] + m[2, 2])) / 2
    x = np.copysign(x, m[2, 1] - m[1, 2])
    y = np.copysign(y, m[0, 2] - m[2, 0])
    z = np.copysign(z, m[1, 0] - m[0, 1])
    return np.array([x, y, z, w])


def assert_same_rotation(q_read, matrix):
    """Quaternions equal up to sign, compared through the rotation each one applies."""
    x, y, z, w = q_read
    from_q = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    np.testing.assert_allclose(from_q, matrix, atol=1e-9)
    expected = quat_from_matrix(matrix)
    assert min(np.abs(q_read - expected).max(), np.abs(q_read + expected).max()) < 1e-6


# -- hand-computed cases -------------------------------------------------------------------------
def two_segments(frames_hips, order="ZYX", **kw):
    """Hips at base (10, 20, 30), Spine 50 up from it; frames only move the hips."""
    base = np.array([[10, 20, 30, 0, 0, 0, 50], [0, 50, 0, 0, 0, 0, 40.0]])
    frames = np.zeros((len(frames_hips), 2, 7))
    frames[:, :, 6] = 1
    frames[:, 0, :6] = frames_hips
    return htr_lines(["Hips", "Spine"], [None, "Hips"], base, frames, order=order, **kw)


def test_rotation_of_the_root_moves_the_child(tmp_path):
    lines = two_segments([[0, 0, 0, 0, 0, 90], [5, 0, 0, 0, 0, 0]], units="cm", first_frame=7)
    m = read_htr(write(tmp_path, lines))
    # frame 7: Rz(90) turns the spine's (0, 50, 0) cm into (-50, 0, 0)
    np.testing.assert_allclose(m.positions[0], [[0.10, 0.20, 0.30], [-0.40, 0.20, 0.30]], atol=1e-12)
    # frame 8: the hips translate 5 cm along x, no rotation
    np.testing.assert_allclose(m.positions[1], [[0.15, 0.20, 0.30], [0.15, 0.70, 0.30]], atol=1e-12)
    s = np.sqrt(0.5)
    for q in m.orientations[0]:
        assert np.allclose(q, [0, 0, s, s]) or np.allclose(q, [0, 0, -s, -s])
    np.testing.assert_allclose(m.times, [0, 1 / 30])
    assert m.metadata["time_origin"] == {"value": 7, "unit": "frame"}
    assert m.metadata["nominal_fps"] == 30
    assert m.joint_set.names == ("Hips", "Spine") and m.joint_set.parents == (-1, 0)
    np.testing.assert_allclose(m.metadata["bone_length_m"], [0.5, 0.4])
    assert m.confidence.dtype == np.float32 and np.all(m.confidence == 1)


@pytest.mark.parametrize("order, expected", [("XYZ", [0, 0, 1]), ("ZYX", [0, 1, 0])])
def test_euler_order_is_the_product_in_the_named_order(tmp_path, order, expected):
    # Rx = 90, Rz = 90 applied to a child 1 m along x. XYZ: Rx(Rz(x)) = Rx(y) = z; ZYX: Rz(Rx(x)) = y.
    base = np.array([[0, 0, 0, 0, 0, 0, 1], [1, 0, 0, 0, 0, 0, 1.0]])
    frames = np.array([[[0, 0, 0, 90, 0, 90, 1], [0, 0, 0, 0, 0, 0, 1]]], dtype=float)
    m = read_htr(write(tmp_path, htr_lines(["a", "b"], [None, "a"], base, frames, order=order, units="m")))
    np.testing.assert_allclose(m.positions[0, 1], expected, atol=1e-12)


def test_radians(tmp_path):
    lines = two_segments([[0, 0, 0, 0, 0, np.pi / 2]], units="cm", angle_units="Radians")
    m = read_htr(write(tmp_path, lines))
    np.testing.assert_allclose(m.positions[0, 1], [-0.40, 0.20, 0.30], atol=1e-12)


@pytest.mark.parametrize(
    "units, scale, factor", [("mm", 1, 1e-3), ("mm", 2.5, 2.5e-3), ("m", 1, 1.0), ("in", 1, 0.0254), ("CM", 1, 1e-2)]
)
def test_units_and_scale_factor(tmp_path, units, scale, factor):
    m = read_htr(write(tmp_path, two_segments([[0, 0, 0, 0, 0, 0]], units=units, scale=scale)))
    np.testing.assert_allclose(m.positions[0], np.array([[10, 20, 30], [10, 70, 30]]) * factor, atol=1e-12)
    np.testing.assert_allclose(m.metadata["bone_length_m"], np.array([50, 40]) * factor)


def test_segment_scale_is_kept_and_does_not_move_joints(tmp_path):
    lines = two_segments([[0, 0, 0, 0, 0, 0]])
    lines[lines.index("[Hips]") + 1] = "1\t0\t0\t0\t0\t0\t0\t1.5"
    m = read_htr(write(tmp_path, lines))
    np.testing.assert_allclose(m.metadata["segment_scale"], [[1.5, 1.0]])
    np.testing.assert_allclose(m.positions[0, 1], [0.01, 0.07, 0.03])


# -- random hierarchies against the forward kinematics above ---------------------------------------
@pytest.mark.parametrize("order", ORDERS)
def test_random_hierarchy_matches_forward_kinematics(tmp_path, order):
    rng = np.random.default_rng(ORDERS.index(order))
    names = ["root", "a", "b", "c", "d", "e"]
    parents = [None, "root", "a", "root", "c", "a"]
    listing = [4, 0, 2, 1, 5, 3]  # some children listed before their parents
    names, parents = [names[i] for i in listing], [parents[i] for i in listing]
    T, J = 4, len(names)
    base = np.concatenate(
        [rng.uniform(-300, 300, (J, 3)), rng.uniform(-180, 180, (J, 3)), rng.uniform(50, 400, (J, 1))], axis=1
    )
    frames = np.concatenate(
        [rng.uniform(-50, 50, (T, J, 3)), rng.uniform(-180, 180, (T, J, 3)), rng.uniform(0.9, 1.1, (T, J, 1))], axis=2
    )
    m = read_htr(write(tmp_path, htr_lines(names, parents, base, frames, order=order, units="mm", scale=1.3)))
    expected = forward_kinematics(names, parents, base, frames, order, 1.3e-3)
    assert m.joint_set.names == tuple(names)
    np.testing.assert_allclose(m.positions, expected[..., :3, 3], atol=1e-9)
    for t in range(T):
        for j in range(J):
            assert_same_rotation(m.orientations[t, j], expected[t, j, :3, :3])
    np.testing.assert_allclose(m.metadata["segment_scale"], frames[..., 6])
    assert m.metadata["euler_rotation_order"] == order


# -- text details ----------------------------------------------------------------------------------
def test_crlf_comments_and_sample_file(tmp_path):
    lines = two_segments([[0, 0, 0, 0, 0, 90], [5, 0, 0, 0, 0, 0]], units="cm", comments=True)
    lines.insert(lines.index("[Spine]") + 2, "   # a comment inside a block")
    lines[lines.index("FileType htr")] = "FileType htr   # inline comment"
    lines[lines.index("Spine\tHips")] = "Spine    Hips  "  # spaces, not tabs
    m = read_htr(write(tmp_path, lines, newline="\r\n"))
    np.testing.assert_allclose(m.positions[0, 1], [-0.40, 0.20, 0.30], atol=1e-12)
    assert m.metadata["header"]["FileType"] == "htr"
    assert m.metadata["gravity_axis"] == "Y" and m.metadata["bone_length_axis"] == "Y"

    sample = read_htr(DATA / "two_segments.htr")
    np.testing.assert_allclose(sample.positions[0], [[0.10, 0.20, 0.30], [-0.40, 0.20, 0.30]], atol=1e-12)
    np.testing.assert_allclose(sample.positions[1], [[0.15, 0.20, 0.30], [0.15, 0.70, 0.30]], atol=1e-12)


def test_bogus_values_mask_the_segment_and_its_descendants(tmp_path):
    names, parents = ["root", "mid", "leaf", "other"], [None, "root", "mid", "root"]
    base = np.array([[0, 0, 0, 0, 0, 0, 1], [0, 10, 0, 0, 0, 0, 1], [0, 10, 0, 0, 0, 0, 1], [10, 0, 0, 0, 0, 0, 1.0]])
    frames = np.zeros((3, 4, 7))
    frames[..., 6] = 1
    lines = htr_lines(names, parents, base, frames)
    lines[lines.index("[mid]") + 2] = "2\t9999999\t0\t0\t0\t0\t0\t1"
    lines[lines.index("[other]") + 3] = "3\t0\t0\t0\t0\t1.#QNAN0\t0\t1"
    m = read_htr(write(tmp_path, lines))
    expected = np.ones((3, 4), bool)
    expected[1, 1:3] = False
    expected[2, 3] = False
    np.testing.assert_array_equal(m.position_mask, expected)
    np.testing.assert_array_equal(m.orientation_mask, expected)
    np.testing.assert_array_equal(m.confidence, expected.astype(np.float32))
    assert np.isnan(m.positions[~expected]).all() and np.isnan(m.orientations[~expected]).all()
    assert np.isnan(m.metadata["segment_scale"][~expected]).all()
    np.testing.assert_allclose(m.positions[1, 0], [0, 0, 0])


def test_registry_detects_htr(tmp_path):
    path = write(tmp_path, two_segments([[0, 0, 0, 0, 0, 0]]), name="dance.HTR")
    assert detect_format(path) == "htr"
    m = read_motion(path)
    assert m.metadata["format"] == "htr" and m.positions.shape == (1, 2, 3)
    reader = readers()["htr"]
    assert reader.sniff(path, path.read_bytes()[:4096])
    assert not reader.sniff(path, b"SpineBase_X,SpineBase_Y\n0.1,0.2\n")


# -- bad input ---------------------------------------------------------------------------------------
def good():
    return two_segments([[0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0]])


def replace(lines, old, new):
    i = lines.index(old)
    lines[i] = new
    return i + 1


def edit_order(lines):
    return replace(lines, "EulerRotationOrder ZYX", "EulerRotationOrder ZYY"), "EulerRotationOrder"


def edit_units(lines):
    return replace(lines, "CalibrationUnits mm", "CalibrationUnits furlong"), "CalibrationUnits"


def edit_rotation_units(lines):
    return replace(lines, "RotationUnits Degrees", "RotationUnits gradians"), "RotationUnits"


def edit_num_segments(lines):
    return replace(lines, "NumSegments 2", "NumSegments 3"), "NumSegments says 3, but the hierarchy lists 2"


def edit_num_frames(lines):
    del lines[lines.index("[Spine]") + 3]
    return lines.index("[Spine]") + 1, "NumFrames says 3 (line 6), but segment 'Spine' has 2 frames"


def edit_unknown_block(lines):
    i = lines.index("[EndOfFile]")
    lines[i:i] = ["[Tail]", "1\t0\t0\t0\t0\t0\t0\t1"]
    return i + 1, "[Tail] is not a segment"


def edit_unknown_parent(lines):
    return replace(lines, "Spine\tHips", "Spine\tPelvis"), "unknown parent 'Pelvis'"


def edit_cycle(lines):
    replace(lines, "Hips\tGLOBAL", "Hips\tSpine")
    return lines.index("Hips\tSpine") + 1, "cycle"


def edit_not_a_number(lines):
    i = lines.index("[Spine]") + 1
    lines[i] = "1\t0\t0\tabc\t0\t0\t0\t1"
    return i + 1, "'abc'"


def edit_column_count(lines):
    i = lines.index("[Hips]") + 1
    lines[i] = "1\t0\t0\t0\t0\t0\t1"
    return i + 1, "needs 8 values per row, found 7"


def edit_missing_block(lines):
    i = lines.index("[Spine]")
    del lines[i : i + 4]
    return lines.index("Spine\tHips") + 1, "segment 'Spine' has no [Spine] data block"


def edit_frame_gap(lines):
    row = lines[lines.index("[Hips]") + 3]
    return replace(lines, row, "5" + row[1:]), "frame 5 follows 2"


def edit_frame_repeat(lines):
    row = lines[lines.index("[Hips]") + 2]
    return replace(lines, row, "1" + row[1:]), "frame 1 follows 1"


def edit_frames_disagree(lines):
    i = lines.index("[Spine]") + 2
    lines[i] = "9" + lines[i][1:]
    return i + 1, "frame number 9 where segment 'Hips' has 2"


def edit_base_value(lines):
    return replace(lines, "Hips\t10\t20\t30\t0\t0\t0\t50", "Hips\t10\t20\tx\t0\t0\t0\t50"), "'x'"


def edit_missing_base(lines):
    lines.remove("Spine\t0\t50\t0\t0\t0\t0\t40")
    return lines.index("[BasePosition]") + 1, "segment 'Spine' has no row in [BasePosition]"


def edit_truncated(lines):
    del lines[-2:]
    lines.append("3\t0\t0")
    return len(lines), "truncated"


def edit_data_before_sections(lines):
    lines.insert(0, "hello")
    return 1, "before the first [section]"


def edit_frame_rate(lines):
    return replace(lines, "DataFrameRate 30", "DataFrameRate 0"), "DataFrameRate"


@pytest.mark.parametrize(
    "edit",
    [
        edit_order,
        edit_units,
        edit_rotation_units,
        edit_num_segments,
        edit_num_frames,
        edit_unknown_block,
        edit_unknown_parent,
        edit_cycle,
        edit_not_a_number,
        edit_column_count,
        edit_missing_block,
        edit_frame_gap,
        edit_frame_repeat,
        edit_frames_disagree,
        edit_base_value,
        edit_missing_base,
        edit_truncated,
        edit_data_before_sections,
        edit_frame_rate,
    ],
    ids=lambda f: f.__name__[5:],
)
def test_bad_input_names_file_and_line(tmp_path, edit):
    lines = good()
    line, words = edit(lines)
    path = write(tmp_path, lines, name="bad_take.htr", newline="\r\n")
    with pytest.raises(FormatError) as err:
        read_htr(path)
    message = str(err.value)
    assert str(path) in message
    assert f"line {line}:" in message, message
    assert words in message, message


@pytest.mark.parametrize(
    "content, words",
    [
        ("", "empty"),
        ("# only a comment\r\n\r\n", "empty"),
    ],
)
def test_empty_file(tmp_path, content, words):
    path = tmp_path / "empty.htr"
    path.write_text(content)
    with pytest.raises(FormatError, match=words) as err:
        read_htr(path)
    assert str(path) in str(err.value)


@pytest.mark.parametrize("section", ["[Header]", "[SegmentNames&Hierarchy]", "[BasePosition]"])
def test_missing_section(tmp_path, section):
    lines = good()
    i = lines.index(section)
    end = next(k for k in range(i + 1, len(lines)) if lines[k].startswith("["))
    del lines[i:end]
    path = write(tmp_path, lines, name="no_section.htr")
    with pytest.raises(FormatError) as err:
        read_htr(path)
    assert str(path) in str(err.value) and f"no {section} section" in str(err.value)


def test_damaged_files_raise_only_format_errors(tmp_path):
    """Random character edits: the reader either reads the file or raises a FormatError naming it."""
    rng = np.random.default_rng(3)
    text = "\r\n".join(good()) + "\r\n"
    alphabet = list("0123456789.-# \t\n[]aXYZ")
    path = tmp_path / "damaged.htr"
    for _ in range(300):
        chars = list(text)
        for _ in range(rng.integers(1, 4)):
            i = int(rng.integers(len(chars)))
            chars[i : i + int(rng.integers(0, 2))] = [str(rng.choice(alphabet))]
        path.write_text("".join(chars))
        try:
            read_htr(path)
        except FormatError as err:
            assert str(path) in str(err)
