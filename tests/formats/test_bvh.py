"""The BVH reader: forward kinematics equal to an independent parser's (bvhio), known answers, and
one clear line for each kind of damage."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kinectdata.core.errors import FormatError
from kinectdata.formats import detect_format, read_motion

AXES = ("X", "Y", "Z")


def _random_bvh(path: Path, seed: int = 0, frames: int = 30) -> None:
    """A BVH file with a branching hierarchy, every rotation order, position channels on the root and
    on some other joints, End Sites, and random values (centimetres, degrees)."""
    rng = np.random.default_rng(seed)
    lines = ["HIERARCHY"]
    columns: list[str] = []

    def joint(name: str, depth: int, root: bool = False) -> None:
        pad = "  " * depth
        lines.append(f"{pad}{'ROOT' if root else 'JOINT'} {name}")
        lines.append(f"{pad}{{")
        offset = rng.normal(0, 10, 3)
        lines.append(f"{pad}  OFFSET {offset[0]:.4f} {offset[1]:.4f} {offset[2]:.4f}")
        rotation = [f"{a}rotation" for a in rng.permutation(AXES)]
        position = [f"{a}position" for a in AXES] if root or rng.random() < 0.3 else []
        channels = position + rotation
        lines.append(f"{pad}  CHANNELS {len(channels)} {' '.join(channels)}")
        columns.extend(channels)
        children = int(rng.integers(0, 3)) if depth < 4 else 0
        for k in range(children):
            joint(f"{name}{k}", depth + 1)
        if not children:
            tip = f"{pad}    OFFSET 0.0 {rng.normal(5, 1):.4f} 0.0"
            lines.extend([f"{pad}  End Site", f"{pad}  {{", tip, f"{pad}  }}"])
        lines.append(f"{pad}}}")

    joint("Hips", 0, root=True)
    lines.extend(["MOTION", f"Frames: {frames}", "Frame Time: 0.0166667"])
    for _ in range(frames):
        row = [rng.normal(0, 50) if c.endswith("position") else rng.uniform(-180, 180) for c in columns]
        lines.append(" ".join(f"{v:.5f}" for v in row))
    path.write_text("\n".join(lines) + "\n")


def test_positions_and_orientations_equal_an_independent_parsers(tmp_path):
    bvhio = pytest.importorskip("bvhio")
    path = tmp_path / "random.bvh"
    _random_bvh(path)
    motion = read_motion(path)  # centimetres by default
    assert motion.metadata["nominal_fps"] == pytest.approx(60.0, rel=1e-5)
    np.testing.assert_allclose(motion.times[:3], [0.0, 0.0166667, 0.0333334])
    root = bvhio.readAsHierarchy(str(path))
    names = list(motion.joint_set.names)
    compared = 0
    for frame in (0, 7, 29):
        root.loadPose(frame, recursive=True)
        for j, *_ in root.layout():
            k = names.index(j.Name)
            np.testing.assert_allclose(motion.positions[frame, k], np.array(j.PositionWorld) / 100, atol=2e-6)
            w, x, y, z = (float(v) for v in j.RotationWorld)  # glm quaternions are (w, x, y, z), float32
            ours = Rotation.from_quat(motion.orientations[frame, k])
            theirs = Rotation.from_quat([x, y, z, w])
            assert (ours.inv() * theirs).magnitude() < 1e-5
            compared += 1
    assert compared == 3 * sum(motion.joint_set.has_orientation)  # every joint but the End Sites


TWO_FRAMES = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 5 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.04
1 2 3 0 0 0 0 0 0
0 100 0 90 0 0 0 0 0
"""


def test_end_sites_units_and_the_joint_set_known_answers(tmp_path):
    path = tmp_path / "two.bvh"
    path.write_text(TWO_FRAMES)
    mm = read_motion(path, unit="mm")
    assert mm.joint_set.names == ("Hips", "Spine", "Spine_End")
    assert mm.joint_set.parents == (-1, 0, 1)
    assert mm.joint_set.has_orientation == (True, True, False)
    np.testing.assert_allclose(mm.positions[0], [[0.001, 0.002, 0.003], [0.001, 0.012, 0.003], [0.001, 0.017, 0.003]])
    # a quarter turn about z at the root: the spine's +y offset points along -x
    np.testing.assert_allclose(mm.positions[1], [[0, 0.1, 0], [-0.01, 0.1, 0], [-0.015, 0.1, 0]], atol=1e-12)
    np.testing.assert_allclose(mm.orientations[1, 0], [0, 0, np.sqrt(0.5), np.sqrt(0.5)], atol=1e-12)
    assert mm.metadata["unit"] == "mm" and mm.metadata["offsets_m"][1] == [0.0, 0.01, 0.0]
    assert mm.times.tolist() == [0.0, 0.04]
    cm = read_motion(path)
    np.testing.assert_allclose(cm.positions, mm.positions * 10)
    other = tmp_path / "other.txt"  # no .bvh extension: found by its content
    other.write_text(TWO_FRAMES.replace("1 2 3", "4 5 6"))
    assert detect_format(other) == "bvh"
    assert read_motion(other).joint_set.name == cm.joint_set.name  # one skeleton, one joint set


