"""The synthetic session as OpenPose would see it: BODY_25 detections in ``--write_json`` files.

Clock. The video covers the skeleton recording's span on the recording clock: video frame ``k``
is at ``k / video_fps`` seconds, so the session's offset applies unchanged
(``audio_time = video_time + offset_s``). The noise-free 3-D motion (Kinect v2 camera space) is
interpolated to the frame times with a cubic spline and projected by :class:`PinholeCamera`.

BODY_25 keypoints from Kinect v2 joints (OpenPose "R" = Kinect "Right" = the person's right):

- Nose, REye, LEye, REar, LEar: Head + :data:`FACE_OFFSETS_M`;
- Neck: SpineShoulder; MidHip: SpineBase;
- RShoulder, RElbow, RWrist: ShoulderRight, ElbowRight, WristRight (L likewise from the Left joints);
- RHip, RKnee, RAnkle: HipRight, KneeRight, AnkleRight (L likewise);
- RBigToe, RSmallToe, RHeel: FootRight, FootRight, AnkleRight + :data:`FOOT_OFFSETS_M` (L likewise).

A face keypoint on the far side of the head (an ear or eye of a person in profile, see
:data:`FACE_HIDDEN_COS`) and a keypoint outside the image are not detected.

Detections (:class:`DetectorModel`): Gaussian pixel noise, a uniform confidence, missed keypoints
(x = y = c = 0, as OpenPose writes them) isolated and in bursts of several frames, and frames where
the dancer is not detected at all. A passer-by (the generator's body walking upright, in profile,
nearer or farther than the dancer) crosses the image for a few seconds and is sometimes listed
before the dancer. Everything is deterministic from the seed.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from kinectdata.core.atomic import durable, flush_file, sync_folder
from kinectdata.core.errors import KinectDataError
from kinectdata.synth.dancer import Body, make_body
from kinectdata.synth.recording import AUDIO_FORMATS, SynthRecording, regeneration_command, write_audio, write_truth

BODY_25 = (
    "Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist", "MidHip",
    "RHip", "RKnee", "RAnkle", "LHip", "LKnee", "LAnkle", "REye", "LEye", "REar", "LEar",
    "LBigToe", "LSmallToe", "LHeel", "RBigToe", "RSmallToe", "RHeel",
)  # fmt: skip
"""OpenPose BODY_25 keypoint order."""
KINECT_SOURCE = {
    "Neck": "SpineShoulder",
    "RShoulder": "ShoulderRight",
    "RElbow": "ElbowRight",
    "RWrist": "WristRight",
    "LShoulder": "ShoulderLeft",
    "LElbow": "ElbowLeft",
    "LWrist": "WristLeft",
    "MidHip": "SpineBase",
    "RHip": "HipRight",
    "RKnee": "KneeRight",
    "RAnkle": "AnkleRight",
    "LHip": "HipLeft",
    "LKnee": "KneeLeft",
    "LAnkle": "AnkleLeft",
}
"""BODY_25 keypoints taken directly from a Kinect v2 joint."""
FACE_OFFSETS_M = {
    "Nose": (0.0, -0.02, 0.10),
    "REye": (0.032, 0.03, 0.08),
    "LEye": (-0.032, 0.03, 0.08),
    "REar": (0.075, 0.0, -0.01),
    "LEar": (-0.075, 0.0, -0.01),
}
"""Face keypoints from the Kinect Head joint (the centre of the head), metres, in the person's
(right, up, forward) axes: right along the shoulder line (ShoulderLeft -> ShoulderRight) made
horizontal, up = camera +y, forward = up x right (where the chest faces)."""
FOOT_OFFSETS_M = {
    "BigToe": ("Foot", (-0.02, 0.0, 0.06)),
    "SmallToe": ("Foot", (0.035, 0.0, 0.03)),
    "Heel": ("Ankle", (0.0, -0.07, -0.05)),
}
"""Foot keypoints: (Kinect joint of the same side, offset in metres in the foot's (out, up, forward)
axes): forward along Ankle -> Foot, out = forward x camera-up for the right foot (its negative for
the left), up = out x forward for the right foot."""
FACE_HIDDEN_COS = -0.25
"""A face keypoint is hidden behind the head where the cosine between its horizontal offset and the
horizontal direction from the head to the camera is below this."""
SEED_STREAM = 2507
"""Spawn key of the detections' random streams, apart from the session's own streams."""


@dataclass(frozen=True)
class PinholeCamera:
    """A distortion-free colour camera at the origin of Kinect camera space, looking along +z.

    Image axes: x right, y down, pixels, (0, 0) at the centre of the top-left pixel. Kinect x points
    to the sensor's left and y up, so ``x = cx - f X / Z`` and ``y = cy - f Y / Z``. The defaults
    resemble the Kinect v2 colour camera (1920 x 1080, focal length about 1060 px, principal point
    at the image centre); the real one sits about 5 cm beside the depth camera, ignored here.
    """

    width_px: int = 1920
    height_px: int = 1080
    focal_px: float = 1060.0
    cx_px: float = 959.5
    cy_px: float = 539.5

    def project(self, points: np.ndarray) -> np.ndarray:
        """[..., 3] camera-space points (metres) -> [..., 2] pixels; NaN for points not in front (Z <= 0)."""
        p = np.asarray(points, dtype=np.float64)
        z = np.where(p[..., 2] > 0, p[..., 2], np.nan)
        return np.stack([self.cx_px - self.focal_px * p[..., 0] / z, self.cy_px - self.focal_px * p[..., 1] / z], -1)

    def inside(self, pixels: np.ndarray) -> np.ndarray:
        """[...] bool: pixel positions [..., 2] that fall on the image (False for NaN)."""
        x, y = pixels[..., 0], pixels[..., 1]
        with np.errstate(invalid="ignore"):
            return (x >= -0.5) & (x < self.width_px - 0.5) & (y >= -0.5) & (y < self.height_px - 0.5)

    def half_view(self) -> float:
        """Half the horizontal field of view as a slope: |X| / Z at the image's side edges."""
        return (self.cx_px + 0.5) / self.focal_px


