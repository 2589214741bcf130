"""kinectdata: music-driven dance research toolkit."""

from kinectdata.core.version import __version__

__all__ = ["__version__"]
