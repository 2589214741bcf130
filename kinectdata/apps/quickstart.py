"""The quickstart: the toolkit's data path run end to end on sample data.

1. ``synth``: synthesise a new session;
2. ``align``: align every session of the sample folder and the new one (``--offset auto``),
   checking each estimated offset against the ground truth;
3. ``build-dataset``: turn the aligned files into a dataset (1x129x5 STFT inputs, yalta65 targets
   normalised into -0.9..0.9, HDF5 shards and a manifest; the four sessions split 2/1/1 into
   train, validation and test), then ``inspect`` it;
4. ``train-baseline``: a short training of the Yalta et al. (2016) network (:data:`QUICK_TRAINING`:
   a demonstration, not the paper's 10-epoch settings), which writes its loss curve;
5. ``evaluate``: SMAPE without and with reset, forward time, trajectory plots, the silence test;
6. ``generate``: motion for the test session's music, written as a canonical CSV.

Steps 4-6 need PyTorch (``pip install kinectdata[train]``); without it the quickstart stops after
step 3 and says so.

:func:`run_listen_quickstart` does the same for the Listen to Dance pipeline (Lee et al. 2018):
synthetic OpenPose sessions -> ``build-dataset --pipeline listen-to-dance`` (offsets from the
2-D clap) -> a short CDHC training -> ``evaluate`` with the rhythm analysis -> ``generate``.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

from kinectdata.align.recipe import align_files, format_summary
from kinectdata.core.errors import KinectDataError
from kinectdata.dataset.build import build_dataset
from kinectdata.dataset.collection import find_sessions
from kinectdata.dataset.config import BuildConfig
from kinectdata.dataset.inspect import inspect
from kinectdata.dataset.pipelines import PIPELINES
from kinectdata.synth import synthesize_recording, write_openpose_recording, write_recording

SAMPLE_SEEDS = (1, 2, 3)
SAMPLE_DURATION_S = 22.0
SAMPLE_COMMAND = "kinectdata synth sample_data --seed 1 --count 3 --duration 22"
"""The command that made ``sample_data/`` (also run by the quickstart when the folder is absent)."""

FRAME_S = 1 / 30
QUICK_TRAINING = {
    "units": 250,
    "feedback": "teacher",
    "sequence": 150,
    "stride": 10,
    "batch_size": 10,
    "epochs": 3,
    "lr": 2e-4,
    "noise_eta": 0.0,
}
"""The quickstart's training: small batches and no gradient noise so that three epochs on four
short sessions show the losses falling (the paper's settings learn too slowly for a demo)."""


def run_quickstart(
    out_dir: str | Path,
    samples: str | Path | None = None,
    echo: Callable[[str], Any] = print,
    **training: Any,
) -> dict[str, Any]:
    """Run the quickstart into ``out_dir``; returns per-session results.

    Args:
        out_dir: output folder (``synth/`` and ``aligned/`` are made inside).
        samples: folder of sample sessions; default ``./sample_data`` when it exists, else the
            sample set is synthesised into ``out_dir/sample_data`` with :data:`SAMPLE_COMMAND`'s options.
        echo: where progress lines go.
        **training: overrides of :data:`QUICK_TRAINING` (e.g. ``epochs=1, units=32``).

    Returns:
        ``{"sessions": {name: {...}}, "dataset": path, "rows": n}``.

    Raises:
        KinectDataError: a step failed, or an estimated offset is off by more than one frame.
    """
    out = Path(out_dir)
    if samples is None:
        samples = Path("sample_data")
        if not samples.is_dir():
            samples = out / "sample_data"
            echo(f"[synth] no ./sample_data here: making it in {samples} ({SAMPLE_COMMAND})")
            for seed in SAMPLE_SEEDS:
                rec = synthesize_recording(seed=seed, duration_s=SAMPLE_DURATION_S)
                write_recording(rec, samples, f"synth_{seed:03d}")
    echo(f"[synth] a new session: seed 7, {SAMPLE_DURATION_S:g} s")
    fresh = synthesize_recording(seed=7, duration_s=SAMPLE_DURATION_S)
    write_recording(fresh, out / "synth", "synth_007")

    sessions = find_sessions(samples) + find_sessions(out / "synth")
    if not sessions:
        raise KinectDataError(f"{samples}: no sessions (a skeleton file with audio of the same name)")
    results = {}
    for s in sessions:
        target = out / "aligned" / f"{s.name}.h5"
        echo(f"[align] {s.skeleton} + {s.audio} -> {target}")
        rec = align_files(s.skeleton, s.audio, target, offset="auto")
        echo(format_summary(rec))
        truth = s.load_truth()
        result = {"aligned": str(target), "frames": rec.n_frames, "offset_s": rec.offset.seconds}
        if truth is not None:
            error = rec.offset.seconds - truth["offset_s"]
            result["offset_error_s"] = error
            echo(f"  offset error against the ground truth: {1000 * error:+.1f} ms")
            if abs(error) > FRAME_S:
                raise KinectDataError(
                    f"{s.name}: estimated offset is {1000 * error:+.1f} ms off the truth (over one frame)"
                )
        results[s.name] = result
    echo(f"[build-dataset] {out / 'aligned'} -> {out / 'dataset'}")
    config = BuildConfig.from_pipeline("yalta2016", split_ratios=(0.5, 0.25, 0.25))
    manifest = build_dataset(out / "aligned", out / "dataset", config)
    echo(f"[inspect] {out / 'dataset'}")
    echo(inspect(out / "dataset", components=6))
    summary = {"sessions": results, "dataset": str(out / "dataset"), "rows": manifest["totals"]["rows"]}
    learned = _train_evaluate_generate(
        out,
        manifest,
        "yalta2016",
        {**QUICK_TRAINING, **training},
        lambda test: next(s.audio for s in sessions if s.name == test),
        "generated.csv",
        echo,
    )
    if learned:
        run = Path(learned["run"])
        echo(
            f"[done] aligned files: {out / 'aligned'}\n       dataset: {out / 'dataset'}\n       run: {run} "
            f"(loss.png, log.csv, model.pt, stream.ts)\n       evaluation: {run / 'evaluation'} (results.json, "
            f"trajectories.png, silence.png)\n       generated motion: {run / 'generated.csv'}"
        )
    return summary | learned


def _train_evaluate_generate(
    out: Path,
    manifest: dict[str, Any],
    pipeline: str,
    settings: dict[str, Any],
    audio_of: Callable[[str], Path],
    generated: str,
    echo: Callable[[str], Any],
) -> dict[str, Any]:
    """Train the pipeline's model on ``out/dataset`` into ``out/run``, evaluate it on the test split
    and generate motion for the first test recording's audio (``audio_of(name)``) into
    ``run/generated``. Returns ``{"run", "history", "evaluation", "generated_frames"}``, or ``{}``
    (said through ``echo``) when PyTorch is not installed."""
    try:
        import torch  # noqa: F401
    except ImportError:
        echo(
            "[done] PyTorch is not installed (pip install 'kinectdata[train]'): stopping before training. "
            f"Dataset in {out / 'dataset'}"
        )
        return {}
    from kinectdata.evaluation.evaluate import evaluate, format_results
    from kinectdata.inference.generate import generate
    from kinectdata.training.config import TrainConfig
    from kinectdata.training.train import train

    model = PIPELINES[pipeline]["model"]
    run = out / "run"
    shutil.rmtree(run, ignore_errors=True)  # a fresh run each time (a run folder refuses to be overwritten)
    echo(
        f"[train-baseline --model {model}] {out / 'dataset'} -> {run} "
        f"({', '.join(f'{k} {v}' for k, v in settings.items())})"
    )

    def progress(row: dict[str, Any]) -> None:
        val = "" if row["val_loss"] is None else f", validation loss {row['val_loss']:.5f}"
        echo(f"  epoch {row['epoch']}: train loss {row['train_loss']:.5f}{val} ({row['seconds']:.1f} s)")

    history = train(out / "dataset", run, TrainConfig.for_model(model, **settings), progress=progress)
    echo(f"[evaluate] {run} on the test split")
    results = evaluate(run, out / "dataset", "test")
    echo(format_results(results))
    audio = audio_of(manifest["splits"]["test"]["recordings"][0])
    echo(f"[generate] {audio} -> {run / generated}")
    motion, _ = generate(run, audio, run / generated)
    return {"run": str(run), "history": history, "evaluation": results, "generated_frames": motion.n_frames}


LISTEN_SEEDS = (11, 12, 14, 15)
"""Synthetic OpenPose sessions of the Listen to Dance quickstart (the detector sees the clap in each)."""
QUICK_CDHC = {
    "channels": 64,
    "decoder_channels": 64,
    "sequence": 150,
    "stride": 10,
    "batch_size": 16,
    "epochs": 3,
    "lr": 1e-3,
}
"""The Listen to Dance quickstart's training: a narrower network and overlapping windows so that
three epochs on four short sessions show the losses falling."""


def run_listen_quickstart(out_dir: str | Path, echo: Callable[[str], Any] = print, **training: Any) -> dict[str, Any]:
    """The Listen to Dance pipeline end to end into ``out_dir`` (see the module docstring);
    ``training`` overrides :data:`QUICK_CDHC`. Returns the dataset manifest's totals, the training
    history and the evaluation results (``{"dataset", "rows", ...}`` as :func:`run_quickstart`)."""
    out = Path(out_dir)
    sessions = out / "openpose_sessions"
    for seed in LISTEN_SEEDS:
        echo(f"[synth] OpenPose session seed {seed}, {SAMPLE_DURATION_S:g} s -> {sessions}")
        write_openpose_recording(
            synthesize_recording(seed=seed, duration_s=SAMPLE_DURATION_S), sessions, f"dance_{seed}"
        )
    config = BuildConfig.from_pipeline("listen-to-dance", split_ratios=(0.5, 0.25, 0.25))
    echo(f"[build-dataset] {sessions} -> {out / 'dataset'} (--pipeline listen-to-dance --video-fps 30)")
    manifest = build_dataset(sessions, out / "dataset", config, video_fps=30.0)
    for r in manifest["recordings"]:
        echo(f"  {r['name']}: {r['frames']} frames, offset {r['offset']['seconds']:+.3f} s ({r['offset']['source']})")
    echo(inspect(out / "dataset", components=4))
    summary = {"dataset": str(out / "dataset"), "rows": manifest["totals"]["rows"]}
    learned = _train_evaluate_generate(
        out,
        manifest,
        "listen-to-dance",
        {**QUICK_CDHC, **training},
        lambda test: sessions / f"{test}.flac",
        "generated.jsonl",
        echo,
    )
    if learned:
        run = Path(learned["run"])
        echo(
            f"[done] dataset: {out / 'dataset'}\n       run: {run} (loss.png, log.csv, model.pt)\n       evaluation: "
            f"{run / 'evaluation'} (results.json, rhythm_real.png, rhythm_generated.png, ...)\n       generated "
            f"motion (OpenPose JSON Lines): {run / 'generated.jsonl'}"
        )
    return summary | learned
