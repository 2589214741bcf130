"""Compare a training recipe on a small real corpus without its test split: ``bench_learning
--corpus tang2018 PATH --folds K``.

The corpus's recordings outside the test split are dealt into K folds (``kinectdata folds``, each
style spread over them); for each model, each fold's dataset is built as the acceptance run builds
the corpus's, a model is trained on the other folds' recordings with ``train-baseline``'s defaults
(and the budget), and scored with ``evaluate`` on the fold's own (the ``val`` split of the fold's
manifest), its turning and travel drawn with the run's seed as the acceptance run draws them.
Printed: each fold's goals a-e (d against the baselines made for the fold's own held-out songs from
its training dances, on both protocols; c asks for the beat followed only where the fold's real
dancers follow it), then the beat-following figures of every fold's held-out songs read together
(:func:`kinectdata.evaluation.pooled.held_out_following`), beside the real dancers' on the same
songs. The test dances are in no fold: nothing here trains, tunes or picks on them.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.apps.real_dance import build_model_dataset
from kinectdata.core.errors import ConfigError
from kinectdata.dataset.build import EmptySplitWarning
from kinectdata.dataset.folds import write_folds
from kinectdata.dataset.recipes import prepare_corpus
from kinectdata.evaluation.evaluate import variety
from kinectdata.evaluation.pooled import held_out_following

from .learning_real import print_epoch, run_as_left, score_split, train_defaults
from .real_goals import goals
from .summary import record


def run_folds(
    corpus: str,
    path: Path,
    out: Path,
    guard_minutes: float | None,
    models: list[str],
    seeds: list[int],
    folds: int,
    changes: dict[str, dict[str, Any]] | None = None,
    only: list[int] | None = None,
    features: dict[str, str] | None = None,
    tag: str = "",
    rescore: bool = False,
) -> dict[str, Any]:
    """Build, train and score every model on each of ``folds`` folds (module docstring; ``only``:
    these folds, numbered from 1) once per seed, each run within ``guard_minutes`` at most; the
    pooled reading printed and returned per model and seed. The folds are dealt the same way whatever
    the seeds (seed 0). A candidate: ``changes[model]``, training settings over the defaults;
    ``features[model]``, a feature preset instead of the recipe's (its datasets built beside the
    recipe's, ``<model>-<preset>_dataset``); ``tag`` names its runs (``<model>-<tag>-seed<N>``) so
    that candidates share one ``out`` and its datasets. ``rescore``: score the runs an earlier call
    left in ``out`` again, without training (after a change to what is drawn at generation: the
    turning, the travel, the standing foot)."""
    unknown = sorted(set(only or ()) - set(range(1, folds + 1)))
    if unknown:
        raise ConfigError(f"there is no fold {unknown[0]} of {folds} (the folds are numbered 1-{folds})")
    out.mkdir(parents=True, exist_ok=True)
    manifest = prepare_corpus(corpus, path)
    listed = manifest.write(out / "recordings.yaml")
    made = [fold for fold in write_folds(listed, folds, by="style", seed=0) if only is None or fold.index in only]
    for fold in made:
        print(f"  fold {fold.index}: validates on {', '.join(fold.validation)} ({len(fold.training)} to train on)")
    summary: dict[str, Any] = {}
    for model in models:
        preset = (features or {}).get(model)
        datasets = {fold.index: out / f"fold{fold.index}" / _dataset_name(model, preset) for fold in made}
        for fold in made:
            with warnings.catch_warnings():  # a fold has no test split by design: it is scored on its val split
                warnings.simplefilter("ignore", EmptySplitWarning)
                build_model_dataset(fold.path, datasets[fold.index], model, manifest, echo=_echo, features=preset)
        for seed in seeds:
            run_name = "-".join(filter(None, (model, tag, f"seed{seed}")))
            runs = {i: (datasets[i], out / f"fold{i}" / run_name) for i in datasets}
            summary.setdefault(model, {})[seed] = _seed_on_folds(
                model, seed, made, runs, guard_minutes, changes, rescore
            )
    (out / f"learning_folds{'-' + tag if tag else ''}.json").write_text(json.dumps(summary, indent=1, default=str))
    return summary


def _echo(line: str) -> None:
    print("  " + line, flush=True)


def _dataset_name(model: str, preset: str | None) -> str:
    """A fold's dataset folder for ``model``: the recipe's features, or ``preset``'s."""
    return f"{model}-{preset}_dataset" if preset else f"{model}_dataset"


def _seed_on_folds(
    model: str,
    seed: int,
    made: list,
    runs: dict[int, tuple[Path, Path]],
    guard_minutes: float | None,
    changes: dict | None,
    rescore: bool = False,
) -> dict[str, Any]:
    """One seed of ``model`` trained (``rescore``: as an earlier call left it) and scored on every fold
    (``runs``: each fold's dataset and run folder); the pooled figures printed and returned."""
    pairs, varied, styled = [], [], []
    for fold in made:
        dataset, run_dir = runs[fold.index]
        if rescore:
            history, trained = run_as_left(run_dir, f"[{model} seed {seed}] fold {fold.index}:")
        else:
            history, trained = train_defaults(
                model, dataset, run_dir, guard_minutes, seed, changes, progress=print_epoch
            )
        results = score_split(run_dir, dataset, "val", 0, seed)
        print(f"  [{model} seed {seed}] fold {fold.index}: trained {trained:.1f} min, "
              f"{history[-1]['step']} steps; on its {len(fold.validation)} held-out dances:")  # fmt: skip
        for goal in goals(results, beat_where_real=True):
            print(f"    {goal.line()}")
        pairs.append((run_dir, dataset))
        divs = variety(results["field"])
        if divs is not None:
            varied.append(divs[0] / divs[1])
        style = results.get("style", {})
        styled += [(n, s["style"], s["named"]) for n, s in style.get("songs", {}).items() if n in style["counted"]]
    pooled = held_out_following(pairs, "val", draw_seed=seed)
    energy = np.array(list(pooled.energy_ratios.values()))
    name = f"{model} seed {seed}"
    print(f"  [{name}] the {len(energy)} held-out dances of the {len(made)} folds together:")
    for line in pooled.generated.verdicts("generated") + pooled.real.verdicts("real"):
        print(f"    {line}")
    print(f"    energy x the real motion's: median {np.median(energy):.2f}, in 0.5-2 for "
          f"{np.mean((energy >= 0.5) & (energy <= 2)):.0%} of the dances")  # fmt: skip
    right = sum(s == said for _, s, said in styled)
    print(f"    Div_k over the real dancers' of each fold: {', '.join(f'{v:.2f}' for v in varied) or 'n/a'}; "
          f"dances in their song's style: {right} of {len(styled)}")  # fmt: skip
    at_level = pooled.generated.in_metre
    record(
        "learning",
        f"{name} on the folds: held-out songs at a metrical level",
        f"{at_level.value:.0%} (chance {at_level.chance:.0%}, p = {at_level.p_value:.2g})",
    )
    return {
        "verdicts": pooled.generated.verdicts("generated"),
        "real": pooled.real.verdicts("real"),
        "energy_ratios": pooled.energy_ratios,
        "runs": pooled.runs,
        "div_k_ratios": varied,
        "style": {"right": right, "counted": len(styled), "named": styled},
    }
