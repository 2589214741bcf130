"""Skeletons for ``.oni`` recordings: NiTE2's user tracker, and timelines taken from an ``.oni``.

An ``.oni`` holds depth and colour, never skeletons. :func:`track_skeleton` plays a recording
back through NiTE2's user tracker (PrimeSense's closed library, which kinectdata cannot ship:
install it and point ``nite_dir`` or ``NITE2_REDIST64`` at the folder with ``libNiTE2.so`` and
its ``NiTE2/`` data folder) and returns the tracked body as a :class:`~kinectdata.core.motion.Motion`
of the ``nite`` joint set (15 joints, metres, quaternions x, y, z, w), timed by the recording's
own depth timestamps. :func:`nite_motion` is the conversion alone, from the tracker's per-frame
joints. :func:`oni_timeline` and :func:`retime` give a skeleton recorded beside an ``.oni``
(one skeleton frame per depth frame) the ``.oni``'s timestamps.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from kinectdata.core.errors import KinectDataError, KinectDataWarning
from kinectdata.core.jointsets import load_joint_set
from kinectdata.core.motion import Motion
from kinectdata.oni.reader import OniFile, OniWarning

NITE_LIBRARY = "libNiTE2.so"
NITE_JOINTS = 15
OPENNI2_LIBRARY_DIRS = ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib", "/usr/local/lib")


class TrackingWarning(KinectDataWarning):
    """NiTE2 tracked only part of a recording."""


@dataclass(frozen=True)
class TrackedFrame:
    """One user-tracker frame: the depth frame's timestamp (us) and index, and per tracked user
    [15, 9] float: x, y, z (mm), position confidence, qx, qy, qz, qw, orientation confidence."""

    timestamp_us: int
    frame_index: int
    users: dict[int, np.ndarray]


def nite_search_dirs(nite_dir: str | os.PathLike | None = None) -> list[Path]:
    """Where NiTE2 is looked for, in order: ``nite_dir``, ``$NITE2_REDIST64``, ``$NITE2_REDIST``,
    ``./NiTE2``, the current folder, ``/usr/lib``, ``/usr/local/lib``, ``/opt/NiTE2*/Redist``."""
    dirs = [Path(nite_dir)] if nite_dir else []
    dirs += [Path(os.environ[v]) for v in ("NITE2_REDIST64", "NITE2_REDIST") if os.environ.get(v)]
    dirs += [Path("NiTE2"), Path("."), Path("/usr/lib"), Path("/usr/local/lib")]
    dirs += sorted(Path("/opt").glob("NiTE*/Redist")) if Path("/opt").is_dir() else []
    return dirs


def find_nite(nite_dir: str | os.PathLike | None = None) -> Path:
    """The folder holding ``libNiTE2.so``.

    Raises:
        KinectDataError: NiTE2 is nowhere it is looked for; the message lists those places.
    """
    searched = nite_search_dirs(nite_dir)
    for folder in searched:
        if (folder / NITE_LIBRARY).is_file():
            return folder.resolve()
    raise KinectDataError(
        f"NiTE2 is not installed: no {NITE_LIBRARY} in "
        + ", ".join(str(d) for d in searched)
        + ". NiTE2 (PrimeSense's skeleton tracker) is not distributed with kinectdata: install it and pass "
        "--nite DIR (the folder with libNiTE2.so and its NiTE2/ data folder) or set NITE2_REDIST64"
    )


def openni2_dir() -> Path:
    """A folder with ``libOpenNI2.so`` and ``OpenNI2/Drivers``, as the ``openni`` bindings want:
    ``$OPENNI2_REDIST64`` or ``$OPENNI2_REDIST`` when set, a system folder that has both, or a
    cache folder of links to Debian's ``libopenni2-0`` files (``libOpenNI2.so.0``).

    Raises:
        KinectDataError: OpenNI2 is not installed.
    """
    for variable in ("OPENNI2_REDIST64", "OPENNI2_REDIST"):
        folder = os.environ.get(variable)
        if folder and (Path(folder) / "libOpenNI2.so").exists() and (Path(folder) / "OpenNI2" / "Drivers").is_dir():
            return Path(folder)
    for d in map(Path, OPENNI2_LIBRARY_DIRS):
        if not (d / "OpenNI2" / "Drivers").is_dir():
            continue
        if (d / "libOpenNI2.so").exists():
            return d
        if (d / "libOpenNI2.so.0").exists():
            cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "kinectdata" / "openni2"
            try:
                cache.mkdir(parents=True, exist_ok=True)
            except OSError:
                cache = Path(tempfile.gettempdir()) / f"kinectdata-openni2-{os.getuid()}"
                cache.mkdir(exist_ok=True)
            for link, target in (("libOpenNI2.so", d / "libOpenNI2.so.0"), ("OpenNI2", d / "OpenNI2")):
                if not (cache / link).exists():
                    (cache / link).symlink_to(target)
            return cache
    raise KinectDataError(
        "OpenNI2 is not installed (no libOpenNI2.so with an OpenNI2/Drivers folder in "
        + ", ".join(OPENNI2_LIBRARY_DIRS)
        + "): apt-get install libopenni2-0, or set OPENNI2_REDIST64"
    )


def nite_motion(frames: Sequence[TrackedFrame], source: str, user: int | None = None) -> Motion:
    """The tracked body of a user as a Motion of the ``nite`` joint set.

    ``user``: a user id, or None for the user whose skeleton was tracked in the most frames.
    Times are the depth timestamps in seconds from the user's first tracked frame (the first
    timestamp itself is kept as ``metadata["time_origin"]`` in microseconds); positions are
    metres; a joint with position confidence 0 is masked, an orientation with confidence 0 or a
    zero quaternion likewise; ``confidence`` is the position confidence.

    Raises:
        KinectDataError: no skeleton was tracked, or not for ``user``.
    """
    counts: dict[int, int] = {}
    for f in frames:
        for uid in f.users:
            counts[uid] = counts.get(uid, 0) + 1
    if not counts:
        raise KinectDataError(f"{source}: NiTE2 tracked no skeleton in {len(frames)} frames")
    if user is None:
        user = max(sorted(counts), key=lambda u: counts[u])
    elif user not in counts:
        raise KinectDataError(f"{source}: user {user} was never tracked; tracked users: {sorted(counts)}")
    picked = [f for f in frames if user in f.users]
    joints = np.stack([np.asarray(f.users[user], dtype=np.float64) for f in picked])  # [T, 15, 9]
    stamps = np.array([f.timestamp_us for f in picked], dtype=np.float64)
    keep = np.concatenate([[True], np.diff(stamps) > 0])  # a repeated timestamp is the same depth frame
    joints, stamps = joints[keep], stamps[keep]
    conf = np.clip(joints[..., 3], 0.0, 1.0)
    valid = conf > 0
    positions = np.where(valid[..., None], joints[..., 0:3] / 1000.0, np.nan)
    quats = joints[..., 4:8]
    norms = np.linalg.norm(quats, axis=-1)
    qvalid = (joints[..., 8] > 0) & (norms > 0)
    orientations = np.where(qvalid[..., None], quats / np.where(norms > 0, norms, 1.0)[..., None], np.nan)
    return Motion(
        (stamps - stamps[0]) / 1e6,
        positions,
        load_joint_set("nite"),
        position_mask=valid,
        confidence=np.where(valid, conf, 0.0),
        orientations=orientations,
        orientation_mask=qvalid,
        metadata={
            "format": "nite2",
            "source": source,
            "user": int(user),
            "time_origin": {"value": float(stamps[0]), "unit": "us"},
            "depth_frame_indices": [int(f.frame_index) for f, k in zip(picked, keep) if k],
        },
    )


def tracked_users(tracker, frame, nite2) -> dict[int, np.ndarray]:
    """Per user whose skeleton NiTE2 tracks in ``frame``, [15, 9] joint rows (see
    :class:`TrackedFrame`); tracking is started for users that just appeared."""
    users = {}
    for u in frame.users:
        if u.is_new():
            tracker.start_skeleton_tracking(u.id)
        elif u.skeleton.state == nite2.SkeletonState.NITE_SKELETON_TRACKED:
            joints = (u.skeleton.joints[k] for k in range(NITE_JOINTS))
            users[int(u.id)] = np.array(
                [
                    [j.position.x, j.position.y, j.position.z, j.positionConfidence]
                    + [j.orientation.x, j.orientation.y, j.orientation.z, j.orientation.w, j.orientationConfidence]
                    for j in joints
                ]
            )
    return users


def track_skeleton(
    path: str | os.PathLike,
    *,
    nite_dir: str | os.PathLike | None = None,
    user: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    timeout_s: float | None = None,
) -> Motion:
    """Run NiTE2's user tracker over a recording's playback; the tracked body as a Motion
    (:func:`nite_motion`).

    The tracker runs in a child process (:mod:`.nite_session`) that reports each frame as it is
    tracked: OpenNI2's file playback can stall at the end of a recording (or anywhere, on some
    machines), so the child is stopped after ``timeout_s`` (default: 30 s plus ten times the
    recording's duration) and the frames tracked until then are used, with a warning.

    Raises:
        KinectDataError: the ``openni`` bindings, OpenNI2 or NiTE2 are missing (the message says
            what and where it was looked for), or nobody was tracked.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OniWarning)
        with OniFile(path) as oni:
            depth = oni.stream("depth")
            total, duration = depth.n_frames, depth.duration_s
    nite_folder = find_nite(nite_dir)
    try:
        import openni  # noqa: F401
    except ImportError:
        raise KinectDataError(
            "skeleton tracking needs the openni Python bindings: pip install 'kinectdata[openni]'"
        ) from None
    timeout_s = 30.0 + 10.0 * duration if timeout_s is None else timeout_s
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "frames.jsonl"
        settings = {"openni2_dir": str(openni2_dir()), "nite_dir": str(nite_folder), "oni": str(path), "frames": total}
        command = [sys.executable, "-m", "kinectdata.oni.nite_session", json.dumps(settings), str(out)]
        child = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + timeout_s
        while child.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)
            if progress and out.exists():
                progress(sum(1 for _ in out.open()), total)
        stalled = child.poll() is None
        if stalled:
            child.kill()
        stderr = child.communicate()[1]
        lines = out.read_text().splitlines() if out.exists() else []
    frames = []
    for line in lines:
        try:
            stamp, index, users = json.loads(line)
        except ValueError:  # the last line, cut by the kill
            break
        frames.append(TrackedFrame(stamp, index, {int(u): np.array(j) for u, j in users.items()}))
    if not frames:
        reason = "stalled" if stalled else f"failed (exit {child.returncode}): {stderr.strip()[-400:]}"
        raise KinectDataError(f"{path}: NiTE2 tracking {reason}")
    if len(frames) < total:
        warnings.warn(
            f"{path}: NiTE2 tracked {len(frames)} of {total} frames before playback stopped",
            TrackingWarning,
            stacklevel=2,
        )
    return nite_motion(frames, str(path), user)


