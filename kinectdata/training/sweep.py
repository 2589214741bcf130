"""``sweep``: the variants of a model's published table trained and scored on one dataset.

A model with a sweep (its kind's ``sweep``: :class:`~kinectdata.models.kind.Sweep`) names
variants, each changing one thing of a base configuration; e.g. the yalta model's are Yalta et
al. (2016) Tables 3-5: the activation (TanH, ReLU, ELU), the LSTM size (250, 1000 units) or the
sequence length (50, 100). Each is trained into ``OUT/<variant>/`` with
:func:`~kinectdata.training.train.train` and evaluated on the test split; ``OUT/results.md`` has
the paper's columns (SMAPE without and, for a model that resets, with reset, training minutes,
forward milliseconds per frame) beside the paper's own figures.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import ConfigError, KinectDataError
from kinectdata.evaluation.evaluate import evaluate
from kinectdata.models.kind import ModelKind, Sweep
from kinectdata.models.registry import MODELS, model_for_dataset, model_kind
from kinectdata.models.run import CHECKPOINT, MODEL, read_config, read_manifest
from kinectdata.training.config import TrainConfig
from kinectdata.training.train import read_log, train


def model_sweep(kind: ModelKind) -> Sweep:
    """The model's sweep; ConfigError naming the models that have one if it has none."""
    if kind.sweep is None:
        others = [k.name for k in MODELS.values() if k.sweep is not None]
        raise ConfigError(
            f"sweep reproduces a model's published table; the {kind.name} model has none "
            f"(models with a sweep: {', '.join(others) or 'none'})"
        )
    return kind.sweep


def _slug(name: str) -> str:
    return name.lower().replace(" ", "-")


def sweep(
    dataset: str | Path,
    out: str | Path,
    base: TrainConfig | None = None,
    variants: list[str] | None = None,
    progress: Callable[[str, dict], None] | None = None,
    checksums: bool = True,
) -> list[dict[str, Any]]:
    """Train and evaluate each variant of the model's sweep (``base.model``'s; default: the
    dataset's model with the sweep's base settings), all by default; returns the rows of the
    table, also written to ``OUT/results.md`` and ``OUT/results.json``. The dataset folder is
    verified once, first (``checksums=False`` skips the shards' SHA-256)."""
    manifest = read_manifest(dataset, checksums=checksums)
    kind = model_kind(base.model if base is not None else model_for_dataset(manifest))
    table = model_sweep(kind)
    base = base or TrainConfig(kind.name, paper=True, **table.base)
    names = variants or list(table.variants)
    unknown = [n for n in names if n not in table.variants]
    if unknown:
        raise KinectDataError(f"unknown variant(s) {unknown}; known: {', '.join(table.variants)}")
    out = Path(out)
    rows = []
    for name in names:
        config = base.replace(**table.variants[name])
        run = out / _slug(name)
        if (run / MODEL).exists():  # a finished variant of an interrupted sweep is kept, if it is this one
            _check_finished(run, config, manifest)
        else:
            train(dataset, run, config, resume=(run / CHECKPOINT).exists(), checksums=False)  # verified above
        row = _scored_before(run, config) or _score(run, dataset, name, config)
        rows.append(row)
        if progress:
            progress(name, row)
    _write_tables(out, rows, base, table, kind)
    return rows


ROW = "sweep_row.json"
"""A scored variant's row of the table, kept in its run folder with the model file it scored."""


def _score(run: Path, dataset: str | Path, name: str, config: TrainConfig) -> dict[str, Any]:
    """Evaluate a variant's run on the test split: its row of the table (also written to ``run/ROW``)."""
    minutes = sum(r["seconds"] for r in read_log(run)) / 60
    result = evaluate(run, dataset, "test", engines=[("torch", "float32")], checksums=False)
    timed = result["forward_time"].get("torch float32", {})  # none for a model that does not stream
    row = {
        "setting": name,
        "run": str(run),
        "smape_without_reset": result["smape"]["without_reset"]["smape_normalised"],
        "smape_with_reset": result["smape"].get("with_reset", {}).get("smape_normalised"),
        "training_minutes": minutes,
        "forward_ms": timed.get("median_ms"),
        "device": timed.get("device"),
        "config": config.to_dict(),
    }
    with atomic_output(run / ROW) as tmp:
        tmp.write_text(json.dumps({"model": _model_stamp(run), "row": row}, indent=1), encoding="utf-8")
    return row


def _scored_before(run: Path, config: TrainConfig) -> dict[str, Any] | None:
    """The row an earlier sweep scored for this very model file and configuration, or None (a
    resumed sweep does not evaluate its finished variants again)."""
    try:
        kept = json.loads((run / ROW).read_text(encoding="utf-8"))
        same = kept["model"] == _model_stamp(run) and kept["row"]["config"] == json.loads(json.dumps(config.to_dict()))
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return kept["row"] if same else None


def _model_stamp(run: Path) -> list[int]:
    """The model file's size and modification time (ns): a retrained model is scored again."""
    stat = (run / MODEL).stat()
    return [stat.st_size, stat.st_mtime_ns]


def _check_finished(run: Path, config: TrainConfig, manifest: dict[str, Any]) -> None:
    saved = read_config(run)
    own = TrainConfig.from_dict(saved["train"])  # settings added since the run was made take their defaults
    differ = [k for k, _, _ in config.differences(own)]
    if saved["dataset"]["build_key"] != manifest["build_key"]:
        differ.append("dataset")
    if differ:
        raise KinectDataError(
            f"{run}: holds a finished run whose {', '.join(differ)} differ from this sweep's; "
            "remove it or sweep into another folder"
        )


def _number(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


def _write_tables(out: Path, rows: list[dict[str, Any]], base: TrainConfig, table: Sweep, kind: ModelKind) -> None:
    """``results.md`` (the table, with the paper's figures where it has them) and ``results.json``."""
    shown = "".join(f", {getattr(base.settings, name)} {name.replace('_', ' ')}" for name in table.shown)
    device = next((r["device"] for r in rows if r["device"]), "")
    columns = ["SMAPE % without reset", *(["with reset"] if kind.resets else []), "training min", "forward ms/frame"]
    paper = ["paper: without", *(["with"] if kind.resets else []), "min", "ms"] if table.paper else []
    lines = [
        f"# {table.title} on this dataset ({base.epochs} epochs, batch {base.batch_size}{shown})",
        "",
        "SMAPE in % on the normalised targets of the test split, free-running from the first true pose. "
        "Training minutes are the epochs' time from each run's log; forward time is the streaming network at batch 1 "
        f"in torch, float32 ({device}). " + (f"Paper: their figures ({table.paper_note})." if table.paper else ""),
        "",
        "| setting | " + " | ".join(columns + paper) + " |",
        "| --- | " + " | ".join(["---:"] * len(columns + paper)) + " |",
    ]
    for r in rows:
        cells = [r["smape_without_reset"], *([r["smape_with_reset"]] if kind.resets else [])]
        cells += [r["training_minutes"], r["forward_ms"]]
        if table.paper:
            p = table.paper.get(r["setting"])
            figures = [None] * 4 if p is None else list(p)
            cells += [figures[0], *([figures[1]] if kind.resets else []), figures[2], figures[3]]
        lines.append(f"| {r['setting']} | " + " | ".join(_number(c) for c in cells) + " |")
    with atomic_output(out / "results.md") as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    with atomic_output(out / "results.json") as tmp:
        tmp.write_text(json.dumps(rows, indent=2) + "\n")
