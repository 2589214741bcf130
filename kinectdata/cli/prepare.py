"""``kinectdata prepare``: a local copy of a dance corpus -> a recordings manifest (a recipe)."""

from __future__ import annotations

from collections import Counter

import click

from kinectdata.cli.options import OffsetType
from kinectdata.dataset.folds import GROUPINGS, write_folds
from kinectdata.dataset.recipes import RECIPES, prepare_corpus

_SHOWN_SKIPPED = 5


@click.command("prepare")
@click.argument("corpus", type=click.Choice(sorted(RECIPES)))
@click.argument("path", type=click.Path(file_okay=False, path_type=str))
@click.option(
    "-o",
    "--out",
    required=True,
    type=click.Path(dir_okay=False),
    help="the recordings manifest to write (.yaml, .json)",
)
@click.option("--music", default=None, help="aistpp: the AIST Dance DB music folder (default: found beside PATH)")
@click.option(
    "--keypoints",
    type=click.Choice(["keypoints3d", "keypoints3d_optim"]),
    default=None,
    help="aistpp: which keypoints to read (default keypoints3d)",
)
@click.option("--split-set", default=None, help="aistpp: the published split (default crossmodal)")
@click.option("--include-unsplit", is_flag=True, default=None, help="aistpp: keep sequences in no split list")
@click.option(
    "--rest-joints", default=None, help="finedance: its smplx_neu_J_1.npy (default: found in PATH or its parent)"
)
@click.option(
    "--split",
    default=None,
    type=click.Choice(["cross_genre", "cross_dancer", "kinectdata", "none"]),
    help="finedance: cross_genre or cross_dancer; tang2018: kinectdata's acceptance split (default) or none (drawn)",
)
@click.option(
    "--labelled-songs",
    is_flag=True,
    default=None,
    help="tang2018: list the folders with a song but no dance as labelled music that teaches the style hearing "
    "(left out by default: on the folds they cost it a held-out song)",
)
@click.option(
    "--unit", type=click.Choice(["cm", "m", "mm", "in"]), default=None, help="bvh-folder: the files' unit (cm)"
)
@click.option(
    "--offset",
    default=None,
    type=OffsetType(),
    help="bvh-folder: seconds (audio = motion + offset) or auto (default 0)",
)
def prepare(corpus, path, out, **options) -> None:
    """Write a recordings manifest for CORPUS (its recipe) read from the local copy at PATH: every
    recording with its music, published split and reading options. Nothing is downloaded or copied;
    build a dataset from the manifest with build-dataset."""
    given = {k: v for k, v in options.items() if v is not None}
    manifest = prepare_corpus(corpus, path, **given)
    manifest.write(out)
    counts = ", ".join(f"{n} {split}" for split, n in manifest.split_counts().items())
    click.echo(f"wrote {out}: {len(manifest.recordings)} recordings of {corpus} ({counts}) under {manifest.root}")
    if manifest.skipped:
        click.echo(f"left out {len(manifest.skipped)}:")
        for name, why in manifest.skipped[:_SHOWN_SKIPPED]:
            click.echo(f"  {name}: {why}")
        if len(manifest.skipped) > _SHOWN_SKIPPED:
            click.echo(f"  ... and {len(manifest.skipped) - _SHOWN_SKIPPED} more")
    if manifest.songs:
        styles = Counter(s.style for s in manifest.songs)
        counted = ", ".join(f"{n} {s}" for s, n in sorted(styles.items()))
        click.echo(
            f"listed {len(manifest.songs)} songs without a dance as labelled music ({counted}): "
            "features that hear the style learn from them"
        )
    flag = " --allow-outside-paths" if manifest.root_outside(out) else ""
    extra = "".join(f" {o}" for o in manifest.build_options)
    click.echo(
        f"next: kinectdata build-dataset {out} -o DATASET --target {manifest.target}{extra} "
        f"--features yalta2016_rhythm{flag}"
    )
    click.echo(
        "  (for the cdhc model: --pipeline listen-to-dance --features listen_to_dance_rhythm_bars "
        "--normalisation maxabs; then kinectdata train-baseline --data DATASET --out RUN)"
    )


@click.command("folds")
@click.argument("manifest", type=click.Path(dir_okay=False, path_type=str))
@click.option("-k", "--count", type=click.IntRange(min=2), default=3, show_default=True, help="how many folds")
@click.option(
    "--by",
    type=click.Choice(GROUPINGS),
    default="style",
    show_default=True,
    help="give every fold its share of each style (or metre) of the manifest",
)
@click.option("--seed", type=int, default=0, show_default=True, help="the order recordings are dealt in")
def folds(manifest, count, by, seed) -> None:
    """Write K cross-validation manifests beside MANIFEST (NAME.fold1ofK.yaml ...), to choose a
    training recipe on a small corpus: fold i validates on its share of the recordings and trains on
    the rest; the test split's recordings are in no fold. Build, train and evaluate --split val on
    each, and compare recipes over all the folds' validation recordings."""
    made = write_folds(manifest, count, by=by, seed=seed)
    for fold in made:
        click.echo(
            f"wrote {fold.path}: validates on {len(fold.validation)} ({', '.join(fold.validation)}), "
            f"trains on {len(fold.training)}"
        )
    click.echo(
        f"next: build each fold with the options you build {manifest} with (kinectdata build-dataset "
        f"{made[0].path} -o DATASET_1 ...), train each recipe on every fold, and compare their evaluate --split val"
    )


COMMANDS = [prepare, folds]
