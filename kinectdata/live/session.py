"""A live session: audio in, one network step per motion frame, each pose sent as it is made.

The audio arrives in small blocks (:mod:`.sources`); each frame's features are computed as soon
as its slice of audio is complete (:class:`~kinectdata.features.streaming.StreamingFeatures`, as
``generate`` computes them), the streaming network steps once (an engine of
:mod:`~kinectdata.inference.engines`, its state carried), and the pose, denormalised and placed
as ``generate`` places it (:mod:`~kinectdata.inference.start`: the floor rule for a root-centred
run), goes to every sink at once. On the same audio the poses are ``generate``'s.

Measured per frame (:class:`LiveStats`): the **latency** from the moment the last sample of the
frame's audio was heard to the moment its pose left for the sinks, and the **processing** time from
the arrival of the block that completed the frame to that moment; over the session, the **jitter**
of the send times against the frame period, frames **late** (latency above one frame period),
input **overruns**, and frames the heard audio called for that were never sent (**dropped**).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.core.errors import ConfigError, KinectDataError
from kinectdata.features import feature_config, needs_metre, song_style, style_input_of
from kinectdata.features.beats import music_beats
from kinectdata.features.metre import recording_metre
from kinectdata.features.silence import silent_frames
from kinectdata.features.streaming import StreamingFeatures
from kinectdata.features.style_input import NO_STYLE
from kinectdata.inference.engines import make_engine, onnxruntime_available
from kinectdata.inference.smoothing import MotionSmoother, run_smoothing
from kinectdata.inference.start import target_poses
from kinectdata.inference.turning import drawn_line, live_turning
from kinectdata.live.sinks import LivePose
from kinectdata.models.registry import model_kind
from kinectdata.models.run import load_model, model_name
from kinectdata.targets.normalization import Normalizer
from kinectdata.targets.specs import TargetSpec

LATENCY_GOAL_MS = (10.0, 25.0)
"""Issue 27's goals: median and 99th percentile of the latency, milliseconds."""
LONGEST_SESSION_S = 6 * 3600.0
"""A device session without --duration plans frames for this long (its frame clock's size)."""


