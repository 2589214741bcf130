"""Do the bundled models learn to dance to real music on real dance, in every seed? ``bench_learning
--corpus tang2018 PATH --seeds 0,1,2``: a local copy of a real corpus (never shipped: the path is
yours), its acceptance split, each model trained with its defaults (their length a number of
epochs, not a time: the model a user gets does not depend on how fast the machine was that day;
``--minutes`` is only a guard, and the output says when it cut a run) once per seed, ``evaluate``
on the test dances, and issue 56's goals a-e (:mod:`benchmarks.real_goals`) printed for each seed
and then over the seeds: met in every seed, each figure's worst value and its spread.

The test dances are never trained on, tuned on or used to pick a checkpoint: training validates
on the validation dances only.
"""

from __future__ import annotations

import json
import shutil
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

from kinectdata.apps.real_dance import build_corpus_datasets
from kinectdata.evaluation.evaluate import evaluate, format_results
from kinectdata.evaluation.listening import ALIVE_RANGE
from kinectdata.training.config import TrainConfig
from kinectdata.training.train import read_log, train

from .bench_learning import loss_figure
from .real_goals import Goal, across_seeds, goals
from .summary import record

PROTOCOLS = ("bailando", "aist")
GUARD_MINUTES = 60.0
"""The time guard of an acceptance run, minutes per model and seed: the recipes' epochs fit 30 minutes
on the 2-core machine (docs/benchmarks.md); a run the guard cuts is named in the output."""


def _per_minute(history: list[dict[str, Any]], minutes: float) -> str:
    """Training steps per minute of a run (the docs' runs: cdhc 144 on 2026-11-28, 82 on 2026-11-29)."""
    return f"{history[-1]['step'] / minutes:.0f}" if minutes > 0 else "?"


def _times(ratio: float | None) -> str:
    """An energy ratio as printed (``-`` when the epoch had no free runs to measure)."""
    return "-" if ratio is None else f"{ratio:.2f} x"


def run(
    corpus: str,
    path: Path,
    out: Path,
    models: list[str],
    seeds: list[int],
    guard_minutes: float | None = GUARD_MINUTES,
    bootstrap: int = 1000,
    changes: dict[str, dict[str, Any]] | None = None,
    rescore: bool = False,
) -> dict[str, Any]:
    """Build, train every model once per seed with its defaults (and ``changes[model]``, for the
    tests' small runs) into ``out/seed<N>/<model>``, each within ``guard_minutes`` at most, evaluate
    each on the test split (``bootstrap`` resamples for the field's intervals), print the goals per
    seed and over the seeds. ``rescore``: evaluate the runs an earlier call left in ``out`` again,
    without training (after a change to the evaluation). Returns ``{model: {seed: summary}}``."""
    datasets, _ = build_corpus_datasets(corpus, path, out, models, echo=lambda line: print("  " + line, flush=True))
    summary: dict[str, Any] = {}
    for model in models:
        per_seed: dict[int, list[Goal]] = {}
        for seed in seeds:
            run_dir = out / f"seed{seed}" / model
            if rescore:
                history, trained = run_as_left(run_dir, f"[{model} seed {seed}]")
            else:
                history, trained = train_defaults(
                    model, datasets[model], run_dir, guard_minutes, seed, changes, progress=print_epoch
                )
            scored = _score(model, seed, corpus, run_dir, datasets[model], history, trained, out, bootstrap)
            per_seed[seed] = scored.pop("goal_objects")
            summary.setdefault(model, {})[seed] = scored
        print(f"  [{model}] the goals over seeds {', '.join(map(str, seeds))}:")
        lines = across_seeds(per_seed)
        for line in lines:
            print(f"    {line}")
        everywhere = sum(all(per_seed[s][i].met for s in seeds) for i in range(len(per_seed[seeds[0]])))
        record(
            "learning",
            f"{model} on {corpus}, seeds {','.join(map(str, seeds))}: goals met in every seed",
            f"{everywhere} of {len(per_seed[seeds[0]])}",
        )
    (out / "learning_real.json").write_text(json.dumps(summary, indent=1, default=str))
    return summary


def run_as_left(run_dir: Path, head: str) -> tuple[list[dict[str, Any]], float]:
    """A run an earlier benchmark left in ``run_dir``, for ``--rescore``: its history and the minutes it
    trained, read from its log; prints that it is not trained again, after ``head`` (``[yalta seed 0]``)."""
    history = read_log(run_dir)
    print(f"  {head} the run in {run_dir}, not trained again", flush=True)
    return history, sum(r["seconds"] or 0.0 for r in history) / 60