DAMAGE = [
    (lambda t: t.replace("HIERARCHY", "HIERARCY"), "expected 'HIERARCHY', found 'HIERARCY'", 1),
    (lambda t: t.replace("Xrotation Yrotation", "Xrotation Wrotation"), "unknown channel 'wrotation'", 5),
    (lambda t: t.replace("OFFSET 0 10 0", "OFFSET 0 ten 0"), "Spine's OFFSET: 'ten' is not a number", 8),
    (lambda t: t.replace("Frame Time: 0.04", "Frame Time: 0"), "Frame Time: 0 s", 18),
    (lambda t: t.replace("Frames: 2", "Frames: 3"), "Frames: 3, but the values stop after 2 whole frame(s)", 20),
    (lambda t: t.replace("0 100 0 90", "0 100 0 nan"), "frame 1: a value is not finite", 20),
    (lambda t: t.replace("0 0 0 0 0 0\n0 100", "0 0 0 0 0\n0 0 100"), "frame 0: 8 values, but a line must hold 9", 19),
    (lambda t: t.replace("1 2 3 0", "1 2 x 0"), "frame 0: 'x' is not a number", 19),
    (lambda t: t.split("MOTION")[0], "the file ends where 'MOTION' should be", 15),
    (lambda t: t.replace("CHANNELS 3 Zrotation", "CHANNELS 7 Zrotation"), "joint 'Spine': 7 channels", 9),
]


@pytest.mark.parametrize("damage, message, line", DAMAGE)
def test_each_damage_is_one_line_with_the_file_and_line(tmp_path, damage, message, line):
    good = tmp_path / "good.bvh"
    good.write_text(damage(TWO_FRAMES))
    with pytest.raises(FormatError) as info:
        read_motion(good, format="bvh")
    text_of_error = str(info.value)
    assert "\n" not in text_of_error and str(good) in text_of_error
    assert message in text_of_error, text_of_error
    assert re.search(rf"line {line}\b", text_of_error), text_of_error


def test_an_unknown_unit_is_refused(tmp_path):
    path = tmp_path / "x.bvh"
    _random_bvh(path, frames=2)
    with pytest.raises(FormatError, match="unit 'ft' is not one of m, cm, mm, in"):
        read_motion(path, unit="ft")


def test_info_reads_a_bvh_file_and_a_damaged_one_is_one_line(tmp_path):
    from click.testing import CliRunner

    from kinectdata.cli import main

    path = tmp_path / "take.bvh"
    path.write_text(TWO_FRAMES)
    result = CliRunner().invoke(main, ["info", str(path)])
    assert result.exit_code == 0, result.output
    assert "format          bvh" in result.output and "(3 joints, 3-D)" in result.output
    path.write_text(TWO_FRAMES.replace("Frames: 2", "Frames: 3"))
    result = CliRunner().invoke(main, ["info", str(path)])
    assert result.exit_code != 0 and "Traceback" not in result.output
    assert f"{path}, line 20: Frames: 3, but the values stop after 2 whole frame(s)" in result.output


# -- writing ------------------------------------------------------------------------------------


def _rotation_error(a: np.ndarray, b: np.ndarray) -> float:
    """Largest angle (radians) between quaternions a and b [..., 4]."""
    return float((Rotation.from_quat(a.reshape(-1, 4)).inv() * Rotation.from_quat(b.reshape(-1, 4))).magnitude().max())


