"""JPEG frames: decoded as Pillow decodes them, refused by size before decoding, faults in one line."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image

from kinectdata.core.errors import KinectDataError
from kinectdata.core.jpeg import decode_jpeg
from kinectdata.oni.codecs import CodecError


def _jpeg(mode: str, size=(32, 24)) -> bytes:
    rng = np.random.default_rng(0)
    shape = (size[1], size[0], 3) if mode == "RGB" else (size[1], size[0])
    out = io.BytesIO()
    Image.fromarray(rng.integers(0, 255, shape, dtype=np.uint8), mode).save(out, "JPEG", quality=90)
    return out.getvalue()


def test_frames_decode_as_pillow_decodes_them():
    data = _jpeg("RGB")
    expected = np.asarray(Image.open(io.BytesIO(data)))
    np.testing.assert_array_equal(decode_jpeg(data, (32, 24), "f", rgb=True), expected)
    grey = _jpeg("L")
    assert decode_jpeg(grey, (32, 24), "f", rgb=False).shape == (24, 32)
    assert decode_jpeg(grey, (32, 24), "f", rgb=True).shape == (24, 32, 3)


def test_a_frame_of_another_size_or_no_jpeg_is_refused_with_the_readers_error():
    with pytest.raises(CodecError, match=r"take.oni, frame 3: a 32 x 24 JPEG in a 640 x 480 stream"):
        decode_jpeg(_jpeg("RGB"), (640, 480), "take.oni, frame 3", CodecError, rgb=False)
    with pytest.raises(KinectDataError, match="f: not a readable JPEG image"):
        decode_jpeg(b"\xff\xd8 not really", (32, 24), "f", rgb=True)
