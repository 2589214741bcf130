"""A synthetic recording session: music track + Kinect v2 skeleton recording + ground truth.

Clocks. The music is generated on the **audio clock** (seconds from the first audio sample). The
skeleton recording has its own clock, 0.0 at its first written frame. The toolkit's offset
convention is ``audio_time = motion_time + offset_s``: the recording starts at audio time
``offset_s``, which is negative when the sensor started before the audio.

Session timeline (audio clock): the sensor starts at ``offset_s`` (-1.5..2.5 s); the dancer
stands still, then claps once at ``clap_time_audio_s`` (1.2-1.8 s after the later of the two
starts); the music starts 1.3-2.0 s after the clap; the sensor stops 0.3-1.0 s before the audio
ends. The audio is ``duration_s`` long.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import soundfile as sf

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import ConfigError
from kinectdata.core.motion import Motion
from kinectdata.core.version import __version__
from kinectdata.formats.csv_writer import write_csv
from kinectdata.synth.dancer import CLAP_LEAD_S, dance
from kinectdata.synth.music import BEATS_PER_BAR, CLAP_ATTACK_S, synthesize_music
from kinectdata.synth.sensor import SensorModel, apply_sensor_defects, sensor_frame_times

GENERATOR_VERSION = "1"
"""Bumped whenever the same arguments would no longer give the same output."""
MIN_DURATION_S = 8.0
OFFSET_RANGE_S = (-1.5, 2.5)
TEMPO_RANGE_BPM = (96, 128)
AUDIO_FORMATS = {"flac": ("FLAC", "PCM_16"), "wav": ("WAV", "PCM_16")}
DIALECTS = ("dumpkinectskeleton", "kinectreader", "lsl_kinect", "canonical")  # as cli/synth.py offers
"""The shipped Kinect v2 CSV dialects (``write_csv`` also takes schema files)."""

_CLAP_AFTER_START_S = (1.2, 1.8)
_MUSIC_AFTER_CLAP_S = (1.3, 2.0)
_TAIL_S = (0.3, 1.0)
_MIN_MUSIC_BEATS = 4


@dataclass
class SynthRecording:
    """One synthetic session.

    Attributes:
        audio: [S, 2] float32 stereo, -1..1.
        sample_rate: Hz.
        motion: the skeleton recording with sensor defects (recording clock, first frame 0.0).
        truth: the ground truth (JSON-ready; see :func:`synthesize_recording`).
        true_motion: the noise-free motion at the same frames (recording clock).
        states: [T, J] int8 Kinect tracking states of ``motion``.
        raw_positions: [T, J, 3] positions as written to a file (no NaN; not-tracked joints hold
            their last value).
        raw_orientations: [T, J, 4] likewise (NaN for leaf joints).
    """

    audio: np.ndarray
    sample_rate: int
    motion: Motion
    truth: dict[str, Any]
    true_motion: Motion | None = None
    states: np.ndarray | None = None
    raw_positions: np.ndarray | None = None
    raw_orientations: np.ndarray | None = None
    options: dict[str, Any] = field(default_factory=dict)

    def written_motion(self) -> Motion:
        """The Motion as a file would hold it: every position valid (not-tracked joints at their
        held values), confidence from the tracking states. Pass ``states`` alongside to writers."""
        return replace(
            self.motion,
            positions=self.raw_positions,
            position_mask=np.ones(self.raw_positions.shape[:2], bool),
            orientations=self.raw_orientations,
            orientation_mask=None if self.raw_orientations is None else np.isfinite(self.raw_orientations).all(-1),
        )


def synthesize_recording(
    *,
    seed: int = 0,
    duration_s: float = 30.0,
    tempo_bpm: float | None = None,
    offset_s: float | None = None,
    clap: bool = True,
    sample_rate: int = 44100,
) -> SynthRecording:
    """Generate a session deterministically from ``seed``.

    Args:
        seed: non-negative integer; every random choice derives from it.
        duration_s: audio length, seconds (at least :data:`MIN_DURATION_S`).
        tempo_bpm: tempo; default a seeded integer in 96..128.
        offset_s: audio time of the recording's first frame; default seeded in -1.5..2.5 s
            (narrowed for short durations so that at least four beats of music are recorded).
        clap: False for a session without the sync clap (neither in the audio nor the motion).
        sample_rate: audio sample rate, Hz.

    Returns:
        A :class:`SynthRecording`. ``truth`` keys: ``generator``, ``generator_version``,
        ``kinectdata_version``, ``seed``, ``command`` (regenerates the session), ``duration_s``,
        ``sample_rate``, ``tempo_bpm``, ``beat_period_s``, ``beat_times_s`` and
        ``downbeat_times_s`` (audio clock), ``music_start_s``, ``sections``, ``key``,
        ``progression``, ``clap``, ``clap_time_audio_s`` (the hands meet; the audio clap's
        onset), ``clap_peak_audio_s``, ``clap_time_motion_s``, ``offset_s``,
        ``offset_convention``, ``motion_start_audio_s``, ``motion_end_audio_s``,
        ``motion_duration_s``, ``n_frames``, ``fps_nominal``, ``timestamp_jitter_sd_s``,
        ``dropped_frames``, ``dropped_frame_times_s`` (nominal, recording clock),
        ``tracking_spans`` (joint, state, start_s, end_s: recording clock), ``noise``,
        ``dancer`` (height, floor, choreography blocks with start times on both clocks).
    """
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError(f"seed must be a non-negative integer, got {seed!r}")
    if duration_s < MIN_DURATION_S:
        raise ConfigError(f"duration_s must be at least {MIN_DURATION_S} s, got {duration_s}")
    root = np.random.SeedSequence(int(seed))
    s_timeline, s_music, s_dance, s_times, s_sensor = root.spawn(5)
    rng = np.random.default_rng(s_timeline)
    # Always draw everything, so that giving a value explicitly changes nothing else.
    drawn_tempo = int(rng.integers(TEMPO_RANGE_BPM[0], TEMPO_RANGE_BPM[1] + 1))
    offset_u = rng.random()
    clap_after = rng.uniform(*_CLAP_AFTER_START_S)
    music_after = rng.uniform(*_MUSIC_AFTER_CLAP_S)
    tail = rng.uniform(*_TAIL_S)

    tempo = float(drawn_tempo if tempo_bpm is None else tempo_bpm)
    if not 30 <= tempo <= 300:
        raise ConfigError(f"tempo_bpm must lie in 30..300, got {tempo}")
    needed_after_offset = clap_after + music_after + _MIN_MUSIC_BEATS * 60.0 / tempo + tail
    hi = min(OFFSET_RANGE_S[1], duration_s - needed_after_offset)
    if hi < OFFSET_RANGE_S[0]:
        raise ConfigError(
            f"duration_s={duration_s} is too short for {tempo} bpm "
            f"(needs about {needed_after_offset + OFFSET_RANGE_S[0]:.1f} s)"
        )
    if offset_s is None:
        offset = OFFSET_RANGE_S[0] + offset_u * (hi - OFFSET_RANGE_S[0])
    else:
        offset = float(offset_s)
        if not np.isfinite(offset):
            raise ConfigError(f"offset_s must be a finite number of seconds, got {offset_s!r}")
        if offset < -5.0 or max(offset, 0.0) + needed_after_offset > duration_s:
            raise ConfigError(
                f"offset_s={offset} leaves too little music in {duration_s} s "
                f"(at most {duration_s - needed_after_offset:.3f} s, at least -5 s)"
            )
    clap_audio = max(offset, 0.0) + clap_after
    music_start = clap_audio + music_after
    motion_end_audio = duration_s - tail

    audio, music = synthesize_music(
        seed=s_music,
        duration_s=duration_s,
        tempo_bpm=tempo,
        music_start_s=music_start,
        clap_time_s=clap_audio if clap else None,
        sample_rate=sample_rate,
    )
    model = SensorModel()
    times, timing = sensor_frame_times(seed=s_times, duration_s=motion_end_audio - offset, model=model)
    true_music_clock = dance(
        seed=s_dance,
        times_s=times + offset,
        beat_times_s=music["beat_times_s"],
        music_start_s=music_start,
        clap_time_s=clap_audio if clap else None,
        tempo_bpm=tempo,
    )
    clap_motion = clap_audio - offset
    true = replace(
        true_music_clock,
        times=times,
        metadata={**true_music_clock.metadata, "clock": "recording", "clap_time_s": clap_motion if clap else None},
    )
    protect = [(clap_motion - CLAP_LEAD_S - 0.2, clap_motion + 1.2)] if clap else []
    sensed = apply_sensor_defects(
        true, seed=s_sensor, protect=protect, foot_window=(music_start - offset, times[-1]), model=model
    )
    motion = sensed.motion
    motion.metadata = {
        "generator": "kinectdata.synth",
        "seed": int(seed),
        "clock": "recording",
        "time_origin": 0.0,
        "joint_set": motion.joint_set.name,
    }

    options = {
        "seed": int(seed),
        "duration_s": float(duration_s),
        "tempo_bpm": tempo,
        "offset_s": offset,
        "clap": bool(clap),
        "sample_rate": int(sample_rate),
    }
    truth: dict[str, Any] = {
        "generator": "kinectdata.synth",
        "generator_version": GENERATOR_VERSION,
        "kinectdata_version": __version__,
        "seed": int(seed),
        "command": regeneration_command(options),
        "duration_s": float(duration_s),
        "sample_rate": int(sample_rate),
        "tempo_bpm": tempo,
        "beat_period_s": music["beat_period_s"],
        "beats_per_bar": BEATS_PER_BAR,
        "beat_times_s": [float(b) for b in music["beat_times_s"]],
        "downbeat_times_s": [float(b) for b in music["downbeat_times_s"]],
        "music_start_s": music_start,
        "sections": music["sections"],
        "key": music["key"],
        "progression": music["progression"],
        "clap": bool(clap),
        "clap_time_audio_s": clap_audio if clap else None,
        "clap_peak_audio_s": clap_audio + CLAP_ATTACK_S if clap else None,
        "clap_time_motion_s": clap_motion if clap else None,
        "offset_s": offset,
        "offset_convention": "audio_time = motion_time + offset_s; motion_time is 0.0 at the first written frame",
        "motion_start_audio_s": offset,
        "motion_end_audio_s": offset + float(times[-1]),
        "motion_duration_s": float(times[-1]),
        "n_frames": int(times.size),
        "fps_nominal": model.fps,
        "timestamp_jitter_sd_s": model.jitter_sd_s,
        "dropped_frames": timing["dropped_frames"],
        "dropped_frame_times_s": timing["dropped_nominal_times_s"],
        "tracking_spans": sensed.spans,
        "noise": {
            "position_sd_m": model.position_sd_m,
            "orientation_sd_rad": model.orientation_sd_rad,
            "inferred_position_sd_m": model.inferred_position_sd_m,
            "inferred_bias_m": list(model.inferred_bias_m),
        },
        "dancer": {
            "height_m": true.metadata["height_m"],
            "floor_y_m": true.metadata["floor_y_m"],
            "blocks": [
                {
                    **b,
                    "start_audio_s": _beat_time(music, b["start_beat"]),
                    "start_motion_s": _beat_time(music, b["start_beat"]) - offset,
                }
                for b in true.metadata["blocks"]
            ],
        },
    }
    return SynthRecording(
        audio=audio,
        sample_rate=int(sample_rate),
        motion=motion,
        truth=truth,
        true_motion=true,
        states=sensed.states,
        raw_positions=sensed.raw_positions,
        raw_orientations=sensed.raw_orientations,
        options=options,
    )


def _beat_time(music: dict[str, Any], beat: int) -> float:
    return float(music["music_start_s"] + beat * music["beat_period_s"])


def _time_origin(dialect: str, seed: int) -> float:
    """First timestamp of the skeleton file, in the dialect's time unit: what the recorder writes.

    LSL-Kinect writes Unix time in milliseconds (a seeded instant in 2024 here); the others
    count from the start of the recording.
    """
    if dialect == "lsl_kinect":
        return float(1_704_067_200_000 + (int(seed) * 7_919_113) % 31_536_000_000)
    return 0.0


def regeneration_command(
    options: dict[str, Any],
    *,
    name: str | None = None,
    dialect: str | None = None,
    audio_format: str | None = None,
    out_dir: str = ".",
) -> str:
    """The ``kinectdata synth`` command line that regenerates a session (values written exactly)."""
    parts = [
        "kinectdata",
        "synth",
        "--seed",
        str(options["seed"]),
        "--duration",
        repr(options["duration_s"]),
        "--tempo",
        repr(options["tempo_bpm"]),
        "--offset",
        repr(options["offset_s"]),
    ]
    if not options["clap"]:
        parts.append("--no-clap")
    parts += ["--sample-rate", str(options["sample_rate"])]
    if dialect is not None:
        parts += ["--dialect", dialect]
    if audio_format is not None:
        parts += ["--audio-format", audio_format]
    if name is not None:
        parts += ["--name", name]
    parts.append(out_dir)
    return " ".join(parts)


def write_recording(
    rec: SynthRecording,
    out_dir: str | Path,
    name: str,
    *,
    dialect: str = "dumpkinectskeleton",
    audio_format: str = "flac",
) -> dict[str, Path]:
    """Write ``<name>.<flac|wav>`` (16-bit), ``<name>.csv`` (skeleton, in the CSV dialect
    ``dialect``: one of :data:`DIALECTS` or anything ``write_csv`` takes) and ``<name>.truth.json``
    into ``out_dir`` (created if missing).

    Returns ``{"audio": path, "skeleton": path, "truth": path}``. The same recording always gives
    byte-identical files. Not-tracked joints are written at their held positions with state 0;
    the truth file adds ``dialect``, ``audio_format``, ``skeleton_time_origin`` (the file's first
    timestamp, in the dialect's unit), ``files`` and the full ``command``.
    """
    if audio_format not in AUDIO_FORMATS:
        raise ConfigError(f"audio_format must be one of {sorted(AUDIO_FORMATS)}, got {audio_format!r}")
    out = Path(out_dir)
    paths = {
        "audio": out / f"{name}.{audio_format}",
        "skeleton": out / f"{name}.csv",
        "truth": out / f"{name}.truth.json",
    }
    write_audio(rec, paths["audio"], audio_format)
    origin = _time_origin(dialect, rec.options["seed"])
    write_csv(rec.written_motion(), paths["skeleton"], dialect, states=rec.states, time_origin=origin)
    truth = {
        **rec.truth,
        "command": regeneration_command(rec.options, name=name, dialect=dialect, audio_format=audio_format),
        "dialect": dialect,
        "audio_format": audio_format,
        "skeleton_time_origin": origin,
        "files": {k: p.name for k, p in paths.items()},
    }
    write_truth(truth, paths["truth"])
    return paths


def write_audio(rec: SynthRecording, path: Path, audio_format: str) -> None:
    """The session's audio as a 16-bit ``audio_format`` file (one of :data:`AUDIO_FORMATS`), atomically."""
    fmt, subtype = AUDIO_FORMATS[audio_format]
    with atomic_output(path) as tmp:
        sf.write(tmp, rec.audio, rec.sample_rate, format=fmt, subtype=subtype)


def write_truth(truth: dict[str, Any], path: Path) -> None:
    """A truth document as indented JSON, atomically."""
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(truth, indent=2) + "\n", encoding="utf-8")
