"""Do the bundled models learn to dance to real music on real dance? ``bench_learning --corpus
tang2018 PATH``: a local copy of a real corpus (never shipped: the path is yours), its acceptance
split, each model trained with its defaults within the budget, ``evaluate`` on the test dances,
and issue 25's goals printed with their figures, chance levels and verdicts:

- a. alive and human: energy 0.5-2 x the real motion's, jerk and PFC at most 2 x the real
  motion's, bone-length variation (CV) at most the real motion's;
- b. no fixed oscillator: the dominant period differs between songs, follows their tempo (rank
  correlation at least the real motion's) and changes when the song is swapped;
- c. listens: the swapped-song, noise and shifted-audio controls pass and silence stops the motion
  (energy at most 0.1 x);
- d. the field's metrics (bailando and aist protocols, 95 % intervals) beside the mean training
  pose with noise at the training dances' speed and the retrieval baseline: the model beats the
  first (lower FID_k and FID_g); the gap to the second is printed, and the same noise at each test
  song's own real speed (an oracle: it knows how fast the answer moves) beside them.

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
from .summary import record

PROTOCOLS = ("bailando", "aist")


def _turning_text(turning: dict[str, Any] | None) -> str:
    """Goal a's energy taken apart: how much of it is the body turning about the vertical (the
    tang2018 dancers turn; a model that never does moves less: docs/benchmarks.md)."""
    if not turning:
        return ""
    return (
        f"; turning {turning['generated_rate_rad_s']:.2f} rad/s, {turning['generated_share']:.0%} of the energy "
        f"(the real motion {turning['real_rate_rad_s']:.2f} rad/s, {turning['real_share']:.0%}); energy without "
        f"the turning {turning['energy_ratio_without_turning']:.2f} x"
    )


def goals(results: dict[str, Any]) -> list[tuple[str, bool, str]]:
    """Issue 25's goals a-d as (goal, met, figures) from ``evaluate``'s results."""
    listening = results["listening"]
    field = results["field"]
    metrics = field.get("metrics", {})
    out = []

    def ratio(name: str) -> tuple[float | None, str]:
        row = metrics.get(name, {})
        g, r = row.get("generated"), row.get("reference")
        if g is None or not r:
            return None, "n/a"
        return g / r, f"{g:.4g} vs {r:.4g} = {g / r:.2f} x"

    if "verdicts" in listening:
        energy = listening["energy_ratio"]
        jerk, jerk_text = ratio("jerk")
        pfc, pfc_text = ratio("PFC")
        bone = metrics.get("bone CV", {})
        bone_ok = bone.get("generated") is not None and bone.get("generated") <= (bone.get("reference") or 0)
        alive = 0.5 <= energy <= 2.0
        human = jerk is not None and jerk <= 2 and pfc is not None and pfc <= 2 and bone_ok
        out.append(
            (
                "a. alive and human",
                alive and human,
                f"energy {energy:.2f} x (0.5-2); jerk {jerk_text} (<= 2); PFC {pfc_text} (<= 2); bone-length CV "
                f"{_num(bone.get('generated'))} vs the real {_num(bone.get('reference'))} (<= real)"
                + _turning_text(listening.get("turning")),
            )
        )
        gen, real = listening["generated"], listening["real"]
        out.append(
            (
                "b. no fixed oscillator",
                listening["no_fixed_oscillator"],
                f"period spread {_num(listening['period_spread'])} x; tempo rank correlation "
                f"{_num(gen['tempo_correlation'])} (p {_num(gen['tempo_p_value'])}) vs the real motion's "
                f"{_num(real['tempo_correlation'])}; period changed with the swapped song in "
                f"{_pct(listening['swapped_period_changes'])} of runs",
            )
        )
        noise = listening["noise"]
        stops = listening["silence_energy_ratio"] <= 0.1
        passes = listening["listens"] and listening["shifted_at_chance"] and stops
        out.append(
            (
                "c. listens",
                passes,
                f"swapped song: at the new song's metre {_pct(listening['swapped_follows_new'])}, the old one's "
                f"{_pct(listening['swapped_follows_old'])}; noise: at a metrical level "
                f"{_pct(None if noise is None else noise['in_metre']['value'])}; shifted audio's Beat Align Score "
                f"{listening['shifted']['beat_align_music']['value']:.3f} (chance "
                f"{listening['shifted']['beat_align_music']['chance']:.3f}, at chance: "
                f"{'yes' if listening['shifted_at_chance'] else 'no'}); "
                f"silence {listening['silence_energy_ratio']:.2g} x",
            )
        )
    for name, entry in [("bailando", field), *results.get("field_protocols", {}).items()]:
        if "comparison" not in entry:
            out.append((f"d. field metrics ({name})", False, entry.get("unavailable", "not scored")))
            continue
        versus = entry["comparison"]
        noise, retrieval = versus.get("mean_pose_noise", {}), versus.get("retrieval", {})
        oracle = versus.get("mean_pose_noise_own_speed", {})
        out.append(
            (
                f"d. beats the mean pose + noise ({entry['protocol']})",
                bool(noise.get("beats")),
                f"FID_k {_num(noise.get('FID_k'))} vs {_num(noise.get('FID_k_baseline'))}, FID_g "
                f"{_num(noise.get('FID_g'))} vs {_num(noise.get('FID_g_baseline'))}; the gap to retrieval: FID_k "
                f"{_num(retrieval.get('FID_k_baseline'))}, FID_g {_num(retrieval.get('FID_g_baseline'))}; "
                f"the noise at each test song's own speed (an oracle): FID_k {_num(oracle.get('FID_k_baseline'))}",
            )
        )
    return out


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
    minutes: float,
    models: list[str],
    seed: int,
    bootstrap: int = 1000,
    changes: dict[str, dict[str, Any]] | None = None,
    rescore: bool = False,
) -> dict[str, Any]:
    """Build, train every model within ``minutes`` with its defaults (and ``changes[model]``, for
    the tests' small runs), evaluate on the test split (``bootstrap`` resamples for the field's
    intervals), print the goals. ``rescore``: evaluate the runs an earlier call left in ``out``
    again, without training (after a change to the evaluation)."""
    datasets, _ = build_corpus_datasets(corpus, path, out, models, echo=lambda line: print("  " + line, flush=True))
    summary = {}
    for model in models:
        run_dir = out / model
        if rescore:
            history = read_log(run_dir)
            trained = sum(r["seconds"] or 0.0 for r in history) / 60
            print(f"  [{model}] the run in {run_dir}, not trained again", flush=True)
            summary[model] = _score(model, corpus, run_dir, datasets[model], history, trained, out, bootstrap)
            continue
        history, trained = train_defaults(model, datasets[model], run_dir, minutes, seed, changes, progress=_progress)
        summary[model] = _score(model, corpus, run_dir, datasets[model], history, trained, out, bootstrap)
    (out / "learning_real.json").write_text(json.dumps(summary, indent=1, default=str))
    return summary


def train_defaults(
    model: str,
    dataset: Path,
    run_dir: Path,
    minutes: float,
    seed: int,
    changes: dict[str, dict[str, Any]] | None = None,
    progress: Callable[[dict[str, Any]], None] | None = None,
) -> tuple[list[dict[str, Any]], float]:
    """Train ``model`` afresh into ``run_dir`` with train-baseline's defaults (and ``changes[model]``,
    for the tests' small runs) within ``minutes``; its history and the minutes it took. Warnings
    print as one line each, as the CLI prints them, not as Python's two with a source line."""
    shutil.rmtree(run_dir, ignore_errors=True)
    # train-baseline's defaults, their epochs included (the cdhc model's kept epochs were 13-38 on
    # the validation dances; trained on to 80 epochs, the epoch its validation figures kept stood
    # nearly still), the budget a limit on top
    config = TrainConfig.for_model(model, **{"max_minutes": minutes, "seed": seed, **(changes or {}).get(model, {})})
    print(f"  [{model}] the defaults of train-baseline ({config.epochs} epochs at most); budget {minutes:g} min",
          flush=True)  # fmt: skip
    started = time.perf_counter()
    with warnings.catch_warnings():
        warnings.showwarning = lambda message, *_a, **_k: print(f"    warning: {message}", flush=True)
        history = train(dataset, run_dir, config, progress=progress)
    return history, (time.perf_counter() - started) / 60


