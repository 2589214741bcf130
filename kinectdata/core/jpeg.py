"""JPEG frames of sensor recordings (an ``.oni``'s JPEG colour, an Azure Kinect's MJPG), decoded by
Pillow (``pip install 'kinectdata[jpeg]'``) once the header says they are the size their stream
declares: a damaged or hostile frame is refused before anything larger is decoded."""

from __future__ import annotations

import io

import numpy as np

from kinectdata.core.errors import KinectDataError


def decode_jpeg(
    payload: bytes, size: tuple[int, int], what: str, error: type[KinectDataError] = KinectDataError, *, rgb: bool
) -> np.ndarray:
    """A JPEG frame as uint8 [H, W, 3] (``rgb``; else as stored: [H, W] for greyscale).

    Args:
        size: (width, height) in pixels the stream declares.
        what: names the file, stream and frame in errors.
        error: the exception class raised (the reader's own).
    """
    try:
        from PIL import Image
    except ImportError:
        raise error(f"{what}: JPEG frames need Pillow: pip install 'kinectdata[jpeg]'") from None
    try:
        with Image.open(io.BytesIO(payload)) as image:
            if image.size != tuple(size):
                raise error(f"{what}: a {image.size[0]} x {image.size[1]} JPEG in a {size[0]} x {size[1]} stream")
            return np.asarray(image.convert("RGB") if rgb else image)
    except KinectDataError:
        raise
    except Exception as exc:  # Pillow raises OSError, SyntaxError, DecompressionBombError...
        raise error(f"{what}: not a readable JPEG image ({exc})") from exc