def train_defaults(
    model: str,
    dataset: Path,
    run_dir: Path,
    guard_minutes: float | None,
    seed: int,
    changes: dict[str, dict[str, Any]] | None = None,
    progress: Callable[[dict[str, Any]], None] | None = None,
) -> tuple[list[dict[str, Any]], float]:
    """Train ``model`` afresh into ``run_dir`` with train-baseline's defaults (and ``changes[model]``,
    for the tests' small runs), all their epochs unless ``guard_minutes`` runs out first (then it says
    so); its history and the minutes it took. Warnings print as one line each, as the CLI prints
    them, not as Python's two with a source line."""
    shutil.rmtree(run_dir, ignore_errors=True)
    config = TrainConfig.for_model(
        model, **{"max_minutes": guard_minutes, "seed": seed, **(changes or {}).get(model, {})}
    )
    guard = "" if guard_minutes is None else f" (a guard of {guard_minutes:g} min)"
    print(f"  [{model} seed {seed}] the defaults of train-baseline: {config.epochs} epochs{guard}", flush=True)
    started = time.perf_counter()
    with warnings.catch_warnings():
        warnings.showwarning = lambda message, *_a, **_k: print(f"    warning: {message}", flush=True)
        history = train(dataset, run_dir, config, progress=progress)
    if len(history) < config.epochs:
        print(f"    the {guard_minutes:g}-minute guard cut this run after {len(history)} of its {config.epochs} "
              "epochs: its model is not the recipe's (a slower machine than the recipe was sized on)",
              flush=True)  # fmt: skip
    return history, (time.perf_counter() - started) / 60


def score_split(run_dir: Path, dataset: Path, split: str, bootstrap: int, seed: int) -> dict[str, Any]:
    """``evaluate`` as the goals read it: ``split``'s recordings on every protocol of :data:`PROTOCOLS`
    with the baselines, ``bootstrap`` resamples for the intervals, the turning and travel drawn with
    the run's own ``seed`` (a seed stands for all of a recipe's chance: the weights and the draws).
    The forward time on torch only: the other engines' times are bench_model's; an ONNX export here
    would cost more than the rest of a small run's evaluation."""
    return evaluate(
        run_dir,
        dataset,
        split,
        more_protocols=PROTOCOLS[1:],
        bootstrap=bootstrap,
        engines=[("torch", "float32")],
        draw_seed=seed,
    )


def print_epoch(row: dict[str, Any]) -> None:
    """One line per trained epoch: its losses, the free-running rhythm loss and the songs' energy."""
    print(f"    epoch {row['epoch']:3d} step {row['step']:5d}: train {row['train_loss']:.4f} "
          f"val {row['val_loss']:.4f}, SMAPE {row['val_smape']:.2f} %, free-running rhythm loss "
          f"{row['val_rhythm']:.3f}, songs' energy {_times(row['val_energy'])}", flush=True)  # fmt: skip


def _score(
    model: str,
    seed: int,
    corpus: str,
    run_dir: Path,
    dataset: Path,
    history: list[dict[str, Any]],
    trained: float,
    out: Path,
    bootstrap: int,
) -> dict[str, Any]:
    """Evaluate a trained run on the test split, print its results and goals; its summary (with the
    goals themselves under ``goal_objects``, for :func:`across_seeds`)."""
    name = f"{model} seed {seed}"
    figure = curves(history, out / f"learning-real-{model}-seed{seed}.png", f"{model} on {corpus}, seed {seed}")
    results = score_split(run_dir, dataset, "test", bootstrap, seed)
    kept = next((r for r in history if r.get("kept")), history[-1])
    print(
        f"  [{name}] trained {trained:.1f} min, {history[-1]['step']} steps ({_per_minute(history, trained)} a "
        f"minute), {len(history)} epochs, model.pt from epoch {kept['epoch']} (lowest free-running validation "
        f"rhythm loss among the epochs moving at {ALIVE_RANGE[0]:g}-{ALIVE_RANGE[1]:g} x the real energy; its "
        f"validation songs: {_times(kept['val_energy'])}); curves: {figure}; on the test dances:"
    )
    print("\n".join("    " + line for line in format_results(results).splitlines()))
    met = goals(results)
    print(f"  [{name}] goals:")
    for goal in met:
        print(f"    {goal.line()}")
    return {
        "minutes": trained,
        "goals": [g.to_dict() for g in met],
        "goal_objects": met,
        "listening": results["listening"],
        "field": results["field"],
        "style": results.get("style"),
    }


def curves(history: list[dict[str, Any]], path: Path, title: str) -> Path:
    """Training and validation loss (top), the free-running validation rhythm loss with the kept
    epoch marked and, on the right axis, the free runs' energy over the real motion's with the band
    an epoch must be in to be kept (bottom), per epoch."""

    def rhythm(bottom, epochs):
        bottom.plot(epochs, [r["val_rhythm"] for r in history], label="free-running validation rhythm loss")
        kept = [r["epoch"] for r in history if r.get("kept")]
        if kept:
            value = next(r["val_rhythm"] for r in history if r["epoch"] == kept[0])
            bottom.plot(kept, [value], "o", label=f"kept: epoch {kept[0]}")
        energy = bottom.twinx()
        energy.plot(epochs, [r.get("val_energy") or float("nan") for r in history], color="tab:green", alpha=0.7)
        energy.axhspan(*ALIVE_RANGE, color="tab:green", alpha=0.1)
        energy.set_yscale("log")
        energy.set_ylabel("validation songs' energy / real (band: kept)")

    labels = ("training loss (teacher + rhythm)", "validation loss (teacher)")
    return loss_figure(history, path, title, labels, rhythm)
