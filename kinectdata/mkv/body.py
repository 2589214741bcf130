"""The body tracker's frames of a take placed on its recording's frames (one device clock).

The Azure Kinect body tracker (k4abt; its offline processor writes the JSON ``azure_json`` reads)
runs on the captures the SDK's playback gives, and stamps each body frame with its capture's
device time in microseconds (``timestamp_usec``): the depth image's, which playback gives as the
block's time plus ``K4A_START_OFFSET_NS`` / 1000 (src/record/internal/matroska_read.cpp). Before
SDK 1.2 playback gave the file's own times instead (the change is the SDK's pull request 592):
such a JSON's times sit ``K4A_START_OFFSET_NS`` / 1000 earlier, which :func:`place_body_frames`
recognises and says. The SDK's playback keeps the offset in microseconds as a 32-bit number
(``start_timestamp_offset_usec``, matroska_read.cpp): a recording started after 71.6 minutes of
device uptime gives the tracker times wrapped by that much, which are recognised too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .recording import K4aRecording


@dataclass(frozen=True)
class BodyPlacement:
    """Where each body frame falls among a track's frames.

    Attributes:
        frame: [N] int64, the track's frame each body frame was stamped with (-1: none within half a
            frame period).
        error_us: [N] float64, body frame time less that frame's time (NaN where none).
        clock: ``device`` (the tracker's times are the device's), ``file`` (an SDK before 1.2:
            the file's own times) or ``device_uint32`` (the device's, with the start offset wrapped
            at 2^32 us as the SDK's playback keeps it: recordings started after 71.6 minutes of
            device uptime).
        track: the track matched (``DEPTH``).
    """

    frame: np.ndarray
    error_us: np.ndarray
    clock: str
    track: str

    @property
    def placed(self) -> int:
        return int(np.sum(self.frame >= 0))

    def describe(self) -> str:
        """One line: how many body frames sit on the track's frames, and how closely."""
        n = len(self.frame)
        if not self.placed:
            return f"body tracking: none of its {n} frames falls on a {self.track} frame of this recording"
        worst = float(np.nanmax(np.abs(self.error_us)))
        first = int(self.frame[self.frame >= 0][0])
        clock = {
            "device": "the device's clock",
            "file": "the file's clock (a body tracker before SDK 1.2)",
            "device_uint32": "the device's clock with the start offset wrapped at 2^32 us (the SDK's playback)",
        }[self.clock]
        return (
            f"body tracking: {self.placed} of {n} frames on {self.track} frames (from frame {first}), on {clock}, "
            f"at most {worst:.0f} us apart"
        )


def tracker_stamps_us(motion) -> np.ndarray:
    """The ``timestamp_usec`` [T] of each frame of a body-tracking JSON read as ``azure_json``
    (its first frame's stamp, ``time_origin``, plus its times), float64 microseconds."""
    return motion.metadata["time_origin"]["value"] + np.round(np.asarray(motion.times, dtype=np.float64) * 1e6)


def place_body_frames(body_device_us: np.ndarray, take: K4aRecording, track: str = "DEPTH") -> BodyPlacement:
    """Match body frames (their ``timestamp_usec``, [N]) to ``track``'s frames of ``take``: each to
    the frame nearest in time, within half the track's frame period (or 1 ms when it has none), on
    the device's clock, or on the file's or the wrapped one when that places more of them."""
    target = take.track(track)
    period = target.frame_period_ns / 1000 if target.frame_period_ns else 2000.0
    stamps = np.asarray(body_device_us, dtype=np.float64)
    best = None
    file_us = target.times_us.astype(np.float64)
    clocks = [("file", file_us)]
    if take.start_offset_us is not None:
        wrapped = (round(take.start_offset_us) % 2**32) + file_us  # the SDK keeps the offset as uint32 us
        clocks = [("device", file_us + take.start_offset_us), *clocks, ("device_uint32", wrapped)]
    for clock, times in clocks:
        frame, error = nearest_frames(stamps, np.asarray(times, dtype=np.float64), period / 2)
        placement = BodyPlacement(frame, error, clock, track)
        if best is None or placement.placed > best.placed:
            best = placement
    return best


def nearest_frames(stamps: np.ndarray, times: np.ndarray, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """For each time in ``stamps`` [N] the index of the nearest of ``times`` [M] (sorted; -1 when
    none is within ``tolerance``, same units) and the difference (NaN where none)."""
    if len(times) == 0:
        return np.full(len(stamps), -1, np.int64), np.full(len(stamps), np.nan)
    right = np.clip(np.searchsorted(times, stamps), 0, len(times) - 1)
    left = np.maximum(right - 1, 0)
    pick = np.where(np.abs(stamps - times[left]) <= np.abs(stamps - times[right]), left, right)
    error = stamps - times[pick]
    near = np.abs(error) <= tolerance
    return np.where(near, pick, -1).astype(np.int64), np.where(near, error, np.nan)
