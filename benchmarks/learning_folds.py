"""Compare a training recipe on a small real corpus without its test split: ``bench_learning
--corpus tang2018 PATH --folds K``.

The corpus's recordings outside the test split are dealt into K folds (``kinectdata folds``, each
style spread over them); for each model, each fold's dataset is built as the acceptance run builds
the corpus's, a model is trained on the other folds' recordings with ``train-baseline``'s defaults
(and the budget), and scored with ``evaluate`` on the fold's own (the ``val`` split of the fold's
manifest). Printed: each fold's goals a-c (d needs the test split's baselines: not here), then the
beat-following figures of every fold's held-out songs read together
(:func:`kinectdata.evaluation.pooled.held_out_following`), beside the real dancers' on the same
songs. The test dances are in no fold: nothing here trains, tunes or picks on them.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.apps.real_dance import build_model_dataset
from kinectdata.dataset.folds import write_folds
from kinectdata.dataset.recipes import prepare_corpus
from kinectdata.evaluation.evaluate import evaluate
from kinectdata.evaluation.pooled import held_out_following

from .learning_real import goals, train_defaults
from .summary import record


def run_folds(
    corpus: str,
    path: Path,
    out: Path,
    minutes: float,
    models: list[str],
    seed: int,
    folds: int,
    changes: dict[str, dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """Build, train and score every model on each of ``folds`` folds (module docstring), each
    fold's training within ``minutes``; the pooled reading printed and returned per model."""
    out.mkdir(parents=True, exist_ok=True)
    manifest = prepare_corpus(corpus, path)
    listed = manifest.write(out / "recordings.yaml")
    made = write_folds(listed, folds, by="style", seed=seed)
    for fold in made:
        print(f"  fold {fold.index}: validates on {', '.join(fold.validation)} ({len(fold.training)} to train on)")
    summary = {}
    for model in models:
        pairs = []
        for fold in made:
            dataset = out / f"fold{fold.index}" / f"{model}_dataset"
            build_model_dataset(fold.path, dataset, model, manifest, echo=lambda line: print("  " + line, flush=True))
            run_dir = out / f"fold{fold.index}" / model
            history, trained = train_defaults(model, dataset, run_dir, minutes, seed, changes)
            results = evaluate(run_dir, dataset, "val", bootstrap=0, engines=[("torch", "float32")], baselines=False)
            print(f"  [{model}] fold {fold.index}: trained {trained:.1f} min, "
                  f"{history[-1]['step']} steps; on its {len(fold.validation)} held-out dances:")  # fmt: skip
            for goal, ok, figures in goals(results)[:3]:
                print(f"    {goal}: {'yes' if ok else 'no'} ({figures})")
            pairs.append((run_dir, dataset))
        pooled = held_out_following(pairs, "val")
        energy = np.array(list(pooled.energy_ratios.values()))
        print(f"  [{model}] the {len(energy)} held-out dances of the {folds} folds together:")
        for line in pooled.generated.verdicts("generated") + pooled.real.verdicts("real"):
            print(f"    {line}")
        print(f"    energy x the real motion's: median {np.median(energy):.2f}, in 0.5-2 for "
              f"{np.mean((energy >= 0.5) & (energy <= 2)):.0%} of the dances")  # fmt: skip
        at_level = pooled.generated.in_metre
        record(
            "learning",
            f"{model} on {corpus}, {folds} folds: held-out songs at a metrical level",
            f"{at_level.value:.0%} (chance {at_level.chance:.0%}, p = {at_level.p_value:.2g})",
        )
        summary[model] = {
            "verdicts": pooled.generated.verdicts("generated"),
            "real": pooled.real.verdicts("real"),
            "energy_ratios": pooled.energy_ratios,
            "runs": pooled.runs,
        }
    (out / "learning_folds.json").write_text(json.dumps(summary, indent=1, default=str))
    return summary
