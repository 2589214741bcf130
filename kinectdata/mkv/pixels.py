"""Decoding a k4arecorder video frame from its pixel format (the track's BITMAPINFOHEADER FOURCC).

- ``b16g``: 16-bit values, big-endian (the recorder swaps the sensor's little-endian depth and
  infrared before writing: src/record/sdk/record.cpp): uint16 [H, W], depth in millimetres.
- ``MJPG``: a JPEG image, decoded by Pillow: uint8 [H, W, 3] RGB.
- ``NV12`` (a Y plane, then interleaved U, V at half resolution), ``YUY2`` (Y0 U Y1 V per pixel
  pair): uint8 [H, W, 3] RGB by the BT.601 limited-range matrix (FFmpeg's when a stream names
  none), each pixel taking the chroma sample of its 2 x 2 (NV12) or 2 x 1 (YUY2) block: FFmpeg's
  ``-sws_flags neighbor+accurate_rnd+full_chroma_int`` within one level.
- ``BGRA``: uint8 [H, W, 3] RGB (alpha dropped).
"""

from __future__ import annotations

import numpy as np

from kinectdata.core.errors import KinectDataError
from kinectdata.core.jpeg import decode_jpeg

FOURCCS = ("b16g", "MJPG", "NV12", "YUY2", "BGRA")


class PixelError(KinectDataError):
    """A frame that cannot be decoded; the message names the file, the track and the frame."""


def _need(what: str, have: int, need: int) -> None:
    if have < need:
        raise PixelError(f"{what}: {have} bytes, a frame of this size needs {need}")


def decode_frame(payload: bytes, track, *, what: str) -> np.ndarray:
    """One frame of ``track`` (its ``fourcc``, ``width``, ``height``) decoded."""
    w, h, fourcc = track.width, track.height, track.fourcc
    if fourcc == "b16g":
        _need(what, len(payload), w * h * 2)
        return np.frombuffer(payload, ">u2", w * h).reshape(h, w).astype(np.uint16)
    if fourcc == "BGRA":
        _need(what, len(payload), w * h * 4)
        return np.frombuffer(payload, np.uint8, w * h * 4).reshape(h, w, 4)[..., 2::-1].copy()
    if fourcc in ("NV12", "YUY2") and (w % 2 or (fourcc == "NV12" and h % 2)):
        raise PixelError(
            f"{what}: {fourcc} needs an even width{' and height' if fourcc == 'NV12' else ''}, not {w} x {h}"
        )
    if fourcc == "NV12":
        _need(what, len(payload), w * h * 3 // 2)
        raw = np.frombuffer(payload, np.uint8, w * h * 3 // 2)
        y = raw[: w * h].reshape(h, w)
        uv = raw[w * h :].reshape(h // 2, w // 2, 2)
        u = np.repeat(np.repeat(uv[..., 0], 2, axis=0), 2, axis=1)
        v = np.repeat(np.repeat(uv[..., 1], 2, axis=0), 2, axis=1)
        return yuv_to_rgb(y, u, v)
    if fourcc == "YUY2":
        _need(what, len(payload), w * h * 2)
        raw = np.frombuffer(payload, np.uint8, w * h * 2).reshape(h, w // 2, 4)
        y = raw[..., [0, 2]].reshape(h, w)
        u = np.repeat(raw[..., 1], 2, axis=1)
        v = np.repeat(raw[..., 3], 2, axis=1)
        return yuv_to_rgb(y, u, v)
    if fourcc == "MJPG":
        return decode_jpeg(payload, (w, h), what, PixelError, rgb=True)
    raise PixelError(f"{what}: pixel format {fourcc!r} is not one the recorder writes ({', '.join(FOURCCS)})")


def yuv_to_rgb(y: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """uint8 RGB [H, W, 3] from uint8 Y, U, V planes [H, W] (BT.601, limited range: Y 16-235, chroma 16-240)."""
    c = (y.astype(np.float32) - 16.0) * (255.0 / 219.0)
    d = (u.astype(np.float32) - 128.0) * (255.0 / 224.0)
    e = (v.astype(np.float32) - 128.0) * (255.0 / 224.0)
    rgb = np.stack([c + 1.402 * e, c - 0.344136 * d - 0.714136 * e, c + 1.772 * d], axis=-1)
    return np.clip(np.rint(rgb), 0, 255).astype(np.uint8)
