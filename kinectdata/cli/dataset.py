"""``kinectdata build-dataset`` and ``kinectdata inspect``."""

from __future__ import annotations

import click

from kinectdata.cli.options import FloatList, default_of
from kinectdata.cli.progress import progress_bar
from kinectdata.core.errors import ConfigError
from kinectdata.dataset.build import build_dataset
from kinectdata.dataset.config import DEFAULT_PIPELINE, TEMPO_PITCHES, BuildConfig
from kinectdata.dataset.executors import EXECUTORS, make_executor
from kinectdata.dataset.inspect import inspect as inspect_report
from kinectdata.dataset.pipelines import PIPELINES
from kinectdata.features import PRESETS, StftConfig
from kinectdata.targets.normalization import METHODS
from kinectdata.targets.specs import shipped_target_specs


@click.command("build-dataset")
@click.argument("source", type=click.Path(exists=True, path_type=str))
@click.option(
    "-o",
    "--out",
    required=True,
    type=click.Path(file_okay=False, path_type=str),
    help="Dataset folder to write (shards + manifest.json). An interrupted build there is resumed.",
)
@click.option(
    "--pipeline",
    default=DEFAULT_PIPELINE,
    show_default=True,
    type=click.Choice(sorted(PIPELINES)),
    help="yalta2016: STFT inputs, yalta65 targets, maxabs (the DCNN + LSTM model). listen-to-dance: "
    "log-mel inputs, listen_to_dance targets (OpenPose 2-D + limb lengths), no normalisation (the CDHC "
    "model). --features, --target and --normalisation override its choices.",
)
@click.option(
    "--target",
    default=None,
    metavar="NAME|FILE",
    help=f"Target spec: which joints' positions, quaternions and limb lengths form the target vector. "
    f"Shipped: {', '.join(shipped_target_specs())}; a spec file; or 'positions' (every joint's position) or "
    "'full' (and every orientation) of whatever joint set the recordings use. Default: the pipeline's.",
)
@click.option(
    "--features",
    "preset",
    default=None,
    type=click.Choice(sorted(PRESETS)),
    help="Audio feature preset: yalta2016 (per-frame 0.1..0.9 power spectrum), motion_dance "
    "(dB mapped from -120..5 dB to -0.9..0.9) or listen_to_dance (80-band log-mel in 0..1); each with _rhythm: "
    "and the music's pulse, computed causally (yalta2016_rhythm [2, 129, 5]: 43 tempi; listen_to_dance_rhythm "
    "[153]: the saliences of 65 tempi and the beat's and bar's phase; listen_to_dance_rhythm_bars: the bar in each "
    "song's metre, from the recordings manifest's beats_per_bar or estimated; listen_to_dance_rhythm_counted: "
    "those levels counted from the beat, clocks that turn once a bar whatever the downbeats sound like; "
    "listen_to_dance_pulse [73]: that pulse alone, without the log-mel bands; listen_to_dance_clocks [6]: the "
    "clocks of listen_to_dance_rhythm_bars alone, at the beat, bar and two bars). "
    "Default: the pipeline's.",
)
@click.option(
    "--power",
    default=None,
    type=click.Choice(["log", "linear"]),
    help="Override the preset's power scale (yalta2016 default: log, i.e. dB).",
)
@click.option(
    "--normalisation",
    default=None,
    type=click.Choice(list(METHODS)),
    help="Target normalisation, fitted on the training split: maxabs (0.9 / max|x| per component, Yalta "
    "et al.) or minmax into -0.9..0.9, or none (targets already in 0..1). Default: the pipeline's.",
)
@click.option(
    "--root-centre",
    is_flag=True,
    help="Positions relative to the root joint per frame (the root itself relative to its first second).",
)
@click.option(
    "--split-ratios",
    default=",".join(f"{v:g}" for v in default_of(BuildConfig, "split_ratios")),
    show_default=True,
    type=FloatList(3),
    help="train,val,test shares for recordings without an explicit split (drawn by recording).",
)
@click.option(
    "--seed",
    default=default_of(BuildConfig, "seed"),
    show_default=True,
    type=click.IntRange(min=0),
    help="Seed for the drawn splits and the augmentation noise.",
)
@click.option(
    "--augment-snr",
    default="",
    type=FloatList(),
    metavar="DB,DB",
    help="Add a copy of each training recording with white noise at each SNR (dB), e.g. 5,10.",
)
@click.option(
    "--augment-tempo",
    default="",
    type=FloatList(),
    metavar="R,R",
    help="Add a copy of each training recording played R times as fast, song and dance (tempo and pitch, "
    "as a turntable; --tempo-pitch kept: the same notes faster), e.g. 0.9,1.1.",
)
@click.option(
    "--tempo-pitch",
    type=click.Choice(TEMPO_PITCHES),
    default=default_of(BuildConfig, "tempo_pitch"),
    show_default=True,
    help="How --augment-tempo plays a song faster: as a turntable (the pitch moves with the tempo) or with "
    "its pitch kept (SoX's tempo effect, else librosa's phase vocoder).",
)
@click.option(
    "--clean",
    is_flag=True,
    help="Clean every skeleton before it is aligned, with kinectdata clean's default stages (sides, gaps, "
    "a 6 Hz zero-phase filter, bone lengths); a manifest entry's own 'clean' wins.",
)
@click.option(
    "--shard-size",
    default=default_of(BuildConfig, "shard_size_mb"),
    show_default=True,
    type=click.FloatRange(min=0, min_open=True),
    help="Shard size limit in MB (uncompressed); a recording is never split across shards.",
)
@click.option(
    "--compression",
    default="none",
    show_default=True,
    type=click.Choice(["none", "gzip", "lzf"]),
    help="HDF5 compression of the shard datasets.",
)
@click.option(
    "--fps",
    default=default_of(BuildConfig, "fps"),
    show_default=True,
    type=click.FloatRange(min=0, min_open=True),
    help="Motion frames per second.",
)
@click.option(
    "--sample-rate",
    default=default_of(BuildConfig, "sample_rate"),
    show_default=True,
    type=click.IntRange(min=8000),
    help="Audio sample rate in Hz for the features.",
)
@click.option(
    "--max-gap",
    default=default_of(BuildConfig, "max_gap"),
    show_default=True,
    type=click.FloatRange(min=0),
    help="Longest tracking gap (seconds) filled by interpolation when aligning.",
)
@click.option(
    "--min-coverage",
    default=default_of(BuildConfig, "min_coverage"),
    show_default=True,
    type=click.FloatRange(0, 1),
    help="Least share (0..1) of a recording's motion its audio must cover.",
)
@click.option(
    "--jobs",
    default=1,
    show_default=True,
    type=click.IntRange(min=1),
    help="Recordings prepared in parallel (processes; --executor local).",
)
@click.option(
    "--executor",
    default="local",
    show_default=True,
    type=click.Choice(list(EXECUTORS)),
    help="Where recordings are prepared: local (this machine, --jobs processes) or dask (one task per recording "
    "on a running Dask cluster, at --scheduler; pip install 'kinectdata[dask]'). Dask workers must see the "
    "recordings and --out at the same paths (a shared filesystem). The output is the same bytes either way.",
)
@click.option(
    "--scheduler",
    default=None,
    metavar="ADDRESS",
    help="--executor dask: the Dask scheduler's address, e.g. tcp://10.0.0.5:8786.",
)
@click.option(
    "--video-fps",
    default=None,
    type=click.FloatRange(min=0, min_open=True),
    help="OpenPose recordings: the videos' frame rate, for recordings that do not give their own.",
)
@click.option("--keep-work", is_flag=True, help="Keep the per-recording work files (.work/) after success.")
@click.option(
    "--allow-outside-paths",
    is_flag=True,
    help="Let a recordings manifest name files outside its own folder (absolute paths, .., symbolic links "
    "leading out); refused by default.",
)
def build_dataset_command(
    source,
    out,
    pipeline,
    target,
    preset,
    power,
    normalisation,
    root_centre,
    split_ratios,
    seed,
    augment_snr,
    augment_tempo,
    tempo_pitch,
    clean,
    shard_size,
    compression,
    fps,
    sample_rate,
    max_gap,
    min_coverage,
    jobs,
    executor,
    scheduler,
    video_fps,
    keep_work,
    allow_outside_paths,
) -> None:
    """Build a training dataset from SOURCE: a recordings manifest (JSON, YAML or CSV with columns
    recording, audio, split, offset, format, schema, body, person, video_fps, name, clean) or a folder of
    aligned .h5 files or of sessions (a skeleton file or OpenPose folder + audio of the same name).

    Each motion frame gets an audio input (1x129x5 STFT, or 80 log-mel bands) and a normalised pose
    target; shards (HDF5) and a manifest.json are written atomically, deterministically, and resumably.
    """
    runner = make_executor(executor, jobs=jobs, scheduler=scheduler)
    features = None
    if power is not None:
        features = PRESETS[preset or PIPELINES[pipeline]["features"]]
        if not isinstance(features, StftConfig):
            raise click.BadParameter(f"applies to STFT features, not {features.extractor}", param_hint="--power")
        try:
            features = StftConfig.from_dict({**features.to_dict(), "power": power})
        except ConfigError as exc:
            raise click.BadParameter(f"not with these features: {exc}", param_hint="--power") from None
    config = BuildConfig.from_pipeline(
        pipeline,
        features=features or preset,
        target=target,
        normalisation=normalisation,
        fps=fps,
        sample_rate=sample_rate,
        root_centre=root_centre,
        split_ratios=split_ratios,
        seed=seed,
        augment_snr=augment_snr,
        augment_tempo=augment_tempo,
        tempo_pitch=tempo_pitch,
        clean={} if clean else None,
        shard_size_mb=shard_size,
        compression=None if compression == "none" else compression,
        max_gap=max_gap,
        min_coverage=min_coverage,
    )
    with progress_bar("preparing", "recording") as progress:
        manifest = build_dataset(
            source,
            out,
            config,
            executor=runner,
            progress=progress,
            keep_work=keep_work,
            video_fps=video_fps,
            allow_outside_paths=allow_outside_paths,
        )
    t = manifest["totals"]
    click.echo(f"wrote {out}: {t['rows']} rows from {t['recordings']} recordings in {t['shards']} shards")
    for split, info in manifest["splits"].items():
        click.echo(f"  {split:<5} {len(info['recordings'])} recordings, {info['rows']} rows")


@click.command("inspect")
@click.argument("path", type=click.Path(exists=True, path_type=str))
@click.option(
    "--components", default="12", show_default=True, help="How many target components to list per split, or 'all'."
)
def inspect_command(path, components) -> None:
    """Show what a dataset folder or shard holds: layout (validated), counts, value ranges, statistics."""
    if components != "all" and not components.isdigit():
        raise click.BadParameter(f"{components!r} is neither a number nor 'all'", param_hint="--components")
    limit = None if components == "all" else int(components)
    if _is_aligned(path):  # an aligned recording, not a shard: what info shows of it
        from kinectdata.align.aligned import AlignedRecording
        from kinectdata.cli.info import aligned_lines

        click.echo(aligned_lines(path, AlignedRecording.load(path)))
        return
    click.echo(inspect_report(path, components=limit))


def _is_aligned(path: str) -> bool:
    import h5py

    try:
        with h5py.File(path, "r") as f:
            return f.attrs.get("format") == "kinectdata.aligned"
    except OSError:
        return False


COMMANDS = [build_dataset_command, inspect_command]
