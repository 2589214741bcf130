"""Skeleton recording formats, one module each, registered by name (see :mod:`.registry`)."""

# Importing the format modules registers their readers and writers.
from kinectdata.formats.registry import Reader, detect_format, read_motion, readers, register_reader
from kinectdata.formats.writers import Writer, Written, register_writer, write_motion, writers

from . import arrays as _arrays  # noqa: F401
from . import arrays_writer as _arrays_writer  # noqa: F401
from . import azure_json as _azure_json  # noqa: F401
from . import bvh as _bvh  # noqa: F401
from . import bvh_writer as _bvh_writer  # noqa: F401
from . import csv as _csv  # noqa: F401
from . import csv_writer as _csv_writer  # noqa: F401
from . import finedance as _finedance  # noqa: F401
from . import htr as _htr  # noqa: F401
from . import ntu as _ntu  # noqa: F401
from . import openpose as _openpose  # noqa: F401
from . import openpose_writer as _openpose_writer  # noqa: F401
from . import tang2018 as _tang2018  # noqa: F401

__all__ = [
    "Reader",
    "Writer",
    "Written",
    "detect_format",
    "read_motion",
    "readers",
    "register_reader",
    "register_writer",
    "write_motion",
    "writers",
]