class LiveDancer:
    """A trained run stepping one frame at a time: features [*F] in, :class:`LivePose` out.

    Args:
        run: the run folder; its model must stream (both bundled models do). A 3-D target's pose is
            placed as ``generate`` places it; a 2-D one (the cdhc model's) is its joints in the
            target's units (0..1 of the training recordings' range, y down).
        engine, precision: as ``generate``'s (torch float32 / float16, onnxruntime float32);
            ``auto``: ONNX Runtime where it is installed and the model runs on it (a yalta step takes
            about half torch's time at batch 1), else torch.
        turning, travel, seed: draw the run's turning about the vertical and its travel across the
            floor one frame at a time, from generators seeded by ``seed``
            (:func:`~kinectdata.inference.turning.live_turning`; held still while the features are
            silence), as ``generate`` draws them on the same audio and seed; a run trained without
            them draws none; a run trained with ``sway`` scales its network's root along the floor
            before them, as ``generate`` does. A run trained with ``smooth_hz`` low-passes each frame after them
            (:class:`~kinectdata.inference.smoothing.MotionSmoother`), as ``generate`` does. A run
            trained with ``style_tempo`` dances live music at its own tempo: a network cannot hear
            music faster than it arrives (:mod:`kinectdata.inference.style_tempo`). A run with a
            phrase code (``--latent-dims``) draws it from row ``seed`` of its table, as ``generate`` does.
    """

    def __init__(
        self,
        run: str | Path,
        engine: str = "auto",
        precision: str = "float32",
        *,
        turning: bool = True,
        seed: int = 0,
        travel: bool = True,
    ):
        net, config = load_model(run)
        self.config, self.seed = config, int(seed)
        for drawn, asked in (("turning", turning), ("travel", travel)):
            if not asked:
                config.pop(drawn, None)
        self.kind = model_kind(model_name(config))
        if not self.kind.streams:
            raise KinectDataError(
                f"{run}: the {self.kind.name} model does not step one frame at a time, so it cannot dance live "
                "(the bundled yalta and cdhc models do)"
            )
        self.data = config["dataset"]
        self.fps, self.sample_rate = float(self.data["fps"]), int(self.data["sample_rate"])
        self.spec = TargetSpec.from_dict(self.data["target"])
        self.features = feature_config(self.data["features"])
        self.norm = Normalizer.from_dict(self.data["normalisation"])
        if engine == "auto":
            offered = "onnxruntime" in self.kind.engines and precision in self.kind.engines["onnxruntime"]
            engine = "onnxruntime" if offered and onnxruntime_available() else "torch"
        self.engine = f"{engine} {precision}"
        self.stepper = make_engine(net, engine, precision, self.kind, draw=self.seed)  # a phrase code's draws too
        self.pose = np.asarray(self.data["start_pose"], np.float32)
        self.anchor: np.ndarray | None = None
        self.joint_set = self.spec.joints
        self.beats_per_bar: int | None = None  # the song's metre, once known (set_metre)
        self.turning = live_turning(config, self.seed)
        self.turning_line = drawn_line(config)
        self.smoother = self._smoother()

    def _smoother(self) -> MotionSmoother | None:
        """The run's smoothing one frame at a time, from rest (:mod:`kinectdata.inference.smoothing`)."""
        cutoff = run_smoothing(self.config)
        return None if cutoff is None else MotionSmoother(self.spec, self.fps, cutoff)

    @property
    def draws_by_metre(self) -> bool:
        """Whether the run draws a song's turning and travel by its metre (``drawn_by_metre``)."""
        return self.turning is not None and bool(self.config.get("drawn_by_metre"))

    def set_metre(self, beats_per_bar: int | None) -> None:
        """The song's metre: its turning and travel are drawn as the run's training dances of that metre
        turned and travelled, where the run has them (:func:`~kinectdata.inference.turning.run_turning`).
        The draws start again."""
        self.beats_per_bar = beats_per_bar
        self.turning = live_turning(self.config, self.seed, beats_per_bar)
        self.turning_line = drawn_line(self.config, beats_per_bar)
        self.smoother = self._smoother()

    def warm_up(self, frames: int = 10) -> None:
        """Step a few silent frames and start again from the mean pose: the first steps of a network
        (memory, kernels chosen) and of the pose's forward kinematics are slow, and a live session's
        first frames must not pay for them."""
        shape = tuple(self.data["feature_shape"])
        silent = np.zeros(shape, np.float32)
        for k in range(frames):
            self.step(silent, k)
        self.stepper.reset()
        self.pose = np.asarray(self.data["start_pose"], np.float32)
        self.anchor = None
        self.turning = live_turning(self.config, self.seed, self.beats_per_bar)  # the draws start again
        self.smoother = self._smoother()  # and the smoothing from rest

    def step(self, features: np.ndarray, index: int) -> LivePose:
        """The pose of frame ``index`` from its features (frames are stepped in order)."""
        self.pose = self.stepper.step(features, self.pose)
        values = self.norm.invert(self.pose[None], self.spec)
        if self.turning is not None:
            stream, silence = self.turning
            values[0] = stream.step(values[0], not silent_frames(np.asarray(features)[None], silence)[0])
        if self.smoother is not None:
            values[0] = self.smoother.step(values[0])
        skeleton = self.data.get("skeleton") or {}
        # placed as generate places it: the floor rule's anchor from the first frame, then held
        positions, orientations, self.anchor = target_poses(
            values, self.spec, skeleton, bool(self.data["root_centre"]), self.anchor
        )
        return LivePose(index, index / self.fps, positions[0], None if orientations is None else orientations[0])


