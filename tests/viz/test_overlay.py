"""The body tracker's skeleton over its depth frames: joints where a pinhole camera puts them
(computed here from the calibration's numbers), one frame per depth frame a body frame falls on."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image
from test_azure_json import BONES, NAMES, make_doc, write

from kinectdata.cli import main
from kinectdata.formats import read_motion
from kinectdata.mkv import K4aRecording
from kinectdata.viz.overlay import depth_image, plan_overlay
from reference.k4a_writer import VideoTrack, depth_track, write_k4a

H, W = 288, 320  # NFOV 2x2 binned: 512 x 512 cropped at (96, 90)
CX, CY, FX, FY = 0.5, 0.5, 0.48, 0.47  # normalised by 1 024 (the calibration file's way)
T0 = 3_000_000_000


COLOUR = {"cx": 0.5, "cy": 0.49, "fx": 0.47, "fy": 0.62}  # normalised by 4 096 x 3 072
SHIFT_M = (-0.032, 0.002, 0.004)  # from the depth camera to the colour camera, metres


def _take(path, n=5, colour=False):
    camera = {
        "Location": "CALIBRATION_CameraLocationD0",
        "Intrinsics": {"ModelType": "CALIBRATION_LensDistortionModelBrownConrady", "ModelParameterCount": 14,
                       "ModelParameters": [CX, CY, FX, FY] + [0.0] * 10},
        "MetricRadius": 1.74, "SensorWidth": 1024, "SensorHeight": 1024,
        "Rt": {"Rotation": [1, 0, 0, 0, 1, 0, 0, 0, 1], "Translation": [0, 0, 0]},
    }  # fmt: skip
    depth = np.full((n, H, W), 2000, np.uint16)
    times = [T0 + i * 33_333_333 for i in range(n)]
    tracks = [depth_track("DEPTH", depth, times, "NFOV_2X2BINNED")]
    cameras = [camera]
    if colour:  # 720p NV12, mid grey, each frame 1 ms before its depth frame
        grey = bytes([128]) * (1280 * 720 * 3 // 2)
        tracks.insert(0, VideoTrack("COLOR", "NV12", 1280, 720, [grey] * n, [t - 1_000_000 for t in times],
                                    {"K4A_COLOR_MODE": "NV12_720P"}))  # fmt: skip
        cameras.append({
            **camera, "Location": "CALIBRATION_CameraLocationPV0", "SensorWidth": 4096, "SensorHeight": 3072,
            "Intrinsics": {**camera["Intrinsics"],
                           "ModelParameters": [COLOUR["cx"], COLOUR["cy"], COLOUR["fx"], COLOUR["fy"]] + [0.0] * 10},
            "Rt": {"Rotation": [1, 0, 0, 0, 1, 0, 0, 0, 1], "Translation": list(SHIFT_M)},
        })  # fmt: skip
    write_k4a(path, tracks, calibration={"CalibrationInformation": {"Cameras": cameras}})
    return [t // 1000 for t in times]


def _body(joint_mm):
    """One body whose every joint is at ``joint_mm`` but the first few, spread around it."""
    positions = np.tile(np.asarray(joint_mm, float), (len(NAMES), 1))
    positions[1:4] += [[50, 0, 0], [0, 50, 0], [0, 0, 100]]
    quats = np.tile([1.0, 0, 0, 0], (len(NAMES), 1))
    return {"body_id": 1, "joint_positions": positions.tolist(), "joint_orientations": quats.tolist()}, positions


def _pixel(point_mm):
    """Pinhole projection in the 2x2-binned mode's pixels, from the calibration's numbers by hand."""
    x, y, z = point_mm
    return FX * 512 * x / z + CX * 512 - 96 - 0.5, FY * 512 * y / z + CY * 512 - 90 - 0.5


def test_joints_are_drawn_where_the_camera_sees_them_on_the_depth_frame_of_their_time(tmp_path):
    stamps = _take(tmp_path / "take.mkv")
    bodies = [_body([100.0 + 40 * k, -200.0, 2000.0]) for k in range(3)]  # moving right frame by frame
    positions = bodies[0][1]
    # body frames on depth frames 1, 2 and 4 (the tracker skipped 0 and 3)
    doc = make_doc([(stamps[i], [body[0]]) for i, body in zip((1, 2, 4), bodies)], NAMES, BONES)
    motion = read_motion(write(tmp_path, doc, "take_body.json"))
    with K4aRecording(tmp_path / "take.mkv") as take:
        plan = plan_overlay(motion, take)
        assert plan.frames.tolist() == [1, 2, 4] and plan.size == (W, H) and plan.fps == pytest.approx(30.0)
        for j in range(4):
            np.testing.assert_allclose(plan.pixels[0, j], _pixel(positions[j]), atol=1e-6)
    out = tmp_path / "overlay.gif"
    result = CliRunner().invoke(main, ["render", str(tmp_path / "take_body.json"), "--over", str(tmp_path / "take.mkv"),
                                       "-o", str(out)])  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "3 depth frames at 30 fps, 320x288" in result.output and "3 of 3 frames on DEPTH frames" in result.output
    with Image.open(out) as gif:
        assert gif.n_frames == 3
        frame = np.asarray(gif.convert("RGB")).astype(int)
    u, v = (round(c) for c in _pixel(positions[0]))
    assert frame[v, u].min() > 235  # a joint: a white dot
    background = depth_image(np.array([[2000]], np.uint16))[0, 0]
    assert np.abs(frame[10, 10] - background).max() <= 8  # the depth of 2 m, grey (the GIF's palette)


def test_only_the_take_s_own_body_tracking_is_drawn_over_it(tmp_path):
    _take(tmp_path / "take.mkv")
    entry, _ = _body([0.0, 0.0, 2000.0])
    other = write(tmp_path, make_doc([(T0 // 1000 + 60_000_000, [entry])], NAMES, BONES), "other_take.json")
    result = CliRunner().invoke(main, ["render", str(other), "--over", str(tmp_path / "take.mkv"), "-o",
                                       str(tmp_path / "o.gif")])  # fmt: skip
    assert result.exit_code == 1 and "none of its 1 frames falls on a DEPTH frame" in result.output
    assert not (tmp_path / "o.gif").exists()
    result = CliRunner().invoke(main, ["render", str(other), "--over", str(tmp_path / "take.mkv"), "-o",
                                       str(tmp_path / "o.avi")])  # fmt: skip
    assert result.exit_code == 1 and "unknown animation type '.avi'" in result.output
    assert not (tmp_path / "o.avi").exists()
    csv = tmp_path / "skeleton.csv"
    result = CliRunner().invoke(main, ["render", str(tmp_path / "take.mkv"), "--over", str(tmp_path / "take.mkv"),
                                       "-o", str(tmp_path / "o.gif")])  # fmt: skip
    assert result.exit_code == 1 and "Traceback" not in result.output and not csv.exists()


def test_joints_are_drawn_on_the_colour_frame_through_the_depth_to_colour_shift(tmp_path):
    stamps = _take(tmp_path / "take.mkv", colour=True)
    entry, positions = _body([100.0, -200.0, 2000.0])
    doc = make_doc([(stamps[i], [entry]) for i in (0, 3)], NAMES, BONES)
    motion = read_motion(write(tmp_path, doc, "take_body.json"))
    with K4aRecording(tmp_path / "take.mkv") as take:
        plan = plan_overlay(motion, take, on="COLOR")
    assert plan.track == "COLOR" and plan.frames.tolist() == [0, 3] and plan.size == (1280, 720)
    # 720p: the 4:3 sensor binned to 1 280 x 960 and cropped 120 rows; the point shifted into the colour camera
    x, y, z = positions[0] + np.array(SHIFT_M) * 1000
    u = COLOUR["fx"] * 1280 * x / z + COLOUR["cx"] * 1280 - 0.5
    v = COLOUR["fy"] * 960 * y / z + COLOUR["cy"] * 960 - 120 - 0.5
    np.testing.assert_allclose(plan.pixels[0, 0], (u, v), atol=1e-6)
    out = tmp_path / "colour.gif"
    result = CliRunner().invoke(main, ["render", str(tmp_path / "take_body.json"), "--over", str(tmp_path / "take.mkv"),
                                       "--on", "color", "-o", str(out)])  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "2 color frames at 30 fps, 1280x720" in result.output
    with Image.open(out) as gif:
        frame = np.asarray(gif.convert("RGB")).astype(int)
    assert frame[round(v), round(u)].min() > 235 and abs(frame[20, 20] - 130).max() <= 8  # a joint on the grey
