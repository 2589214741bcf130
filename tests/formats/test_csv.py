"""Schema-driven CSV reading and writing."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from helpers import random_motion

from kinectdata.core.errors import FormatError, SchemaError
from kinectdata.core.jointsets import load_joint_set
from kinectdata.formats import detect_format, read_motion
from kinectdata.formats.csv import detect_csv_schema
from kinectdata.formats.csv_schema import load_csv_schema, shipped_csv_schemas
from kinectdata.formats.csv_writer import write_csv

DIALECTS = ["canonical", "dumpkinectskeleton", "kinectreader", "lsl_kinect"]


# ---------------------------------------------------------------------------------------------
# The real KinectReader file
# ---------------------------------------------------------------------------------------------
def test_real_kinectreader_file_matches_a_plain_parse(fixture_csv):
    rows = [line.rstrip(",\n").split(",") for line in fixture_csv.read_text().splitlines()]
    ref = np.array(rows, dtype=np.float64)  # [T, 101]
    m = read_motion(fixture_csv)
    assert m.metadata["schema"] == "kinectreader"
    assert m.n_frames == len(rows) == 154 and m.n_joints == 25
    np.testing.assert_allclose(m.times, (ref[:, 0] - ref[0, 0]) * 1e-7, rtol=0, atol=1e-12)
    joints = ref[:, 1:].reshape(-1, 25, 4)
    np.testing.assert_array_equal(m.positions, joints[..., :3])
    np.testing.assert_array_equal(m.confidence, np.select([joints[..., 3] == 2, joints[..., 3] == 1], [1.0, 0.5], 0.0))
    assert m.positions[0, 0].tolist() == [0.0111604, -0.367822, 2.69467]
    assert m.metadata["time_origin"] == {"value": 89810293609.0, "unit": "ticks"}
    assert not m.has_orientations
    assert (m.confidence == 0.5).sum() == (joints[..., 3] == 1).sum() > 0


def test_detection_of_every_shipped_dialect(tmp_path, fixture_csv):
    assert detect_csv_schema(fixture_csv).name == "kinectreader"
    m = random_motion()
    for name in DIALECTS:
        path = tmp_path / f"{name}.txt"  # no .csv extension: found by content through the registry
        write_csv(m, path, name)
        assert detect_format(path) == "csv"
        assert detect_csv_schema(path).name == name


@pytest.mark.parametrize("dialect", DIALECTS)
def test_round_trip_through_every_dialect(tmp_path, dialect):
    m = random_motion(seed=3)
    path = tmp_path / "x.csv"
    write_csv(m, path, dialect)
    r = read_motion(path, schema=dialect)
    assert r.joint_set.names == m.joint_set.names
    np.testing.assert_allclose(r.times, m.times, atol=1e-6)
    np.testing.assert_array_equal(r.position_mask, m.position_mask)
    np.testing.assert_allclose(r.positions[m.position_mask], m.positions[m.position_mask], atol=5e-7)
    np.testing.assert_array_equal(r.confidence, m.confidence)
    has_q = load_csv_schema(dialect).get("orientation") is not None
    assert r.has_orientations == has_q
    if has_q:
        gated = load_csv_schema(dialect).get("orientation").get("gated_by_tracking", True)
        expect = m.orientation_mask & (m.position_mask if gated else True)
        np.testing.assert_array_equal(r.orientation_mask, expect)
        np.testing.assert_allclose(r.orientations[expect], m.orientations[expect], atol=2e-6)


def test_a_file_longer_than_the_parsers_chunks_reads_every_row_in_place(tmp_path):
    """Rows are parsed in chunks of _CHUNK_ROWS straight into their columns: the rows at every chunk
    boundary land where they belong (checked against values computed from the row number)."""
    from kinectdata.formats.csv import _CHUNK_ROWS

    js = load_joint_set("nite")
    n = 2 * _CHUNK_ROWS + 17
    lines = ["# kinectdata motion csv v1", "# joint_set: nite"]
    lines.append(",".join(["time"] + [f"{j}.{c}" for j in js.names for c in ("x", "y", "z", "confidence")]))
    for r in range(n):
        cells = [f"{r / 30:.6f}"]
        for j in range(len(js)):
            cells += [f"{r * 1e-4:.4f}", f"{j:d}", "" if (r, j) == (_CHUNK_ROWS, 3) else "1.5", "1"]
        lines.append(",".join(cells))
    path = tmp_path / "long.csv"
    path.write_text("\n".join(lines) + "\n")
    m = read_motion(path)
    assert m.n_frames == n
    np.testing.assert_allclose(m.positions[:, 0, 0], np.arange(n) * 1e-4, atol=1e-12)
    assert not m.position_mask[_CHUNK_ROWS, 3] and m.position_mask.sum() == n * len(js) - 1
    assert (m.positions[:, :, 1] == np.arange(len(js)))[m.position_mask].all()


def test_canonical_keeps_any_joint_set_and_missing_orientations(tmp_path):
    js = load_joint_set("nite")
    rng = np.random.default_rng(1)
    from kinectdata.core.motion import Motion

    m = Motion(np.arange(5) / 30, rng.normal(size=(5, 15, 3)), js)
    write_csv(m, tmp_path / "n.csv")
    r = read_motion(tmp_path / "n.csv")
    assert r.joint_set.name == "nite" and not r.has_orientations
    np.testing.assert_allclose(r.positions, m.positions, atol=5e-7)


def test_canonical_carries_a_joint_set_kinectdata_does_not_ship_whole(tmp_path):
    """Its joints, bones, roles and SMPL-24 mapping come back from the file's one JSON line; a line
    that is not a joint set, or takes a shipped name with other joints, is one error naming the file."""
    from helpers import DANCER19, TO_SMPL24

    from kinectdata.core.jointsets import JointSet, joint_set_from_dict
    from kinectdata.core.motion import Motion

    joints = [{"name": n, "parent": p} for n, p in DANCER19.items()]
    js = joint_set_from_dict(
        {"name": "dancer19", "joints": joints, "roles": {"root": "pelvis"}, "to_smpl24": TO_SMPL24}
    )
    m = Motion(np.arange(4) / 30, np.random.default_rng(2).normal(size=(4, len(js), 3)), js)
    write_csv(m, tmp_path / "d.csv")
    r = read_motion(tmp_path / "d.csv")
    assert (r.joint_set.name, r.joint_set.names, r.joint_set.parents) == ("dancer19", js.names, js.parents)
    assert r.joint_set.to_smpl24 == TO_SMPL24 and r.joint_set.roles == {"root": "pelvis"}
    assert r.joint_set.bones() == js.bones()
    text = (tmp_path / "d.csv").read_text()
    for bad, says in (
        ('{"name": "dancer19"', "its joint set is not JSON"),
        ('{"name": "dancer19", "joints": 3}', "joints"),
        (
            json.dumps(JointSet.custom("nite", list(js.names)).to_dict()),
            "takes the shipped name 'nite' with other joints",
        ),
    ):
        broken = tmp_path / "broken.csv"
        line = next(x for x in text.splitlines() if x.startswith("# joint_set_document: "))
        broken.write_text(text.replace(line, f"# joint_set_document: {bad}"))
        with pytest.raises(FormatError, match=re.escape(str(broken)) + ".*joint_set_document.*" + says):
            read_motion(broken)


def test_dumpkinectskeleton_leaf_zero_quaternions_are_missing(tmp_path):
    m = random_motion(seed=5, untracked=0.0)
    write_csv(m, tmp_path / "d.csv", "dumpkinectskeleton")
    text = (tmp_path / "d.csv").read_text().splitlines()
    head_row = next(line for line in text[1:] if line.split(",")[1] == "3")  # Head: a leaf
    assert head_row.split(",")[5:9] == ["0.000000"] * 4
    r = read_motion(tmp_path / "d.csv")
    assert not r.orientation_mask[:, r.joint_set.index("Head")].any()


# ---------------------------------------------------------------------------------------------
# New dialects through schema files alone
# ---------------------------------------------------------------------------------------------
def _csharp_logger_schema(tmp_path):
    schema = {
        "name": "csharp_logger",
        "description": "Timestamp,Index,BodyID,SpineBase_X,...,SpineBase_inferred",
        "joint_set": "kinect_v2",
        "layout": "wide",
        "header": True,
        "time": {"column": "Timestamp", "unit": "us"},
        "body": {"column": "BodyID"},
        "position": {"columns": ["{joint}_X", "{joint}_Y", "{joint}_Z"], "unit": "m"},
        "tracking": {"column": "{joint}_inferred", "values": {"0": 1.0, "1": 0.5}},
    }
    path = tmp_path / "csharp.schema.json"
    path.write_text(json.dumps(schema))
    return path


def test_new_wide_dialect_with_bodies_through_a_schema_file(tmp_path):
    js = load_joint_set("kinect_v2")
    cols = ["Timestamp", "Index", "BodyID"] + [f"{n}_{c}" for n in js.names for c in ("X", "Y", "Z", "inferred")]
    lines = [",".join(cols)]
    expected = {}
    for k in range(6):
        for body, frames in (("72057594037930001", range(6)), ("72057594037930002", range(2, 4))):
            if k not in frames:
                continue
            vals = [(k * 25 + j) * 0.001 + (0.5 if body.endswith("2") else 0) for j in range(25)]
            flag = [1 if (k == 3 and j == 7) else 0 for j in range(25)]
            cells = [str(1_000_000 + k * 33_333), str(k), body]
            for j in range(25):
                cells += [f"{vals[j]:.6f}", f"{-vals[j]:.6f}", "2.5", str(flag[j])]
            lines.append(",".join(cells))
            expected[(body, k)] = vals
    data = tmp_path / "take.csv"
    data.write_text("\n".join(lines) + "\n")
    schema = _csharp_logger_schema(tmp_path)

    m = read_motion(data, schema=schema)
    assert m.metadata["body"] == "72057594037930001"  # present in 6 frames, the other in 2
    assert m.metadata["bodies"] == {"72057594037930001": 6, "72057594037930002": 2}
    np.testing.assert_allclose(m.times, np.arange(6) * 0.033333)
    np.testing.assert_allclose(m.positions[4, :, 0], expected[("72057594037930001", 4)])
    np.testing.assert_allclose(m.positions[4, :, 1], -np.array(expected[("72057594037930001", 4)]))
    assert m.confidence[3, 7] == 0.5 and m.confidence[2, 7] == 1.0

    other = read_motion(data, schema=schema, body="72057594037930002")
    assert other.n_frames == 2
    np.testing.assert_allclose(other.positions[0, :, 0], expected[("72057594037930002", 2)])
    with pytest.raises(
        FormatError,
        match=r"take\.csv, column 'BodyID': no body with id '9'; the file has: 72057594037930001 \(6 frames\)",
    ):
        read_motion(data, schema=schema, body="9")


def test_new_dialect_millimetres_without_time_column(tmp_path):
    az = load_joint_set("azure_kinect")
    schema = {
        "name": "azure_recorder",
        "joint_set": "azure_kinect",
        "layout": "wide",
        "header": True,
        "time": {"fps": 30},
        "position": {"columns": ["{joint}.x", "{joint}.y", "{joint}.z"], "unit": "mm"},
    }
    (tmp_path / "az.json").write_text(json.dumps(schema))
    header = ",".join(f"{n}.{c}" for n in az.names for c in "xyz")
    rows = [",".join(str(float(100 * k + j)) for j in range(96)) for k in range(4)]
    (tmp_path / "az.csv").write_text(header + "\n" + "\n".join(rows) + "\n")
    m = read_motion(tmp_path / "az.csv", schema=tmp_path / "az.json")
    assert m.joint_set.name == "azure_kinect"
    np.testing.assert_allclose(m.times, np.arange(4) / 30)
    assert m.positions[2, 1].tolist() == pytest.approx([0.203, 0.204, 0.205])  # mm -> m
    assert m.metadata["nominal_fps"] == 30


def test_a_long_dialect_with_joint_names(tmp_path):
    schema = {
        "name": "long_names",
        "joint_set": "nite",
        "layout": "long",
        "header": True,
        "time": {"column": "t", "unit": "s"},
        "joint": {"column": "joint", "values": "name"},
        "joint_names": {"Head": "HEAD", "Torso": "TORSO"},
        "position": {"columns": ["x", "y", "z"], "unit": "cm"},
    }
    (tmp_path / "s.json").write_text(json.dumps(schema))
    (tmp_path / "l.csv").write_text("t,joint,x,y,z\n0.0,Head,1,2,3\n0.0,Torso,4,5,6\n0.05,Head,7,8,9\n")
    m = read_motion(tmp_path / "l.csv", schema=tmp_path / "s.json")
    js = m.joint_set
    assert m.n_frames == 2
    assert m.positions[0, js.index("HEAD")].tolist() == pytest.approx([0.01, 0.02, 0.03])
    assert m.positions[1, js.index("HEAD")].tolist() == pytest.approx([0.07, 0.08, 0.09])
    assert not m.position_mask[1, js.index("TORSO")]  # no row for it in frame 1
    assert not m.position_mask[:, js.index("NECK")].any()
    (tmp_path / "bad.csv").write_text("t,joint,x,y,z\n0.0,Head,1,2,3\n0.0,Elbow,4,5,6\n")
    with pytest.raises(FormatError, match=r"bad\.csv, line 3, column 'joint': unknown joint name 'Elbow'"):
        read_motion(tmp_path / "bad.csv", schema=tmp_path / "s.json")


# ---------------------------------------------------------------------------------------------
# Bad schemas
# ---------------------------------------------------------------------------------------------
def _schema_error(tmp_path, doc_or_text) -> str:
    path = tmp_path / "my.schema.json"
    path.write_text(doc_or_text if isinstance(doc_or_text, str) else json.dumps(doc_or_text))
    with pytest.raises(SchemaError) as err:
        load_csv_schema(path)
    assert "my.schema.json" in str(err.value)
    return str(err.value)


def test_bad_schemas_get_clear_errors(tmp_path):
    good = json.loads(json.dumps(load_csv_schema("lsl_kinect").document))
    assert "line 2" in _schema_error(tmp_path, '{"name": "x",\n "layout": }')
    doc = dict(good)
    del doc["position"]
    assert "'position' is a required property" in _schema_error(tmp_path, doc)
    doc = dict(good, layout="diagonal")
    assert "layout" in _schema_error(tmp_path, doc)
    doc = dict(good, position={"columns": ["X", "Y", "Z"], "unit": "m"})
    assert "must contain {joint}" in _schema_error(tmp_path, doc)
    doc = dict(good, signature="([")
    assert "signature is not a valid regular expression" in _schema_error(tmp_path, doc)
    doc = dict(good, tracking={"column": "{joint}_Conf", "values": {"2": 1.7}})
    assert "tracking/values/2" in _schema_error(tmp_path, doc)
    kr = json.loads(json.dumps(load_csv_schema("kinectreader").document))
    kr["time"] = {"column": "stamp", "unit": "ticks"}
    assert "time.column 'stamp' is not among 'columns'" in _schema_error(tmp_path, kr)
    with pytest.raises(SchemaError, match=r"^unknown CSV schema 'nope': no such file.*shipped: canonical"):
        load_csv_schema("nope")


def test_shipped_schemas_are_valid():
    assert set(shipped_csv_schemas()) == set(DIALECTS)
    for name in shipped_csv_schemas():
        assert load_csv_schema(name).name == name


# ---------------------------------------------------------------------------------------------
# Bad input files: each error names the file and the line
# ---------------------------------------------------------------------------------------------
@pytest.fixture
def lsl_file(tmp_path):
    path = tmp_path / "take.csv"
    write_csv(random_motion(T=10, untracked=0.0), path, "lsl_kinect")
    return path


def _edit(path, line_no, fn):
    lines = path.read_text().splitlines()
    lines[line_no - 1] = fn(lines[line_no - 1])
    path.write_text("\n".join(lines) + "\n")


def _cells(line, index, value):
    cells = line.split(",")
    cells[index] = value
    return ",".join(cells)


def _error(path, **kw) -> str:
    with pytest.raises(FormatError) as err:
        read_motion(path, **kw)
    message = str(err.value)
    assert message.startswith(str(path)), message
    return message


def test_missing_column(lsl_file):
    _edit(lsl_file, 3, lambda h: h.replace(",SpineMid_Z", ""))
    msg = _error(lsl_file)
    assert re.search(r"line 3: missing column\(s\) SpineMid_Z", msg), msg


def test_unknown_joint_name_in_header(lsl_file):
    _edit(lsl_file, 3, lambda h: h.replace("HandLeft_", "HandLefty_"))
    msg = _error(lsl_file)
    assert "line 3, column 'HandLefty_X': unknown joint name 'HandLefty'" in msg


def test_non_numeric_cell(lsl_file):
    _edit(lsl_file, 7, lambda row: _cells(row, 5, "1,2".replace(",", ";")))
    assert "line 7, column 'SpineMid_X': non-numeric value '1;2'" in _error(lsl_file)


def test_nan_cell(lsl_file):
    _edit(lsl_file, 8, lambda row: _cells(row, 2, "NaN"))
    assert "line 8, column 'SpineBase_Y': 'NaN' is not a number" in _error(lsl_file)


def test_empty_cell_without_missing_values(lsl_file):
    _edit(lsl_file, 8, lambda row: _cells(row, 3, ""))
    assert "line 8, column 'SpineBase_Z': empty cell" in _error(lsl_file)


def test_time_going_backwards(lsl_file):
    _edit(lsl_file, 9, lambda row: _cells(row, 0, "-5"))
    msg = _error(lsl_file)
    assert "line 9: time goes backwards: -5 ms after" in msg and "on line 8" in msg


def test_duplicated_timestamp(lsl_file):
    lines = lsl_file.read_text().splitlines()
    lines[8] = _cells(lines[8], 0, lines[7].split(",")[0])
    lsl_file.write_text("\n".join(lines) + "\n")
    assert "line 9: duplicated timestamp" in _error(lsl_file) and "(also on line 8)" in _error(lsl_file)


def test_wrong_field_count(lsl_file):
    _edit(lsl_file, 6, lambda row: row.rsplit(",", 3)[0])
    assert "line 6: expected 101 fields as the header says, found 98" in _error(lsl_file)


def test_unknown_tracking_state(tmp_path):
    path = tmp_path / "d.csv"
    write_csv(random_motion(T=3), path, "dumpkinectskeleton")
    _edit(path, 5, lambda row: _cells(row, 9, "7"))
    assert "line 5, column 'state': unknown tracking state '7'" in _error(path)


def test_long_format_duplicate_and_backwards(tmp_path):
    path = tmp_path / "d.csv"
    write_csv(random_motion(T=4, untracked=0.0), path, "dumpkinectskeleton")
    lines = path.read_text().splitlines()
    dup = lines[:30] + [lines[29]] + lines[30:]
    path.write_text("\n".join(dup) + "\n")
    msg = _error(path)
    assert "line 31: joint" in msg and "appears twice" in msg and "also on line 30" in msg
    back = lines[:27] + [_cells(lines[27], 0, "0.000000")] + lines[28:]
    path.write_text("\n".join(back) + "\n")
    assert "line 28: time goes backwards" in _error(path)


def test_not_a_unit_quaternion(tmp_path):
    path = tmp_path / "d.csv"
    write_csv(random_motion(T=3, untracked=0.0), path, "dumpkinectskeleton")
    _edit(path, 4, lambda row: ",".join(row.split(",")[:5] + ["0.5", "0", "0", "0.5"] + row.split(",")[9:]))
    assert "line 4, column 'qx': orientation of joint 'Neck' is not a unit quaternion (norm 0.707" in _error(path)


def test_junk_orientation_of_an_untracked_joint_is_masked_not_an_error(tmp_path):
    path = tmp_path / "d.csv"
    write_csv(random_motion(T=3, untracked=0.0), path, "dumpkinectskeleton")
    junk = ["0.5", "0", "0", "0.5"]
    _edit(path, 4, lambda row: ",".join(row.split(",")[:5] + junk + ["0"]))  # Neck, frame 0, not tracked
    m = read_motion(path)
    neck = m.joint_set.index("Neck")
    assert not m.position_mask[0, neck] and not m.orientation_mask[0, neck]


def test_masked_positions_are_written_as_not_tracked_in_every_dialect(tmp_path):
    m = random_motion(T=4, untracked=0.0, inferred=0.0)
    mask = m.position_mask.copy()
    mask[2, 7] = False
    from kinectdata.core.motion import Motion

    m = Motion(
        m.times,
        m.positions,
        m.joint_set,
        position_mask=mask,
        confidence=np.ones(mask.shape),
        orientations=m.orientations,
    )
    for dialect in DIALECTS:
        write_csv(m, tmp_path / f"{dialect}.csv", dialect)
        back = read_motion(tmp_path / f"{dialect}.csv")
        assert not back.position_mask[2, 7] and back.position_mask.sum() == mask.sum(), dialect


def test_schema_naming_unknown_joints_or_joint_set_is_refused_in_its_own_file(tmp_path, fixture_csv):
    doc = json.loads(json.dumps(load_csv_schema("kinectreader").document))
    for change, expected in [
        ({"joints": ["SpineBase", "Nope"]}, "joints: 'Nope' is not a joint of kinect_v2"),
        ({"joint_names": {"Spine_Base": "SpineBottom"}}, "joint_names: 'Spine_Base' maps to 'SpineBottom'"),
        ({"joint_set": "kinect_v3"}, "joint_set 'kinect_v3': unknown joint set 'kinect_v3': no such file"),
    ]:
        path = tmp_path / "mine.json"
        path.write_text(json.dumps({**doc, **change}))
        with pytest.raises(SchemaError) as err:
            read_motion(fixture_csv, schema=path)
        assert str(err.value).startswith(f"{path}: {expected}"), str(err.value)


def test_empty_and_header_only_files(tmp_path):
    empty = tmp_path / "empty.csv"
    empty.write_text("")
    assert "empty file" in _error(empty)
    assert "empty file" in _error(empty, schema="kinectreader") or "no data rows" in _error(
        empty, schema="kinectreader"
    )
    only = tmp_path / "only.csv"
    write_csv(random_motion(T=2), only, "lsl_kinect")
    only.write_text("\n".join(only.read_text().splitlines()[:3]) + "\n")
    assert "no data rows after the header (line 3)" in _error(only)


def test_unrecognised_dialect_points_to_schema_option(tmp_path):
    path = tmp_path / "odd.csv"
    path.write_text("a,b,c\n1,2,3\n")
    assert "pass --schema FILE" in _error(path)


def test_kinectreader_nan_and_garbage(fixture_csv, tmp_path):
    path = tmp_path / "kr.csv"
    path.write_text(fixture_csv.read_text())
    _edit(path, 100, lambda row: _cells(row, 30, "nan"))
    assert "line 100, column 'HandLeft.y': 'nan' is not a number" in _error(path)  # cell 30 = joint 7, y


# ---------------------------------------------------------------------------------------------
# Reported on real files
# ---------------------------------------------------------------------------------------------
def _write_schema(path, doc):
    path.write_text(json.dumps(doc))
    return path


def test_nite_logger_zeros_are_untracked_with_zero_is_untracked(tmp_path):
    """A SimpleOpenNI logger writes a lost joint, or a whole lost user, as 0,0,0 (in millimetres)."""
    js = load_joint_set("nite")
    rng = np.random.default_rng(7)
    T, J = 200, len(js)
    pos = rng.uniform(-800, 800, size=(T, J, 3)).round(3)
    pos[pos == 0] = 1.0
    lost = np.zeros((T, J), bool)
    lost[30:170] = True  # 140 whole frames at the origin: the user was lost
    lost[5:12, js.index("LEFT_HAND")] = True  # one joint lost
    lost[180, [js.index("HEAD"), js.index("RIGHT_FOOT")]] = True
    pos[lost] = 0.0
    pos[3, js.index("TORSO")] = [0.0, 0.0, 512.5]  # zeros in some coordinates only: a position
    header = ["millis"] + [f"{n}_{c}" for n in js.names for c in ("x", "y", "z", "conf")]
    rows = [",".join([str(33 * k)] + [f"{v:g}" for j in range(J) for v in (*pos[k, j], 0.5)]) for k in range(T)]
    data = tmp_path / "simpleopenni.csv"
    data.write_text(",".join(header) + "\n" + "\n".join(rows) + "\n")
    doc = {
        "name": "simpleopenni_logger",
        "joint_set": "nite",
        "layout": "wide",
        "header": True,
        "time": {"column": "millis", "unit": "ms"},
        "position": {"columns": ["{joint}_x", "{joint}_y", "{joint}_z"], "unit": "mm", "zero_is_untracked": True},
        "tracking": {"column": "{joint}_conf", "scale": "confidence"},
    }
    m = read_motion(data, schema=_write_schema(tmp_path / "logger.json", doc))
    np.testing.assert_array_equal(m.position_mask, ~lost)
    np.testing.assert_array_equal(m.confidence, np.where(lost, 0.0, 0.5))
    np.testing.assert_allclose(m.positions[~lost], pos[~lost] / 1000)
    assert m.position_mask[3, js.index("TORSO")] and not m.position_mask[30:170].any()
    doc["position"]["zero_is_untracked"] = False  # the default: zeros are a position
    assert read_motion(data, schema=_write_schema(tmp_path / "plain.json", doc)).position_mask.all()


def test_headerless_dialect_holding_some_joints_in_its_own_order(tmp_path):
    js = load_joint_set("kinect_v2")
    held = ["Head", "Neck", "SpineShoulder", "HandRight", "HandLeft"]  # file order, not joint-set order
    doc = {
        "name": "upper_body_logger",
        "joint_set": "kinect_v2",
        "joints": held,
        "layout": "wide",
        "header": False,
        "delimiter": "\t",
        "columns": ["t", {"per_joint": ["{joint}.x", "{joint}.y", "{joint}.z", "{joint}.state"]}],
        "time": {"column": "t", "unit": "s"},
        "position": {"columns": ["{joint}.x", "{joint}.y", "{joint}.z"], "unit": "m"},
        "tracking": {"column": "{joint}.state", "values": {"0": 0.0, "1": 0.5, "2": 1.0}},
    }
    schema = _write_schema(tmp_path / "upper.json", doc)
    rows = []
    for k in range(6):
        cells = [f"{k / 30:.6f}"] + [f"{k + i / 10:g}\t{-i:g}\t2.5\t{1 if (k, i) == (2, 3) else 2}" for i in range(5)]
        rows.append("\t".join(cells))
    data = tmp_path / "upper.csv"
    data.write_text("\n".join(rows) + "\n")
    m = read_motion(data, schema=schema)
    assert m.joint_set.name == "kinect_v2" and m.n_frames == 6
    for i, name in enumerate(held):
        j = js.index(name)
        np.testing.assert_allclose(m.positions[:, j], np.c_[np.arange(6) + i / 10, np.full(6, -i), np.full(6, 2.5)])
    assert m.confidence[2, js.index("HandRight")] == 0.5 and m.confidence[3, js.index("HandRight")] == 1.0
    absent = [j for j in range(len(js)) if js.names[j] not in held]
    assert m.position_mask[:, [js.index(n) for n in held]].all() and not m.position_mask[:, absent].any()
    (tmp_path / "more.csv").write_text("\t".join(["0"] * 101) + "\n")  # all 25 joints: not this dialect
    msg = _error(tmp_path / "more.csv", schema=schema)
    assert "line 1: the file does not look like the upper_body_logger dialect: its rows hold 21 fields" in msg


def _canonical_with_columns_dropped(tmp_path, keep):
    """A canonical CSV of a kinect_v2 motion whose header keeps only the columns ``keep`` accepts."""
    m = random_motion(T=5, seed=11, untracked=0.0)
    path = tmp_path / "sub.csv"
    write_csv(m, path)
    lines = path.read_text().splitlines()
    header = lines[2].split(",")
    kept = [i for i, c in enumerate(header) if c == "time" or keep(c)]
    table = [",".join(line.split(",")[i] for i in kept) for line in lines[2:]]
    path.write_text("\n".join(lines[:2] + table) + "\n")
    return m, path


def test_canonical_csv_holding_some_joints_reads_the_others_as_untracked(tmp_path):
    held = {"Head", "HandLeft", "HandRight"}
    m, path = _canonical_with_columns_dropped(tmp_path, lambda c: c.split(".")[0] in held)
    r = read_motion(path)
    assert r.joint_set.name == "kinect_v2" and r.n_joints == 25
    idx = [m.joint_set.index(n) for n in sorted(held)]
    expected_mask = np.zeros_like(m.position_mask)
    expected_mask[:, idx] = m.position_mask[:, idx]
    np.testing.assert_array_equal(r.position_mask, expected_mask)
    np.testing.assert_allclose(r.positions[:, idx], m.positions[:, idx], atol=5e-7)
    assert (r.confidence[:, [j for j in range(25) if j not in idx]] == 0).all()


def test_canonical_csv_with_a_joint_partly_present_or_no_joint_is_refused(tmp_path):
    _, path = _canonical_with_columns_dropped(tmp_path, lambda c: c.startswith(("Head.", "Neck.")) and c != "Neck.z")
    msg = _error(path)
    assert "\n" not in msg
    assert re.search(r"line 3: missing column\(s\) Neck\.z \(joint 'Neck' has 'Neck\.x', 'Neck\.y', .*must be all", msg)
    _, path = _canonical_with_columns_dropped(tmp_path, lambda c: False)
    msg = _error(path)
    assert "line 3: the file does not look like the canonical dialect: its header names none" in msg
    assert "the header has 'time')" in msg


def test_joint_set_file_is_found_from_the_schema_folder_not_the_working_folder(tmp_path, monkeypatch):
    folder = tmp_path / "dialects"
    (folder / "sets").mkdir(parents=True)
    joint_set = {"name": "three", "joints": [{"name": n, "parent": None} for n in "ABC"], "aliases": {"Alpha": "A"}}
    (folder / "sets" / "three.json").write_text(json.dumps(joint_set))
    doc = {
        "name": "markers",
        "joint_set": "sets/three.json",
        "layout": "wide",
        "header": True,
        "time": {"column": "t", "unit": "s"},
        "position": {"columns": ["{joint}x", "{joint}y", "{joint}z"], "unit": "m"},
    }
    schema = _write_schema(folder / "markers.json", doc)
    data = tmp_path / "take.csv"
    data.write_text("t,Ax,Ay,Az,Bx,By,Bz,Cx,Cy,Cz\n0,1,2,3,4,5,6,7,8,9\n0.1,1,2,3,4,5,6,7,8,9\n")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    m = read_motion(data, schema=schema)
    assert list(m.joint_set.names) == ["A", "B", "C"] and m.positions[1, 2].tolist() == [7, 8, 9]
    broken = _write_schema(folder / "broken.json", dict(doc, joint_set="sets/nope.json"))
    with pytest.raises(SchemaError) as err:
        read_motion(data, schema=broken)
    expected = (
        f"{broken}: joint_set 'sets/nope.json': joint-set file not found: {folder / 'sets' / 'nope.json'} "
        "(a relative path is resolved from the folder of the schema file)"
    )
    assert str(err.value) == expected
    twice = _write_schema(folder / "twice.json", dict(doc, joints=["A", "Alpha"]))
    with pytest.raises(SchemaError, match=r"twice\.json: joints: 'Alpha' and 'A' are the same joint$"):
        read_motion(data, schema=twice)


def _semicolon_schema(tmp_path, **extra):
    doc = {
        "name": "excel_de",
        "joint_set": "nite",
        "joints": ["HEAD", "TORSO"],
        "layout": "wide",
        "header": True,
        "delimiter": ";",
        "time": {"column": "Zeit", "unit": "s"},
        "position": {"columns": ["{joint}_X", "{joint}_Y", "{joint}_Z"], "unit": "m"},
        **extra,
    }
    return _write_schema(tmp_path / f"excel{len(extra)}.json", doc)


def test_decimal_commas_get_a_hint_and_read_with_the_decimal_option(tmp_path):
    header = "Zeit;HEAD_X;HEAD_Y;HEAD_Z;TORSO_X;TORSO_Y;TORSO_Z"
    rows = ['0,000;0,123;1,456;2;-0,5;"1,25";3', "0,033;0,223;1,556;2,1;-0,4;1,35;3,5"]
    data = tmp_path / "excel.csv"
    data.write_text("\n".join([header, *rows]) + "\n")
    msg = _error(data, schema=_semicolon_schema(tmp_path))
    assert "excel.csv, line 2, column 'Zeit': non-numeric value '0,000': it looks like a number with a decimal " in msg
    assert '"decimal": ","' in msg and "\n" not in msg
    m = read_motion(data, schema=_semicolon_schema(tmp_path, decimal=","))
    js = m.joint_set
    np.testing.assert_allclose(m.times, [0, 0.033])
    np.testing.assert_allclose(m.positions[:, js.index("HEAD")], [[0.123, 1.456, 2], [0.223, 1.556, 2.1]])
    np.testing.assert_allclose(m.positions[:, js.index("TORSO")], [[-0.5, 1.25, 3], [-0.4, 1.35, 3.5]])
    data.write_text("\n".join([header, rows[0], rows[1].replace("1,556", "1.556")]) + "\n")
    msg = _error(data, schema=_semicolon_schema(tmp_path, decimal=","))
    assert "line 3, column 'HEAD_Y': non-numeric value '1.556' (the excel_de dialect's decimal separator is ',')" in msg
    with pytest.raises(SchemaError, match=r"excel2\.json: decimal ',' is also the delimiter"):
        load_csv_schema(_semicolon_schema(tmp_path, decimal=",", delimiter=","))


def test_quoted_decimal_commas_in_a_comma_separated_file_get_a_hint(lsl_file):
    _edit(lsl_file, 5, lambda row: _cells(row, 1, '"0,25"'))
    msg = _error(lsl_file)
    assert (
        "line 5: expected 101 fields as the header says, found 102: '0,25' looks like a number with a decimal " in msg
    )
    assert "export it again with decimal points" in msg and "\n" not in msg


def test_wrong_schema_says_the_file_is_not_in_that_dialect(lsl_file, fixture_csv):
    msg = _error(fixture_csv, schema="lsl_kinect")
    assert "repeats" not in msg and "\n" not in msg
    assert re.search(
        r"Ges01_wavehand\.csv, line 2: the file does not look like the lsl_kinect dialect: its header names none of "
        r"that dialect's joint columns \(it expects columns like 'TimeSpan', 'SpineBase_X', 'SpineBase_Y', .*; "
        r"the header has '89810634305', '0\.0115979', ",
        msg,
    ), msg
    msg = _error(lsl_file, schema="kinectreader")
    assert re.search(
        r"take\.csv, line 1: the file does not look like the kinectreader dialect: its rows hold 101 fields "
        r"\('time', 'SpineBase\.x', .*\), but its first row holds 4 \('Software : LSL_Kinect', ",
        msg,
    ), msg


def test_the_docs_nite_example_dialect_reads_a_file_shaped_as_it_says(tmp_path):
    text = (Path(__file__).parents[2] / "docs" / "csv-schemas.md").read_text(encoding="utf-8")
    block = re.search(r"## Example: a NiTE logger.*?```json\n(.*?)```", text, re.S).group(1)
    schema = tmp_path / "nite_upper_body.json"
    schema.write_text(block)
    lost_hand = "1,5;-2;1000,25;" + ";".join(["10;20;30"] * 2) + ";0;0;0;4;5;6"
    (tmp_path / "take.csv").write_text(f"0;{lost_hand}\n33;{lost_hand.replace(';0;0;0;', ';7;0;0;')}\n")
    m = read_motion(tmp_path / "take.csv", schema=schema)
    js = m.joint_set
    assert m.positions[0, js.index("HEAD")].tolist() == pytest.approx([0.0015, -0.002, 1.00025])
    assert m.position_mask[:, js.index("LEFT_HAND")].tolist() == [False, True]
    assert m.position_mask[:, js.index("RIGHT_HAND")].all() and not m.position_mask[:, js.index("LEFT_KNEE")].any()


def test_the_writer_writes_what_the_new_options_describe(tmp_path):
    """write_csv in a headerless dialect holding some joints, and in a decimal-comma dialect: the
    file has the dialect's shape (checked on its text) and reads back to the joints written."""
    m = random_motion(T=5, untracked=0.0)
    js = m.joint_set
    held = ["Head", "Neck", "HandRight"]
    doc = {
        "name": "upper_logger",
        "joint_set": "kinect_v2",
        "joints": held,
        "layout": "wide",
        "header": False,
        "delimiter": ";",
        "decimal": ",",
        "columns": ["t", {"per_joint": ["{joint}.x", "{joint}.y", "{joint}.z"]}],
        "time": {"column": "t", "unit": "s"},
        "position": {"columns": ["{joint}.x", "{joint}.y", "{joint}.z"], "unit": "m"},
    }
    schema = _write_schema(tmp_path / "upper.json", doc)
    write_csv(m, tmp_path / "upper.csv", schema)
    first = (tmp_path / "upper.csv").read_text().splitlines()[0].split(";")
    assert len(first) == 1 + 3 * len(held) and "." not in ";".join(first)
    assert first[1] == f"{m.positions[0, js.index('Head'), 0]:.6f}".replace(".", ",")
    back = read_motion(tmp_path / "upper.csv", schema=schema)
    idx = [js.index(n) for n in held]
    np.testing.assert_allclose(back.positions[:, idx], m.positions[:, idx], atol=5e-7)
    assert back.position_mask[:, idx].all() and back.position_mask.sum() == 5 * len(held)


