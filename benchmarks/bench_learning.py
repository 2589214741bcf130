"""Do the bundled models learn to dance to the music? Trained on a synthetic corpus with known beats,
scored on songs at tempi never seen in training, with the listening controls.

The corpus (``kinectdata.synth``): sessions at tempi spread over 80-160 BPM, each with its own
seed (arm figures, steps, sway), :data:`CORPUS_MINUTES` of training music in all; validation and
test sessions at tempi that no training session has (:data:`VAL_TEMPI`, :data:`TEST_TEMPI`).
Both pipelines' datasets are built from it (``yalta2016``: the Kinect v2 skeleton with STFT
inputs; ``listen-to-dance``: the same dances seen by OpenPose, log-mel inputs).

Each model is trained with its learning recipe (:data:`RECIPES`, stated in the output) within a
time budget (``--minutes``, default 30 per model on this 2-core machine), measuring beat following
on the test songs after every epoch, then ``evaluate`` runs on the test split: beat following with
chance levels, the tempo's rank correlation, the swapped-song, noise, shifted-audio and silence
controls, phase against baselines, energy against the real motion, SMAPE with and without reset.
``--ablations`` trains each ablation of :data:`ABLATIONS` with the same budget and prints the same
figures for each (what the recipe's changes are worth, and the paper's own settings).

Run alone: ``python -m benchmarks.bench_learning --minutes 30 --seed 0 [--models yalta,cdhc]
[--ablations | --only-ablations 3,4] [--out DIR]``. Goals (issue 13): beat following >= 80 % of test songs, tempo rank
correlation >= 0.9, the controls, Beat Align Score >= 0.8 x the real motion's and above the
baselines, energy 0.5-2 x the real motion's.

A real corpus (``--corpus tang2018 PATH``): :mod:`.learning_real` (the acceptance run, ``--seeds``)
or, with ``--folds K``, :mod:`.learning_folds` (a candidate tried on folds outside the test split:
``--fold``, ``--set``, ``--features``, ``--tag``).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import torch

from kinectdata.apps.quickstart import SYNTHETIC_LOOP
from kinectdata.core.errors import KinectDataError
from kinectdata.dataset.build import build_dataset
from kinectdata.dataset.config import BuildConfig
from kinectdata.evaluation.beat_following import RecordingBeats, beat_following
from kinectdata.evaluation.evaluate import evaluate, split_songs
from kinectdata.synth import synthesize_recording, write_openpose_recording, write_recording
from kinectdata.training.config import TrainConfig
from kinectdata.training.train import train

from .summary import record

CORPUS_MINUTES = 30.0
TRAIN_TEMPI = tuple(range(80, 161, 4))
"""21 training sessions, 80..160 BPM every 4."""
VAL_TEMPI = (94, 142)
TEST_TEMPI = (86, 102, 118, 134, 150)
"""Test tempi: none is a training or validation tempo."""
TEST_SECONDS = 60.0
PIPELINES = {"yalta": "yalta2016", "cdhc": "listen-to-dance"}

RECIPES: dict[str, dict[str, Any]] = {
    "yalta": {
        **SYNTHETIC_LOOP,
        "units": 128,
        "feedback": "teacher",
        "velocity_weight": 10.0,
        "sequence": 150,
        "batch_size": 8,
        "lr": 1e-3,
        "noise_eta": 0.0,
        "clip_norm": 1.0,
    },
    "cdhc": {
        **SYNTHETIC_LOOP,
        "channels": 128,
        "decoder_channels": 128,
        "dropout": 0.05,  # as it was measured: the real-dance default is now 0
        "velocity_weight": 10.0,
        "sequence": 150,
        "batch_size": 8,
        "lr": 1e-3,
    },
}
"""The settings each model learns the beat with on 2 CPU cores (docs/training.md, "Learning the
beat"): teacher feedback, a loss on the frame-to-frame changes, small batches, Adam 1e-3, no
gradient noise; 128 units (yalta) and 128 channels (cdhc) instead of the papers' 500 and 256, which
fit 4x fewer steps into the budget."""
ABLATIONS: dict[str, dict[str, dict[str, Any]]] = {
    "yalta": {
        "the paper's settings (500 units, predicted feedback, batch 50, lr 1e-4, gradient noise, MSE)": {
            "units": 500,
            "feedback": "predicted",
            "velocity_weight": 0.0,
            "batch_size": 50,
            "lr": 1e-4,
            "noise_eta": 0.01,
            "clip_norm": None,
        },
        "the paper's width (500 units), recipe otherwise": {"units": 500},
        "no velocity loss": {"velocity_weight": 0.0},
        "predicted feedback (the paper's)": {"feedback": "predicted"},
        "noise 0.05 on the fed-back pose": {"previous_noise": 0.05},
    },
    "cdhc": {
        "the paper's width (256/128 channels), batch 16, lr 2e-4, 300-frame sequences, no velocity loss": {
            "channels": 256,
            "decoder_channels": 128,
            "velocity_weight": 0.0,
            "batch_size": 16,
            "lr": 2e-4,
            "sequence": 300,
        },
        "no velocity loss": {"velocity_weight": 0.0},
    },
}
"""One change each from the recipe; ``--ablations`` trains them all with the same budget."""


def make_corpus(root: Path, seed: int, corpus_minutes: float = CORPUS_MINUTES, models=("yalta", "cdhc")) -> dict:
    """Synthesise the sessions and build the datasets the ``models`` need; returns their paths."""
    per_session = max(30.0, 60 * corpus_minutes / len(TRAIN_TEMPI))
    plan = (
        [(t, "train", per_session) for t in TRAIN_TEMPI]
        + [(t, "val", TEST_SECONDS) for t in VAL_TEMPI]
        + [(t, "test", TEST_SECONDS) for t in TEST_TEMPI]
    )
    datasets = {}
    started = time.perf_counter()
    for model in models:
        sessions = root / f"{model}_sessions"
        made = {"seed": seed, "corpus_minutes": corpus_minutes}
        stamp = sessions / "corpus.json"
        if stamp.is_file() and json.loads(stamp.read_text()) == made:
            datasets[model] = root / f"{model}_dataset"  # kept from an earlier run into --out
            print(f"  {model} corpus: reused from {sessions}", flush=True)
            continue
        lines = ["recordings:"]
        for i, (tempo, split, seconds) in enumerate(plan):
            rec = synthesize_recording(seed=1000 * seed + i, duration_s=seconds, tempo_bpm=float(tempo))
            name = f"{split}_{i:02d}_{tempo}bpm"
            if model == "yalta":
                paths = write_recording(rec, sessions, name)
                skeleton = Path(paths["skeleton"]).name
            else:
                paths = write_openpose_recording(rec, sessions, name)
                skeleton = Path(paths["openpose"]).name
            offset = rec.truth["offset_s"]  # known: the benchmark measures learning, not offset finding
            lines.append(
                f"  - {{recording: {skeleton}, audio: {Path(paths['audio']).name}, split: {split}, offset: {offset!r}}}"
            )
        (sessions / "recordings.yaml").write_text("\n".join(lines) + "\n")
        config = BuildConfig.from_pipeline(PIPELINES[model])
        manifest = build_dataset(
            sessions / "recordings.yaml", root / f"{model}_dataset", config, jobs=2, video_fps=30.0
        )
        datasets[model] = root / f"{model}_dataset"
        stamp.write_text(json.dumps(made))  # the corpus is complete: a rerun into --out reuses it
        minutes = {s: manifest["splits"][s]["rows"] / 30 / 60 for s in ("train", "val", "test")}
        print(
            f"  {model} corpus: {len(plan)} sessions, train {minutes['train']:.1f} min at {TRAIN_TEMPI[0]}-"
            f"{TRAIN_TEMPI[-1]} BPM, val {minutes['val']:.1f} min at {VAL_TEMPI}, test {minutes['test']:.1f} min at "
            f"{TEST_TEMPI} BPM ({time.perf_counter() - started:.0f} s so far)",
            flush=True,
        )
    return datasets


def beat_metrics(run: Path, dataset: Path):
    """An ``epoch_metrics`` for :func:`train`: beat following of the generated motion on the test songs."""

    def measure(net: torch.nn.Module) -> dict[str, float]:
        config = json.loads((run / "config.json").read_text())
        found = split_songs(net, config, dataset, "test")
        motions = found.generate_many([(s.features, s.first_pose) for s in found.songs])
        recs = [RecordingBeats(s.name, m, None, s.fps, s.beats_s, first_frame=1) for s, m in zip(found.songs, motions)]
        result = beat_following(recs, draws=100)
        return {
            "test_in_metre": result.in_metre.value,
            "test_at_beat": result.at_beat.value,
            "test_beat_align": result.beat_align_music.value,
            "test_beat_align_chance": result.beat_align_music.chance,
        }

    return measure


def train_and_score(
    name: str, model: str, settings: dict[str, Any], dataset: Path, out: Path, minutes: float, seed: int
) -> dict[str, Any]:
    """Train within ``minutes``, then ``evaluate`` on the test split; print and return the figures."""
    run = out / name
    shutil.rmtree(run, ignore_errors=True)  # a rerun into --out trains afresh
    config = TrainConfig.for_model(model, **settings, epochs=1000, max_minutes=minutes, seed=seed)
    print(
        f"  [{name}] {model}: {', '.join(f'{k} {v}' for k, v in settings.items())}; budget {minutes:g} min", flush=True
    )

    def progress(row: dict[str, Any]) -> None:
        print(
            f"    epoch {row['epoch']:3d} step {row['step']:5d}: train {row['train_loss']:.4f} val "
            f"{row['val_loss']:.4f}, test songs at a metrical level {row['test_in_metre']:.0%} (at the beat "
            f"{row['test_at_beat']:.0%}), Beat Align Score "
            f"{row['test_beat_align']:.3f} (chance {row['test_beat_align_chance']:.3f}), "
            f"{row['frames_per_second']:.0f} frames/s",
            flush=True,
        )

    started = time.perf_counter()
    history = train(dataset, run, config, progress=progress, epoch_metrics=beat_metrics(run, dataset))
    trained = time.perf_counter() - started
    results = evaluate(run, dataset, "test", engines=[])
    listening = results["listening"]
    figure = learning_curves(history, run / "learning.png", f"{name}: {model}")
    smape = results["smape"]
    print(f"  [{name}] trained {trained / 60:.1f} min, {history[-1]['step']} steps, {len(history)} epochs")
    if results.get("turning"):
        print(f"    {results['turning']}")
    for mode, v in smape.items():
        print(f"    SMAPE {mode.replace('_', ' ')}: {v['smape_normalised']:.2f} % normalised")
    for line in listening.get("verdicts", [f"listening not measured: {listening.get('unavailable')}"]):
        print(f"    {line}")
    print(f"    curves: {figure}")
    return {"history": history, "results": results, "minutes": trained / 60, "figure": str(figure)}


def learning_curves(history: list[dict[str, Any]], path: Path, title: str) -> Path:
    """Training and validation loss, and the test songs' beat figures, per epoch."""

    def beats(bottom, epochs):
        in_metre = [r["test_in_metre"] for r in history]
        bottom.plot(epochs, in_metre, label="test songs with the period at a metrical level")
        bottom.plot(epochs, [r["test_beat_align"] for r in history], label="Beat Align Score")
        bottom.plot(epochs, [r["test_beat_align_chance"] for r in history], "--", label="its chance level")
        bottom.set_ylim(0, 1.05)

    return loss_figure(history, path, title, ("training loss", "validation loss"), beats)


def loss_figure(
    history: list[dict[str, Any]], path: Path, title: str, labels: tuple[str, str], draw_bottom: Any
) -> Path:
    """A learning-curve figure saved at ``path``: training and validation loss per epoch on top (log
    scale, ``labels``), below what ``draw_bottom(axes, epochs)`` draws."""
    from kinectdata.core.figures import pyplot

    plt = pyplot()
    epochs = [r["epoch"] for r in history]
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    top.plot(epochs, [r["train_loss"] for r in history], label=labels[0])
    top.plot(epochs, [r["val_loss"] for r in history], label=labels[1])
    top.set_yscale("log")
    top.legend()
    top.set_title(title)
    draw_bottom(bottom, epochs)
    bottom.set_xlabel("epoch")
    bottom.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _headline(model: str, name: str, scored: dict[str, Any]) -> None:
    listening = scored["results"]["listening"]
    if "generated" not in listening:
        return
    g = listening["generated"]
    record(
        "learning",
        f"{model} ({name}, {scored['minutes']:.0f} min): test songs in metre / tempo rho / BAS vs real / energy",
        f"{g['in_metre']['value']:.0%} (chance {g['in_metre']['chance']:.0%}) / "
        f"{g['tempo_correlation'] if g['tempo_correlation'] is None else round(g['tempo_correlation'], 2)} / "
        f"{listening['phase_ratio']:.2f}x / {listening['energy_ratio']:.2f}x",
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_learning", description=__doc__.split("\n")[0])
    parser.add_argument(
        "--minutes",
        type=float,
        default=None,
        help="the synthetic corpus: training budget per model and ablation (default 30); a real corpus: a time "
        "guard per run (default 60: the recipes' epochs fit 30 minutes on the 2-core machine)",
    )
    parser.add_argument("--seed", type=int, default=0, help="the synthetic corpus's and its training's seed")
    parser.add_argument(
        "--seeds",
        default="0",
        help="with --corpus: the training seeds, comma-separated (0,1,2: each goal per seed and over the seeds)",
    )
    parser.add_argument("--models", default="yalta,cdhc")
    parser.add_argument("--corpus-minutes", type=float, default=CORPUS_MINUTES)
    parser.add_argument("--ablations", action="store_true", help="also train every ablation (same budget each)")
    parser.add_argument(
        "--only-ablations", default=None, help="comma-separated ablation numbers (1-based): run those, not the recipe"
    )
    parser.add_argument("--out", type=Path, default=None, help="keep the corpus, runs and figures here")
    parser.add_argument(
        "--corpus",
        nargs=2,
        metavar=("NAME", "PATH"),
        default=None,
        help="a real corpus instead of the synthetic one: a recipe's name (tang2018) and your local copy",
    )
    parser.add_argument(
        "--rescore",
        action="store_true",
        help="with --corpus and --out: evaluate the runs an earlier benchmark left in --out again, without training "
        "(with --folds: the fold runs of the candidate --tag names, after a change to what is drawn at generation)",
    )
    parser.add_argument(
        "--folds",
        type=int,
        default=None,
        metavar="K",
        help="with --corpus: train and score on K cross-validation folds of the dances outside the test split "
        "(--minutes per fold), to compare a recipe without the test split",
    )
    parser.add_argument("--fold", default=None, metavar="N[,N]", help="with --folds: train and score these folds only")
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="SETTING=VALUE",
        help="with --folds: a candidate's training setting over the defaults of every model run (repeatable; "
        "VALUE read as JSON where it parses, else as text: --set bend_weight=10 --set inputs=music)",
    )
    parser.add_argument(
        "--features",
        action="append",
        default=[],
        metavar="MODEL=PRESET",
        help="with --folds: MODEL's datasets built with a feature preset instead of the recipe's (repeatable)",
    )
    parser.add_argument(
        "--tag", default="", help="with --folds: name the candidate's runs (<model>-<tag>-seed<N>) to keep them apart"
    )
    parser.add_argument(
        "--threads", type=int, default=2, help="torch threads (1: two runs side by side on the 2-core machine)"
    )
    parser.add_argument(
        "--allow-librosa",
        action="store_true",
        help="with --corpus: run without SoX, the songs of the tempo control and the style tempo stretched by "
        "librosa's phase vocoder (its figures differ from SoX's: docs/rhythm.md)",
    )
    args = parser.parse_args(argv or [])
    if args.rescore and (args.corpus is None or args.out is None):
        parser.error("--rescore evaluates the runs of an earlier real-corpus benchmark: give --corpus and --out")
    if args.folds is not None and args.corpus is None:
        parser.error("--folds cross-validates on a real corpus: give --corpus")
    candidate = [name for name in ("fold", "set", "features", "tag") if getattr(args, name)]
    if candidate and args.folds is None:
        said = f"--{candidate[0]} tries a candidate on the folds: give --folds K"
        parser.error(f"{said} (an acceptance run is the recipe's)")
    only = _numbers(parser, "--fold", args.fold) if args.fold else None
    changes = _pairs(parser, "--set", args.set, json_values=True)
    features = _pairs(parser, "--features", args.features, json_values=False)
    models = [m.strip() for m in args.models.split(",") if m.strip()]
    if set(features) - set(models):
        parser.error(f"--features names {sorted(set(features) - set(models))[0]}, a model not in --models")
    seeds = _numbers(parser, "--seeds", args.seeds)
    if args.corpus is not None:
        _require_sox(args.allow_librosa)
    if args.threads < 1:
        parser.error(f"--threads takes a whole number of at least 1, not {args.threads}")
    torch.set_num_threads(args.threads)
    if args.corpus is None:
        print("  real corpus: not run (--corpus tang2018 PATH: a local copy of Dance with Melody, docs/corpora.md)")
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        if args.corpus is not None:
            try:
                _real(args, out, models, seeds, only, changes, features)
            except KinectDataError as exc:
                parser.exit(1, f"{parser.prog}: {exc}\n")
            return
        minutes = 30.0 if args.minutes is None else args.minutes
        datasets = make_corpus(out, args.seed, args.corpus_minutes, models)
        summary = {}
        for model in models:
            if not args.only_ablations:
                scored = train_and_score(
                    "recipe", model, RECIPES[model], datasets[model], out / model, minutes, args.seed
                )
                _headline(model, "recipe", scored)
                summary[f"{model} recipe"] = scored["results"]["listening"]
            if args.ablations or args.only_ablations:
                chosen = {int(k) for k in args.only_ablations.split(",")} if args.only_ablations else None
                for number, (label, change) in enumerate(ABLATIONS[model].items(), start=1):
                    if chosen is not None and number not in chosen:
                        continue
                    name = f"ablation-{number}"
                    print(f"  {name}: {label}")
                    scored = train_and_score(
                        name, model, {**RECIPES[model], **change}, datasets[model], out / model, minutes, args.seed
                    )
                    _headline(model, label, scored)
                    summary[f"{model} {name}: {label}"] = scored["results"]["listening"]
        (out / "learning.json").write_text(json.dumps(summary, indent=1, default=str))


def _real(
    args: argparse.Namespace,
    out: Path,
    models: list[str],
    seeds: list[int],
    only: list[int] | None,
    changes: dict[str, Any],
    features: dict[str, str],
) -> None:
    """The real corpus's run: its acceptance split (or, with ``--rescore``, the runs already there),
    or with ``--folds`` its folds, a candidate's ``changes`` and ``features`` tried on them."""
    name, path = args.corpus
    if args.folds is None:
        from .learning_real import run

        run(name, Path(path), out, models, seeds, _guard(args.minutes), rescore=args.rescore)
        return
    from .learning_folds import run_folds

    for model in models:  # a setting no model knows fails now, not after the datasets are built
        TrainConfig.for_model(model, **changes)
    run_folds(
        name,
        Path(path),
        out,
        _guard(args.minutes),
        models,
        seeds,
        args.folds,
        changes={model: changes for model in models},
        only=only,
        features=features,
        tag=args.tag,
        rescore=args.rescore,
    )


def _numbers(parser: argparse.ArgumentParser, option: str, text: str) -> list[int]:
    """``option``'s comma-separated whole numbers (at least one), or the parser's one-line error."""
    try:
        numbers = [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        parser.error(f"{option} takes whole numbers separated by commas, not {text!r}")
    if not numbers:
        parser.error(f"{option} names no number")
    return numbers


def _pairs(parser: argparse.ArgumentParser, option: str, given: list[str], json_values: bool) -> dict[str, Any]:
    """``option``'s ``NAME=VALUE`` pairs as a mapping (``json_values``: each value read as JSON where it
    parses, else kept as text), or the parser's one-line error."""
    pairs: dict[str, Any] = {}
    for item in given:
        name, equals, value = item.partition("=")
        if not equals or not name.strip() or not value.strip():
            parser.error(f"{option} takes NAME=VALUE, not {item!r}")
        if json_values:
            try:
                value = json.loads(value)
            except json.JSONDecodeError:
                pass
        pairs[name.strip()] = value
    return pairs


def _require_sox(allow_librosa: bool) -> None:
    """Exit with one line unless the songs can be stretched by SoX (or, with ``allow_librosa``, by
    librosa): the goals' tempo figures are SoX's, and librosa's fallback moved them on the same
    network (docs/rhythm.md), so a run without SoX must say it is one."""
    from kinectdata.align.stretch import available_stretcher

    found = available_stretcher()
    if found == "sox" or (found == "librosa" and allow_librosa):
        return
    if found is None:
        why = "neither SoX nor librosa is installed (apt-get install sox)"
    else:
        why = ("SoX is not installed (apt-get install sox); --allow-librosa runs with librosa's phase vocoder "
               "instead, whose tempo figures differ from SoX's")  # fmt: skip
    print(f"bench_learning: the real corpus's tempo control stretches its songs with SoX: {why}", file=sys.stderr)
    raise SystemExit(2)


def _guard(minutes: float | None) -> float:
    """A real corpus's time guard per run, minutes (``--minutes``, default the acceptance run's)."""
    from .learning_real import GUARD_MINUTES

    return GUARD_MINUTES if minutes is None else minutes


if __name__ == "__main__":
    main(sys.argv[1:])
