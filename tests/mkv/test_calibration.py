"""The calibration attachment and depth unprojected through it, against independent computations:
the SDK's mode arithmetic done by hand, the lens model written out here and inverted by scipy."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.optimize import fsolve

from kinectdata.mkv.calibration import CalibrationError, depth_to_points, read_calibration

# a depth camera in the shape of an Azure Kinect's calibration (values made up, not a device's)
PARAMETERS = [0.5006, 0.5048, 0.4926, 0.4927, 0.61, -0.061, -0.0036, 0.93, 0.031, -0.016, 0, 0, -4.1e-5, -1.2e-4]


def _calibration(model="CALIBRATION_LensDistortionModelBrownConrady", colour_height=3072):
    depth = {
        "Location": "CALIBRATION_CameraLocationD0",
        "Purpose": "CALIBRATION_CameraPurposeDepth",
        "Intrinsics": {"ModelType": model, "ModelParameterCount": 14, "ModelParameters": PARAMETERS},
        "MetricRadius": 1.74,
        "SensorWidth": 1024,
        "SensorHeight": 1024,
        "Rt": {"Rotation": [1, 0, 0, 0, 1, 0, 0, 0, 1], "Translation": [0, 0, 0]},
    }
    colour = {
        **depth,
        "Location": "CALIBRATION_CameraLocationPV0",
        "Intrinsics": {**depth["Intrinsics"], "ModelParameters": [0.4997, 0.4983, 0.4706, 0.6272] + [0.0] * 10},
        "SensorWidth": 4096,
        "SensorHeight": colour_height,
        "Rt": {"Rotation": [1, 0.002, 0, -0.002, 1, 0.1, 0, -0.1, 1], "Translation": [-0.032, -0.002, 0.004]},
    }
    return json.dumps({"CalibrationInformation": {"Cameras": [depth, colour], "Metadata": {"SerialId": "1"}}}).encode()


def _forward(x, y, p, cross):
    """The lens model as the SDK's transformation_project_internal writes it, from the parameters in
    the file's order (cx, cy, fx, fy in pixels, k1-k6, codx, cody, p2, p1)."""
    cx, cy, fx, fy, k1, k2, k3, k4, k5, k6, codx, cody, p2, p1 = p
    x, y = x - codx, y - cody
    r2 = x * x + y * y
    d = (1 + k1 * r2 + k2 * r2**2 + k3 * r2**3) / (1 + k4 * r2 + k5 * r2**2 + k6 * r2**3)
    xd = x * d + (r2 + 2 * x * x) * p2 + cross * x * y * p1
    yd = y * d + (r2 + 2 * y * y) * p1 + cross * x * y * p2
    return (xd + codx) * fx + cx, (yd + cody) * fy + cy


def test_depth_modes_put_the_intrinsics_in_their_pixels():
    cal = read_calibration(_calibration())
    unbinned = cal.depth_intrinsics("NFOV_UNBINNED")  # 1024 x 1024 cropped at (192, 180) to 640 x 576
    assert unbinned.size == (640, 576)
    assert unbinned.cx == pytest.approx(0.5006 * 1024 - 192 - 0.5)
    assert unbinned.cy == pytest.approx(0.5048 * 1024 - 180 - 0.5)
    assert unbinned.fx == pytest.approx(0.4926 * 1024) and unbinned.fy == pytest.approx(0.4927 * 1024)
    binned = cal.depth_intrinsics("NFOV_2X2BINNED")  # binned to 512 x 512, cropped at (96, 90)
    assert binned.cx == pytest.approx(0.5006 * 512 - 96 - 0.5) and binned.fx == pytest.approx(0.4926 * 512)
    wide = cal.depth_intrinsics("WFOV_UNBINNED")
    assert wide.size == (1024, 1024) and wide.cy == pytest.approx(0.5048 * 1024 - 0.5)
    colour = cal.color_intrinsics(720)  # 4:3 sensor binned to 1280 x 960, cropped 120 rows
    assert colour.cy == pytest.approx(0.4983 * 960 - 120 - 0.5) and colour.fy == pytest.approx(0.6272 * 960)
    assert cal.cameras["color"].translation_m[0] == pytest.approx(-0.032)
    with pytest.raises(CalibrationError, match="depth mode 'NFOV'"):
        cal.depth_intrinsics("NFOV")


