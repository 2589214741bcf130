"""Synthetic sample data: a music track with a clear beat and a Kinect v2 skeleton dancing to it.

Deterministic (seeded) sessions for the quickstart, the tests and model training:

- :func:`synthesize_music` (``music``): the track, with a sync clap before the music starts;
- :func:`dance` (``dancer``): the true motion of a dancer locked to the beats, with the clap;
- :func:`sensor_frame_times`, :func:`apply_sensor_defects` (``sensor``): Kinect v2 timing, noise
  and tracking states;
- :func:`synthesize_recording`, :func:`write_recording` (``recording``): a whole session (audio,
  skeleton recording, ground truth) and its files;
- :func:`synthesize_openpose`, :func:`write_openpose_recording` (``openpose``): the session as
  OpenPose BODY_25 2-D detections of a video (noise, misses, a passer-by) and its files.

Offset convention (toolkit-wide): ``audio_time = motion_time + offset_s``, motion_time being
0.0 at the recording's first frame.
"""

from __future__ import annotations

from kinectdata.synth.dancer import Body, dance, make_body
from kinectdata.synth.music import synthesize_music
from kinectdata.synth.openpose import (
    DetectorModel,
    OpenPoseVideo,
    PinholeCamera,
    synthesize_openpose,
    write_openpose_recording,
)
from kinectdata.synth.recording import (
    GENERATOR_VERSION,
    SynthRecording,
    regeneration_command,
    synthesize_recording,
    write_recording,
)
from kinectdata.synth.sensor import SensorModel, SensorOutput, apply_sensor_defects, sensor_frame_times

__all__ = [
    "GENERATOR_VERSION",
    "Body",
    "DetectorModel",
    "OpenPoseVideo",
    "PinholeCamera",
    "SensorModel",
    "SensorOutput",
    "SynthRecording",
    "apply_sensor_defects",
    "dance",
    "make_body",
    "regeneration_command",
    "sensor_frame_times",
    "synthesize_music",
    "synthesize_openpose",
    "synthesize_recording",
    "write_openpose_recording",
    "write_recording",
]
