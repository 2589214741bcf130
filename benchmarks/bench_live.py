"""Dancing live: a song replayed through the live input path at real-time pace into a local OSC
receiver that timestamps each frame's arrival (issue 27's goals on 2 cores).

A run is trained for a moment on the sample sessions (its weights do not change the cost of a
step: the default yalta model, 128 units). The song is the sample songs end to end, looped to the
length asked (10 minutes by default). The receiver, a thread of this process, parses every bundle
with python-osc and stamps its arrival on the monotonic clock; a frame's latency is the arrival
minus the moment the last sample of its audio was heard. Goals: median within 10 ms, 99th
percentile within 25 ms, no frame dropped, and the poses those ``kinectdata generate`` makes from
the same audio with the same engine (the recording written by ``--record`` against them).

``python -m benchmarks.bench_live [--minutes 10] [--run RUN ...] [--music SONG]``: ``--run`` adds a
trained run (the real-dance runs of ``bench_learning --corpus tang2018``) measured the same way,
``--music`` a song to loop instead of the sample songs (a corpus song: real music).
"""

from __future__ import annotations

import argparse
import socket
import tempfile
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import soundfile

from kinectdata.align.aligned import AlignedRecording
from kinectdata.align.audio import load_audio
from kinectdata.dataset.build import build_dataset
from kinectdata.dataset.prepare import BuildConfig
from kinectdata.features import PRESETS
from kinectdata.inference.generate import generate
from kinectdata.live.clock import MonotonicClock
from kinectdata.live.session import LATENCY_GOAL_MS, LiveDancer, run_live
from kinectdata.live.sinks import OscSink, RecordSink
from kinectdata.live.sources import FileSource
from kinectdata.targets.specs import load_target_spec
from kinectdata.training.config import TrainConfig
from kinectdata.training.train import train

from .summary import record

SAMPLES = Path(__file__).parent.parent / "sample_data"


class StampingReceiver:
    """Keeps (frame number, arrival time) of every OSC bundle sent to its port."""

    def __init__(self):
        from pythonosc.osc_bundle import OscBundle

        self.parse = OscBundle
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.socket.bind(("127.0.0.1", 0))
        self.socket.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
        self.port = self.socket.getsockname()[1]
        self.arrivals: list[tuple[int, float]] = []
        self.running = True
        self.thread = threading.Thread(target=self._listen, daemon=True)
        self.thread.start()

    def _listen(self) -> None:
        self.socket.settimeout(0.2)
        while self.running:
            try:
                data = self.socket.recv(65536)
            except TimeoutError:
                continue
            arrived = time.monotonic()
            first = next(iter(self.parse(data)))
            self.arrivals.append((int(first.params[0]), arrived))

    def stop(self) -> list[tuple[int, float]]:
        time.sleep(0.3)
        self.running = False
        self.thread.join()
        self.socket.close()
        return self.arrivals


def _song(folder: Path, seconds: float, music: Path | None = None) -> Path:
    """``music`` (default: the sample songs end to end), looped to ``seconds``, as a 16 kHz WAV."""
    sources = [music] if music is not None else sorted(SAMPLES.glob("synth_*.flac"))
    one = np.concatenate([load_audio(p, 16000).samples for p in sources])
    song = np.tile(one, int(np.ceil(seconds * 16000 / one.size)))[: int(seconds * 16000)]
    path = folder / "song.wav"
    soundfile.write(path, song.astype(np.float32), 16000, subtype="FLOAT")
    return path


