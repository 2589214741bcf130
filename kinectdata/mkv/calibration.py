"""The device calibration a k4arecorder file carries (its ``calibration.json`` attachment), and
depth pixels turned into points through it.

The JSON and its units are the Azure Kinect Sensor SDK's (src/calibration/calibration.c): each
camera's ``Intrinsics.ModelParameters`` are cx, cy, fx, fy, k1-k6, codx, cody, p2, p1 (and a
metric radius), with cx, cy, fx, fy divided by the sensor's width and height and measured from the
image's corner; ``Rt`` takes a point from the depth camera's frame to the camera's (rotation row by
row, translation in metres). A depth mode's pixels are a binned and cropped part of the depth
sensor's 1 024 x 1 024 (src/transformation/mode_specific_calibration.c): the intrinsics in pixels
are the normalised ones times the binned resolution, less the crop, and cx, cy less half a pixel.

Unprojection follows the SDK's lens model (src/transformation/intrinsic_transformation.c): a
rational radial term ``(1 + k1 r^2 + k2 r^4 + k3 r^6) / (1 + k4 r^2 + k5 r^4 + k6 r^6)`` and
tangential terms p1, p2 (Brown-Conrady doubles the cross terms that Rational6KT has once), inverted
per pixel by Gauss-Newton from a first guess, as the SDK does; a pixel whose ray lies beyond the
metric radius, or that does not converge, has no point.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass

import numpy as np

from kinectdata.core.errors import KinectDataError

DEPTH_MODES = {
    # mode: (binned resolution, crop offset, output resolution), pixels
    "NFOV_2X2BINNED": ((512, 512), (96, 90), (320, 288)),
    "NFOV_UNBINNED": ((1024, 1024), (192, 180), (640, 576)),
    "WFOV_2X2BINNED": ((512, 512), (0, 0), (512, 512)),
    "WFOV_UNBINNED": ((1024, 1024), (0, 0), (1024, 1024)),
    "PASSIVE_IR": ((1024, 1024), (0, 0), (1024, 1024)),
}
COLOR_MODES = {
    # height: (binned resolution of the 4:3 sensor, crop offset, output resolution)
    720: ((1280, 960), (0, 120), (1280, 720)),
    1080: ((1920, 1440), (0, 180), (1920, 1080)),
    1440: ((2560, 1920), (0, 240), (2560, 1440)),
    1536: ((2048, 1536), (0, 0), (2048, 1536)),
    2160: ((3840, 2880), (0, 360), (3840, 2160)),
    3072: ((4096, 3072), (0, 0), (4096, 3072)),
}
MODELS = {
    "CALIBRATION_LensDistortionModelBrownConrady": "brown_conrady",
    "CALIBRATION_LensDistortionModelRational6KT": "rational_6kt",
}


class CalibrationError(KinectDataError):
    """A calibration that cannot be read or used; the message says which part."""


@dataclass(frozen=True)
class CameraCalibration:
    """One camera's calibration as recorded (normalised intrinsics).

    Attributes:
        location: ``CALIBRATION_CameraLocationD0`` (depth) or ``...PV0`` (colour).
        model: ``brown_conrady`` or ``rational_6kt``.
        parameters: [15] cx, cy, fx, fy (divided by the sensor's size), k1-k6, codx, cody, p2, p1,
            metric radius (a zero where the file gives fewer).
        sensor_size: (width, height) pixels. metric_radius: the largest radius on the z = 1 plane
            the lens model holds for.
        rotation: [3, 3]; translation_m: [3], metres: from the depth camera's frame to this one's.
    """

    location: str
    model: str
    parameters: tuple[float, ...]
    sensor_size: tuple[int, int]
    metric_radius: float
    rotation: np.ndarray
    translation_m: np.ndarray

    def in_pixels(self, binned: tuple[int, int], crop: tuple[int, int], output: tuple[int, int]) -> Intrinsics:
        """The intrinsics of an image mode in pixels, (0, 0) the centre of the first pixel."""
        p = [float(v) for v in self.parameters]
        cx, cy = p[0] * binned[0] - crop[0] - 0.5, p[1] * binned[1] - crop[1] - 0.5
        return Intrinsics(
            self.model, cx, cy, p[2] * binned[0], p[3] * binned[1], tuple(p[4:10]), (p[10], p[11]),
            (p[13], p[12]), self.metric_radius, tuple(output),
        )  # fmt: skip


@dataclass(frozen=True)
class Intrinsics:
    """A camera mode's lens model in pixels: ``k`` k1-k6, ``centre`` codx, cody, ``p`` p1, p2,
    ``size`` (width, height)."""

    model: str
    cx: float
    cy: float
    fx: float
    fy: float
    k: tuple[float, ...]
    centre: tuple[float, float]
    p: tuple[float, float]
    metric_radius: float
    size: tuple[int, int]

    def project(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixels [..., 2] of points on the z = 1 plane [..., 2] and whether each lies within
        the metric radius: the lens model forward."""
        x, y = xy[..., 0] - self.centre[0], xy[..., 1] - self.centre[1]
        u, v, _ = self._forward(x, y)
        inside = x * x + y * y <= self.metric_radius**2
        return np.stack([u, v], axis=-1), inside

    def _forward(self, x, y):
        k1, k2, k3, k4, k5, k6 = self.k
        p1, p2 = self.p
        rs = x * x + y * y
        a = 1 + rs * (k1 + rs * (k2 + rs * k3))
        b = 1 + rs * (k4 + rs * (k5 + rs * k6))
        b = np.where(b == 0, 1.0, b)
        d = a / b
        cross = 2.0 if self.model == "brown_conrady" else 1.0
        xd = x * d + (rs + 2 * x * x) * p2 + cross * x * y * p1
        yd = y * d + (rs + 2 * y * y) * p1 + cross * x * y * p2
        u = (xd + self.centre[0]) * self.fx + self.cx
        v = (yd + self.centre[1]) * self.fy + self.cy
        # the Jacobian d(u, v)/d(x, y)
        da = k1 + 2 * k2 * rs + 3 * k3 * rs * rs
        db = k4 + 2 * k5 * rs + 3 * k6 * rs * rs
        dd = 2 * (da * b - a * db) / (b * b)  # d(d)/d(r^2), twice
        jxx = self.fx * (d + x * x * dd + 6 * x * p2 + cross * y * p1)
        jxy = self.fx * (x * y * dd + 2 * y * p2 + cross * x * p1)
        jyx = self.fy * (x * y * dd + 2 * x * p1 + cross * y * p2)
        jyy = self.fy * (d + y * y * dd + 6 * y * p1 + cross * x * p2)
        return u, v, (jxx, jxy, jyx, jyy)

    def unproject(self, uv: np.ndarray, passes: int = 20) -> tuple[np.ndarray, np.ndarray]:
        """Points on the z = 1 plane [..., 2] of pixels [..., 2] and whether each was found (within
        the metric radius, the pixel matched to 1e-3 px): the SDK's first guess (the radial term
        inverted at the distorted radius, a tangential correction), then Gauss-Newton steps while
        the squared pixel error falls, up to ``passes`` evaluations."""
        uv = np.asarray(uv, dtype=np.float64)
        k1, k2, k3, k4, k5, k6 = self.k
        p1, p2 = self.p
        xd = (uv[..., 0] - self.cx) / self.fx - self.centre[0]
        yd = (uv[..., 1] - self.cy) / self.fy - self.centre[1]
        rs = xd * xd + yd * yd
        a = 1 + rs * (k1 + rs * (k2 + rs * k3))
        b = 1 + rs * (k4 + rs * (k5 + rs * k6))
        scale = b / np.where(a == 0, 1.0, a)
        x, y = xd * scale, yd * scale
        two_xy, xx, yy = 2 * x * y, x * x, y * y
        x, y = x - ((yy + 3 * xx) * p2 + two_xy * p1), y - ((xx + 3 * yy) * p1 + two_xy * p2)
        x, y = x + self.centre[0], y + self.centre[1]
        best_x, best_y = x.copy(), y.copy()
        best = np.full(x.shape, np.inf)
        active = np.ones(x.shape, dtype=bool)
        inside = np.ones(x.shape, dtype=bool)
        for step in range(passes):
            cx_, cy_ = x - self.centre[0], y - self.centre[1]
            inside &= ~active | (cx_ * cx_ + cy_ * cy_ <= self.metric_radius**2)
            u, v, (jxx, jxy, jyx, jyy) = self._forward(cx_, cy_)
            ex, ey = uv[..., 0] - u, uv[..., 1] - v
            err = ex * ex + ey * ey
            improved = active & inside & (err < best)
            best_x, best_y, best = (np.where(improved, x, best_x), np.where(improved, y, best_y),
                                    np.where(improved, err, best))  # fmt: skip
            active = improved & (err >= 1e-22) & (step + 1 < passes)
            if not active.any():
                break
            det = jxx * jyy - jxy * jyx
            det = np.where(det == 0, 1.0, det)
            x = np.where(active, x + (jyy * ex - jxy * ey) / det, x)
            y = np.where(active, y + (-jyx * ex + jxx * ey) / det, y)
        found = inside & (best <= 1e-6)
        return np.stack([best_x, best_y], axis=-1), found


@dataclass(frozen=True)
class DeviceCalibration:
    """A recording's calibration: its cameras by location (``depth`` and ``color``) and the
    attachment's ``Metadata`` (serial number, factory date...)."""

    cameras: dict[str, CameraCalibration]
    metadata: dict

    def depth_intrinsics(self, mode: str) -> Intrinsics:
        """The depth camera's intrinsics in ``mode``'s pixels (``NFOV_UNBINNED``...)."""
        if mode not in DEPTH_MODES:
            raise CalibrationError(f"depth mode {mode!r} is not one of {', '.join(DEPTH_MODES)}")
        camera = self._camera("depth")
        if camera.sensor_size != (1024, 1024):
            raise CalibrationError(
                f"the depth camera's sensor is {camera.sensor_size}, not the 1024 x 1024 its modes crop"
            )
        return camera.in_pixels(*DEPTH_MODES[mode])

    def color_intrinsics(self, height: int) -> Intrinsics:
        """The colour camera's intrinsics for images ``height`` pixels high (720, 1080, ... 3072)."""
        if height not in COLOR_MODES:
            raise CalibrationError(f"no colour mode is {height} pixels high ({', '.join(map(str, COLOR_MODES))})")
        camera = self._camera("color")
        width, sensor_height = camera.sensor_size
        binned, crop, output = COLOR_MODES[height]
        if width * 9 // 16 != sensor_height and width * 3 // 4 != sensor_height:
            raise CalibrationError(f"the colour camera's sensor is {width} x {sensor_height}: neither 16:9 nor 4:3")
        if width * 9 // 16 == sensor_height:  # a 16:9 calibration: the SDK first takes it to 4:3
            p = list(camera.parameters)
            p[1], p[3] = (p[1] * 2304 + 384) / 3072, p[3] * 2304 / 3072
            camera = CameraCalibration(camera.location, camera.model, tuple(p), (4096, 3072), camera.metric_radius,
                                       camera.rotation, camera.translation_m)  # fmt: skip
        return camera.in_pixels(binned, crop, output)

    def _camera(self, which: str) -> CameraCalibration:
        if which not in self.cameras:
            raise CalibrationError(f"the calibration has no {which} camera")
        return self.cameras[which]


LOCATIONS = {"CALIBRATION_CameraLocationD0": "depth", "CALIBRATION_CameraLocationPV0": "color"}


def read_calibration(raw: bytes, *, source: str = "calibration.json") -> DeviceCalibration:
    """The calibration in a recording's ``calibration.json`` attachment."""
    try:
        info = json.loads(raw.rstrip(b"\0").decode("utf-8"))["CalibrationInformation"]
        cameras = {}
        for camera in info.get("Cameras", []):
            which = LOCATIONS.get(camera["Location"])
            if which is None:
                continue
            intrinsics = camera["Intrinsics"]
            model = MODELS.get(intrinsics["ModelType"])
            if model is None:
                raise CalibrationError(
                    f"{source}: the {which} camera's lens model {intrinsics['ModelType']!r} is not one the SDK "
                    f"unprojects ({', '.join(MODELS)})"
                )
            count = int(intrinsics.get("ModelParameterCount", len(intrinsics["ModelParameters"])))
            values = [float(v) for v in intrinsics["ModelParameters"][: min(count, 15)]]
            if len(values) < 14:
                raise CalibrationError(f"{source}: the {which} camera has {len(values)} lens parameters, 14 needed")
            if not (values[2] > 0 and values[3] > 0):
                raise CalibrationError(f"{source}: the {which} camera's focal lengths must be positive: {values[2:4]}")
            rt = camera["Rt"]
            cameras[which] = CameraCalibration(
                location=camera["Location"],
                model=model,
                parameters=tuple(values + [0.0] * (15 - len(values))),
                sensor_size=(int(camera["SensorWidth"]), int(camera["SensorHeight"])),
                metric_radius=float(camera["MetricRadius"]),
                rotation=np.asarray(rt["Rotation"], dtype=np.float64).reshape(3, 3),
                translation_m=np.asarray(rt["Translation"], dtype=np.float64).reshape(3),
            )
        return DeviceCalibration(cameras, dict(info.get("Metadata", {})))
    except CalibrationError:
        raise
    except (ValueError, KeyError, TypeError, AttributeError, IndexError, OverflowError, RecursionError) as exc:
        what = f"no {exc}" if isinstance(exc, KeyError) else str(exc)
        raise CalibrationError(f"{source}: not an Azure Kinect calibration ({what})") from None


def depth_to_points(depth_mm: np.ndarray, intrinsics: Intrinsics) -> np.ndarray:
    """Points [H, W, 3] in millimetres in the depth camera's frame (x right, y down, z forward) from
    a depth image [H, W] (uint16, mm); a pixel with no depth or no ray gives (0, 0, 0), as the
    SDK's point cloud does."""
    h, w = depth_mm.shape
    if (w, h) != tuple(intrinsics.size):
        raise CalibrationError(f"a {w} x {h} depth image in a mode of {intrinsics.size[0]} x {intrinsics.size[1]}")
    table, found = xy_table(intrinsics)
    z = np.where(found, depth_mm.astype(np.float32), np.float32(0))
    return np.concatenate([table * z[..., None], z[..., None]], axis=-1)


@functools.lru_cache(maxsize=4)
def xy_table(intrinsics: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """Every pixel's ray on the z = 1 plane [H, W, 2] and whether it has one [H, W] (computed once
    per mode and kept: read-only arrays)."""
    w, h = intrinsics.size
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    table, found = intrinsics.unproject(np.stack([u, v], axis=-1))
    table = table.astype(np.float32)
    table.flags.writeable = found.flags.writeable = False
    return table, found
