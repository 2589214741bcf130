"""OpenNI ``.oni`` recordings, read without OpenNI (see ``docs/oni.md``).

- :mod:`.records`: the container (file header, records, fields, both layouts);
- :mod:`.codecs`: the frame codecs (16zP, 16zT, Im8z, NONE, JPEG), vectorised numpy decoders;
- :mod:`.reader`: :class:`OniFile`, streams, the frame index and frame decoding.
"""

from kinectdata.oni.reader import OniFile, OniFrame, OniStream, OniWarning
from kinectdata.oni.records import OniError

__all__ = ["OniError", "OniFile", "OniFrame", "OniStream", "OniWarning"]
