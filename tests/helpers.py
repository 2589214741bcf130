"""Helpers shared by the tests (import as `from helpers import ...`)."""

from __future__ import annotations

import threading
import time
from types import SimpleNamespace

import numpy as np
from scipy.spatial.transform import Rotation

from kinectdata.core.jointsets import load_joint_set
from kinectdata.core.motion import Motion


def random_motion(T: int = 40, seed: int = 0, untracked: float = 0.05, inferred: float = 0.1) -> Motion:
    """A Kinect v2 Motion with random positions, orientations and tracking, jittered 30 fps times."""
    rng = np.random.default_rng(seed)
    js = load_joint_set("kinect_v2")
    t = np.arange(T) / 30.0 + rng.normal(0, 0.002, T)
    t -= t[0]
    conf = rng.choice([0.0, 0.5, 1.0], size=(T, len(js)), p=[untracked, inferred, 1 - untracked - inferred])
    q = Rotation.random(T * len(js), random_state=seed).as_quat().reshape(T, len(js), 4)
    return Motion(t, rng.normal(0, 0.6, (T, len(js), 3)), js, position_mask=conf > 0, confidence=conf, orientations=q)


# yalta65, written out here as the tests' independent expectation of kinectdata/schemas/targets/yalta65.json
YALTA_POSITIONS = ["SpineBase", "HandLeft", "HandRight"]
YALTA_ORIENTATIONS = [
    "SpineBase",
    "SpineMid",
    "SpineShoulder",
    "Neck",
    "ShoulderLeft",
    "ElbowLeft",
    "WristLeft",
    "ShoulderRight",
    "ElbowRight",
    "WristRight",
    "HipLeft",
    "KneeLeft",
    "HipRight",
    "KneeRight",
]


def skip_unless_installed(missing: str | None, what: str) -> None:
    """Skip a test whose system dependency is missing here, but fail it under CI (``CI`` set), whose
    ``.ci/run`` installs that dependency: a broken install must not pass as a skipped test."""
    import os

    import pytest

    if missing is None:
        return
    message = f"{what} not usable here: {missing}"
    if os.environ.get("CI"):
        pytest.fail(f"{message} (CI installs it: .ci/run)")
    pytest.skip(message)


# name -> parent: pelvis, a three-bone spine to the head, two arms and two legs of three bones
DANCER19 = {
    "pelvis": None,
    "spine1": "pelvis",
    "spine2": "spine1",
    "neck": "spine2",
    "head": "neck",
    "l_shoulder": "spine2",
    "l_elbow": "l_shoulder",
    "l_wrist": "l_elbow",
    "r_shoulder": "spine2",
    "r_elbow": "r_shoulder",
    "r_wrist": "r_elbow",
    "l_hip": "pelvis",
    "l_knee": "l_hip",
    "l_ankle": "l_knee",
    "l_toe": "l_ankle",
    "r_hip": "pelvis",
    "r_knee": "r_hip",
    "r_ankle": "r_knee",
    "r_toe": "r_ankle",
}


def _same(joint: str) -> dict:
    return {"from": {joint: 1}, "exact": True}


def _between(a: str, b: str) -> dict:
    return {"from": {a: 0.5, b: 0.5}, "exact": False}


TO_SMPL24 = {
    "pelvis": _same("pelvis"),
    "left_hip": _same("l_hip"),
    "right_hip": _same("r_hip"),
    "spine1": _same("spine1"),
    "left_knee": _same("l_knee"),
    "right_knee": _same("r_knee"),
    "spine2": _same("spine2"),
    "left_ankle": _same("l_ankle"),
    "right_ankle": _same("r_ankle"),
    "spine3": _between("spine2", "neck"),
    "left_foot": _same("l_toe"),
    "right_foot": _same("r_toe"),
    "neck": _same("neck"),
    "left_collar": _between("spine2", "l_shoulder"),
    "right_collar": _between("spine2", "r_shoulder"),
    "head": _same("head"),
    "left_shoulder": _same("l_shoulder"),
    "right_shoulder": _same("r_shoulder"),
    "left_elbow": _same("l_elbow"),
    "right_elbow": _same("r_elbow"),
    "left_wrist": _same("l_wrist"),
    "right_wrist": _same("r_wrist"),
    "left_hand": {"from": {"l_wrist": 1}, "exact": False, "note": "no hand joint: the wrist stands in"},
    "right_hand": {"from": {"r_wrist": 1}, "exact": False, "note": "no hand joint: the wrist stands in"},
}
"""How the made-up dancer's joints make SMPL-24's, in its joint-set file."""


def write_dancer19_schemas(folder) -> None:
    """Write the made-up dancer's joint-set file (``dancer19.json``, with its roles and SMPL-24 mapping)
    and a CSV dialect for it (``dancer19_csv.json``: wide, ``t`` in seconds, ``{joint}_x`` in metres)
    into ``folder``."""
    import json

    joints = [{"name": n, "parent": p} for n, p in DANCER19.items()]
    (folder / "dancer19.json").write_text(
        json.dumps({"name": "dancer19", "joints": joints, "roles": {"root": "pelvis"}, "to_smpl24": TO_SMPL24})
    )
    dialect = {
        "name": "dancer19_csv",
        "joint_set": "dancer19.json",
        "layout": "wide",
        "header": True,
        "time": {"column": "t", "unit": "s"},
        "position": {"columns": ["{joint}_x", "{joint}_y", "{joint}_z"], "unit": "m"},
    }
    (folder / "dancer19_csv.json").write_text(json.dumps(dialect))


