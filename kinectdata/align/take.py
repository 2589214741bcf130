"""Aligning a take folder (:mod:`kinectdata.capture.take`): its skeleton with its audio, with the
offset from the take's clock stamps instead of an estimate."""

from __future__ import annotations

import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.align.recipe import align_files
from kinectdata.capture.k4a import BODY, MKV
from kinectdata.capture.openni import CSV, ONI
from kinectdata.capture.take import read_take
from kinectdata.core.errors import KinectDataError
from kinectdata.formats import read_motion
from kinectdata.mkv.body import place_body_frames, tracker_stamps_us
from kinectdata.mkv.recording import K4aRecording, MkvWarning


def align_take(take_dir: str | os.PathLike, out: str | os.PathLike | None = None, **options: Any):
    """Align a take's skeleton with its audio using the offset from its clock stamps.

    An OpenNI2 take's skeleton is ``take.json``'s, or a ``take.csv`` made later (``kinectdata oni
    skeleton TAKE/take.oni -o TAKE/take.csv``); its times are the ``.oni``'s, so its time 0 is the
    ``.oni`` time of its first frame. An Azure Kinect take's skeleton is the body tracker's JSON
    saved as ``take_body.json``: its frames are placed on ``take.mkv``'s depth frames by their
    device timestamps (:func:`kinectdata.mkv.body.place_body_frames`), and so on the take's clock.
    Other options go to :func:`kinectdata.align.recipe.align_files`.
    """
    take = Path(take_dir)
    if options.get("timeline") is not None:
        raise KinectDataError(f"{take}: a take's skeleton is already on its recording's timeline; give no --timeline")
    options.pop("timeline", None)
    doc = read_take(take)
    if "offset" in options and options["offset"] not in (None, "take"):
        raise KinectDataError(f"{take}: a take's offset comes from its clock stamps; do not give --offset")
    options.pop("offset", None)
    reading = {k: options.get(k) for k in ("format", "schema", "body")}
    if doc["sensor"] == "k4a":
        skeleton, start_clock_s = _k4a_skeleton(take, doc, reading)
    else:
        skeleton, start_clock_s = _openni_skeleton(take, doc, reading)
    if not doc.get("audio"):
        raise KinectDataError(f"{take}: this take has no audio (captured without --audio-device); align needs music")
    offset = start_clock_s - doc["audio"]["first_sample_clock_s"]
    return align_files(skeleton, take / doc["audio"]["file"], out, offset=offset, **options)


def _openni_skeleton(take: Path, doc: dict[str, Any], reading: dict[str, Any]) -> tuple[Path, float]:
    """The skeleton file and the clock time of its time 0."""
    skeleton = take / (doc["skeleton"]["file"] if doc.get("skeleton") else CSV)
    if not skeleton.is_file():
        raise KinectDataError(
            f"{take}: this take has no skeleton (NiTE2 was not available when it was captured); make one with "
            f"`kinectdata oni skeleton {take / ONI} -o {take / CSV}` where NiTE2 is installed"
        )
    origin = read_motion(skeleton, **reading).metadata.get("time_origin") or {"value": 0.0, "unit": "s"}
    origin_s = float(origin["value"]) * {"s": 1.0, "ms": 1e-3, "us": 1e-6}.get(origin.get("unit", "s"), 1.0)
    return skeleton, doc["oni"]["zero_clock_s"] + origin_s


def _k4a_skeleton(take: Path, doc: dict[str, Any], reading: dict[str, Any]) -> tuple[Path, float]:
    """The body tracker's JSON and the clock time of its time 0, from the depth frame its first
    placed body frame was stamped with."""
    skeleton = take / BODY
    if not skeleton.is_file():
        raise KinectDataError(
            f"{take}: no {BODY}: run the Azure Kinect Body Tracking SDK's offline processor on {take / MKV} "
            f"and save its JSON as {skeleton}"
        )
    motion = read_motion(skeleton, **{**reading, "format": reading.get("format") or "azure_json"})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MkvWarning)
        with K4aRecording(take / doc["mkv"]["file"]) as mkv:
            placement = place_body_frames(tracker_stamps_us(motion), mkv, doc["mkv"]["clock_track"])
            track_us = mkv.track(doc["mkv"]["clock_track"]).times_us
    if not placement.placed:
        raise KinectDataError(f"{skeleton}: {placement.describe()} ({take / MKV}): not this take's body tracking")
    first = int(np.flatnonzero(placement.frame >= 0)[0])
    file_us = float(track_us[placement.frame[first]]) + float(placement.error_us[first])
    return skeleton, doc["mkv"]["zero_clock_s"] + file_us / 1e6 - float(motion.times[first])