def _progress(row: dict[str, Any]) -> None:
    print(f"    epoch {row['epoch']:3d} step {row['step']:5d}: train {row['train_loss']:.4f} "
          f"val {row['val_loss']:.4f}, SMAPE {row['val_smape']:.2f} %, free-running rhythm loss "
          f"{row['val_rhythm']:.3f}, songs' energy {_times(row['val_energy'])}", flush=True)  # fmt: skip


def _score(
    model: str,
    corpus: str,
    run_dir: Path,
    dataset: Path,
    history: list[dict[str, Any]],
    trained: float,
    out: Path,
    bootstrap: int,
) -> dict[str, Any]:
    """Evaluate a trained run on the test split, print its results and goals; its summary."""
    figure = curves(history, out / f"learning-real-{model}.png", f"{model} on {corpus}: the defaults")
    # the forward time on torch only: the other engines' times are bench_model's; an ONNX export here
    # would cost more than the rest of a small run's evaluation
    results = evaluate(
        run_dir, dataset, "test", more_protocols=PROTOCOLS[1:], bootstrap=bootstrap, engines=[("torch", "float32")]
    )
    kept = next((r for r in history if r.get("kept")), history[-1])
    print(
        f"  [{model}] trained {trained:.1f} min, {history[-1]['step']} steps ({_per_minute(history, trained)} a "
        f"minute: the machine's speed decides how far a time budget goes), {len(history)} epochs, model.pt "
        f"from epoch {kept['epoch']} (lowest free-running validation rhythm loss among the epochs moving at "
        f"{ALIVE_RANGE[0]:g}-{ALIVE_RANGE[1]:g} x the real energy; its validation songs: "
        f"{_times(kept['val_energy'])}); curves: {figure}; "
        "on the test dances:"
    )
    print("\n".join("    " + line for line in format_results(results).splitlines()))
    met = goals(results)
    print(f"  [{model}] goals:")
    for goal, ok, figures in met:
        print(f"    {goal}: {'yes' if ok else 'no'} ({figures})")
    record(
        "learning",
        f"{model} on {corpus} ({trained:.0f} min): goals met",
        f"{sum(ok for _, ok, _ in met)} of {len(met)}",
    )
    return {"minutes": trained, "goals": met, "listening": results["listening"], "field": results["field"]}


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


def _num(v: Any) -> str:
    return "n/a" if v is None else f"{v:.3g}"


def _pct(v: float | None) -> str:
    return "n/a" if v is None else f"{v:.0%}"