def measure(run: Path, song: Path, minutes: float, work: Path, name: str) -> dict:
    """Dance ``run`` live to ``song`` into a stamping receiver and a recording; the figures and verdicts."""
    dancer = LiveDancer(run)
    clock = MonotonicClock()
    source = FileSource(song, dancer.sample_rate, round(dancer.sample_rate * 0.005), clock)
    receiver = StampingReceiver()
    osc = OscSink(f"127.0.0.1:{receiver.port}", dancer.joint_set)
    recorder = RecordSink(work / f"{name}.h5", dancer.joint_set, dancer.fps, dancer.sample_rate, source.name)
    print(f"  [{name}] dancing live to {minutes:g} min of music ({dancer.engine}, 5 ms blocks)...", flush=True)
    stats = run_live(dancer, source, [osc, recorder], clock, record=recorder)
    arrivals = dict(receiver.stop())
    osc.close()
    heard = np.asarray(stats.sent_s) - np.asarray(stats.latency_ms) / 1000
    arrived = np.array([arrivals.get(k, np.nan) for k in range(stats.frames)])
    latency = (arrived - heard) * 1000
    got = np.isfinite(latency)
    median, p99 = np.percentile(latency[got], 50), np.percentile(latency[got], 99)
    dropped = stats.expected_frames - int(got.sum())
    recorder.write("bench_live")
    danced = AlignedRecording.load(work / f"{name}.h5").motion.positions
    engine, precision = dancer.engine.split()
    expected, _ = generate(run, song, engine=engine, precision=precision)
    same = danced.shape == expected.positions.shape
    same = same and np.allclose(danced, expected.positions, atol=1e-6, equal_nan=True)
    s = stats.summary()
    goal_median, goal_p99 = LATENCY_GOAL_MS
    print(f"  [{name}] {stats.frames} frames over {stats.heard_s / 60:.1f} min; processing per frame median "
          f"{s['processing_median_ms']:.2f} ms, 99th percentile {s['processing_p99_ms']:.2f} ms")  # fmt: skip
    print(f"  [{name}] latency, audio heard -> pose arrived at the receiver: median {median:.1f} ms (goal "
          f"{goal_median:g}: {'yes' if median <= goal_median else 'no'}), 99th percentile {p99:.1f} ms (goal "
          f"{goal_p99:g}: {'yes' if p99 <= goal_p99 else 'no'})")  # fmt: skip
    print(f"  [{name}] frames dropped: {dropped} (goal 0: {'yes' if dropped == 0 else 'no'}); late: "
          f"{s['frames_late']}; input overruns: {s['input_overruns']}")  # fmt: skip
    print(f"  [{name}] poses identical to kinectdata generate on the same audio ({dancer.engine}): "
          f"{'yes' if same else 'no'}")  # fmt: skip
    record("live", f"{name}: latency to the receiver, median / p99", f"{median:.1f} / {p99:.1f} ms")
    record("live", f"{name}: frames dropped over {minutes:g} min", str(dropped))
    return {"median_ms": median, "p99_ms": p99, "dropped": dropped, "same": same}


def main(minutes: float = 10.0, runs: tuple[Path, ...] = (), music: Path | None = None) -> None:
    """The small model trained here for a moment, then each of ``runs`` (the real-dance runs of
    ``bench_learning --corpus tang2018``), on ``music`` looped (default: the sample songs)."""
    import torch

    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        config = BuildConfig(features=PRESETS["yalta2016"].to_dict(), target=load_target_spec("yalta65").to_dict())
        with warnings.catch_warnings():  # a run trained for a moment: its warnings say so, and do not matter here
            warnings.simplefilter("ignore")
            build_dataset(SAMPLES, tmp / "ds", config)
            train(tmp / "ds", tmp / "run", TrainConfig(epochs=1, sequence=60, stride=300))
        song = _song(tmp, minutes * 60, music)
        measure(tmp / "run", song, minutes, tmp, "small yalta")
        for run in runs:
            measure(Path(run), song, minutes, tmp, Path(run).name)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--run", action="append", default=[], type=Path,
                        help="a trained run to measure too (repeatable): the real-dance runs")  # fmt: skip
    parser.add_argument("--music", type=Path, default=None, help="the song to loop (default: the sample songs)")
    args = parser.parse_args()
    main(args.minutes, tuple(args.run), args.music)
