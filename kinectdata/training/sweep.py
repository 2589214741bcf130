"""``sweep``: the variants of Yalta et al. (2016) Tables 3-5 trained and scored on one dataset.

Each variant changes one thing of the base (ELU, 500 units, sequences of 150): the activation
(TanH, ReLU, ELU), the LSTM size (250, 1000 units) or the sequence length (50, 100). Each is
trained into ``OUT/<variant>/`` with :func:`~kinectdata.training.train.train` and evaluated on
the test split; ``OUT/results.md`` has the paper's columns (SMAPE without and with reset,
training minutes, forward milliseconds per frame) beside the paper's own figures.
"""

from __future__ import annotations

import csv
import dataclasses
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.evaluate import evaluate
from kinectdata.models.run import CHECKPOINT, LOG, MODEL, read_config, read_manifest
from kinectdata.training.config import TrainConfig
from kinectdata.training.train import train

VARIANTS: dict[str, dict[str, Any]] = {
    "TanH": {"activation": "tanh"},
    "ReLU": {"activation": "relu"},
    "ELU": {},
    "250 units": {"units": 250},
    "1000 units": {"units": 1000},
    "50 steps": {"sequence": 50},
    "100 steps": {"sequence": 100},
}
"""Changes from the base configuration (ELU, 500 units, 150 steps), as in the paper's tables."""

PAPER = {  # SMAPE % without reset, with reset, training minutes, forward ms/frame (GTX Titan X)
    "TanH": (19.73, 20.34, 1182.79, 9.16),
    "ReLU": (19.67, 20.27, 1152.02, 8.54),
    "ELU": (18.57, 19.20, 1139.81, 10.94),
    "250 units": (19.76, 20.28, 663.99, 10.16),
    "1000 units": (17.81, 18.53, 1305.85, 14.97),
    "50 steps": (22.99, 23.73, 247.19, 10.94),
    "100 steps": (19.16, 20.01, 774.75, 10.94),
}


def _slug(name: str) -> str:
    return name.lower().replace(" ", "-")


def sweep(
    dataset: str | Path,
    out: str | Path,
    base: TrainConfig | None = None,
    variants: list[str] | None = None,
    progress: Callable[[str, dict], None] | None = None,
) -> list[dict[str, Any]]:
    """Train and evaluate each variant (all of :data:`VARIANTS` by default); returns the rows of
    the table, also written to ``OUT/results.md`` and ``OUT/results.json``."""
    base = base or TrainConfig(activation="elu", units=500, sequence=150)
    names = variants or list(VARIANTS)
    unknown = [n for n in names if n not in VARIANTS]
    if unknown:
        raise KinectDataError(f"unknown variant(s) {unknown}; known: {', '.join(VARIANTS)}")
    out = Path(out)
    manifest = read_manifest(dataset)
    rows = []
    for name in names:
        config = dataclasses.replace(base, **VARIANTS[name])
        run = out / _slug(name)
        if (run / MODEL).exists():  # a finished variant of an interrupted sweep is kept, if it is this one
            _check_finished(run, config, manifest)
        else:
            train(dataset, run, config, resume=(run / CHECKPOINT).exists())
        with open(run / LOG) as f:
            minutes = sum(float(r["seconds"]) for r in csv.DictReader(f)) / 60
        result = evaluate(run, dataset, "test", engines=[("torch", "float32")])
        row = {
            "setting": name,
            "run": str(run),
            "smape_without_reset": result["smape"]["without_reset"]["smape_normalised"],
            "smape_with_reset": result["smape"]["with_reset"]["smape_normalised"],
            "training_minutes": minutes,
            "forward_ms": result["forward_time"]["torch float32"]["median_ms"],
            "device": result["forward_time"]["torch float32"]["device"],
            "config": config.to_dict(),
        }
        rows.append(row)
        if progress:
            progress(name, row)
    _write_tables(out, rows, base)
    return rows


def _check_finished(run: Path, config: TrainConfig, manifest: dict[str, Any]) -> None:
    saved = read_config(run)
    own = TrainConfig(**saved["train"]).to_dict()  # settings added since the run was made take their defaults
    differ = [k for k, v in config.to_dict().items() if own[k] != v]
    if saved["dataset"]["build_key"] != manifest["build_key"]:
        differ.append("dataset")
    if differ:
        raise KinectDataError(
            f"{run}: holds a finished run whose {', '.join(differ)} differ from this sweep's; "
            "remove it or sweep into another folder"
        )


def _write_tables(out: Path, rows: list[dict[str, Any]], base: TrainConfig) -> None:
    lines = [
        f"# Yalta et al. (2016) Tables 3-5 on this dataset ({base.epochs} epochs, batch {base.batch_size}, "
        f"{base.feedback} feedback)",
        "",
        "SMAPE in % on the normalised targets of the test split, free-running from the first true pose. "
        "Training minutes are the epochs' time from each run's log; forward time is the streaming network at batch 1 "
        f"in torch, float32 ({rows[0]['device'] if rows else ''}). "
        "Paper: their figures (GTX Titan X, about 15 Latin songs).",
        "",
        "| setting | SMAPE % without reset | with reset | training min | forward ms/frame "
        "| paper: without | with | min | ms |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in rows:
        p = PAPER[r["setting"]]
        lines.append(
            f"| {r['setting']} | {r['smape_without_reset']:.2f} | {r['smape_with_reset']:.2f} | "
            f"{r['training_minutes']:.2f} | {r['forward_ms']:.2f} | {p[0]:.2f} | {p[1]:.2f} | {p[2]:.2f} | {p[3]:.2f} |"
        )
    with atomic_output(out / "results.md") as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    with atomic_output(out / "results.json") as tmp:
        tmp.write_text(json.dumps(rows, indent=2) + "\n")
