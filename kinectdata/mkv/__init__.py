"""Azure Kinect and Orbbec Femto recordings (k4arecorder ``.mkv``), read without the SDK."""

from kinectdata.mkv.recording import ImuSamples, K4aRecording, MkvError, MkvTrack, MkvWarning

__all__ = ["ImuSamples", "K4aRecording", "MkvError", "MkvTrack", "MkvWarning"]
