"""The Listen to Dance path: OpenPose reading, the 2-D clap offset, mel features, CDHC training and
generation.

- OpenPose: a folder of 3 000 BODY_25 frame files (the synthetic generator's, two people in part of
  them) read and tracked; frames per second.
- Offset: ``--offset auto`` on 30 synthetic OpenPose sessions (seeds 200-229, 12 s): how many
  found by the 2-D clap, their error against the truth, how many refused.
- Mel features: 10 minutes of noise at 16 kHz, 30 fps; times real time on one thread.
- CDHC (full size: 256/128 channels, 9.0 M parameters), torch on the CPU: training frames per
  second (batches of 16 x 300 frames, teacher forcing, L1 + limb loss, Adam), and generation of
  60 s of dance (1 800 frames): whole-song :func:`~kinectdata.models.cdhc.generate` and the
  frame-by-frame streaming engine (median ms per frame, batch 1).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from kinectdata.align.recipe import align_files
from kinectdata.core.errors import AlignmentError
from kinectdata.features import PRESETS, mel_features
from kinectdata.formats import read_motion
from kinectdata.inference.engines import make_engine
from kinectdata.models.cdhc import CdhcConfig, CdhcNet, cdhc_loss, generate
from kinectdata.synth import synthesize_openpose, synthesize_recording, write_openpose_recording
from kinectdata.synth.openpose import write_openpose_folder

from .summary import record


def _openpose(tmp: Path) -> None:
    rec = synthesize_recording(seed=7, duration_s=102.0)
    video = synthesize_openpose(rec)
    folder = write_openpose_folder(video, tmp / "take_openpose", "take")
    n = len(list(folder.glob("*_keypoints.json")))
    start = time.perf_counter()
    motion = read_motion(folder, video_fps=30.0)
    seconds = time.perf_counter() - start
    people = motion.metadata["people"]
    record("reading", "OpenPose folder (BODY_25, tracked)", f"{n / seconds:.0f} frames/s")
    print(
        f"  OpenPose folder: {n} frame files ({len(people)} tracks) read in {seconds:.2f} s, {n / seconds:.0f} frames/s"
    )


def _offsets(tmp: Path) -> None:
    errors, refused = [], 0
    for seed in range(200, 230):
        rec = synthesize_recording(seed=seed, duration_s=12.0)
        paths = write_openpose_recording(rec, tmp, f"s{seed}")
        try:
            result = align_files(paths["openpose"], paths["audio"], video_fps=30.0)
        except AlignmentError:
            refused += 1
            continue
        errors.append(abs(result.offset.seconds - rec.truth["offset_s"]) * 1000)
    e = np.array(errors)
    print(
        f"  2-D clap offset: {len(e)} of 30 found, {refused} refused; error median {np.median(e):.1f} ms, "
        f"p95 {np.percentile(e, 95):.1f} ms, max {e.max():.1f} ms (one video frame: 33.3 ms)"
    )


def _mel() -> None:
    audio = np.random.default_rng(0).normal(0, 0.1, 600 * 16000).astype(np.float32)
    starts = np.round(np.arange(600 * 30) * 16000 / 30).astype(np.int64)
    start = time.perf_counter()
    mel_features(audio, starts, PRESETS["listen_to_dance"])
    seconds = time.perf_counter() - start
    print(f"  mel features: 600 s of audio in {seconds:.2f} s, {600 / seconds:.0f}x real time")
    record("features", "listen_to_dance log-mel, one core", f"{600 / seconds:.0f}x real time")


def _cdhc() -> None:
    torch.manual_seed(0)
    config = CdhcConfig(output_dim=44, input_dim=80)
    net = CdhcNet(config)
    params = sum(p.numel() for p in net.parameters())
    optimizer = torch.optim.Adam(net.parameters(), lr=2e-4)
    audio, poses = torch.rand(16, 300, 80), torch.rand(16, 301, 44)
    mask = torch.ones(16, 300, 44, dtype=torch.bool)
    times = []
    for _ in range(4):
        start = time.perf_counter()
        loss, _ = cdhc_loss(net(audio, poses[:, :-1]), poses[:, 1:], mask, config)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        times.append(time.perf_counter() - start)
    print(
        f"  CDHC training: {params / 1e6:.1f} M parameters, {16 * 300 / np.median(times[1:]):.0f} frames/s "
        f"({torch.get_num_threads()} threads)"
    )
    step = np.median(times[1:])
    record("training", "cdhc step, batch 16 x 300 (9.0 M parameters)", f"{step:.2f} s ({16 * 300 / step:.0f} frames/s)")
    net.eval()
    song = np.random.default_rng(1).random((1800, 80), dtype=np.float32)
    start = time.perf_counter()
    generate(net, song, np.full(44, 0.5, np.float32))
    whole = time.perf_counter() - start
    engine = make_engine(net)
    pose, steps = np.full(44, 0.5, np.float32), []
    for k in range(300):
        started = time.perf_counter()
        pose = engine.step(song[k], pose)
        steps.append(time.perf_counter() - started)
    record("generation", "cdhc streaming, per frame", f"{np.median(steps[10:]) * 1e3:.2f} ms")
    print(
        f"  CDHC generation: 60 s (1800 frames) in {whole:.2f} s ({60 / whole:.0f}x real time); streaming "
        f"{np.median(steps[10:]) * 1e3:.2f} ms per frame median, p95 {np.percentile(steps[10:], 95) * 1e3:.2f} ms"
    )


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        _openpose(Path(tmp))
        _offsets(Path(tmp))
    _mel()
    _cdhc()


if __name__ == "__main__":
    main()
