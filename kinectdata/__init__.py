"""kinectdata: music-driven dance research toolkit."""

__version__ = "0.1.0"