class FakeInput:
    """Stands in for sounddevice.InputStream: delivers a 440 Hz tone in real time, with the
    stream clock 1000 s ahead of the monotonic clock, as PortAudio's may be."""

    def __init__(self, device, samplerate, channels, dtype, callback):
        self.rate, self.channels, self.callback = samplerate, channels, callback
        self.running = False

    def start(self):
        self.running = True
        self.t0 = time.monotonic()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        block, n = 480, 0
        while self.running:
            due = self.t0 + (n + 1) * block / self.rate
            time.sleep(max(0.0, due - time.monotonic()))
            t = (n * block + np.arange(block)) / self.rate
            data = np.repeat((0.1 * np.sin(2 * np.pi * 440 * t)).astype(np.float32)[:, None], self.channels, 1)
            info = SimpleNamespace(
                inputBufferAdcTime=1000 + n * block / self.rate, currentTime=1000 + time.monotonic() - self.t0
            )
            self.callback(data, block, info, None)
            n += 1

    def stop(self):
        self.running = False
        self.thread.join()

    def close(self):
        pass


def pulsed_tone(bpm: float, seconds: float, rate: int, tone_hz: float = 880.0) -> np.ndarray:
    """[S] float32: a tone whose loudness swells and falls sharply on every beat at ``bpm``."""
    t = np.arange(int(seconds * rate)) / rate
    return (np.abs(np.cos(np.pi * bpm / 60 * t)) ** 8 * np.sin(2 * np.pi * tone_hz * t)).astype(np.float32)


def envelope_beat_s(samples: np.ndarray, rate: int, lags_s: tuple[float, float]) -> float:
    """The lag (s, within ``lags_s``) where the loudness envelope's autocorrelation (5-ms hops) peaks."""
    hop = max(1, rate // 200)
    envelope = np.sqrt(np.convolve(np.asarray(samples, np.float64) ** 2, np.ones(hop) / hop, mode="same")[::hop])
    envelope -= envelope.mean()
    r = np.correlate(envelope, envelope, mode="full")[len(envelope) - 1 :]
    lags = np.arange(len(r)) * hop / rate
    inside = (lags >= lags_s[0]) & (lags <= lags_s[1])
    return float(lags[inside][np.argmax(r[inside])])


def _tone(rate: int, seconds: float, freqs: tuple[float, ...], decay_s: float) -> np.ndarray:
    t = np.arange(int(seconds * rate)) / rate
    return sum(np.sin(2 * np.pi * f * t) for f in freqs) / len(freqs) * np.exp(-t / decay_s)


def _click(rng: np.random.Generator, rate: int, highpass: bool) -> np.ndarray:
    """A 5 ms burst of noise, differenced (brighter) for the high click."""
    burst = rng.normal(0, 1, int(0.005 * rate))
    if highpass:
        burst = np.diff(burst, prepend=0.0)
    return burst / np.abs(burst).max()


def metre_music(
    bpm: float, beats_per_bar: int, bars: int, seed: int, rate: int = 22050
) -> tuple[np.ndarray, np.ndarray]:
    """(mono samples [S] full scale, beat times [B] s): on every downbeat a low bass tone (55/82 Hz)
    and a click, on the other beats a high click and a chord (A major, 440-660 Hz, or in alternate bars
    D major); every hit's loudness jitters, and white noise 40 dB below full scale runs underneath."""
    rng = np.random.default_rng(seed)
    beat = 60.0 / bpm
    first = 0.25 + rng.uniform(0, 0.05)
    beats = first + beat * np.arange(bars * beats_per_bar)
    out = np.zeros(int((beats[-1] + 2 * beat) * rate))
    for k, b in enumerate(beats):
        at = int(round(b * rate))
        gain = rng.uniform(0.7, 1.0)
        if k % beats_per_bar == 0:
            hit = 0.8 * _tone(rate, 0.9 * beat, (55.0, 82.4), 0.25)
            hit[: int(0.005 * rate)] += 0.3 * _click(rng, rate, False)
        else:
            chord = (440.0, 554.4, 659.3) if (k // beats_per_bar) % 2 == 0 else (587.3, 740.0, 880.0)
            hit = 0.3 * _tone(rate, 0.9 * beat, chord, 0.15)
            hit[: int(0.005 * rate)] += 0.4 * _click(rng, rate, True)
        out[at : at + hit.size] += gain * hit
    out += rng.normal(0, 0.01, out.size)
    return (out / max(1.0, np.abs(out).max())).astype(np.float32), beats


def danced_live(run, song, seed: int, beats_per_bar: int | None = None) -> np.ndarray:
    """[T, J, 3] the positions a run dances live to ``song`` (a file played at real-time pace on a
    virtual clock), for holding them to ``generate``'s on the same song and seed."""
    from kinectdata.live import sources
    from kinectdata.live.clock import VirtualClock
    from kinectdata.live.session import LiveDancer, run_live

    dancer, kept = LiveDancer(run, "torch", seed=seed), []

    class Kept:
        def send(self, pose):
            kept.append(pose.positions)

    clock = VirtualClock(100.0)
    run_live(
        dancer, sources.FileSource(song, dancer.sample_rate, 80, clock), [Kept()], clock, beats_per_bar=beats_per_bar
    )
    return np.stack(kept)
