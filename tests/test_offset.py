"""Offset estimation on synthetic sessions with known offsets, and refusal when ambiguous."""

from __future__ import annotations

import numpy as np
import pytest

from kinectdata.audio import Audio, resample, to_mono
from kinectdata.errors import AlignmentError
from kinectdata.offset import audio_claps, estimate_offset, motion_claps
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
    from kinectdata.jointsets import JointSet
    from kinectdata.motion import Motion

    js = JointSet.custom("bare", ["a", "b"])
    m = Motion(np.arange(10) / 30, np.zeros((10, 2, 3)), js)
    assert motion_claps(m) == []
