"""Unit, up-axis and speed doubts about a recording, and its bone lengths (kinectdata info)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import REPO

from kinectdata.cli import main
from kinectdata.core import body_checks
from kinectdata.formats import read_motion


@pytest.fixture(scope="module")
def take():
    return read_motion(REPO / "sample_data" / "synth_001.csv")


def _with(motion, **changes):
    return dataclasses.replace(motion, metadata=dict(motion.metadata), **changes)


def test_a_kinect_take_raises_no_doubt_and_its_bones_are_measured(take):
    assert body_checks.unit_doubt(take) is None
    assert body_checks.up_axis_doubt(take) is None
    assert body_checks.speed_doubt(take) is None
    bones = body_checks.bone_lengths(take)
    js = take.joint_set
    hip, knee = js.index("HipLeft"), js.index("KneeLeft")
    lengths = [
        np.linalg.norm(take.positions[t, knee] - take.positions[t, hip])
        for t in range(take.n_frames)
        if take.position_mask[t, hip] and take.position_mask[t, knee]
    ]
    assert bones["HipLeft-KneeLeft"] == pytest.approx(np.median(lengths))
    assert len(bones) == len(js) - 1 and 0.3 < bones["HipLeft-KneeLeft"] < 0.5


@pytest.mark.parametrize(
    "factor, words",
    [(100, "centimetres read as metres"), (1000, "millimetres read as metres"), (0.01, "metres read as centimetres")],
)
def test_a_body_of_the_wrong_size_is_doubted(take, factor, words):
    doubt = body_checks.unit_doubt(_with(take, positions=take.positions * factor))
    assert doubt is not None and words in doubt


def test_a_body_on_its_back_or_upside_down_is_doubted(take):
    lying = _with(take, positions=take.positions[..., [0, 2, 1]], orientations=None, orientation_mask=None)
    assert "above the feet along z" in body_checks.up_axis_doubt(lying)
    upside_down = _with(take, positions=take.positions * [1, -1, 1], orientations=None, orientation_mask=None)
    assert "below the feet along y" in body_checks.up_axis_doubt(upside_down)
    told = _with(lying)
    told.metadata["gravity_axis"] = "Z"  # an HTR file that says z is up
    assert body_checks.up_axis_doubt(told) is None


def test_without_roles_the_longest_axis_must_be_up(take):
    from kinectdata.core.jointsets import JointSet

    js = take.joint_set
    anonymous = JointSet("anonymous", js.names, js.parents)  # no head or feet roles
    standing = _with(take, joint_set=anonymous, orientations=None, orientation_mask=None)
    assert body_checks.up_axis_doubt(standing) is None
    lying = _with(standing, positions=take.positions[..., [1, 0, 2]])
    assert "longest along x, but the up axis is y" in body_checks.up_axis_doubt(lying)


def test_a_stated_rate_far_from_the_truth_shows_as_speed(take):
    """The sample take (22 s of dance, hands at about 2 m/s): read 20 times too fast it is no dancer's
    speed, 10 times too slow it is slower than dance; its own rate, and a short slow take, say nothing."""
    too_high = body_checks.speed_doubt(_with(take, times=take.times / 20))
    assert "no dancer's speed" in too_high and "stated frame rate too high" in too_high
    too_low = body_checks.speed_doubt(_with(take, times=take.times * 10))
    assert "slower than dance" in too_low and "stated frame rate too low" in too_low
    assert body_checks.speed_doubt(take) is None
    short = _with(take, times=take.times * 10)
    short = _with(short, times=short.times[:30], positions=short.positions[:30], position_mask=short.position_mask[:30],
                  confidence=short.confidence[:30], orientations=None, orientation_mask=None)  # fmt: skip
    assert short.duration < body_checks.MIN_SLOW_TAKE_S and body_checks.speed_doubt(short) is None


def test_info_prints_the_bones_and_the_doubts(take, tmp_path):
    from kinectdata.formats.csv_writer import write_csv

    path = tmp_path / "giant.csv"
    write_csv(_with(take, positions=take.positions * 100), path, "canonical")
    result = CliRunner().invoke(main, ["info", str(path)])
    assert result.exit_code == 0, result.output
    assert "bones           24, median length" in result.output
    assert "unit            the body spans" in result.output and "centimetres read as metres" in result.output
