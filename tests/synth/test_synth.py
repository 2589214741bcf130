"""Tests of the synthetic data generator (kinectdata.synth): properties checked by independent
computations on the generated audio and motion."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import signal
from scipy.spatial.transform import Rotation

from kinectdata.formats.csv import read_csv_motion
from kinectdata.synth import (
    apply_sensor_defects,
    dance,
    sensor_frame_times,
    synthesize_music,
    synthesize_recording,
    write_recording,
)
from kinectdata.synth.dancer import CLAP_HAND_GAP_M, make_body
from kinectdata.synth.music import INTRO_BARS

SR = 44100
LEAVES = {"Head", "HandTipLeft", "ThumbLeft", "HandTipRight", "ThumbRight", "FootLeft", "FootRight"}
MAIN_CHILD = {
    "SpineBase": "SpineMid",
    "SpineMid": "SpineShoulder",
    "SpineShoulder": "Neck",
    "Neck": "Head",
    "ShoulderLeft": "ElbowLeft",
    "ElbowLeft": "WristLeft",
    "WristLeft": "HandLeft",
    "HandLeft": "HandTipLeft",
    "HipRight": "KneeRight",
    "KneeRight": "AnkleRight",
    "AnkleRight": "FootRight",
}


# -- helpers -----------------------------------------------------------------------------------
def _dbfs(x) -> float:
    return float(20 * np.log10(np.sqrt(np.mean(np.square(x, dtype=np.float64))) + 1e-20))


def _low_band_onsets(audio: np.ndarray, sr: int, hop: int = 44) -> tuple[np.ndarray, np.ndarray]:
    """Onset strength of the < 200 Hz band: rise of the log energy in a trailing 10 ms window."""
    x = audio.mean(axis=1).astype(np.float64)
    low = signal.sosfilt(signal.butter(4, 200, "low", fs=sr, output="sos"), x)
    k = int(0.010 * sr)
    energy = np.convolve(low**2, np.ones(k) / k, "full")[: low.size][::hop]
    flux = np.diff(np.log(energy + 1e-12), prepend=np.log(energy[0] + 1e-12))
    return np.arange(energy.size) * hop / sr, flux


def _beat_grid(start: float, tempo: float, duration: float) -> np.ndarray:
    period = 60.0 / tempo
    return start + period * np.arange(int((duration - start) / period) + 1)


def _dance(seed=0, tempo=120.0, music_start=3.0, clap=1.4, duration=12.0, rate=120.0, extra=()):
    times = np.union1d(np.arange(0.0, duration, 1.0 / rate), np.asarray(extra, float))
    beats = _beat_grid(music_start, tempo, duration)
    m = dance(
        seed=seed, times_s=times, beat_times_s=beats, music_start_s=music_start, clap_time_s=clap, tempo_bpm=tempo
    )
    return m, beats


def _hand_distance(m) -> np.ndarray:
    return np.linalg.norm(m.joint_positions("HandLeft") - m.joint_positions("HandRight"), axis=1)


def _bend(m, a: str, b: str, c: str) -> np.ndarray:
    """Flexion at joint b in degrees (0 = straight) from positions."""
    u = m.joint_positions(a) - m.joint_positions(b)
    v = m.joint_positions(c) - m.joint_positions(b)
    cos = np.sum(u * v, axis=1) / np.linalg.norm(u, axis=1) / np.linalg.norm(v, axis=1)
    return 180.0 - np.degrees(np.arccos(np.clip(cos, -1, 1)))


@pytest.fixture(scope="module")
def rec():
    return synthesize_recording(seed=7, duration_s=12.0)


# -- music -------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def music():
    return synthesize_music(seed=3, duration_s=12.0, tempo_bpm=112, music_start_s=2.5, clap_time_s=1.0)


def test_music_shape_levels_and_info(music):
    audio, info = music
    assert audio.shape == (round(12.0 * SR), 2) and audio.dtype == np.float32
    peak = 20 * np.log10(np.abs(audio).max())
    assert -1.5 < peak <= -0.9
    assert -73 < _dbfs(audio[: int(0.9 * SR)]) < -67  # the noise floor before the clap
    assert _dbfs(audio[int(2.6 * SR) :]) > -30  # the music is loud
    assert not np.array_equal(audio[:, 0], audio[:, 1])  # stereo
    period = 60 / 112
    beats = np.asarray(info["beat_times_s"])
    assert beats[0] == 2.5 and np.allclose(np.diff(beats), period) and beats[-1] <= 12.0 < beats[-1] + period
    assert np.allclose(info["downbeat_times_s"], beats[::4])
    assert info["sections"][0]["name"] == "intro"
    assert info["sections"][1]["start_s"] == pytest.approx(2.5 + INTRO_BARS * 4 * period)


@pytest.mark.parametrize("seed,tempo", [(3, 112), (4, 96), (5, 128)])
def test_low_band_onsets_fall_on_the_beats(seed, tempo):
    audio, info = synthesize_music(seed=seed, duration_s=12.0, tempo_bpm=tempo, music_start_s=2.0, clap_time_s=0.8)
    t, flux = _low_band_onsets(audio, SR)
    period = info["beat_period_s"]
    for beat in info["beat_times_s"][:-1]:
        sel = (t > beat - period / 3) & (t < beat + period / 3)
        assert abs(t[sel][np.argmax(flux[sel])] - beat) < 0.015
    # Beats are where the low band starts: off-beat eighths are much weaker there.
    on = [flux[np.abs(t - b) < 0.015].max() for b in info["beat_times_s"][:-1]]
    off = [flux[np.abs(t - b - period / 2) < 0.015].max() for b in info["beat_times_s"][: 4 * INTRO_BARS - 1]]
    assert min(on) > 3 * max(off)


def test_clap_is_the_sharpest_transient_before_the_music(music):
    audio, info = music
    clap, start = info["clap_time_s"], info["music_start_s"]
    x = audio[: int(start * SR)].mean(axis=1).astype(np.float64)
    noise = np.sqrt(np.mean(x[: int(0.9 * SR)] ** 2))
    # Sharpest: the biggest sample-to-sample jump and the biggest sample are right after the onset.
    jump = int(np.argmax(np.abs(np.diff(x))))
    assert 0 <= jump / SR - clap < 0.004
    assert 0 <= np.argmax(np.abs(x)) / SR - clap < 0.004
    # It starts at the onset: nothing above the noise before it, clearly above right after.
    onset = np.flatnonzero(np.abs(x) > 30 * noise)[0] / SR
    assert 0 <= onset - clap < 0.001
    # Band-passed noise burst: most energy in 0.7-4 kHz; decays 30 dB within 40 ms.
    burst = x[int(clap * SR) : int((clap + 0.06) * SR)]
    spec = np.abs(np.fft.rfft(burst, 8192)) ** 2
    f = np.fft.rfftfreq(8192, 1 / SR)
    assert spec[(f > 700) & (f < 4000)].sum() > 0.8 * spec.sum()
    peak_db = _dbfs(x[int(clap * SR) : int((clap + 0.005) * SR)])
    assert _dbfs(x[int((clap + 0.04) * SR) : int((clap + 0.05) * SR)]) < peak_db - 30
    assert info["clap_peak_s"] > clap


def test_music_without_clap_is_silent_before_it_starts():
    audio, _ = synthesize_music(seed=3, duration_s=8.0, tempo_bpm=112, music_start_s=2.5, clap_time_s=None)
    assert 20 * np.log10(np.abs(audio[: int(2.49 * SR)]).max()) < -55


# -- dancer ------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed,tempo", [(0, 120.0), (1, 97.0), (2, 127.0)])
def test_bounce_lowest_on_the_beats_with_the_beat_period(seed, tempo):
    music_start = 3.0
    times = np.arange(0.013, 12.0, 1 / 30)  # a 30 fps grid not aligned with the beats
    beats = _beat_grid(music_start, tempo, 12.0)
    m = dance(seed=seed, times_s=times, beat_times_s=beats, music_start_s=music_start, clap_time_s=1.4, tempo_bpm=tempo)
    y = m.joint_positions("SpineBase")[:, 1]
    period = 60 / tempo
    for beat in beats[2:-1]:  # the groove fades in over the first two beats
        sel = np.flatnonzero(np.abs(times - beat) < period / 2)
        assert abs(times[sel[np.argmin(y[sel])]] - beat) <= 1 / 30 + 1e-9
    # Dominant period of the vertical root motion while dancing = the beat period.
    seg = y[times > music_start + 2 * period]
    seg = seg - seg.mean()
    spec = np.abs(np.fft.rfft(seg * np.hanning(seg.size), 16 * seg.size))
    freqs = np.fft.rfftfreq(16 * seg.size, 1 / 30)
    assert abs(freqs[np.argmax(spec)] - tempo / 60) < 0.05
    assert np.ptp(seg) > 0.03  # a visible bounce


@pytest.mark.parametrize("seed,tempo,clap", [(0, 120.0, 1.4), (1, 97.0, 0.9), (5, 110.0, 1.77), (6, 128.0, 1.2)])
def test_clap_hands_meet_exactly_once(seed, tempo, clap):
    m, _ = _dance(
        seed=seed,
        tempo=tempo,
        clap=clap,
        music_start=clap + 1.5,
        duration=24.0,
        rate=240,
        extra=[clap, clap - 0.005, clap - 0.02],
    )
    t, d = m.times, _hand_distance(m)
    at = np.flatnonzero(t == clap)[0]
    assert d[at] < 0.04 and d[at] == pytest.approx(CLAP_HAND_GAP_M, abs=1e-6)
    assert (d[t == clap - 0.02][0] - d[t == clap - 0.005][0]) / 0.015 > 1.0  # closing fast just before
    assert np.all(d[np.abs(t - clap) > 0.5] > 0.15)
    assert np.argmin(d) >= at and t[np.argmin(d)] - clap < 0.1  # held briefly after the impact


def test_no_clap_means_hands_apart_everywhere():
    m, _ = _dance(seed=4, clap=None, duration=20.0)
    assert _hand_distance(m).min() > 0.15


@pytest.mark.parametrize("seed", [0, 3])
def test_forward_kinematics_consistency(seed):
    m, _ = _dance(seed=seed, rate=60)
    js = m.joint_set
    q = m.orientations
    has = js.orientation_mask
    assert set(np.array(js.names)[~has]) == LEAVES
    assert np.all(np.isnan(q[:, ~has])) and not m.orientation_mask[:, ~has].any()
    assert np.allclose(np.linalg.norm(q[:, has], axis=-1), 1.0)
    for parent, child in js.bones():
        bone = m.positions[:, child] - m.positions[:, parent]
        length = np.linalg.norm(bone, axis=1)
        assert np.ptp(length) < 1e-9, js.names[child]
        # The child sits at a fixed offset in the parent's frame: R_parent^-1 (p_child - p_parent).
        local = Rotation.from_quat(q[:, parent]).inv().apply(bone)
        assert np.ptp(local, axis=0).max() < 1e-9, js.names[child]
        if MAIN_CHILD.get(js.names[parent]) == js.names[child]:  # the y axis points at the main child
            assert np.allclose(local[0], [0, length[0], 0], atol=1e-9)
    # Consecutive quaternions keep their sign (learning targets must not flip).
    dots = np.sum(q[1:, has] * q[:-1, has], axis=-1)
    assert dots.min() > 0


def test_plausible_body_in_camera_space():
    m, _ = _dance(seed=2, rate=30)
    body = make_body(m.metadata["height_m"])
    assert 1.55 < m.metadata["height_m"] < 1.85 and body.length("KneeLeft") > 0.35
    p = {n: m.joint_positions(n) for n in m.joint_set.names}
    assert np.all((p["SpineBase"][:, 2] > 2.1) & (p["SpineBase"][:, 2] < 2.9))
    assert np.all(p["ShoulderLeft"][:, 0] < p["ShoulderRight"][:, 0])  # facing the sensor: left at -x
    assert np.all(p["HipLeft"][:, 0] < p["HipRight"][:, 0])
    assert np.all(p["Head"][:, 1] > p["Neck"][:, 1])
    assert np.all(p["FootLeft"][:, 2] < p["AnkleLeft"][:, 2])  # toes towards the sensor (-z)
    floor = m.metadata["floor_y_m"]
    assert -1.0 < floor < -0.9
    feet = np.stack([p["FootLeft"][:, 1], p["FootRight"][:, 1], p["AnkleLeft"][:, 1], p["AnkleRight"][:, 1]])
    assert feet.min() > floor and np.median(p["FootLeft"][:, 1]) < floor + 0.06
    assert p["Head"][:, 1].max() - floor == pytest.approx(m.metadata["height_m"] - 0.09, abs=0.06)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_joint_limits_and_smoothness(seed):
    m, _ = _dance(seed=seed, tempo=(96.0, 110.0, 120.0, 128.0)[seed], duration=40.0, rate=60)
    for side in ("Left", "Right"):
        elbow = _bend(m, f"Shoulder{side}", f"Elbow{side}", f"Wrist{side}")
        knee = _bend(m, f"Hip{side}", f"Knee{side}", f"Ankle{side}")
        wrist = _bend(m, f"Elbow{side}", f"Wrist{side}", f"Hand{side}")
        assert 0 <= elbow.min() and elbow.max() <= 150
        assert 0 < knee.min() and knee.max() <= 120
        assert wrist.max() <= 70
        # Knees bend forwards: the knee is in front of (-z) the hip-ankle line.
        hip, kn, ank = (m.joint_positions(f"{j}{side}") for j in ("Hip", "Knee", "Ankle"))
        assert np.all(kn[:, 2] < (hip[:, 2] + ank[:, 2]) / 2 + 1e-3)
    # No jumps: joint speeds stay human (outside the clap's impact the accelerations too).
    v = np.linalg.norm(np.diff(m.positions, axis=0), axis=-1) * 60
    assert v.max() < 6.0
    a = np.linalg.norm(np.diff(m.positions, 2, axis=0), axis=-1) * 3600
    far = np.abs(m.times[1:-1] - 1.4) > 0.2
    assert a[far].max() < 200


def test_still_before_the_music_except_the_clap():
    m, _ = _dance(seed=1, clap=1.4, music_start=3.5, rate=60)
    t = m.times
    v = np.linalg.norm(np.diff(m.positions, axis=0), axis=-1) * 60
    arms = [
        m.joint_set.index(n)
        for n in m.joint_set.names
        if any(k in n for k in ("Shoulder", "Elbow", "Wrist", "Hand", "Thumb"))
    ]
    still = np.ones(m.n_joints, bool)
    still[arms] = False
    before = t[1:] < 3.5
    assert v[before][:, still].max() < 0.03  # breathing only
    quiet = before & (np.abs(t[1:] - 1.4) > 1.0)
    assert v[quiet].max() < 0.03
    assert v[(t[1:] > 5.5) & (t[1:] < 8)].max() > 0.5  # and then it dances


def test_dance_does_not_depend_on_the_sampling():
    a, beats = _dance(seed=9, rate=30, duration=20.0)
    sub = a.times[::7][5:40]
    b = dance(seed=9, times_s=sub, beat_times_s=beats, music_start_s=3.0, clap_time_s=1.4, tempo_bpm=120.0)
    assert np.allclose(b.positions, a.positions[::7][5:40], atol=1e-12)
    assert a.metadata["blocks"][0]["figure"] == "swing"
    assert len({blk["figure"] for blk in a.metadata["blocks"]}) >= 3  # variety between bars


def test_dance_rejects_a_clap_too_close_to_the_music():
    with pytest.raises(ValueError, match="clap"):
        _dance(clap=2.5, music_start=3.0)


# -- sensor ------------------------------------------------------------------------------------
def test_frame_timing_statistics():
    times, info = sensor_frame_times(seed=11, duration_s=120.0)
    assert times[0] == 0.0 and np.all(np.diff(times) > 0)
    grid = np.round(times * 30)
    residual = times - grid / 30
    assert 0.0017 < residual[1:].std() < 0.0023  # jitter sd 2 ms, not cumulative
    assert np.abs(residual).max() < 0.011
    missing = int(grid[-1] + 1 - times.size)
    assert missing == info["dropped_frames"] > 0
    assert info["dropped_frames"] / info["n_nominal"] < 0.012
    assert np.allclose(
        sorted(set(range(int(grid[-1]) + 1)) - set(grid.astype(int))),
        np.round(np.array(info["dropped_nominal_times_s"]) * 30),
    )


def test_sensor_noise_states_and_spans(rec):
    truth, motion, states = rec.true_motion, rec.motion, rec.states
    js = motion.joint_set
    tracked = states == 2
    err = (rec.raw_positions - truth.positions)[tracked]
    assert 0.0025 < err.std() < 0.0035
    assert np.allclose(motion.confidence, np.select([states == 2, states == 1], [1.0, 0.5], 0.0))
    assert np.array_equal(motion.position_mask, states > 0)
    assert np.all(np.isnan(motion.positions[states == 0])) and np.all(np.isfinite(rec.raw_positions))
    spans = rec.truth["tracking_spans"]
    rebuilt = np.full_like(states, 2)
    for s in spans:
        rebuilt[s["first_frame"] : s["last_frame"] + 1, js.index(s["joint"])] = s["state"]
        assert motion.times[s["first_frame"]] == s["start_s"] and motion.times[s["last_frame"]] == s["end_s"]
    assert np.array_equal(rebuilt, states)
    groups = {}
    for s in spans:
        groups.setdefault(s["group"], []).append(s)
    hands = [g for g in groups.values() if "Wrist" in g[0]["joint"]]
    feet = [g for g in groups.values() if "Ankle" in g[0]["joint"] or "Foot" in g[0]["joint"]]
    assert hands and len(feet) == 1
    for g in hands:
        assert {s["joint"][:-4] if s["joint"].endswith("Left") else s["joint"][:-5] for s in g} == {
            "Wrist",
            "Hand",
            "HandTip",
            "Thumb",
        }
        assert 0.05 <= g[0]["end_s"] - g[0]["start_s"] <= 0.3
    assert feet[0][0]["end_s"] - feet[0][0]["start_s"] >= 0.6 and feet[0][0]["state"] == 0
    # Not-tracked joints hold the last written value; inferred ones are noisier than tracked ones.
    lost = np.argwhere(states == 0)
    i, j = lost[0]
    assert np.array_equal(rec.raw_positions[i, j], rec.raw_positions[i - 1, j])
    inf_err = (rec.raw_positions - truth.positions)[states == 1]
    if inf_err.size:
        assert inf_err.std() > 2 * err.std()


def test_sensor_protects_given_windows():
    times, _ = sensor_frame_times(seed=1, duration_s=20.0)
    truth = dance(
        seed=1,
        times_s=times,
        beat_times_s=_beat_grid(3.0, 120.0, 25.0),
        music_start_s=3.0,
        clap_time_s=1.4,
        tempo_bpm=120.0,
    )
    for seed in range(5):
        out = apply_sensor_defects(truth, seed=seed, protect=[(0.0, 4.0)], foot_window=(10.0, 20.0))
        assert np.all(out.states[times < 4.0] == 2)
        foot = [s for s in out.spans if s["joint"].startswith("Ankle")]
        assert foot and foot[0]["start_s"] >= 10.0


# -- the recording -----------------------------------------------------------------------------
def test_offset_convention_and_coverage(rec):
    tr = rec.truth
    assert tr["clap_time_audio_s"] - tr["clap_time_motion_s"] == pytest.approx(tr["offset_s"], abs=1e-12)
    assert rec.motion.times[0] == 0.0 and tr["motion_start_audio_s"] == tr["offset_s"]
    assert -1.5 <= tr["offset_s"] <= 2.5
    assert tr["motion_end_audio_s"] < tr["duration_s"] == rec.audio.shape[0] / rec.sample_rate
    assert 0 < tr["clap_time_audio_s"] < tr["music_start_s"]
    assert 0 < tr["clap_time_motion_s"] < rec.motion.times[-1]
    # Independent check: the clap found in the audio and in the true motion gives the offset.
    x = rec.audio[: int(tr["music_start_s"] * SR)].mean(axis=1)
    audio_clap = np.flatnonzero(np.abs(x) > 0.05)[0] / SR
    assert audio_clap == pytest.approx(tr["clap_time_audio_s"], abs=0.001)
    d = _hand_distance(rec.true_motion)
    first_close = rec.motion.times[np.flatnonzero(d < 0.04)[0]]  # first frame after the impact
    assert 0 <= first_close - tr["clap_time_motion_s"] < 1 / 30 + 0.01
    assert audio_clap - first_close == pytest.approx(tr["offset_s"], abs=0.04)
    # The beat grid matches the dance: root lowest near the beats (in recording time).
    beats_motion = np.array(tr["beat_times_s"]) - tr["offset_s"]
    y = rec.true_motion.joint_positions("SpineBase")[:, 1]
    t = rec.motion.times
    period = tr["beat_period_s"]
    for b in beats_motion[2:]:
        sel = np.flatnonzero(np.abs(t - b) < period / 2)
        if b < t[-1] - period and sel.size > 5:
            assert abs(t[sel[np.argmin(y[sel])]] - b) < 0.045


def test_truth_contents(rec):
    tr = rec.truth
    for key in (
        "seed",
        "generator_version",
        "tempo_bpm",
        "beat_times_s",
        "downbeat_times_s",
        "music_start_s",
        "clap_time_audio_s",
        "clap_time_motion_s",
        "offset_s",
        "duration_s",
        "sample_rate",
        "tracking_spans",
        "dropped_frames",
        "command",
    ):
        assert key in tr
    assert 96 <= tr["tempo_bpm"] <= 128
    assert tr["beat_times_s"][0] == tr["music_start_s"]
    assert tr["command"].startswith("kinectdata synth --seed 7 --duration 12.0")
    assert tr["dropped_frames"] == rec.motion.timing()["dropped_frames"]
    json.dumps(tr)  # JSON-ready


def test_determinism_and_regeneration(rec):
    again = synthesize_recording(seed=7, duration_s=12.0)
    assert np.array_equal(again.audio, rec.audio)
    assert np.array_equal(again.motion.positions, rec.motion.positions, equal_nan=True)
    assert np.array_equal(again.motion.orientations, rec.motion.orientations, equal_nan=True)
    assert np.array_equal(again.motion.times, rec.motion.times)
    assert again.truth == rec.truth
    # The command line's explicit values regenerate the same session.
    same = synthesize_recording(
        seed=7, duration_s=12.0, tempo_bpm=rec.truth["tempo_bpm"], offset_s=rec.truth["offset_s"]
    )
    assert np.array_equal(same.raw_positions, rec.raw_positions) and same.truth == rec.truth
    other = synthesize_recording(seed=8, duration_s=12.0)
    assert other.truth["offset_s"] != rec.truth["offset_s"]


def test_recording_without_clap():
    r = synthesize_recording(seed=7, duration_s=12.0, clap=False)
    tr = r.truth
    assert tr["clap"] is False and tr["clap_time_audio_s"] is None and tr["clap_time_motion_s"] is None
    assert 20 * np.log10(np.abs(r.audio[: int((tr["music_start_s"] - 0.01) * SR)]).max()) < -55
    assert _hand_distance(r.true_motion).min() > 0.15
    assert "--no-clap" in tr["command"]


def test_explicit_offsets_and_limits():
    r = synthesize_recording(seed=2, duration_s=10.0, tempo_bpm=100, offset_s=-1.2)
    assert r.truth["offset_s"] == -1.2 and r.truth["tempo_bpm"] == 100.0
    assert r.truth["clap_time_motion_s"] > 1.2  # the sensor ran 1.2 s before the audio
    with pytest.raises(ValueError):
        synthesize_recording(seed=0, duration_s=5.0)
    with pytest.raises(ValueError):
        synthesize_recording(seed=0, duration_s=8.0, offset_s=2.5, tempo_bpm=96)


def test_write_recording_audio_and_truth(rec, tmp_path):
    import soundfile as sf

    a = write_recording(rec, tmp_path / "a", "s7")
    b = write_recording(rec, tmp_path / "b", "s7", audio_format="wav", dialect="kinectreader")
    data, sr = sf.read(a["audio"], dtype="float32")
    assert sr == SR and data.shape == rec.audio.shape and sf.info(a["audio"]).subtype == "PCM_16"
    assert np.abs(data - rec.audio).max() < 1e-4
    assert b["audio"].suffix == ".wav"
    truth = json.loads(a["truth"].read_text())
    assert truth["offset_s"] == rec.truth["offset_s"] and truth["dialect"] == "dumpkinectskeleton"
    assert truth["files"] == {"audio": "s7.flac", "skeleton": "s7.csv", "truth": "s7.truth.json"}
    assert "--name s7" in truth["command"] and "--dialect dumpkinectskeleton" in truth["command"]
    again = write_recording(rec, tmp_path / "c", "s7")
    for key in ("audio", "skeleton", "truth"):
        assert a[key].read_bytes() == again[key].read_bytes()


@pytest.mark.parametrize("dialect", ["dumpkinectskeleton", "kinectreader", "lsl_kinect", "canonical"])
def test_write_recording_round_trip(rec, tmp_path, dialect):
    paths = write_recording(rec, tmp_path / "a", "s7", dialect=dialect)
    again = write_recording(rec, tmp_path / "b", "s7", dialect=dialect)
    assert paths["skeleton"].read_bytes() == again["skeleton"].read_bytes()
    back = read_csv_motion(paths["skeleton"], schema=dialect)
    ok = rec.motion.position_mask
    assert np.allclose(back.times, rec.motion.times, atol=1e-6)
    assert np.array_equal(back.position_mask, ok) and np.array_equal(back.confidence, rec.motion.confidence)
    assert np.abs(back.positions[ok] - rec.motion.positions[ok]).max() < 1e-5
    text = paths["skeleton"].read_text()
    assert "nan" not in text.lower()  # not-tracked joints are written as values with state 0
