"""Where live poses go: OSC receivers over UDP, and a recording of what was heard and danced.

OSC address space (one bundle per frame, its time tag "immediately"; docs/live.md):

- ``/kinectdata/frame``: int32 frame number (0, 1, ...), float32 time of the frame in seconds from
  the start of the audio (``k / fps``);
- ``/kinectdata/joint/<name>/position``: float32 x, y, z in metres, y up, right-handed, for each
  joint the run places in that frame (a 2-D target's x, y in its units: the cdhc model's 0..1, y down);
- ``/kinectdata/joint/<name>/rotation``: float32 x, y, z, w, a unit quaternion (the joint's
  orientation in the world), for each joint the run's target gives an orientation.

UDP needs no receiver: a frame sent to a port nobody listens on is lost, counted, and the
session goes on.
"""

from __future__ import annotations

import socket
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinectdata.core.errors import KinectDataError
from kinectdata.core.jointsets import JointSet
from kinectdata.core.motion import Motion

PREFIX = "/kinectdata"


@dataclass(frozen=True)
class LivePose:
    """One frame of a live dance.

    Attributes:
        index: frame number from the start (frame k at ``k / fps`` s of the audio).
        time_s: ``k / fps``.
        positions: [J, 3] metres, y up, or [J, 2] a 2-D target's units (NaN for joints not placed).
        orientations: [J, 4] unit quaternions x, y, z, w (NaN where the target gives none), or None.
    """

    index: int
    time_s: float
    positions: np.ndarray
    orientations: np.ndarray | None = None


def parse_address(text: str) -> tuple[str, int]:
    """``HOST:PORT`` -> (host, port); KinectDataError for anything else."""
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise KinectDataError(f"{text!r}: give a receiver as HOST:PORT (e.g. 127.0.0.1:9000)")
    return host, int(port)


class UdpSink:
    """Sends each frame's datagram (its subclass's :meth:`bundle`) to ``host:port`` over UDP, and
    counts the frames sent and those the network refused."""

    label = "UDP"

    def __init__(self, address: str):
        self.address = address
        host, port = parse_address(address)
        try:
            self.target = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)[0]
            self.socket = socket.socket(self.target[0], socket.SOCK_DGRAM)
        except OSError as exc:
            raise KinectDataError(f"{address}: cannot send there ({exc.strerror or exc})") from None
        self.sent = 0
        self.failed = 0

    def bundle(self, pose: LivePose) -> bytes:
        raise NotImplementedError

    def send(self, pose: LivePose) -> None:
        try:
            self.socket.sendto(self.bundle(pose), self.target[4])
            self.sent += 1
        except OSError:  # the network went away (or refused): count, go on
            self.failed += 1

    def close(self) -> None:
        self.socket.close()

    def summary(self) -> str:
        lost = f", {self.failed} not delivered" if self.failed else ""
        return f"{self.label} {self.address}: {self.sent} frames sent{lost}"


class OscSink(UdpSink):
    """Each frame as one OSC bundle, as the module docstring says."""

    label = "OSC"

    def __init__(self, address: str, joint_set: JointSet):
        self.encoder = FrameEncoder(joint_set.names, joint_set.dimensions)
        super().__init__(address)

    def bundle(self, pose: LivePose) -> bytes:
        return self.encoder.bundle(pose)


class FrameEncoder:
    """One frame as the bytes of an OSC bundle, with python-osc's encoders of OSC's types. Each
    message's address and type tags are encoded once, at the start: python-osc's message builder
    parses every message it builds again, a millisecond a frame that a live frame cannot spare."""

    def __init__(self, names: tuple[str, ...], dimensions: int = 3):
        try:
            from pythonosc.parsing import osc_types
        except ImportError:
            raise KinectDataError("--osc needs python-osc: pip install 'kinectdata[live]'") from None
        self.types = osc_types
        self.frame = osc_types.write_string(f"{PREFIX}/frame") + osc_types.write_string(",if")
        self.position = [_head(osc_types, f"{PREFIX}/joint/{n}/position", "," + "f" * dimensions) for n in names]
        self.rotation = [_head(osc_types, f"{PREFIX}/joint/{n}/rotation", ",ffff") for n in names]
        self.start = osc_types.write_string("#bundle") + (1).to_bytes(8, "big")  # time tag 1: immediately

    def bundle(self, pose: LivePose) -> bytes:
        t = self.types
        parts = [self.frame + t.write_int(pose.index) + t.write_float(pose.time_s)]
        for j, p in enumerate(pose.positions):
            if np.isfinite(p).all():
                parts.append(self.position[j] + np.asarray(p, ">f4").tobytes())
            if pose.orientations is not None and np.isfinite(pose.orientations[j]).all():
                parts.append(self.rotation[j] + np.asarray(pose.orientations[j], ">f4").tobytes())
        return self.start + b"".join(len(m).to_bytes(4, "big") + m for m in parts)


def _head(types, address: str, tags: str) -> bytes:
    return types.write_string(address) + types.write_string(tags)


@dataclass
class RecordSink:
    """Keeps what was heard and danced, and writes it at the end as an aligned recording (``.h5``,
    atomically: nothing is left if the session fails before), which ``info``, ``render`` and
    ``score`` read: frame k's pose at ``k / fps``, the audio's sample 0 at frame 0's start."""

    path: Path
    joint_set: JointSet
    fps: float
    sample_rate: int
    source: str
    audio: list[np.ndarray] = field(default_factory=list)
    positions: list[np.ndarray] = field(default_factory=list)
    orientations: list[np.ndarray] = field(default_factory=list)

    def hear(self, samples: np.ndarray) -> None:
        self.audio.append(np.asarray(samples, np.float32))

    def send(self, pose: LivePose) -> None:
        self.positions.append(pose.positions)
        if pose.orientations is not None:
            self.orientations.append(pose.orientations)

    def write(self, run: str) -> Path | None:
        """Write the recording (None when no frame was danced)."""
        from kinectdata.align.aligned import AlignedRecording, Provenance

        if not self.positions:
            return None
        n = len(self.positions)
        motion = Motion(
            times=np.arange(n) / self.fps,
            positions=np.stack(self.positions),
            joint_set=self.joint_set,
            orientations=np.stack(self.orientations) if len(self.orientations) == n else None,
            metadata={"format": "live", "source": self.source, "run": run},
        )
        recording = AlignedRecording(
            motion=motion,
            audio=np.concatenate([np.zeros(0, np.float32), *self.audio]),
            sample_rate=self.sample_rate,
            fps=self.fps,
            position_interpolated=np.zeros((n, len(self.joint_set)), bool),
            orientation_interpolated=None if motion.orientations is None else np.zeros((n, len(self.joint_set)), bool),
            provenance=Provenance(motion={"format": "live", "run": run}, audio={"source": self.source}),
            summary={"frames": n, "made_by": "kinectdata live"},
        )
        recording.save(self.path)
        return self.path
