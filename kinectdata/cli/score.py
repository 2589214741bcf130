"""``kinectdata score``: the field's metrics (FID, diversity, Beat Align Score, PFC) of two sets of dance;
``kinectdata smpl24``: a recording as the field's SMPL-24 joint array."""

from __future__ import annotations

import click

from kinectdata.cli.options import reader_options
from kinectdata.cli.progress import progress_bar
from kinectdata.evaluation.field_scores import score_sets, write_metrics_json
from kinectdata.evaluation.motion_sets import DanceReading, load_dance_set
from kinectdata.evaluation.protocols import PROTOCOLS, get_protocol
from kinectdata.formats import read_motion


@click.command("score")
@click.argument("generated", type=click.Path(path_type=str))
@click.argument("reference", type=click.Path(path_type=str))
@click.option(
    "--protocol",
    type=click.Choice(list(PROTOCOLS)),
    default="bailando",
    show_default=True,
    help="whose table to reproduce: aist (mint / AI Choreographer), bailando, edge",
)
@click.option("-o", "--out", default="metrics.json", show_default=True, help="where to write the record")
@click.option("--music", default=None, help="folder with each file's music by stem (for the Beat Align Score)")
@click.option("--beats", default=None, help='JSON {"<file stem>": [beat times, s]}: music beats known already')
@click.option("--fps", "array_fps", type=float, default=60.0, show_default=True, help="frame rate of .npy/.npz arrays")
@click.option("--up", "array_up", type=click.Choice(["y", "z"]), default="y", show_default=True,
              help="vertical axis of .npy/.npz arrays (EDGE saves z up)")  # fmt: skip
@click.option("--mapping", default=None, help="joint-mapping file to SMPL-24 for a joint set without a shipped one")
@click.option("--allow-pickle", is_flag=True, help="read .pkl files and .npy files holding dicts (runs their code)")
@click.option("--bootstrap", type=int, default=1000, show_default=True, help="resamples for the 95 %% intervals")
@click.option("--seed", type=int, default=0, show_default=True)
def score(
    generated, reference, protocol, out, music, beats, array_fps, array_up, mapping, allow_pickle, bootstrap, seed
):
    """Score GENERATED dance against REFERENCE dance (each a folder of files, or one file) with the
    field's metrics: FID_k, FID_g, Div_k, Div_g, Beat Align Score, PFC, bone-length variation and
    jerk, each with a bootstrap interval, and write metrics.json recording the protocol."""
    chosen = get_protocol(protocol)
    reading = DanceReading(array_fps, array_up, mapping, music, allow_pickle)
    with progress_bar("reading generated", "file") as progress:
        gen = load_dance_set(generated, chosen, reading, beats=beats, progress=progress)
    with progress_bar("reading reference", "file") as progress:
        ref = load_dance_set(reference, chosen, reading, beats=beats, progress=progress)
    scores = score_sets(gen, ref, chosen, bootstrap=bootstrap, seed=seed)
    path = write_metrics_json(scores, out)
    click.echo(scores.table())
    click.echo(f"wrote {path}")


@click.command("smpl24")
@click.argument("recording", type=click.Path(path_type=str))
@click.option("-o", "--out", required=True, type=click.Path(dir_okay=False), help="the .npy file to write")
@click.option("--fps", type=float, default=60.0, show_default=True, help="frame rate of the array (AIST++: 60)")
@click.option("--mapping", default=None, help="joint-mapping file to SMPL-24 for a joint set without a mapping")
@reader_options
def smpl24(recording, out, fps, mapping, reading) -> None:
    """Write RECORDING (any 3-D recording kinectdata reads, or an aligned .h5) as the field's joint
    array: [T, 24, 3] float32 SMPL-24 joints in metres, y up, at --fps, for the peers' tools and for
    `score` (which reads it back with --fps and --up y)."""
    from kinectdata.evaluation.motion_sets import save_smpl24, smpl24_joints

    if recording.lower().endswith((".h5", ".hdf5")):
        from kinectdata.align.aligned import AlignedRecording

        motion = AlignedRecording.load(recording, audio=False).motion
    else:
        motion = read_motion(recording, **reading)
    sequence = smpl24_joints(motion, fps, source=recording, mapping=mapping)
    save_smpl24(sequence, out)
    frames = sequence.positions.shape[0]
    click.echo(f"wrote {out}: {frames} frames of SMPL-24 joints at {fps:g} fps ({frames / fps:.2f} s)")
    for joint, note in ((sequence.mapping or {}).get("stand_ins") or {}).items():
        click.echo(f"  {joint}: {note}")


COMMANDS = [score, smpl24]