@pytest.mark.parametrize("unit", ["cm", "m"])
def test_a_written_bvh_reads_back_as_the_same_motion(tmp_path, unit):
    from kinectdata.formats.bvh_writer import write_bvh

    path = tmp_path / "random.bvh"
    _random_bvh(path, seed=2)
    motion = read_motion(path)
    write_bvh(motion, tmp_path / "again.bvh", unit=unit)
    back = read_motion(tmp_path / "again.bvh", unit=unit)
    assert back.joint_set.names == motion.joint_set.names and back.joint_set.parents == motion.joint_set.parents
    np.testing.assert_allclose(back.positions, motion.positions, atol=1e-6)  # 6 decimals: a micrometre in m
    ok = motion.joint_set.orientation_mask
    assert _rotation_error(back.orientations[:, ok], motion.orientations[:, ok]) < 1e-7
    np.testing.assert_allclose(back.times, motion.times, atol=1e-6)


def test_positions_alone_are_solved_on_the_rest_skeleton_and_read_alike_by_bvhio(tmp_path):
    """Without orientations the rotations are solved from the positions: a rigid motion (read from a
    BVH, its orientations dropped) comes back at the same positions, in kinectdata and in bvhio."""
    import dataclasses

    bvhio = pytest.importorskip("bvhio")
    from kinectdata.formats.bvh_writer import write_bvh

    path = tmp_path / "random.bvh"
    _random_bvh(path, seed=4)
    rigid = dataclasses.replace(read_motion(path), orientations=None, orientation_mask=None)
    write_bvh(rigid, tmp_path / "solved.bvh")
    back = read_motion(tmp_path / "solved.bvh")
    np.testing.assert_allclose(back.positions, rigid.positions, atol=1e-7)
    root = bvhio.readAsHierarchy(str(tmp_path / "solved.bvh"))
    names = list(back.joint_set.names)
    for frame in (0, 13):
        root.loadPose(frame, recursive=True)
        for j, *_ in root.layout():
            np.testing.assert_allclose(
                np.array(j.PositionWorld) / 100, rigid.positions[frame, names.index(j.Name)], atol=2e-6
            )


def test_a_kinect_recording_with_gaps_is_written_with_its_chain(tmp_path):
    """The bundled Kinect v2 recording: masked frames are held, leaves without orientation get an End
    Site, and the positions come back where the orientations carry the bones (the sensor's noise
    moves the joints off that rigid chain by about a centimetre)."""
    from conftest import REPO

    from kinectdata.formats.bvh_writer import write_bvh

    motion = read_motion(REPO / "sample_data" / "synth_001.csv")
    assert not motion.position_mask.all()  # the recording has tracking gaps
    write_bvh(motion, tmp_path / "take.bvh")
    back = read_motion(tmp_path / "take.bvh")
    names = list(back.joint_set.names)
    assert {f"{n}_End" for n in ("Head", "HandTipLeft", "FootRight")} <= set(names)
    index = [names.index(n) for n in motion.joint_set.names]
    root = motion.joint_set.names.index("SpineBase")
    ok = motion.position_mask[:, root]
    np.testing.assert_allclose(back.positions[ok, index[root]], motion.positions[ok, root], atol=1e-8)
    error = np.linalg.norm(back.positions[:, index] - motion.positions, axis=-1)[motion.position_mask]
    assert np.median(error) < 0.02 and error.max() < 0.1  # metres: centimetres off, not a wrong axis or unit
    np.testing.assert_allclose(back.times[1], np.median(np.diff(motion.times)), rtol=0.02)


def test_what_bvh_cannot_hold_is_refused_with_one_line(tmp_path):
    from kinectdata.core.errors import KinectDataError
    from kinectdata.formats.bvh_writer import write_bvh

    flat = read_motion(_two_frames(tmp_path))
    with pytest.raises(KinectDataError, match="unit 'ft' is not one of m, cm, mm, in"):
        write_bvh(flat, tmp_path / "a.bvh", unit="ft")
    import dataclasses

    from kinectdata.core.jointsets import load_joint_set

    js = load_joint_set("openpose_mpi")
    image = dataclasses.replace(
        flat,
        joint_set=js,
        positions=np.zeros((2, len(js), 2)),
        orientations=None,
        orientation_mask=None,
        position_mask=np.ones((2, len(js)), bool),
        confidence=np.ones((2, len(js)), np.float32),
    )
    with pytest.raises(KinectDataError, match="BVH holds 3-D skeletons; joint set 'openpose_mpi' is 2-D"):
        write_bvh(image, tmp_path / "b.bvh")
    assert not (tmp_path / "a.bvh").exists() and not (tmp_path / "b.bvh").exists()


def _two_frames(tmp_path: Path) -> Path:
    path = tmp_path / "two.bvh"
    path.write_text(TWO_FRAMES)
    return path
