"""The rhythm part of ``evaluate``: does the motion, real and generated, move with the music's beat?

For each recording of the split, the music's beats on the recording's motion clock (frame k at k / fps):

- **ground truth** when the recording's audio (for an aligned ``.h5``: the audio it was aligned
  from, as its provenance names it) has a ``<name>.truth.json`` beside it with ``beat_times_s`` on
  the audio clock (``kinectdata synth`` writes one), shifted by the audio time of the recording's
  first frame (its alignment's ``audio_trimmed_start_s``);
- else the **beat tracker** (:func:`kinectdata.features.beats.music_beats`, librosa) on the recording's
  audio over the same span;
- else none, and the report says why (audio moved away, librosa not installed).

Then, for the real motion and the generated one (:mod:`kinectdata.evaluation.rhythm`, ``docs/rhythm.md``):
the autocorrelation of the target's joint trajectories per axis with its peaks against the beat
period (Lee et al. 2018), and the Beat Align Score and motion-beat F-measure of the motion's beats
(local minima of joint speed) against the music's beats inside the motion's span. Positions are the
target spec's, denormalised (metres, or the 2-D target's units); generated motion covers frames
1..T-1 (the first true pose starts it), and its beat times are placed on the same clock.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from kinectdata.align.aligned import audio_blocks
from kinectdata.align.audio import AudioReader
from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.rhythm import beat_alignment_report, beat_period_s, motion_beats, rhythm_report
from kinectdata.features.beats import music_beats
from kinectdata.targets.specs import TargetSpec


def target_positions(values: np.ndarray, mask: np.ndarray, spec: TargetSpec) -> tuple[np.ndarray, np.ndarray]:
    """The positions [T, P, C] and their mask [T, P] inside target vectors [T, D] (denormalised)."""
    pos = values[:, spec.position_slice].reshape(len(values), len(spec.positions), spec.dimensions)
    pmask = mask[:, spec.position_slice].reshape(pos.shape).all(axis=-1)
    return pos, pmask


def recording_beats(entry: dict[str, Any], info: dict[str, Any], frames: int, fps: float, sample_rate: int):
    """(beat times [B] s on the recording's motion clock, source, None) or (None, None, why not)."""
    start = float(info.get("alignment", {}).get("audio_trimmed_start_s", 0.0))
    audio = entry.get("audio")
    source_audio = audio if audio is not None else _aligned_from(entry["recording"])
    if source_audio is not None:
        truth = Path(source_audio).with_name(Path(source_audio).name.rsplit(".", 1)[0] + ".truth.json")
        if truth.is_file():
            try:
                beats = np.asarray(json.loads(truth.read_text())["beat_times_s"], np.float64)
                return beats - start, "ground truth", None
            except (OSError, ValueError, KeyError, TypeError) as exc:
                return None, None, f"{truth}: no readable beat_times_s ({exc})"
    try:
        beats, _ = music_beats(recording_audio(entry, info, frames, fps, sample_rate), sample_rate)
    except (KinectDataError, OSError) as exc:
        return None, None, str(exc)
    return beats, "beat tracker", None


def recording_audio(entry: dict[str, Any], info: dict[str, Any], frames: int, fps: float, sample_rate: int):
    """[S] float32 mono samples at ``sample_rate`` of a recording's music over its ``frames`` motion
    frames, sample 0 at frame 0: from the audio file the manifest names (from its aligned start), or
    from an aligned ``.h5``'s own audio. Raises KinectDataError or OSError when it cannot be read."""
    audio = entry.get("audio")
    if audio is not None:
        start = float(info.get("alignment", {}).get("audio_trimmed_start_s", 0.0))
        samples = np.concatenate(list(AudioReader(audio, sample_rate).blocks()))
        first = int(round(start * sample_rate))
        return samples[first : first + int(np.ceil(frames / fps * sample_rate))]
    return np.concatenate(list(audio_blocks(entry["recording"])))


def _aligned_from(aligned: str) -> Path | None:
    """The audio file an aligned ``.h5`` was made from (its provenance path, as given or relative to
    the ``.h5``'s folder), or None."""
    try:
        with h5py.File(aligned, "r") as f:
            path = json.loads(f.attrs["provenance"])["audio"]["path"]
    except (OSError, KeyError, ValueError, TypeError):
        return None
    for candidate in (Path(path), Path(aligned).parent / path):
        if candidate.is_file():
            return candidate
    return None


def motion_rhythm(
    positions: np.ndarray, mask: np.ndarray, fps: float, beats: np.ndarray, source: str, first_frame: int = 0
) -> dict[str, Any]:
    """Autocorrelation report and beat alignment of one motion [T, P, C] whose row 0 is frame ``first_frame``."""
    span = (first_frame / fps, (first_frame + len(positions) - 1) / fps)
    inside = beats[(beats >= span[0]) & (beats <= span[1])]
    period = beat_period_s(inside if inside.size >= 2 else beats)
    axes = ["x", "y", "z"][: positions.shape[-1]]
    report = rhythm_report(positions, mask, fps, period, source, axis_names=axes)
    report["beat_alignment"] = beat_alignment_report(inside, motion_beats(positions, mask, fps) + span[0], fps)
    return report


def split_beats(
    recordings: list[dict[str, Any]], manifest: dict[str, Any], fps: float
) -> dict[str, tuple[np.ndarray | None, str | None, str | None]]:
    """Per recording of a split (dicts with ``name``, ``recording``, ``info``, ``current``): its
    music's beats as :func:`recording_beats` finds them, ``(beats, source, why not)``."""
    inputs = {e["name"]: e for e in manifest["inputs"]}
    rate = manifest["config"]["sample_rate"]
    return {
        r["name"]: recording_beats(inputs[r["recording"]], r["info"], len(r["current"]), fps, rate) for r in recordings
    }


def rhythm_evaluation(
    recordings: list[dict[str, Any]],
    generated: dict[str, np.ndarray],
    real_values: dict[str, tuple[np.ndarray, np.ndarray]],
    spec: TargetSpec,
    beats: dict[str, tuple[np.ndarray | None, str | None, str | None]],
    fps: float,
) -> dict[str, Any]:
    """Per recording: the beats' source and period, and :func:`motion_rhythm` of the real motion
    (frames 0..T-1) and the generated one (frames 1..T-1). ``real_values[name]`` = (denormalised
    targets [T, D], mask [T, D]); ``generated[name]`` = denormalised [T-1, D]; ``beats[name]`` as
    :func:`split_beats` gives them."""
    out: dict[str, Any] = {}
    for rec in recordings:
        values, mask = real_values[rec["name"]]
        music, source, why = beats[rec["name"]]
        if music is None:
            out[rec["name"]] = {"unavailable": why}
            continue
        real_pos, real_mask = target_positions(values, mask, spec)
        gen_pos, _ = target_positions(generated[rec["name"]], np.ones_like(generated[rec["name"]], bool), spec)
        try:
            out[rec["name"]] = {
                "beat_source": source,
                "real": motion_rhythm(real_pos, real_mask, fps, music, source),
                "generated": motion_rhythm(gen_pos, None, fps, music, source, first_frame=1),
            }
        except KinectDataError as exc:  # too short for its beat period, too few beats
            out[rec["name"]] = {"unavailable": str(exc)}
    return out


def summarize_rhythm(per_recording: dict[str, Any]) -> dict[str, Any]:
    """Means over the recordings with a report: share with a y (vertical) peak at the beat period, and
    the beat alignment scores, for real and generated motion."""
    done = [r for r in per_recording.values() if "real" in r]
    summary: dict[str, Any] = {"recordings": len(done), "unavailable": len(per_recording) - len(done)}
    for which in ("real", "generated"):
        if not done:
            break
        summary[which] = {
            "y_peak_at_beat_share": float(np.mean([r[which]["axes"]["y"]["peak_at_beat"] for r in done])),
            "x_peak_at_beat_share": float(np.mean([r[which]["axes"]["x"]["peak_at_beat"] for r in done])),
            "y_autocorrelation_at_beat": float(
                np.nanmean([_nan(r[which]["axes"]["y"]["autocorrelation_at_beat"]) for r in done])
            ),
            "beat_align_score": float(np.mean([r[which]["beat_alignment"]["beat_align_score"] for r in done])),
            "f_measure": float(np.mean([r[which]["beat_alignment"]["f_measure"] for r in done])),
        }
    return summary


def _nan(v: float | None) -> float:
    return float("nan") if v is None else float(v)