def test_a_16_by_9_colour_calibration_is_taken_to_4_by_3_first():
    legacy = read_calibration(_calibration(colour_height=2304)).color_intrinsics(1080)
    # normalised cy, fy over 2304 rows become (cy * 2304 + 384) / 3072 and fy * 2304 / 3072
    assert legacy.cy == pytest.approx((0.4983 * 2304 + 384) / 3072 * 1440 - 180 - 0.5)
    assert legacy.fy == pytest.approx(0.6272 * 2304 / 3072 * 1440)


@pytest.mark.parametrize(
    "model, cross, centre",
    [
        ("CALIBRATION_LensDistortionModelBrownConrady", 2.0, (0.0, 0.0)),
        ("CALIBRATION_LensDistortionModelRational6KT", 1.0, (0.012, -0.008)),  # 6KT has a centre of distortion
    ],
)
def test_points_are_the_rays_scipy_finds_times_the_depth(model, cross, centre):
    raw = json.loads(_calibration(model))
    parameters = [*PARAMETERS[:10], *centre, *PARAMETERS[12:]]
    raw["CalibrationInformation"]["Cameras"][0]["Intrinsics"]["ModelParameters"] = parameters
    intrinsics = read_calibration(json.dumps(raw).encode()).depth_intrinsics("NFOV_UNBINNED")
    # NFOV unbinned by hand: 1 024 x 1 024 cropped at (192, 180), (0, 0) the first pixel's centre
    p = [parameters[0] * 1024 - 192 - 0.5, parameters[1] * 1024 - 180 - 0.5, parameters[2] * 1024,
         parameters[3] * 1024, *parameters[4:]]  # fmt: skip
    rng = np.random.default_rng(0)
    depth = rng.integers(300, 5000, (576, 640)).astype(np.uint16)
    depth[0, 0] = 0  # no depth: no point
    points = depth_to_points(depth, intrinsics)
    assert points.dtype == np.float32 and points.shape == (576, 640, 3)
    np.testing.assert_array_equal(points[0, 0], 0)
    for v, u in [(288, 320), (10, 20), (570, 630), (100, 500), (400, 60)]:
        guess = [(u - p[0]) / p[2], (v - p[1]) / p[3]]
        ray = fsolve(lambda xy, u=u, v=v: np.subtract(_forward(*xy, p, cross), (u, v)), guess, xtol=1e-11)
        np.testing.assert_allclose(points[v, u, :2], ray * depth[v, u], rtol=2e-6, atol=2e-4)
        assert points[v, u, 2] == depth[v, u]


def test_rays_beyond_the_metric_radius_have_no_point():
    raw = json.loads(_calibration())
    raw["CalibrationInformation"]["Cameras"][0]["MetricRadius"] = 0.5  # rays past 0.5 on the z = 1 plane
    intrinsics = read_calibration(json.dumps(raw).encode()).depth_intrinsics("WFOV_UNBINNED")
    points = depth_to_points(np.full((1024, 1024), 1000, np.uint16), intrinsics)
    centre, corner = points[512, 512], points[0, 0]
    assert centre[2] == 1000 and np.all(corner == 0)


def test_a_calibration_that_is_not_one_says_what_is_missing():
    with pytest.raises(CalibrationError, match="no 'CalibrationInformation'"):
        read_calibration(b"{}", source="take.mkv: calibration.json")
    bad = json.loads(_calibration())
    bad["CalibrationInformation"]["Cameras"][0]["Intrinsics"]["ModelType"] = "CALIBRATION_LensDistortionModelTheta"
    with pytest.raises(CalibrationError, match="lens model 'CALIBRATION_LensDistortionModelTheta'"):
        read_calibration(json.dumps(bad).encode())
