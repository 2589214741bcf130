"""Offset estimation on synthetic sessions with known offsets, and refusal when ambiguous."""

from __future__ import annotations

import numpy as np
import pytest

from kinectdata.align.audio import Audio, resample, to_mono
from kinectdata.align.offset import audio_claps, estimate_offset, motion_claps
from kinectdata.core.errors import AlignmentError
from kinectdata.synth import synthesize_recording

FRAME = 1 / 30


def _audio16k(rec) -> Audio:
    return Audio(resample(to_mono(rec.audio), rec.sample_rate, 16000), 16000)


@pytest.mark.parametrize("seed,offset", [(11, -1.4), (12, 0.0), (13, 0.37), (14, 1.9), (15, 2.45), (3, None)])
def test_auto_offset_recovers_injected_offsets_within_one_frame(seed, offset):
    rec = synthesize_recording(seed=seed, duration_s=12.0, offset_s=offset)
    est = estimate_offset(rec.motion, _audio16k(rec))
    assert est.method == "clap" and est.confidence == 1.0
    assert abs(est.offset - rec.truth["offset_s"]) < FRAME


def test_clap_events_are_found_in_both_streams():
    rec = synthesize_recording(seed=21, duration_s=12.0)
    claps = motion_claps(rec.motion)
    assert len(claps) == 1 and abs(claps[0] - rec.truth["clap_time_motion_s"]) < FRAME
    isolated = audio_claps(_audio16k(rec))
    sharpest = max(isolated, key=lambda e: e[1])
    assert abs(sharpest[0] - rec.truth["clap_time_audio_s"]) < 0.006  # 5 ms analysis frames


@pytest.mark.parametrize("seed", [31, 32, 33])
def test_steady_beat_without_clap_is_refused_not_guessed(seed):
    rec = synthesize_recording(seed=seed, duration_s=12.0, clap=False)
    with pytest.raises(
        AlignmentError, match=r"no clap in the motion.*cross-correlation is ambiguous.*--offset SECONDS"
    ):
        estimate_offset(rec.motion, _audio16k(rec))


def test_two_equal_claps_in_the_audio_are_ambiguous():
    rec = synthesize_recording(seed=41, duration_s=12.0)
    audio = _audio16k(rec)
    clap_at = int(round(rec.truth["clap_time_audio_s"] * 16000))
    burst = audio.samples[clap_at - 80 : clap_at + 1600].copy()
    samples = audio.samples.copy()
    # a second identical clap 0.6 s earlier, in the silence before the first one
    start = clap_at - int(0.6 * 16000) - 80
    samples[start : start + burst.size] += burst
    with pytest.raises(AlignmentError, match=r"fit about equally well"):
        estimate_offset(rec.motion, Audio(samples, 16000))


def test_max_offset_excludes_far_candidates():
    rec = synthesize_recording(seed=12, duration_s=12.0, offset_s=1.5)
    audio = _audio16k(rec)
    assert estimate_offset(rec.motion, audio, max_offset=2.0).offset == pytest.approx(1.5, abs=FRAME)
    with pytest.raises(AlignmentError):
        estimate_offset(rec.motion, audio, max_offset=1.0)


def test_motion_without_hand_roles_has_no_claps():
    from kinectdata.core.jointsets import JointSet
    from kinectdata.core.motion import Motion

    js = JointSet.custom("bare", ["a", "b"])
    m = Motion(np.arange(10) / 30, np.zeros((10, 2, 3)), js)
    assert motion_claps(m) == []


def _irregular_events_scene(offset, sr=16000, seed=0, t0=0.0):
    """Motion whose right foot kicks at irregular times, audio with a hit at the same times."""
    from kinectdata.core.jointsets import load_joint_set
    from kinectdata.core.motion import Motion

    rng = np.random.default_rng(seed)
    events = np.sort(rng.uniform(2, 50, 25))
    t = np.arange(0, 55, 1 / 30)
    pos = np.zeros((t.size, 25, 3))
    pos[..., 0], pos[..., 2] = np.linspace(-0.3, 0.3, 25), 2.5
    for e in events:
        d = t - e
        pos[:, 19, 1] += 0.15 * np.clip(d / 0.06, 0, 1) * np.clip(1 - (d - 0.06) / 0.44, 0, 1) * (d > 0)
    x = rng.normal(0, 0.001, 60 * sr)
    for e in events:
        i, k = int((e + offset) * sr), np.arange(int(0.05 * sr))
        x[i : i + k.size] += rng.normal(0, 0.3, k.size) * np.exp(-k / (0.01 * sr))
    return Motion(t + t0, pos, load_joint_set("kinect_v2")), Audio(x.astype(np.float32), sr)


@pytest.mark.parametrize("sr,t0", [(16000, 0.0), (22050, 0.0), (11025, 0.0), (16000, 5.0)])
def test_cross_correlation_succeeds_on_irregular_events_at_any_rate_and_start(sr, t0):
    motion, audio = _irregular_events_scene(0.8, sr=sr, t0=t0)
    est = estimate_offset(motion, audio)
    assert est.method == "xcorr" and est.confidence > 0.5
    assert est.offset == pytest.approx(0.8 - t0, abs=FRAME)


def test_low_sample_rate_audio_is_analysed_at_16k():
    rec = synthesize_recording(seed=12, duration_s=12.0, offset_s=0.6)
    audio = Audio(resample(to_mono(rec.audio), rec.sample_rate, 2000), 2000)
    est = estimate_offset(rec.motion, audio)
    assert est.method == "clap" and est.offset == pytest.approx(0.6, abs=FRAME)


@pytest.mark.parametrize("frames,samples", [(None, 0), (None, 100), (1, 16000 * 4)])
def test_inputs_too_short_to_correlate_are_refused_not_an_index_error(frames, samples):
    """A one-frame recording, or a few samples of audio, leave nothing to cross-correlate."""
    rec = synthesize_recording(seed=3, duration_s=8.0)
    motion = rec.motion if frames is None else rec.motion.select(slice(0, frames))
    audio = Audio(np.random.default_rng(0).normal(0, 0.1, samples).astype(np.float32), 16000)
    with pytest.raises(AlignmentError, match=r"is too short to estimate their offset"):
        estimate_offset(motion, audio)