@dataclass(frozen=True)
class DetectorModel:
    """What the pose detector gets wrong (pixels, probabilities per keypoint or frame)."""

    noise_sd_px: float = 2.0
    """Standard deviation of the Gaussian noise added to x and to y, pixels."""
    confidence_range: tuple[float, float] = (0.4, 0.95)
    """Confidences are uniform in this range."""
    isolated_miss_rate: float = 0.02
    """Per keypoint and frame: missed on its own."""
    burst_start_rate: float = 0.006
    """Per keypoint and frame: a burst of missed frames starts."""
    burst_frames: tuple[int, int] = (3, 8)
    """Burst length, frames (uniform, inclusive)."""
    frame_miss_rate: float = 0.01
    """Per frame: the dancer is not detected at all (a video of 200 frames or more has one at least)."""
    passer_first_probability: float = 0.4
    """Per frame with both people: the passer-by is listed first."""

    @property
    def miss_rate(self) -> float:
        """Expected fraction of missed keypoints in a long video (isolated or inside a burst)."""
        lo, hi = self.burst_frames
        lengths = np.arange(lo, hi + 1)
        # Frame i is inside a burst that started d frames earlier if one started then, longer than d.
        outside = np.prod([1.0 - self.burst_start_rate * np.mean(lengths > d) for d in range(hi)])
        return float(1.0 - (1.0 - self.isolated_miss_rate) * outside)


