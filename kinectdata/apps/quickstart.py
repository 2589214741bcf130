"""The quickstart: the toolkit's data path run end to end on sample data, ending with a model that
dances to music it has never heard, and the verdicts that show it.

1. ``synth``: synthesise a new session;
2. ``align``: align every session of the sample folder and the new one (``--offset auto``),
   checking each estimated offset against the ground truth;
3. ``build-dataset``: turn the aligned files into a dataset (1x129x5 STFT inputs, yalta65 targets
   normalised into -0.9..0.9, HDF5 shards and a manifest), then ``inspect`` it;
4. the four sample sessions hold 88 s of dance, too little to learn a beat from: a **learning
   corpus** is synthesised (:func:`learning_corpus`: sessions at tempi spread over 80-160 BPM to
   train on, five at tempi none of them has to test on) and built the same way;
5. ``train-baseline``: the Yalta et al. (2016) network with the learning recipe
   (:data:`QUICK_TRAINING`: teacher feedback, small batches, Adam 1e-3; docs/training.md,
   "Learning the beat") within a time budget (``minutes``);
6. ``evaluate`` on the test songs: SMAPE, forward time, plots, the silence test, and the verdicts:
   does the generated motion follow the beat and the tempo, move on the beats, listen to the music
   (swapped-song and noise controls), stay alive; each figure beside its chance level;
7. ``generate``: motion for a test song's music, written as a canonical CSV.

Steps 5-7 need PyTorch (``pip install kinectdata[train]``); without it the quickstart stops after
step 4 and says so.

:func:`run_listen_quickstart` does the same for the Listen to Dance pipeline (Lee et al. 2018):
synthetic OpenPose sessions -> ``build-dataset --pipeline listen-to-dance`` (offsets from the
2-D clap) -> a CDHC training -> ``evaluate`` with the verdicts -> ``generate``.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

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
SYNTHETIC_LOOP = {
    "stride": None,
    "free_weight": 0.0,
    "silence_share": 0.0,
    "keep": "last",
    "inputs": "music-and-poses",
    "context": 0,
    "precision": "float32",
}
"""What the synthetic recipe leaves out of the real-dance defaults: non-overlapping windows, the
teacher-forced loss alone, no silenced windows, the last epoch kept, the previous poses given to
the decoder, no context before the windows, float32 throughout (docs/training.md, "Learning the
beat": it learns the synthetic dancer, not real dance; measured so before the context and the
yalta model's bfloat16 existed)."""

QUICK_TRAINING = {
    **SYNTHETIC_LOOP,
    "units": 128,
    "feedback": "teacher",
    "velocity_weight": 10.0,
    "sequence": 150,
    "batch_size": 8,
    "epochs": 1000,
    "lr": 1e-3,
    "noise_eta": 0.0,
    "clip_norm": 1.0,
}
"""The quickstart's training: the learning benchmark's recipe (docs/training.md, "Learning the
beat") at a width that learns within a few minutes on 2 CPU cores; the time budget ends it."""
QUICK_MINUTES = 6.0
"""The quickstart's training budget, minutes."""
CORPUS_MINUTES = 8.0
"""Minutes of training music the quickstart synthesises."""
SESSION_S = 45.0
TEST_SESSION_S = 40.0
TEMPO_RANGE_BPM = (80.0, 160.0)


def learning_corpus(
    folder: str | Path, corpus_minutes: float = CORPUS_MINUTES, *, openpose: bool = False, seed: int = 500
) -> Path:
    """Synthesise sessions to learn from into ``folder`` and a ``recordings.yaml`` that splits them:
    ``corpus_minutes`` of training sessions (45 s each, at least 2; shorter for a corpus under 90 s) at
    tempi spread evenly over 80-160 BPM, one validation and five test sessions (40 s; at least 16 s)
    at tempi spread over the same range,
    each at least 2 BPM from every training tempo (never heard in training). Offsets are the
    synthesiser's truth (the quickstart shows ``--offset auto`` on the sample sessions). Returns
    the manifest's path."""
    folder = Path(folder)
    session_s = min(SESSION_S, max(15.0, corpus_minutes * 60 / 2))  # a tiny corpus (tests): shorter sessions
    test_s = min(TEST_SESSION_S, max(16.0, session_s))  # two bars of lags at 84 BPM fit twice
    count = max(2, int(round(corpus_minutes * 60 / session_s)))
    tempi = np.linspace(*TEMPO_RANGE_BPM, count)
    held_out = []
    for tempo in np.linspace(TEMPO_RANGE_BPM[0] + 4, TEMPO_RANGE_BPM[1] + 4 - 8, 6):
        while np.min(np.abs(tempi - tempo)) < 2:  # never a training tempo
            tempo += 2.5
        held_out.append(float(tempo))
    plan = [(float(t), "train", session_s) for t in tempi]
    plan += [(held_out[1], "val", test_s)]
    plan += [(t, "test", test_s) for t in (held_out[0], *held_out[2:])]
    lines = ["recordings:"]
    for i, (tempo, split, seconds) in enumerate(plan):
        rec = synthesize_recording(seed=seed + i, duration_s=seconds, tempo_bpm=round(tempo, 1))
        name = f"{split}_{i:02d}_{tempo:.0f}bpm"
        if openpose:
            paths = write_openpose_recording(rec, folder, name)
            motion = Path(paths["openpose"]).name
        else:
            paths = write_recording(rec, folder, name)
            motion = Path(paths["skeleton"]).name
        audio = Path(paths["audio"]).name
        lines.append(f"  - {{recording: {motion}, audio: {audio}, split: {split}, offset: {rec.truth['offset_s']!r}}}")
    manifest = folder / "recordings.yaml"
    manifest.write_text("\n".join(lines) + "\n")
    return manifest


def run_quickstart(
    out_dir: str | Path,
    samples: str | Path | None = None,
    echo: Callable[[str], Any] = print,
    *,
    minutes: float = QUICK_MINUTES,
    corpus_minutes: float = CORPUS_MINUTES,
    **training: Any,
) -> dict[str, Any]:
    """Run the quickstart into ``out_dir``; returns per-session results.

    Args:
        out_dir: output folder (``synth/`` and ``aligned/`` are made inside).
        samples: folder of sample sessions; default ``./sample_data`` when it exists, else the
            sample set is synthesised into ``out_dir/sample_data`` with :data:`SAMPLE_COMMAND`'s options.
        echo: where progress lines go.
        minutes: the training's time budget.
        corpus_minutes: minutes of training music to synthesise (:func:`learning_corpus`).
        **training: overrides of :data:`QUICK_TRAINING` (e.g. ``epochs=1, units=32``).

    Returns:
        ``{"sessions": {name: {...}}, "dataset": path, "rows": n}``, and when PyTorch is there
        ``"run"``, ``"history"``, ``"evaluation"``, ``"generated_frames"``.

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
    seconds = sum(r["frames"] for r in results.values()) / 30
    echo(
        f"[learn] the sample sessions hold {seconds:.0f} s of dance, too little to learn a beat from: synthesising "
        f"{corpus_minutes:g} min of sessions at {TEMPO_RANGE_BPM[0]:.0f}-{TEMPO_RANGE_BPM[1]:.0f} BPM to train on and "
        f"five at tempi never heard in training to test on -> {out / 'corpus'}"
    )
    corpus = learning_corpus(out / "corpus", corpus_minutes)
    echo(f"[build-dataset] {corpus} -> {out / 'learn_dataset'}")
    learn = build_dataset(corpus, out / "learn_dataset", BuildConfig.from_pipeline("yalta2016"), jobs=2)
    rows = {k: v["rows"] for k, v in learn["splits"].items()}
    echo(f"  {rows['train'] / 1800:.1f} min to train on, {rows.get('test', 0) / 1800:.1f} min of test songs")
    learned = train_evaluate_generate(
        out,
        learn,
        "yalta2016",
        {**QUICK_TRAINING, "max_minutes": minutes, **training},
        "generated.csv",
        echo,
    )
    if learned:
        run = Path(learned["run"])
        echo(
            f"[done] aligned files: {out / 'aligned'}\n       dataset: {out / 'learn_dataset'}\n       run: {run} "
            f"(loss.png, log.csv, model.pt, stream.ts)\n       evaluation: {run / 'evaluation'} (results.json, "
            f"trajectories.png, silence.png)\n       generated motion: {run / 'generated.csv'}"
        )
    return summary | learned


def _audio_of(manifest: dict[str, Any], recording: str) -> Path:
    """The audio file a dataset's recording was built from (its manifest's input entry)."""
    source = next(r["recording"] for r in manifest["recordings"] if r["name"] == recording)
    return Path(next(e["audio"] for e in manifest["inputs"] if e["name"] == source))


def train_evaluate_generate(
    out: Path,
    manifest: dict[str, Any],
    pipeline: str,
    settings: dict[str, Any],
    generated: str,
    echo: Callable[[str], Any],
    *,
    dataset: Path | None = None,
    split: str = "test",
    why_split: str = "songs at tempi never heard in training",
) -> dict[str, Any]:
    """Train the pipeline's model on ``dataset`` (default ``out/learn_dataset``; its ``manifest``)
    into ``out/run``, evaluate it on ``split`` and generate motion for that split's first
    recording's audio (as the manifest names it) into ``run/generated``. Returns ``{"run",
    "history", "evaluation", "generated_frames"}``, or ``{}`` (said through ``echo``) when PyTorch
    is not installed."""
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
    dataset = dataset or out / "learn_dataset"
    run = out / "run"
    shutil.rmtree(run, ignore_errors=True)  # a fresh run each time (a run folder refuses to be overwritten)
    shown = {k: v for k, v in settings.items() if not (k == "epochs" and settings.get("max_minutes"))}
    echo(f"[train-baseline --model {model}] {dataset} -> {run} ({', '.join(f'{k} {v}' for k, v in shown.items())})")

    def progress(row: dict[str, Any]) -> None:
        val = "" if row["val_loss"] is None else f", validation loss {row['val_loss']:.5f}"
        stopped = "; the time budget ran out" if row.get("stopped") else ""
        echo(
            f"  epoch {row['epoch']}: train loss {row['train_loss']:.5f}{val} ({row['seconds']:.1f} s, step "
            f"{row['step']}){stopped}"
        )

    history = train(dataset, run, TrainConfig.for_model(model, **settings), progress=progress)
    echo(f"[evaluate] {run} on the {split} split ({why_split})")
    # the forward time on the default engine only: exporting for every engine would add seconds
    # to a first run (`kinectdata evaluate` times them all)
    results = evaluate(run, dataset, split, engines=[("torch", "float32")])
    echo(format_results(results))
    audio = _audio_of(manifest, manifest["splits"][split]["recordings"][0])
    echo(f"[generate] {audio} -> {run / generated}")
    motion, _ = generate(run, audio, run / generated)
    return {"run": str(run), "history": history, "evaluation": results, "generated_frames": motion.n_frames}


LISTEN_SEEDS = (11, 12, 14, 15)
"""Synthetic OpenPose sessions of the Listen to Dance quickstart (the detector sees the clap in each)."""
QUICK_CDHC = {
    **SYNTHETIC_LOOP,
    "channels": 64,
    "decoder_channels": 64,
    "dropout": 0.05,  # the synthetic recipe's, measured before the real-dance default became 0
    "sequence": 150,
    "batch_size": 8,
    "epochs": 1000,
    "lr": 1e-3,
}
"""The Listen to Dance quickstart's training: the learning benchmark's cdhc recipe, narrower."""


def run_listen_quickstart(
    out_dir: str | Path,
    echo: Callable[[str], Any] = print,
    *,
    minutes: float = QUICK_MINUTES,
    corpus_minutes: float = CORPUS_MINUTES,
    **training: Any,
) -> dict[str, Any]:
    """The Listen to Dance pipeline end to end into ``out_dir`` (see the module docstring): four
    OpenPose sessions built with their offsets from the 2-D clap, then a learning corpus of
    ``corpus_minutes`` (:func:`learning_corpus`) trained on within ``minutes``; ``training``
    overrides :data:`QUICK_CDHC`. Returns the clap dataset's totals, the training history and the
    evaluation results (``{"dataset", "rows", ...}`` as :func:`run_quickstart`)."""
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
    echo(
        f"[learn] synthesising {corpus_minutes:g} min of OpenPose sessions at {TEMPO_RANGE_BPM[0]:.0f}-"
        f"{TEMPO_RANGE_BPM[1]:.0f} BPM to train on and five at unheard tempi to test on -> {out / 'corpus'}"
    )
    corpus = learning_corpus(out / "corpus", corpus_minutes, openpose=True)
    echo(f"[build-dataset] {corpus} -> {out / 'learn_dataset'} (--pipeline listen-to-dance)")
    learn = build_dataset(corpus, out / "learn_dataset", config, jobs=2, video_fps=30.0)
    learned = train_evaluate_generate(
        out,
        learn,
        "listen-to-dance",
        {**QUICK_CDHC, "max_minutes": minutes, **training},
        "generated.jsonl",
        echo,
    )
    if learned:
        run = Path(learned["run"])
        echo(
            f"[done] dataset: {out / 'learn_dataset'}\n       run: {run} (loss.png, log.csv, model.pt)\n       "
            f"evaluation: {run / 'evaluation'} (results.json, rhythm_real.png, rhythm_generated.png, ...)\n       "
            f"generated motion (OpenPose JSON Lines): {run / 'generated.jsonl'}"
        )
    return summary | learned
