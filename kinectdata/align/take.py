"""Aligning a take folder (:mod:`kinectdata.capture.take`): its skeleton with its audio, with the
offset from the take's clock stamps instead of an estimate."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from kinectdata.align.recipe import align_files
from kinectdata.capture.take import CSV, ONI, read_take
from kinectdata.core.errors import KinectDataError
from kinectdata.formats import read_motion


def align_take(take_dir: str | os.PathLike, out: str | os.PathLike | None = None, **options: Any):
    """Align a take's skeleton with its audio using the offset from its clock stamps.

    The skeleton is ``take.json``'s, or a ``take.csv`` made later (``kinectdata oni skeleton
    TAKE/take.oni -o TAKE/take.csv``); its times are the ``.oni``'s, so its time 0 is the ``.oni``
    time of its first frame. Other options go to :func:`kinectdata.align.recipe.align_files`.
    """
    take = Path(take_dir)
    if options.get("timeline") is not None:
        raise KinectDataError(f"{take}: a take's skeleton is already on its .oni's timeline; give no --timeline")
    options.pop("timeline", None)
    doc = read_take(take)
    skeleton = take / (doc["skeleton"]["file"] if doc.get("skeleton") else CSV)
    if not skeleton.is_file():
        raise KinectDataError(
            f"{take}: this take has no skeleton (NiTE2 was not available when it was captured); make one with "
            f"`kinectdata oni skeleton {take / ONI} -o {take / CSV}` where NiTE2 is installed"
        )
    if not doc.get("audio"):
        raise KinectDataError(f"{take}: this take has no audio (captured without --audio-device); align needs music")
    if "offset" in options and options["offset"] not in (None, "take"):
        raise KinectDataError(f"{take}: a take's offset comes from its clock stamps; do not give --offset")
    options.pop("offset", None)
    reading = {k: options.get(k) for k in ("format", "schema", "body")}
    origin = read_motion(skeleton, **reading).metadata.get("time_origin") or {"value": 0.0, "unit": "s"}
    origin_s = float(origin["value"]) * {"s": 1.0, "ms": 1e-3, "us": 1e-6}.get(origin.get("unit", "s"), 1.0)
    offset = doc["oni"]["zero_clock_s"] + origin_s - doc["audio"]["first_sample_clock_s"]
    return align_files(skeleton, take / doc["audio"]["file"], out, offset=offset, **options)