@dataclass
class OpenPoseVideo:
    """Synthetic BODY_25 detections of a session's video.

    Attributes:
        times: [N] frame times, seconds, recording clock (``k / video_fps``).
        dancer: [N, 25, 3] detections (x, y pixels, confidence); zeros where missed.
        dancer_true: [N, 25, 2] noise-free projection, pixels (NaN behind the camera).
        dancer_detected: [N] bool, False where the dancer is missing from the frame.
        passer: [N, 25, 3], ``passer_true`` [N, 25, 2], ``passer_detected`` [N] likewise.
        passer_first: [N] bool, frames where the passer-by is listed before the dancer.
        info: the truth file's ``"openpose"`` section (JSON-ready).
    """

    times: np.ndarray
    dancer: np.ndarray
    dancer_true: np.ndarray
    dancer_detected: np.ndarray
    passer: np.ndarray
    passer_true: np.ndarray
    passer_detected: np.ndarray
    passer_first: np.ndarray
    info: dict[str, Any]

    @property
    def n_frames(self) -> int:
        return int(self.times.size)

    def people(self, frame: int) -> list[np.ndarray]:
        """The [25, 3] detections of one frame in the order OpenPose lists them."""
        found = [self.dancer[frame]] if self.dancer_detected[frame] else []
        if self.passer_detected[frame]:
            found.insert(0 if self.passer_first[frame] else len(found), self.passer[frame])
        return found