def test_a_header_repeating_many_columns_names_a_few_and_counts_the_rest(tmp_path):
    """A canonical CSV whose columns all appear twice (a damaged or concatenated export): one short
    line naming five of the repeated columns and how many more, not a 2 000-character list."""
    m = random_motion(T=5, seed=11, untracked=0.0)
    path = tmp_path / "twice.csv"
    write_csv(m, path)
    lines = path.read_text().splitlines()
    path.write_text("\n".join(lines[:2] + [f"{line},{line}" for line in lines[2:]]) + "\n")
    header = lines[2].split(",")
    repeated = sorted(set(header))
    with pytest.raises(FormatError) as caught:
        read_motion(path)
    message = str(caught.value)
    named = ", ".join(map(repr, repeated[:5]))
    assert f"line 3: the header repeats column(s) {named} and {len(repeated) - 5} more" in message
    assert len(message) < 300


def test_a_dialect_declares_its_up_axis_and_handedness(tmp_path):
    """An Xsens-like export: z up, left-handed, with orientations. Read through a schema that says so,
    the body stands along y, positions are the file's turned by (x, y, z) -> (-x, z, -y), and
    every orientation still turns each bone as in the file (checked on vectors)."""
    from click.testing import CliRunner
    from scipy.spatial.transform import Rotation

    from kinectdata.cli import main

    names = ["pelvis", "head", "foot"]
    schema = {
        "name": "zup_left",
        "joint_set": "auto",
        "layout": "wide",
        "header": True,
        "up": "z",
        "handedness": "left",
        "time": {"column": "t", "unit": "s"},
        "position": {"columns": ["{joint}_x", "{joint}_y", "{joint}_z"], "unit": "m"},
        "orientation": {"columns": ["{joint}_qx", "{joint}_qy", "{joint}_qz", "{joint}_qw"], "order": "xyzw"},
    }
    (tmp_path / "zup.json").write_text(json.dumps(schema))
    rng = np.random.default_rng(3)
    T = 40
    file_pos = np.array([[0.2, 0.1, 0.9], [0.2, 0.15, 1.7], [0.25, 0.1, 0.05]]) + rng.normal(0, 0.01, (T, 3, 3))
    file_q = Rotation.random(T * 3, random_state=4).as_quat().reshape(T, 3, 4)
    header = ["t"] + [f"{j}_{a}" for j in names for a in ("x", "y", "z", "qx", "qy", "qz", "qw")]
    rows = [
        ",".join([f"{k / 240:.6f}"] + [f"{v:.9f}" for j in range(3) for v in (*file_pos[k, j], *file_q[k, j])])
        for k in range(T)
    ]
    (tmp_path / "take.csv").write_text("\n".join([",".join(header), *rows]) + "\n")
    m = read_motion(tmp_path / "take.csv", schema=str(tmp_path / "zup.json"))
    # independent: mirror x, then z up -> y up, as a matrix written out here
    to_ours = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]) @ np.diag([-1.0, 1, 1])
    np.testing.assert_allclose(m.positions, file_pos @ to_ours.T, atol=1e-9)
    assert (m.positions[:, 1, 1] > m.positions[:, 2, 1] + 1.5).all()  # the head above the foot, along y
    v = rng.normal(size=3)
    for k, j in ((0, 0), (17, 1), (39, 2)):  # a bone v in the joint's frame: where the file puts it, in our axes
        ours = Rotation.from_quat(m.orientations[k, j]).apply(v)
        theirs = to_ours @ Rotation.from_quat(file_q[k, j]).apply(np.diag([-1.0, 1, 1]) @ v)
        np.testing.assert_allclose(ours, theirs, atol=1e-6)
    info = CliRunner().invoke(main, ["info", str(tmp_path / "take.csv"), "--schema", str(tmp_path / "zup.json")])
    assert info.exit_code == 0 and "but the up axis is" not in info.output, info.output