def oni_timeline(path: str | os.PathLike, stream: str = "depth") -> np.ndarray:
    """[N] seconds: the timestamps of a recording's frames, from its first frame."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OniWarning)
        with OniFile(path) as oni:
            s = oni.stream(stream)
            stamps = s.timestamps_us.astype(np.float64)
    if stamps.size == 0:
        raise KinectDataError(f"{path}: its {stream} stream has no frames to take a timeline from")
    return (stamps - stamps[0]) / 1e6


def retime(motion: Motion, oni_path: str | os.PathLike, stream: str = "depth") -> Motion:
    """The motion with the ``.oni``'s frame timestamps as its times: skeleton frame k is depth
    frame k. The counts must agree.

    Raises:
        KinectDataError: the motion and the stream have different numbers of frames.
    """
    times = oni_timeline(oni_path, stream)
    source = motion.metadata.get("source", "the skeleton")
    if times.size != motion.n_frames:
        raise KinectDataError(
            f"{source}: {motion.n_frames} skeleton frames, but {oni_path} has {times.size} {stream} frames; "
            "--timeline needs one skeleton frame per frame of the recording"
        )
    if times.size > 1 and not np.all(np.diff(times) > 0):
        raise KinectDataError(f"{oni_path}: its {stream} timestamps do not increase; cannot use them as a timeline")
    metadata = dict(motion.metadata, timeline={"oni": str(oni_path), "stream": stream})
    return replace(motion, times=times, metadata=metadata)