# -- geometry ----------------------------------------------------------------------------------
def body25_points(positions: np.ndarray, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """BODY_25 keypoints in camera space from Kinect v2 joints (see the module's docstring).

    Args:
        positions: [T, J, 3] Kinect v2 camera-space positions, metres.
        names: the J joint names of ``positions`` (must include the 25 Kinect v2 joints used).

    Returns:
        ``(points, seen)``: [T, 25, 3] metres and [T, 25] bool, False for face keypoints on the
        far side of the head.
    """
    p = {n: positions[:, i] for i, n in enumerate(names)}
    up = np.array([0.0, 1.0, 0.0])
    out = np.zeros(positions.shape[:1] + (len(BODY_25), 3))
    seen = np.ones(out.shape[:2], bool)
    for name, joint in KINECT_SOURCE.items():
        out[:, BODY_25.index(name)] = p[joint]
    right = _unit((p["ShoulderRight"] - p["ShoulderLeft"]) * [1.0, 0.0, 1.0])
    forward = np.cross(up, right)
    head = p["Head"]
    to_camera = _unit(-head * [1.0, 0.0, 1.0])
    for name, (r, u, f) in FACE_OFFSETS_M.items():
        horizontal = r * right + f * forward
        out[:, BODY_25.index(name)] = head + horizontal + u * up
        seen[:, BODY_25.index(name)] = np.sum(_unit(horizontal) * to_camera, -1) > FACE_HIDDEN_COS
    for side, sign in (("R", 1.0), ("L", -1.0)):
        kinect = "Right" if side == "R" else "Left"
        toe = _unit(p[f"Foot{kinect}"] - p[f"Ankle{kinect}"])
        lateral = _unit(np.cross(toe, up))  # the person's right for a foot pointing forward
        foot_up = np.cross(lateral, toe)
        for name, (joint, (o, u, f)) in FOOT_OFFSETS_M.items():
            out[:, BODY_25.index(side + name)] = p[f"{joint}{kinect}"] + sign * o * lateral + u * foot_up + f * toe
    return out, seen


@dataclass(frozen=True)
class Walk:
    """The passer-by's path: straight across the view at a fixed depth, in profile.

    ``direction`` +1 walks along camera +x (towards the image's left), -1 along -x (to its right);
    ``start_s`` is when the walk starts, :attr:`MARGIN_M` beyond the image's side edge (recording
    clock); it ends as far beyond the other edge.
    """

    MARGIN_M: ClassVar[float] = 0.6

    height_m: float
    depth_m: float
    speed_m_s: float
    direction: float
    start_s: float
    phase: float

    def start_x(self, camera: PinholeCamera) -> float:
        """Where the walk starts, camera x, metres."""
        return -self.direction * (camera.half_view() * self.depth_m + self.MARGIN_M)


def walker_positions(body: Body, walk: Walk, times: np.ndarray, floor_y: float, camera: PinholeCamera) -> np.ndarray:
    """[T, 25, 3] Kinect v2 joint positions (metres, camera space) of ``body`` walking along ``walk``.

    Straight legs and arms swing about the hips and shoulders (a step of 0.41 body heights, arms
    opposite the legs); the pelvis dips as the legs part, so the feet stay near the floor.
    """
    js = body.joint_set
    leg_m = body.root_height_m
    step_m = 0.41 * body.height_m
    swing = np.arcsin(step_m / (2 * leg_m)) * np.sin(np.pi * walk.speed_m_s / step_m * times + walk.phase)
    pos = np.tile(body.rest_positions, (times.size, 1, 1))
    for side, sign in (("Right", 1.0), ("Left", -1.0)):
        _swing(pos, js.names, f"Hip{side}", [f"{n}{side}" for n in ("Knee", "Ankle", "Foot")], sign * swing)
        arm = [f"{n}{side}" for n in ("Elbow", "Wrist", "Hand", "HandTip", "Thumb")]
        _swing(pos, js.names, f"Shoulder{side}", arm, -0.6 * sign * swing)
    yaw = Rotation.from_euler("y", -walk.direction * np.pi / 2)  # rest faces -z; walk faces +-x
    root = np.stack(
        [
            walk.start_x(camera) + walk.direction * walk.speed_m_s * (times - walk.start_s),
            floor_y + body.root_height_m - leg_m * (1 - np.cos(swing)),
            np.full(times.size, walk.depth_m),
        ],
        axis=1,
    )
    return yaw.apply(pos.reshape(-1, 3)).reshape(pos.shape) + root[:, None]


def _swing(pos: np.ndarray, names: Sequence[str], pivot: str, joints: Sequence[str], angle: np.ndarray) -> None:
    """Turn ``joints`` about ``pivot`` by ``angle`` [T] radians about the body's +x (rest) axis:
    positive angles move a hanging limb forward (-z)."""
    rot = Rotation.from_rotvec(angle[:, None] * [1.0, 0.0, 0.0])
    c = names.index(pivot)
    for name in joints:
        j = names.index(name)
        pos[:, j] = pos[:, c] + rot.apply(pos[:, j] - pos[:, c])


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


# -- detections --------------------------------------------------------------------------------
def _draw_walk(rng: np.random.Generator, video_s: float, camera: PinholeCamera) -> Walk:
    """The passer-by: nearer (1.5-1.8 m) or farther (3.3-3.9 m) than the dancer, walking at
    1.1-1.6 m/s; in view for at most 40 % of the video (near and faster when the video is short)."""
    height = rng.uniform(1.55, 1.90)
    near = rng.random() < 0.5
    depths = (rng.uniform(1.5, 1.8), rng.uniform(3.3, 3.9))
    speed = rng.uniform(1.1, 1.6)
    direction = float(rng.choice([-1.0, 1.0]))
    start_u, phase = rng.random(), rng.uniform(0, 2 * np.pi)
    max_view_s = 0.4 * video_s

    def view_s(depth):
        return 2 * camera.half_view() * depth / speed

    depth = depths[0] if near or view_s(depths[1]) > max_view_s else depths[1]
    speed = max(speed, 2 * camera.half_view() * depth / max_view_s)
    walk_s = 2 * (camera.half_view() * depth + Walk.MARGIN_M) / speed
    start = start_u * max(video_s - walk_s, 0.0)
    return Walk(float(height), float(depth), float(speed), direction, float(start), float(phase))


def _detect(
    true_px: np.ndarray, seen: np.ndarray, rng: np.random.Generator, model: DetectorModel, camera: PinholeCamera
) -> tuple[np.ndarray, np.ndarray]:
    """Noisy detections [N, 25, 3] of true pixel positions [N, 25, 2] visible where ``seen`` [N, 25].

    Returns ``(detections, missed)``: zeros where not seen or missed; ``missed`` [N, 25] marks the
    keypoints the detector dropped (isolated or in bursts), seen or not.
    """
    N, K = seen.shape
    xy = true_px + rng.normal(0.0, model.noise_sd_px, true_px.shape)
    conf = rng.uniform(*model.confidence_range, (N, K))
    missed = rng.random((N, K)) < model.isolated_miss_rate
    starts = rng.random((N, K)) < model.burst_start_rate
    lengths = rng.integers(model.burst_frames[0], model.burst_frames[1] + 1, (N, K))
    for d in range(model.burst_frames[1]):
        missed[d:] |= starts[: N - d] & (lengths[: N - d] > d)
    keep = seen & ~missed
    xy[..., 0] = np.clip(xy[..., 0], 0.0, camera.width_px - 1.0)
    xy[..., 1] = np.clip(xy[..., 1], 0.0, camera.height_px - 1.0)
    out = np.where(keep[..., None], np.concatenate([xy, conf[..., None]], axis=-1), 0.0)
    return out, missed


def synthesize_openpose(
    rec: SynthRecording,
    *,
    video_fps: float = 30.0,
    seed: int | None = None,
    model: DetectorModel = DetectorModel(),
    camera: PinholeCamera = PinholeCamera(),
) -> OpenPoseVideo:
    """OpenPose BODY_25 detections of a video of the session (pure: no files).

    Args:
        rec: a session from :func:`~kinectdata.synth.synthesize_recording` (needs ``true_motion``).
        video_fps: frames per second; frame ``k`` is at ``k / video_fps`` s on the recording clock,
            up to the recording's last frame.
        seed: seed of the detections and the passer-by; default the session's seed.
        model: detection noise and misses.
        camera: the colour camera.

    Returns:
        An :class:`OpenPoseVideo`; its ``info`` states the camera, the noise, the missed frames and
        which detection is the dancer in each frame.
    """
    true = rec.true_motion
    if true is None or true.joint_set.name != "kinect_v2":
        raise KinectDataError("OpenPose output needs the session's noise-free Kinect v2 motion (rec.true_motion)")
    if not (np.isfinite(video_fps) and video_fps > 0):
        raise KinectDataError(f"video_fps must be a positive number of frames per second, got {video_fps!r}")
    seed = rec.options["seed"] if seed is None else seed
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise KinectDataError(f"seed must be a non-negative integer, got {seed!r}")
    s_walk, s_dancer, s_passer = np.random.SeedSequence(int(seed), spawn_key=(SEED_STREAM,)).spawn(3)
    n = int(np.floor(true.times[-1] * video_fps + 1e-9)) + 1
    times = np.arange(n) / video_fps
    names = true.joint_set.names

    dancer_3d, dancer_seen = body25_points(CubicSpline(true.times, true.positions, axis=0)(times), names)
    dancer_true = camera.project(dancer_3d)
    rng = np.random.default_rng(s_dancer)
    dancer, missed = _detect(dancer_true, dancer_seen & camera.inside(dancer_true), rng, model, camera)
    dancer_detected = rng.random(n) >= model.frame_miss_rate
    if dancer_detected.all() and n >= 200:
        dancer_detected[int(rng.integers(n))] = False

    rng = np.random.default_rng(s_walk)
    walk = _draw_walk(rng, float(times[-1]), camera)
    floor_y = rec.truth["dancer"]["floor_y_m"]
    walker = walker_positions(make_body(walk.height_m), walk, times, floor_y, camera)
    passer_3d, passer_seen = body25_points(walker, names)
    passer_true = camera.project(passer_3d)
    passer_seen &= camera.inside(passer_true)
    passer_detected = passer_seen[:, BODY_25.index("Neck")] & passer_seen[:, BODY_25.index("MidHip")]
    rng = np.random.default_rng(s_passer)
    passer, _ = _detect(passer_true, passer_seen, rng, model, camera)
    both = passer_detected & dancer_detected
    passer_first = both & (rng.random(n) < model.passer_first_probability)
    if both.any() and not passer_first.any():
        both_frames = np.flatnonzero(both)
        passer_first[both_frames[both_frames.size // 2]] = True

    visible = (dancer_seen & camera.inside(dancer_true))[dancer_detected]
    info = {
        "layout": "BODY_25",
        "keypoints": list(BODY_25),
        "seed": int(seed),
        "video_fps": float(video_fps),
        "n_frames": n,
        "frame_times": "video frame k is at k / video_fps s on the recording clock: audio_time = video_time + offset_s",
        "image_size_px": [camera.width_px, camera.height_px],
        "camera": {
            **asdict(camera),
            "model": "pinhole, no distortion, at the origin of Kinect camera space: x = cx - f X / Z, y = cy - f Y / Z",
        },
        "detector": {**_lists(asdict(model)), "miss_rate": model.miss_rate},
        "noise_sd_px": model.noise_sd_px,
        "miss_rate": model.miss_rate,
        "dancer_missed_fraction": float(missed[dancer_detected][visible].mean()) if visible.any() else 0.0,
        "dancer": {
            "present_frames": int(dancer_detected.sum()),
            "missing_frames": np.flatnonzero(~dancer_detected).tolist(),
            "index": "people[0], except people[1] in passer_by.listed_first_frames; absent in missing_frames",
        },
        "passer_by": _passer_info(walk, passer_detected, passer_first, times, camera, np.median(dancer_3d[..., 2])),
    }
    return OpenPoseVideo(
        times=times,
        dancer=dancer,
        dancer_true=dancer_true,
        dancer_detected=dancer_detected,
        passer=passer,
        passer_true=passer_true,
        passer_detected=passer_detected,
        passer_first=passer_first,
        info=info,
    )


def _lists(fields: dict[str, Any]) -> dict[str, Any]:
    """Tuples as lists, as they come back from JSON."""
    return {k: list(v) if isinstance(v, tuple) else v for k, v in fields.items()}


def _passer_info(walk: Walk, detected, first, times, camera: PinholeCamera, dancer_depth: float) -> dict[str, Any]:
    frames = np.flatnonzero(detected)
    span = (int(frames[0]), int(frames[-1])) if frames.size else (None, None)
    return {
        "first_frame": span[0],
        "last_frame": span[1],
        "start_s": None if span[0] is None else float(times[span[0]]),
        "end_s": None if span[1] is None else float(times[span[1]]),
        "present_frames": int(frames.size),
        "listed_first_frames": np.flatnonzero(first).tolist(),
        "height_m": walk.height_m,
        "depth_m": walk.depth_m,
        "nearer_than_dancer": bool(walk.depth_m < dancer_depth),
        "speed_m_s": walk.speed_m_s,
        "walks": "right_to_left" if walk.direction > 0 else "left_to_right",
        "walk_start_s": walk.start_s,
        "walk_start_x_m": walk.start_x(camera),
    }


# -- files -------------------------------------------------------------------------------------
_EMPTY_PARTS = ",".join(
    f'"{k}":[]'
    for k in (
        "face_keypoints_2d",
        "hand_left_keypoints_2d",
        "hand_right_keypoints_2d",
        "pose_keypoints_3d",
        "face_keypoints_3d",
        "hand_left_keypoints_3d",
        "hand_right_keypoints_3d",
    )
)


def frame_json(people: Sequence[np.ndarray]) -> str:
    """One frame's file as OpenPose 1.7 ``--write_json`` writes it: one line, numbers with six
    significant digits (C++ stream defaults), missed keypoints as ``0,0,0``."""
    entries = []
    for kp in people:
        values = ",".join(f"{float(v):.6g}" for v in np.asarray(kp).reshape(-1))
        entries.append(f'{{"person_id":[-1],"pose_keypoints_2d":[{values}],{_EMPTY_PARTS}}}')
    return '{"version":1.3,"people":[' + ",".join(entries) + "]}"


def keypoint_file_name(stem: str, frame: int) -> str:
    """``<stem>_<frame:012d>_keypoints.json``, OpenPose's name for frame ``frame`` of video ``stem``."""
    return f"{stem}_{frame:012d}_keypoints.json"


def write_openpose_folder(video: OpenPoseVideo, folder: str | Path, stem: str) -> Path:
    """Write one keypoint file per frame into ``folder``, atomically.

    The files go to a hidden staging folder beside ``folder`` and the complete folder is renamed
    into place; an existing ``folder`` is replaced only then. On any error nothing is left behind
    (a crash leaves only the hidden ``.<name>.*.partial`` staging folder).
    """
    folder = Path(folder)
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", suffix=".partial", dir=folder.parent))
    except OSError as exc:
        raise KinectDataError(f"{folder}: cannot write here ({exc.strerror or exc})") from exc
    try:
        new = staging / folder.name
        new.mkdir()  # the user's umask applies, unlike mkdtemp's 0700
        for k in range(video.n_frames):
            (new / keypoint_file_name(stem, k)).write_text(frame_json(video.people(k)), encoding="utf-8")
        _fsync(new)
        old = staging / "replaced"
        if folder.exists():
            os.replace(folder, old)
        try:
            os.replace(new, folder)
        except OSError:
            if old.exists():
                os.replace(old, folder)
            raise
    except OSError as exc:
        raise KinectDataError(f"{folder}: cannot write the keypoint files ({exc.strerror or exc})") from exc
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return folder


def _fsync(folder: Path) -> None:
    """Flush a folder's files and the folder itself to disk (before it is renamed into place).

    One ``os.sync`` where there is one (POSIX): it flushes every written file at once, where a
    ``fsync`` per file commits the file system's journal once per file (1 800 keypoint files:
    about 3 s against 0.02 s on a virtual disk). Nothing when writes are not
    :func:`~kinectdata.core.atomic.durable`."""
    if not durable():
        return
    if hasattr(os, "sync"):
        os.sync()
        return
    for path in folder.iterdir():
        flush_file(path)
    sync_folder(folder)


def write_openpose_recording(
    rec: SynthRecording,
    out_dir: str | Path,
    stem: str,
    *,
    video_fps: float = 30.0,
    audio_format: str = "flac",
    seed: int | None = None,
    model: DetectorModel = DetectorModel(),
) -> dict[str, Path]:
    """Write ``<stem>.<flac|wav>`` (16-bit), ``<stem>_openpose/`` (one OpenPose BODY_25
    ``<stem>_<frame:012d>_keypoints.json`` per video frame) and ``<stem>.truth.json`` into
    ``out_dir`` (created if missing).

    Returns ``{"audio": path, "openpose": folder, "truth": path}``; the same arguments always give
    byte-identical files. The truth is the session's plus ``format``, ``audio_format``, ``files``,
    the full ``command`` (exact when ``seed`` is None) and the ``openpose`` section of
    :func:`synthesize_openpose` with ``folder`` and ``file_pattern``.
    """
    if audio_format not in AUDIO_FORMATS:
        raise KinectDataError(f"audio_format must be one of {sorted(AUDIO_FORMATS)}, got {audio_format!r}")
    video = synthesize_openpose(rec, video_fps=video_fps, seed=seed, model=model)
    out = Path(out_dir)
    paths = {
        "audio": out / f"{stem}.{audio_format}",
        "openpose": out / f"{stem}_openpose",
        "truth": out / f"{stem}.truth.json",
    }
    write_audio(rec, paths["audio"], audio_format)
    write_openpose_folder(video, paths["openpose"], stem)
    command = regeneration_command(rec.options, name=stem, audio_format=audio_format).removesuffix(" .")
    truth = {
        **rec.truth,
        "command": f"{command} --format openpose --video-fps {float(video_fps)!r} .",
        "format": "openpose",
        "audio_format": audio_format,
        "files": {k: p.name for k, p in paths.items()},
        "openpose": {
            **video.info,
            "folder": paths["openpose"].name,
            "file_pattern": f"{stem}_{{frame:012d}}_keypoints.json",
        },
    }
    write_truth(truth, paths["truth"])
    return paths
