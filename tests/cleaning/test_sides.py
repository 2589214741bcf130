"""Left and right swapped back: against a dancer who turns her back to a simulated frontal tracker."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import kinectdata as kd
from kinectdata.cleaning.sides import find_side_swaps, mirrored_pairs
from kinectdata.core.jointsets import JointSet
from kinectdata.synth.dancer import dance
from kinectdata.synth.sensor import apply_sensor_defects
from kinectdata.synth.turns import draw_turns, frontal_tracker, turn_about_vertical


def _turning_dancer(seed: int, seconds: float = 40.0, heading=None):
    """The true motion of a dancer who turns round, and what a frontal tracker writes of it."""
    times = np.arange(0, seconds, 1 / 30)
    truth = dance(seed=seed, times_s=times, beat_times_s=np.arange(2.0, seconds, 0.5), music_start_s=2.0,
                  clap_time_s=None, tempo_bpm=120)  # fmt: skip
    js = truth.joint_set
    if heading is None:
        heading = draw_turns(times, np.random.default_rng(seed), turns_per_minute=6.0)
    truth = turn_about_vertical(truth, heading, js.index("SpineBase"))
    noisy = apply_sensor_defects(truth, seed=seed).motion
    seen, mirrored = frontal_tracker(noisy, "HipLeft", "HipRight")
    return truth, seen, mirrored


def test_the_turns_make_the_tracker_mirror_the_dancer_while_she_faces_away():
    truth, seen, mirrored = _turning_dancer(0)
    assert mirrored, "the drawn turns never took the dancer's back to the sensor"
    js = truth.joint_set
    first, last = mirrored[0]
    middle = (first + last) // 2
    # facing away, the tracker's "left" hand is where her right hand truly is
    np.testing.assert_allclose(seen.positions[middle, js.index("HandLeft")],
                               truth.positions[middle, js.index("HandRight")], atol=0.03)  # fmt: skip
    # and where she faces it, the labels are hers
    np.testing.assert_allclose(seen.positions[5, js.index("HandLeft")], truth.positions[5, js.index("HandLeft")],
                               atol=0.03)  # fmt: skip


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_mirrored_stretch_is_found_to_the_frame_and_swapped_back(seed):
    truth, seen, mirrored = _turning_dancer(seed)
    found = find_side_swaps(seen.positions, seen.position_mask, seen.joint_set)
    assert found.intervals == mirrored
    assert found.judged_by == ("feet" if mirrored else "majority")
    cleaned = kd.clean_motion(seen, kd.CleanConfig(gaps=False, jitter="none", bones=False))
    frames = found.frames(seen.n_frames)

    def error(m):  # mean distance to the truth in the mirrored frames, metres (over the valid samples)
        return float(np.linalg.norm(m.positions - truth.positions, axis=-1)[frames][m.position_mask[frames]].mean())

    if mirrored:
        assert error(cleaned.motion) < 0.1 * error(seen)
        assert len(cleaned.report.sides.intervals_s) == len(mirrored)
        assert "mirrored stretches swapped back" in "\n".join(cleaned.report.lines())


def test_the_feet_tell_which_side_is_mirrored_when_she_mostly_faces_away():
    """Turned away for most of the recording: 'the parity with fewer frames' would repair the wrong
    one; where the toes point against the hips' facing does not."""
    times = np.arange(0, 30, 1 / 30)
    heading = np.pi * np.clip((times - 3.0) / 0.8, 0, 1) - np.pi * np.clip((times - 26.0) / 0.8, 0, 1)
    truth, seen, mirrored = _turning_dancer(4, 30.0, heading)
    assert sum(b - a + 1 for a, b in mirrored) > 0.6 * seen.n_frames
    found = find_side_swaps(seen.positions, seen.position_mask, seen.joint_set)
    assert (found.intervals, found.judged_by) == (mirrored, "feet")
    js = seen.joint_set
    no_feet = dataclasses.replace(js, roles={k: v for k, v in js.roles.items() if "foot" not in k})
    guessed = find_side_swaps(seen.positions, seen.position_mask, no_feet)
    assert guessed.judged_by == "majority" and guessed.intervals != mirrored


def test_a_tracker_that_swaps_only_the_hands_makes_no_flip():
    """Hands cross and a tracker may trade them; hips and shoulders do not: one limb is no flip."""
    truth, seen, _ = _turning_dancer(5, 20.0, heading=np.zeros(600))
    js = seen.joint_set
    hands = [("HandLeft", "HandRight"), ("WristLeft", "WristRight"), ("HandTipLeft", "HandTipRight"),
             ("ThumbLeft", "ThumbRight")]  # fmt: skip
    p = seen.positions.copy()
    for a, b in hands:
        i, j = js.index(a), js.index(b)
        p[200:260, [i, j]] = p[200:260, [j, i]]
    assert find_side_swaps(p, seen.position_mask, js).flips == ()


def test_a_joint_set_without_sides_is_said_in_one_line():
    custom = JointSet.custom("chain", ["a", "b", "c", "d"], [None, "a", "b", "c"])
    motion = kd.Motion(times=np.arange(10) / 30.0, positions=np.random.default_rng(0).normal(size=(10, 4, 3)),
                       joint_set=custom)  # fmt: skip
    with pytest.raises(kd.ConfigError, match="fewer than two mirrored pairs"):
        mirrored_pairs(custom)
    report = kd.clean_motion(motion).report
    assert (
        report.lines()[0]
        == "sides: not looked at (joint set chain has fewer than two mirrored pairs: its sides cannot be told)"
    )


def test_clean_on_the_command_line_names_the_stretches_it_swapped_back(tmp_path):
    import subprocess
    import sys

    truth, seen, mirrored = _turning_dancer(0, 20.0)
    assert mirrored
    kd.write_motion(seen, tmp_path / "turning.csv")
    run = subprocess.run(
        [sys.executable, "-m", "kinectdata", "clean", str(tmp_path / "turning.csv"), "-o", str(tmp_path / "out.csv"),
         "--up", "+y"],
        capture_output=True, text=True,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    line = run.stdout.splitlines()[0]
    assert line.startswith(f"sides: {len(mirrored)} mirrored stretches swapped back") and "judged by the feet" in line
    back = kd.read_motion(tmp_path / "out.csv")
    js = back.joint_set
    first, last = mirrored[0]
    hand = js.index("HandLeft")
    assert (
        np.linalg.norm(back.positions[first : last + 1, hand] - truth.positions[first : last + 1, hand], axis=-1).max()
        < 0.05
    )
    upside_down = subprocess.run(
        [sys.executable, "-m", "kinectdata", "clean", str(tmp_path / "turning.csv"), "-o", str(tmp_path / "o2.csv"),
         "--up", "-y"],
        capture_output=True, text=True,
    )  # fmt: skip
    assert upside_down.returncode == 0, upside_down.stderr  # -y is a value, not an option
