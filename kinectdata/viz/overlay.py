"""A body tracker's skeleton drawn over the depth (or colour) frames of its take (``render --over take.mkv``).

The Azure Kinect body tracker's JSON (read as ``azure_json``: kinectdata's camera axes, x to the
sensor's left, y up, metres) holds each joint in the depth camera's frame, and each body frame's
device time is its depth frame's (:mod:`kinectdata.mkv.body`). So each body frame is placed on its
depth frame and each joint projected into it through the recording's calibration: the depth
camera's lens model (:meth:`kinectdata.mkv.calibration.Intrinsics.project`) at the point
(-x, -y, z), the SDK's axes (x right, y down). Depth is shown grey, near light and far dark
(:data:`DEPTH_RANGE_MM`), no depth black; bones in :mod:`.render`'s colours (the person's right
red, left blue), joints as white dots ringed in black. One output frame per depth frame a body
frame falls on, at the depth track's rate. Over the colour frames instead, each joint is taken into
the colour camera's frame by the calibration's ``Rt`` (from the depth camera's frame; translation
in metres) and projected through the colour camera's lens model in the colour mode's pixels; each
depth frame's colour frame is the one nearest its device time (a capture's colour and depth
differ by the recorder's ``K4A_DEPTH_DELAY_NS``).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from kinectdata.core.errors import KinectDataError
from kinectdata.core.motion import Motion

DEPTH_RANGE_MM = (500.0, 5000.0)
"""Depth shown from light (near) to dark (far), millimetres."""
JOINT_RADIUS_PX = 3
_SIDE_COLOURS = {"right": (214, 39, 40), "left": (31, 119, 180), "centre": (220, 220, 220)}


def project_joints(
    positions: np.ndarray, intrinsics, rotation=None, translation_mm=None
) -> tuple[np.ndarray, np.ndarray]:
    """Pixels [..., J, 2] of joints [..., J, 3] (kinectdata's camera axes, metres, in the depth
    camera's frame) in a camera's image, and whether each is seen (in front of the camera, within
    the lens model's radius, inside the image). ``rotation`` [3, 3] and ``translation_mm`` [3] take
    a point from the depth camera's frame (the SDK's axes, mm) to the camera's (a calibration's
    ``Rt``); None: the depth camera itself."""
    camera = np.asarray(positions, dtype=np.float64) * np.array([-1000.0, -1000.0, 1000.0])  # SDK axes, mm
    if rotation is not None:
        camera = camera @ np.asarray(rotation, dtype=np.float64).T + np.asarray(translation_mm, dtype=np.float64)
    z = camera[..., 2]
    ahead = z > 0
    xy = camera[..., :2] / np.where(ahead, z, 1.0)[..., None]
    uv, inside = intrinsics.project(xy)
    width, height = intrinsics.size
    u, v = uv[..., 0], uv[..., 1]
    seen = ahead & inside & np.isfinite(uv).all(axis=-1)
    return uv, seen & (u >= -0.5) & (u < width - 0.5) & (v >= -0.5) & (v < height - 0.5)


def depth_image(depth_mm: np.ndarray) -> np.ndarray:
    """uint8 RGB [H, W, 3] of a depth frame [H, W] (mm): near light, far dark, no depth black."""
    near, far = DEPTH_RANGE_MM
    level = 1.0 - np.clip((depth_mm.astype(np.float32) - near) / (far - near), 0.0, 1.0)
    grey = np.where(depth_mm > 0, 40 + 200 * level, 0).astype(np.uint8)
    return np.repeat(grey[..., None], 3, axis=-1)


@dataclass(frozen=True)
class Overlay:
    """What :func:`plan_overlay` matched: the track drawn on (``DEPTH`` or ``COLOR``), its frames
    to draw [N], the body frame on each [N], the joints' pixels [N, J, 2] and whether each is seen
    [N, J]; the track's rate and size; the placement's one-line summary."""

    track: str
    frames: np.ndarray
    body_frames: np.ndarray
    pixels: np.ndarray
    seen: np.ndarray
    fps: float
    size: tuple[int, int]
    summary: str


def plan_overlay(motion: Motion, take, *, start: float = 0.0, end: float | None = None, on: str = "DEPTH") -> Overlay:
    """Place the body frames of ``motion`` (an ``azure_json`` recording of the take ``take``) on
    its depth frames and project their joints into the frames of ``on``: ``DEPTH``, or ``COLOR``
    (the colour frame nearest each depth frame's device time, within half a colour frame period;
    the joints taken into the colour camera's frame by the calibration's ``Rt``); only body
    frames from ``start`` to ``end`` seconds of the motion."""
    from kinectdata.mkv.body import nearest_frames, place_body_frames, tracker_stamps_us

    if motion.metadata.get("format") != "azure_json" or motion.joint_set.dimensions != 3:
        raise KinectDataError(
            f"{motion.metadata.get('source', 'the motion')}: only the body tracker's JSON of the take (azure_json, "
            "joints in the depth camera's frame) can be drawn over its frames"
        )
    placement = place_body_frames(tracker_stamps_us(motion), take)
    chosen = placement.frame >= 0
    chosen &= motion.times >= start
    if end is not None:
        chosen &= motion.times < end
    if not chosen.any():
        raise KinectDataError(f"{take.path}: {placement.describe()}; nothing to draw")
    bodies = np.flatnonzero(chosen)
    frames = placement.frame[bodies]
    calibration = take.calibration()
    track = take.track(on)
    if on == "DEPTH":
        pixels, seen = project_joints(motion.positions[bodies], calibration.depth_intrinsics(take.depth_mode()))
        size = (track.width, track.height)
    else:
        depth_times = take.track("DEPTH").times_us[frames]
        frames, _ = nearest_frames(depth_times, track.times_us, (track.frame_period_ns or 33_333_333) / 2000)
        bodies, frames = bodies[frames >= 0], frames[frames >= 0]
        if not len(frames):
            raise KinectDataError(f"{take.path}: no {on} frame near the depth frames the body frames fall on")
        camera = calibration.cameras.get("color")
        if camera is None:
            raise KinectDataError(f"{take.path}: the calibration has no colour camera")
        intrinsics = calibration.color_intrinsics(track.height)
        pixels, seen = project_joints(
            motion.positions[bodies], intrinsics, camera.rotation, camera.translation_m * 1000.0
        )
        size = intrinsics.size
    seen &= motion.position_mask[bodies]
    fps = 1e9 / track.frame_period_ns if track.frame_period_ns else 30.0
    return Overlay(on, frames, bodies, pixels, seen, fps, tuple(size), placement.describe())


def draw_overlays(motion: Motion, take, plan: Overlay) -> Iterator[np.ndarray]:
    """Each planned frame (depth, or colour) with its body drawn: uint8 RGB [H, W, 3]."""
    from PIL import Image, ImageDraw

    from kinectdata.core.jointsets import joint_side

    names = motion.joint_set.names
    bones = motion.joint_set.bones()  # (parent, child)
    colours = [_SIDE_COLOURS[joint_side(names[child])] for _, child in bones]
    track = take.track(plan.track)
    for k, index in enumerate(plan.frames.tolist()):
        raw = take.frame(track, index)
        image = Image.fromarray(depth_image(raw) if plan.track == "DEPTH" else raw)
        draw = ImageDraw.Draw(image)
        uv, seen = plan.pixels[k], plan.seen[k]
        for (parent, child), colour in zip(bones, colours):
            if seen[child] and seen[parent]:
                draw.line([tuple(uv[parent]), tuple(uv[child])], fill=colour, width=2)
        r = JOINT_RADIUS_PX
        for j in np.flatnonzero(seen):
            u, v = uv[j]
            draw.ellipse([u - r, v - r, u + r, v + r], fill=(255, 255, 255), outline=(0, 0, 0))
        yield np.asarray(image)


def render_overlay(
    motion: Motion,
    take_path,
    out,
    *,
    start: float = 0.0,
    end: float | None = None,
    on: str = "DEPTH",
    progress=None,
) -> dict:
    """Write ``motion`` (the take's body-tracking JSON, read) drawn over the frames of the
    recording ``take_path`` (``on``: its ``DEPTH`` or ``COLOR`` track) to ``out`` (.mp4 or .gif,
    atomically), at that track's rate and size, no sound. Returns what was written: frames, fps,
    size, the placement's summary."""
    import warnings

    from kinectdata.mkv import K4aRecording

    from .render import animation_kind, write_animation

    kind = animation_kind(out)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a cut-short take still has its frames; `mkv info` says why
        take = K4aRecording(take_path)
    with take:
        plan = plan_overlay(motion, take, start=start, end=end, on=on)
        total = len(plan.frames)

        def frames():
            for k, frame in enumerate(draw_overlays(motion, take, plan)):
                if progress:
                    progress(k + 1, total)
                yield frame

        count = write_animation(kind, frames(), out, plan.fps, plan.size)
    return {"frames": count, "fps": plan.fps, "size": plan.size, "placement": plan.summary}
