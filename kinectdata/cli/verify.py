"""``kinectdata verify``: a dataset folder checked against its manifest's checksums and the layout."""

from __future__ import annotations

import click

from kinectdata.dataset.verify import read_manifest, verify_dataset


@click.command("verify")
@click.argument("dataset", type=click.Path(path_type=str))
def verify(dataset: str) -> None:
    """Check a DATASET folder: manifest.json against its schema, every shard against the manifest's
    SHA-256 and size and the shard layout, and the manifest's accounts of splits, recordings and rows.

    Lists every problem found, one per line naming its file, and exits with status 1 if there is any,
    0 when the dataset is intact."""
    problems = verify_dataset(dataset)
    for problem in problems:
        click.echo(str(problem))
    if problems:
        raise click.ClickException(f"{dataset}: {len(problems)} problem{'s' * (len(problems) > 1)} found")
    totals = read_manifest(dataset)["totals"]
    click.echo(
        f"{dataset}: intact, {totals['shards']} shards ({totals['rows']} rows, {totals['recordings']} recordings) "
        "match manifest.json"
    )


COMMANDS = [verify]