@dataclass
class LiveStats:
    """What a session measured (seconds and milliseconds as named)."""

    fps: float
    source: str
    latency_ms: list[float] = field(default_factory=list)
    processing_ms: list[float] = field(default_factory=list)
    sent_s: list[float] = field(default_factory=list)
    overruns: int = 0
    expected_frames: int = 0
    heard_s: float = 0.0
    ended: str = "the audio ended"
    fault: str | None = None
    sinks: list[str] = field(default_factory=list)

    @property
    def frames(self) -> int:
        return len(self.latency_ms)

    def to_dict(self) -> dict[str, Any]:
        """The ``--stats`` JSON: the summary and every frame's figures."""
        return {"summary": self.summary(), "per_frame": {"latency_ms": self.latency_ms,
                "processing_ms": self.processing_ms, "sent_s": self.sent_s}}  # fmt: skip

    def summary(self) -> dict[str, Any]:
        lat, proc = np.asarray(self.latency_ms), np.asarray(self.processing_ms)
        period_ms = 1000.0 / self.fps
        gaps = np.diff(self.sent_s) * 1000.0
        return {
            "source": self.source,
            "ended": self.ended,
            "fault": self.fault,
            "frames_sent": self.frames,
            "frames_dropped": max(0, self.expected_frames - self.frames),
            "audio_heard_s": self.heard_s,
            "latency_median_ms": _stat(lat, 50),
            "latency_p99_ms": _stat(lat, 99),
            "latency_max_ms": float(lat.max()) if lat.size else None,
            "processing_median_ms": _stat(proc, 50),
            "processing_p99_ms": _stat(proc, 99),
            "send_jitter_p99_ms": _stat(np.abs(gaps - period_ms), 99) if gaps.size else None,
            "frames_late": int((lat > period_ms).sum()),
            "input_overruns": self.overruns,
            "sinks": self.sinks,
        }

    def lines(self) -> list[str]:
        """The printout, each figure with its goal and a plain verdict."""
        s = self.summary()
        if not self.frames:
            return [f"no frame danced: {s['ended']} after {s['audio_heard_s']:.2f} s of audio"]
        median, p99 = LATENCY_GOAL_MS
        lines = [
            f"danced {s['frames_sent']} frames to {s['audio_heard_s']:.1f} s of {s['source']} ({s['ended']})",
            f"  latency, a frame's audio heard -> its pose sent: median {s['latency_median_ms']:.1f} ms "
            f"(goal {median:g}: {_yes(s['latency_median_ms'] <= median)}), 99th percentile "
            f"{s['latency_p99_ms']:.1f} ms (goal {p99:g}: {_yes(s['latency_p99_ms'] <= p99)})",
            f"  processing per frame: median {s['processing_median_ms']:.2f} ms, 99th percentile "
            f"{s['processing_p99_ms']:.2f} ms (a frame lasts {1000 / self.fps:.1f} ms)",
            f"  frames late (latency above a frame period): {s['frames_late']}; dropped: {s['frames_dropped']}; "
            f"input overruns: {s['input_overruns']}"
            + (
                ""
                if s["send_jitter_p99_ms"] is None
                else f"; send jitter (99th percentile) {s['send_jitter_p99_ms']:.1f} ms"
            ),
        ]
        return lines + [f"  {sink}" for sink in self.sinks]


