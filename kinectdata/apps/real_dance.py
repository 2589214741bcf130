"""The quickstart on a real corpus (``kinectdata quickstart --corpus tang2018 PATH``): what a user
does with their first real dance corpus, with the settings that learn on one.

1. ``prepare``: the corpus's recipe writes ``recordings.yaml`` (its published split, the
   recordings it leaves out and why);
2. ``build-dataset``: the model's pipeline with the music's pulse stacked on its spectra
   (:data:`REAL_DANCE_BUILDS`; spectra alone do not let a model hear the beat of real songs,
   docs/training.md, "Learning real dance"), the corpus's generic target as the recipe says
   (root-centred for tang2018);
3. ``train-baseline`` with its defaults (the real-dance recipe) within a time budget;
4. ``evaluate`` on the **validation** dances: the test dances are left for the final figures
   (``python -m benchmarks.bench_learning --corpus ...``), never looked at while settings are tried;
5. ``generate``: motion for the first validation song.

The corpus is read where it is (``--allow-outside-paths``): nothing of it is copied.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from kinectdata.core.errors import ConfigError
from kinectdata.dataset.build import build_dataset
from kinectdata.dataset.config import BuildConfig
from kinectdata.dataset.pipelines import PIPELINES
from kinectdata.dataset.recipes import prepare_corpus
from kinectdata.dataset.recipes.manifest import CorpusManifest

REAL_DANCE_BUILDS: dict[str, dict[str, Any]] = {
    "yalta2016": {"features": "yalta2016_rhythm", "without_styles": "yalta2016_rhythm", "normalisation": None},
    "listen-to-dance": {
        "features": "listen_to_dance_rhythm_bars_style",
        "without_styles": "listen_to_dance_rhythm_bars",
        "normalisation": "maxabs",
    },
}
"""How a real corpus's dataset is built for each pipeline's model: the pipeline's features with the
music's pulse, the corpus's generic target normalised into -0.9..0.9 (the listen-to-dance
pipeline's per-video min-max is for 2-D OpenPose poses; ``maxabs`` keeps each coordinate's zero).
The cdhc model's pulse counts the levels in each song's own metre (beat, two beats, bar, two bars):
with its jitter term, over three cross-validation folds its periods then ranked with the songs'
tempi at 0.91 against 0.43 with bars of 3 and 4 beats. The pulse alone (``listen_to_dance_pulse``)
jittered less and scored a lower FID_k on the folds but listened (goal c's verdict) in none of four
fold runs where these features did in two (docs/notebook/2026-11-real-dance.md). It also hears the
song's dance style (``_style``: the training songs told their recipe's style, every other song heard
by the classifier the build fits on them): without it the model danced one dance for every style
(2 and 5 of 12 held-out dances in their song's style on folds 1 and 2), with it 10 and 7 of 12, as
varied as the real dancers (docs/notebook/2026-12-real-dance-variety.md); a corpus whose recipe does
not give every training recording a style is built with the ``without_styles`` features."""

REAL_QUICK_MINUTES = 25.0
"""The real-corpus quickstart's training budget, minutes: what docs/notebook/2026-11-real-dance.md's validation runs
of the defaults were given (one thread each)."""


def model_of(pipeline: str) -> str:
    """The model a pipeline trains (``yalta2016`` -> ``yalta``, ``listen-to-dance`` -> ``cdhc``)."""
    return PIPELINES[pipeline]["model"]


def pipeline_of(model: str) -> str:
    """The pipeline of :data:`REAL_DANCE_BUILDS` whose model is ``model``."""
    for pipeline in REAL_DANCE_BUILDS:
        if model_of(pipeline) == model:
            return pipeline
    known = ", ".join(map(model_of, REAL_DANCE_BUILDS))
    raise ConfigError(f"no real-corpus build for the model {model!r} (models: {known})")


def build_corpus_datasets(
    corpus: str,
    path: str | Path,
    out: str | Path,
    models: list[str],
    echo: Callable[[str], Any] = print,
) -> tuple[dict[str, Path], dict[str, dict[str, Any]]]:
    """The recordings manifest of a local corpus copy (``out/recordings.yaml``) and one dataset per
    model (``out/<model>_dataset``, :data:`REAL_DANCE_BUILDS`; a finished build is reused).

    Returns:
        ``({model: dataset folder}, {model: the dataset's manifest})``.
    """
    out = Path(out)
    manifest = prepare_corpus(corpus, path)
    listed = manifest.write(out / "recordings.yaml")
    counts = ", ".join(f"{n} {split}" for split, n in manifest.split_counts().items())
    echo(f"[prepare {corpus}] {path} -> {listed}: {len(manifest.recordings)} recordings ({counts}), "
         f"{len(manifest.skipped)} left out (the reasons are in the file)")  # fmt: skip
    folders, built = {}, {}
    for model in models:
        folders[model] = out / f"{model}_dataset"
        built[model] = build_model_dataset(listed, folders[model], model, manifest, echo)
    return folders, built


def build_model_dataset(
    listed: str | Path,
    folder: str | Path,
    model: str,
    manifest: CorpusManifest,
    echo: Callable[[str], Any] = print,
    features: str | None = None,
) -> dict[str, Any]:
    """Build the recordings manifest file ``listed`` (the corpus's, or one of its folds) into
    ``folder`` as ``model`` trains on the corpus (:data:`REAL_DANCE_BUILDS`, the recipe's target and
    build options; ``features``: a feature preset of its pipeline's instead of the recipe's, for a
    candidate tried on the folds); the dataset's manifest (a finished build is reused)."""
    pipeline = pipeline_of(model)
    how = REAL_DANCE_BUILDS[pipeline]
    told = all(r.style for r in manifest.recordings if r.split in (None, "train"))  # a training song is told its style
    features = features or (how["features"] if told else how["without_styles"])
    config = BuildConfig.from_pipeline(
        pipeline,
        features=features,
        target=manifest.target,
        normalisation=how["normalisation"],
        root_centre="--root-centre" in manifest.build_options,
    )
    echo(f"[build-dataset] {listed} -> {folder} (--pipeline {pipeline} --features {features}"
         f" --target {manifest.target}{' --root-centre' if config.root_centre else ''})")  # fmt: skip
    started = time.perf_counter()
    built = build_dataset(listed, folder, config, jobs=2, allow_outside_paths=True)
    rows = {s: built["splits"][s]["rows"] for s in built["splits"]}
    echo(f"  {rows} rows ({time.perf_counter() - started:.0f} s)")
    return built


def run_real_quickstart(
    corpus: str,
    path: str | Path,
    out_dir: str | Path,
    echo: Callable[[str], Any] = print,
    *,
    pipeline: str = "yalta2016",
    minutes: float = REAL_QUICK_MINUTES,
    **training: Any,
) -> dict[str, Any]:
    """The real-corpus quickstart into ``out_dir`` (module docstring): prepare, build, train the
    pipeline's model with ``train-baseline``'s defaults (``training`` overrides them, e.g.
    ``epochs=1`` in tests) within ``minutes``, evaluate on the validation split, generate.

    Returns:
        ``{"dataset", "rows", "run", "history", "evaluation", "generated_frames"}`` (the last four
        only when PyTorch is installed).

    Raises:
        KinectDataError: the corpus cannot be read or built (one line naming the file).
    """
    from kinectdata.apps.quickstart import train_evaluate_generate

    out = Path(out_dir)
    model = model_of(pipeline)
    folders, built = build_corpus_datasets(corpus, path, out, [model], echo)
    summary = {"dataset": str(folders[model]), "rows": built[model]["totals"]["rows"]}
    # only the budget: train-baseline's defaults keep their epochs (the cdhc model trained past them stood still)
    settings = {"max_minutes": minutes, **training}
    generated = "generated.csv"  # the corpus's own joint set: the canonical CSV holds any
    learned = train_evaluate_generate(
        out,
        built[model],
        pipeline,
        settings,
        generated,
        echo,
        dataset=folders[model],
        split="val",
        why_split="the validation dances: the test dances are kept for the acceptance run",
    )
    if learned:
        run = Path(learned["run"])
        echo(
            f"[done] recordings: {out / 'recordings.yaml'}\n       dataset: {folders[model]}\n       run: {run} "
            f"(loss.png, log.csv, model.pt)\n       evaluation: {run / 'evaluation'} (results.json, metrics.json, "
            f"figures)\n       generated motion: {run / generated}"
        )
    return summary | learned
