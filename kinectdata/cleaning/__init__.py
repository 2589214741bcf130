"""Cleaning a recording: jitter filtered, bones held to one length, each stage reported
(:mod:`.clean`; the filters in :mod:`.jitter`, :mod:`.bones`, :mod:`.recurrence`)."""

from kinectdata.cleaning.clean import CleanConfig, Cleaned, CleanReport, StageReport, clean_motion

__all__ = ["CleanConfig", "CleanReport", "Cleaned", "StageReport", "clean_motion"]