def run_live(
    dancer: LiveDancer,
    source,
    sinks: list,
    clock,
    *,
    duration: float | None = None,
    beats_per_bar: int | None = None,
    record=None,
    style: str | None = None,
) -> LiveStats:
    """Dance to ``source`` (:mod:`.sources`) until it ends, ``duration`` seconds of audio have been
    heard, or Ctrl-C; send each pose to ``sinks`` (``send(pose)``); ``record`` (a
    :class:`~kinectdata.live.sinks.RecordSink`) also hears the audio. Returns the figures.

    ``beats_per_bar``: the song's metre, for features that count bars; None: estimated from a
    file before it plays, 4 for a device. ``style``: the song's dance style, for a run whose features
    hear it; None: heard in a file before it plays (a device's song is not known in advance: give it).
    """
    sr, fps = dancer.sample_rate, dancer.fps
    stats = LiveStats(fps=fps, source=source.name)
    dancer.warm_up()
    whole = getattr(source, "reader", None)
    planned = whole.n_samples / sr if whole is not None else (duration or LONGEST_SESSION_S)
    if duration is not None:
        planned = min(planned, duration)
    n = int(np.floor(planned * fps + 1e-9))
    starts = np.round(np.arange(n) * sr / fps).astype(np.int64)
    bar = None
    counts_bars = needs_metre(dancer.features)
    by_metre = counts_bars or dancer.draws_by_metre  # the features' bars, or the draws' metre
    showing = [sink for sink in sinks if getattr(sink, "wants_beats", False)]  # the live view's beat
    samples = beats = None
    hears_style = style_input_of(dancer.features) is not None
    if hears_style and style is None and whole is None:
        raise ConfigError(
            f"the run hears the song's style ({', '.join(style_input_of(dancer.features).styles)}), which cannot be "
            "heard from a device before the song has played: give --style"
        )
    if whole is not None and (showing or (by_metre and beats_per_bar is None) or (hears_style and style is None)):
        samples = np.concatenate([np.zeros(0, np.float32), *whole.blocks()])  # the file read once
        try:
            beats = music_beats(samples, sr)[0]
        except KinectDataError:  # no librosa: no beats to show, the metre's default
            pass
    for sink in showing:
        sink.beats = beats
    if by_metre:
        known = None if beats_per_bar is not None or beats is None else samples
        bar = recording_metre(None, known, sr, beats_s=beats, given=beats_per_bar).beats_per_bar
        if dancer.draws_by_metre:
            dancer.set_metre(bar)
    ends = starts + dancer.features.span[1]
    heard = _HeardClock(sr)
    got = [0.0]
    watching = [sink for sink in sinks if hasattr(sink, "heard_latency")]  # the live view shows it

    def step(k0: int, features: np.ndarray, padded: np.ndarray) -> None:
        for i in range(features.shape[0]):
            k = k0 + i
            pose = dancer.step(features[i], k)
            for sink in sinks:
                sink.send(pose)
            sent = clock.now()
            stats.latency_ms.append(1000.0 * (sent - heard.at(min(int(ends[k]), heard.samples))))
            for sink in watching:
                sink.heard_latency(stats.latency_ms[-1])
            stats.processing_ms.append(1000.0 * (sent - got[0]))
            stats.sent_s.append(sent)

    heard_style, _ = song_style(dancer.features, samples, style)
    featurizer = StreamingFeatures(
        starts,
        dancer.features,
        step,
        beats_per_bar=bar if counts_bars else None,
        live=True,
        style=NO_STYLE if heard_style is None else heard_style,
    )
    limit = int(round(planned * sr))  # samples to hear
    exhausted = False
    try:
        for block in source.blocks():
            got[0] = clock.now()
            samples = block.samples[: max(0, limit - heard.samples)]
            stats.overruns += int(block.overrun)
            heard.add(samples.size, block.heard_s)
            if record is not None:
                record.hear(samples)
            featurizer.push(samples)
            if heard.samples >= limit:
                break
        exhausted = whole is not None and heard.samples >= whole.n_samples
        if not exhausted and duration is not None and heard.samples >= limit:
            stats.ended = f"{duration:g} s heard"
    except KeyboardInterrupt:
        stats.ended = "stopped (Ctrl-C)"
    except KinectDataError as exc:  # the device went away: what was danced is kept, and said
        stats.ended = "stopped"
        stats.fault = str(exc)
    finally:
        source.close()
    if exhausted:  # a file's last frames, their slices padded past its end, as generate makes them
        got[0] = clock.now()
        featurizer.finish()
    stats.heard_s = heard.samples / sr
    stats.expected_frames = n if exhausted else int(np.searchsorted(ends, heard.samples, side="right"))
    stats.sinks = [sink.summary() for sink in sinks if hasattr(sink, "summary")]
    return stats


class _HeardClock:
    """When each sample of the live audio was heard: blocks' last samples and their times."""

    def __init__(self, rate: int):
        self.rate = rate
        self.samples = 0
        self.ends: list[int] = []
        self.times: list[float] = []

    def add(self, count: int, heard_s: float) -> None:
        if count:
            self.samples += count
            self.ends.append(self.samples)
            self.times.append(heard_s)

    def at(self, sample: int) -> float:
        """Clock time at which sample ``sample`` (exclusive end of a slice) had been heard."""
        b = int(np.searchsorted(self.ends, sample, side="left"))
        b = min(b, len(self.ends) - 1)
        return self.times[b] - (self.ends[b] - sample) / self.rate


def _stat(values: np.ndarray, q: float) -> float | None:
    return float(np.percentile(values, q)) if values.size else None


def _yes(flag: bool) -> str:
    return "yes" if flag else "no"
