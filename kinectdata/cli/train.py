"""``train-baseline``, ``evaluate``, ``generate``, ``export`` and ``sweep``: the reference model's commands.

torch is imported inside the commands, so the rest of the command line works without it.
"""

from __future__ import annotations

import dataclasses

import click

from kinectdata.core.errors import KinectDataError


def _torch_or_fail() -> None:
    try:
        import torch  # noqa: F401
    except ImportError:
        raise KinectDataError(
            "these commands need PyTorch: pip install 'kinectdata[train]' (on a CPU-only machine install the CPU "
            "wheel first, e.g. pip install torch==2.13.0)"
        ) from None


def train_options(f):
    """The training settings. Options whose default depends on the model show it as
    "yalta / cdhc" (:data:`kinectdata.training.config.MODEL_DEFAULTS`)."""
    options = [
        click.option(
            "--model",
            default=None,
            type=click.Choice(["yalta", "cdhc"]),
            help="yalta: the DCNN + deep LSTM of Yalta et al. (2016); cdhc: the encoder-decoder of Lee et al. "
            "(2018). Default: the dataset's (cdhc for mel features, yalta for STFT).",
        ),
        click.option(
            "--units",
            default=None,
            type=click.IntRange(min=1),
            help="yalta: LSTM units per layer (the paper: 250, 500, 1000). [default: 500]",
        ),
        click.option(
            "--activation",
            default=None,
            type=click.Choice(["tanh", "relu", "elu"]),
            help="yalta: activation after each convolution and fc1. [default: elu]",
        ),
        click.option(
            "--feedback",
            default=None,
            type=click.Choice(["predicted", "teacher"]),
            help="yalta: previous pose fed to the decoder: the model's own output (the paper) or the true one. "
            "cdhc always trains with the true one (teacher forcing). [default: predicted]",
        ),
        click.option(
            "--channels",
            default=None,
            type=click.IntRange(min=1),
            help="cdhc: width of the audio and skeleton encoders. [default: 256]",
        ),
        click.option(
            "--decoder-channels",
            default=None,
            type=click.IntRange(min=1),
            help="cdhc: width of the fused code and the decoder. [default: 128]",
        ),
        click.option(
            "--dropout",
            default=None,
            type=click.FloatRange(0, 1, max_open=True),
            help="cdhc: dropout after each highway block. [default: 0.05]",
        ),
        click.option(
            "--limb-weight",
            default=None,
            type=click.FloatRange(min=0),
            help="cdhc: weight of the limb-length loss added to the L1 loss. [default: 1]",
        ),
        click.option(
            "--sequence",
            default=None,
            type=click.IntRange(min=1),
            help="Frames per training sequence (at 30 fps, 150 frames = 5 s). [default: 150 / 300]",
        ),
        click.option(
            "--stride",
            default=None,
            type=click.IntRange(min=1),
            help="Frames between training sequence starts. Default: --sequence (no overlap).",
        ),
        click.option(
            "--batch-size", default=None, type=click.IntRange(min=1), help="Sequences per batch. [default: 50 / 16]"
        ),
        click.option(
            "--epochs", default=None, type=click.IntRange(min=1), help="Passes over the data. [default: 10 / 20]"
        ),
        click.option(
            "--lr",
            default=None,
            type=click.FloatRange(min=0, min_open=True),
            help="Adam learning rate. [default: 1e-4 / 2e-4]",
        ),
        click.option(
            "--noise-eta",
            default=None,
            type=click.FloatRange(min=0),
            help="Gradient noise: variance eta / (1 + step)^gamma; 0 turns it off. [default: 0.01 / 0]",
        ),
        click.option(
            "--noise-gamma",
            default=None,
            type=click.FloatRange(min=0),
            help="Gradient noise annealing exponent. [default: 0.55]",
        ),
        click.option(
            "--clip-norm",
            default=None,
            type=click.FloatRange(min=0, min_open=True),
            help="Clip the gradient's global norm to this before the noise. [default: none / 1]",
        ),
        click.option(
            "--seed",
            default=None,
            type=click.IntRange(min=0),
            help="Seed of initialisation, batch order and noise. [default: 0]",
        ),
        click.option(
            "--device",
            default=None,
            type=click.Choice(["auto", "cpu", "cuda"]),
            help="auto: CUDA when present, else CPU. [default: auto]",
        ),
    ]
    for option in reversed(options):
        f = option(f)
    return f


def make_train_config(model: str | None, data: str | None = None, **settings):
    """The TrainConfig of the typed settings over the model's defaults; the model defaults to the
    dataset's (read from ``data``'s manifest)."""
    from kinectdata.models.registry import model_for_features
    from kinectdata.models.run import read_manifest
    from kinectdata.training.config import TrainConfig

    if model is None:
        model = "yalta" if data is None else model_for_features(read_manifest(data)["config"]["features"])
    return TrainConfig.for_model(model, **settings)


def _row(row: dict) -> str:
    val = "-" if row["val_loss"] is None else f"{row['val_loss']:.5f}"
    smape = "-" if row["val_smape"] is None else f"{row['val_smape']:.2f} %"
    return (
        f"epoch {row['epoch']:>3}: train loss {row['train_loss']:.5f}, validation loss {val}, "
        f"validation SMAPE {smape} ({row['seconds']:.1f} s, {row['frames_per_second']:.0f} frames/s)"
    )


@click.command("train-baseline")
@click.option("--data", required=True, type=click.Path(exists=True, file_okay=False), help="Dataset folder.")
@click.option("--out", required=True, type=click.Path(file_okay=False), help="Run folder to write.")
@click.option("--resume", is_flag=True, help="Continue the run in --out from its last checkpoint, exactly.")
@train_options
def train_baseline(data, out, resume, **options) -> None:
    """Train a bundled model on a dataset: the DCNN + deep LSTM of Yalta et al. (2016) (the paper's
    settings by default: Adam 1e-4, MSE, sequences of 150, batches of 50, 10 epochs, annealed
    gradient noise) or the CDHC encoder-decoder of Lee et al. (2018) (teacher forcing, L1 +
    limb-length loss; Adam 2e-4, sequences of 300, batches of 16, 20 epochs).

    Writes into --out: config.json, checkpoint.pt (each epoch, atomically), log.csv, loss.png,
    and at the end model.pt (and for yalta stream.ts, TorchScript of the streaming network). With
    --resume the run's own settings are used; --epochs (to train longer) and --device may be given."""
    _torch_or_fail()
    from kinectdata.training.train import train

    if resume:  # the run's settings, with what was typed on the command line checked against them
        from kinectdata.models.run import read_config
        from kinectdata.training.config import TrainConfig

        typed = {k: v for k, v in options.items() if v is not None}
        config = dataclasses.replace(TrainConfig(**read_config(out)["train"]), **typed)
    else:
        config = make_train_config(data=data, **options)
    history = train(data, out, config, resume=resume, progress=lambda r: click.echo(_row(r)))
    from kinectdata.training.distributed import World

    if World.from_environment().main:  # under torchrun, one line from rank 0
        files = "log.csv, loss.png, model.pt" + (", stream.ts" if config.model == "yalta" else "")
        click.echo(f"run: {out} ({len(history)} epochs; {files})")


@click.command("evaluate")
@click.option("--run", "run_dir", required=True, type=click.Path(exists=True, file_okay=False), help="Run folder.")
@click.option("--data", required=True, type=click.Path(exists=True, file_okay=False), help="Dataset folder.")
@click.option("--split", default="test", show_default=True, type=click.Choice(["train", "val", "test"]))
@click.option("--out", default=None, type=click.Path(file_okay=False), help="Default: RUN/evaluation.")
@click.option(
    "--silence",
    default=5.0,
    show_default=True,
    type=click.FloatRange(min=2),
    help="Seconds of silence inserted for the silence test (the first second lets the motion settle).",
)
def evaluate_command(run_dir, data, split, out, silence) -> None:
    """Score a run as the paper does: SMAPE (%) free-running without and with reset, on normalised
    and denormalised values; per-frame forward time; generated-against-real plots; the silence test."""
    _torch_or_fail()
    from kinectdata.evaluation.evaluate import evaluate, format_results

    results = evaluate(run_dir, data, split, out=out, silence_seconds=silence)
    click.echo(format_results(results))


@click.command("generate")
@click.option("--run", "run_dir", required=True, type=click.Path(exists=True, file_okay=False), help="Run folder.")
@click.argument("audio", type=click.Path(dir_okay=False))
@click.option(
    "-o",
    "--out",
    required=True,
    type=click.Path(dir_okay=False),
    help="File to write: canonical CSV (yalta), OpenPose JSON Lines (cdhc, e.g. dance.jsonl).",
)
@click.option(
    "--engine",
    default="torch",
    show_default=True,
    type=click.Choice(["torch", "onnxruntime"]),
    help="What runs the network: torch, or ONNX Runtime (fastest on CPUs; pip install 'kinectdata[export]').",
)
@click.option(
    "--precision",
    default="float32",
    show_default=True,
    type=click.Choice(["float32", "float16"]),
    help="Weights of the torch engine (float16: half the memory traffic, faster on CPUs).",
)
def generate_command(run_dir, audio, out, engine, precision) -> None:
    """Generate dance motion for AUDIO (any file libsndfile reads), streaming frame by frame, and
    write it: a yalta run's (metres, unit quaternions) as the canonical CSV that align reads, a cdhc
    run's (x, y in 0..1, y down) as OpenPose JSON Lines that the openpose reader reads."""
    _torch_or_fail()
    from kinectdata.inference.generate import generate

    motion, timing = generate(run_dir, audio, out, engine=engine, precision=precision)
    click.echo(
        f"wrote {out}: {timing['frames']} frames ({motion.duration:.2f} s) in {timing['seconds']:.2f} s "
        f"({timing['x_real_time']:.0f}x real time; network step {timing['step_median_ms']:.3f} ms median)"
    )
    if motion.joint_set.dimensions == 2:
        fps = 1 / float(motion.times[1] - motion.times[0]) if motion.n_frames > 1 else 30.0
        click.echo(f"  (OpenPose JSON Lines hold no frame rate: read or render it with --video-fps {fps:g})")


@click.command("export")
@click.option("--run", "run_dir", required=True, type=click.Path(exists=True, file_okay=False), help="Run folder.")
@click.option("-o", "--out", required=True, type=click.Path(dir_okay=False), help="File to write (.onnx or .ts).")
@click.option(
    "--format",
    "fmt",
    default=None,
    type=click.Choice(["torchscript", "onnx"]),
    help="Default: from the suffix (.onnx: ONNX, else TorchScript).",
)
@click.option(
    "--precision",
    default="float32",
    show_default=True,
    type=click.Choice(["float32", "float16"]),
    help="Weights of the TorchScript network (ONNX is float32).",
)
def export_command(run_dir, out, fmt, precision) -> None:
    """Write a run's streaming network (one frame per call, state passed in and out) as a
    self-describing TorchScript or ONNX file for a robot: the metadata inside gives frame and
    sample rate, feature settings, target components, normalisation and the start pose.
    ONNX needs pip install 'kinectdata[export]'."""
    _torch_or_fail()
    from kinectdata.inference.export import export_run

    path = export_run(run_dir, out, fmt, precision)
    click.echo(f"wrote {path}")


@click.command("sweep")
@click.option("--data", required=True, type=click.Path(exists=True, file_okay=False), help="Dataset folder.")
@click.option("--out", required=True, type=click.Path(file_okay=False), help="Folder for the runs and results.md.")
@click.option("--only", default=None, help="Comma-separated variants (default: all of Tables 3-5).")
@train_options
def sweep_command(data, out, only, **options) -> None:
    """Train and evaluate the variants of the paper's Tables 3-5 (TanH/ReLU/ELU, 250/1000 units,
    50/100 steps) and write OUT/results.md with the paper's columns beside its figures."""
    _torch_or_fail()
    from kinectdata.models.registry import model_for_features
    from kinectdata.models.run import read_manifest
    from kinectdata.training.sweep import sweep

    dataset_model = model_for_features(read_manifest(data)["config"]["features"])
    if options["model"] not in (None, "yalta") or dataset_model != "yalta":
        raise click.UsageError(
            "sweep reproduces the tables of Yalta et al. (2016): it trains the yalta model only, on an STFT "
            f"dataset{'' if dataset_model == 'yalta' else f' ({data} is a {dataset_model} dataset)'}"
        )
    variants = None if only is None else [v.strip() for v in only.split(",")]
    rows = sweep(
        data,
        out,
        make_train_config(**options),
        variants,
        progress=lambda name, r: click.echo(
            f"{name}: SMAPE {r['smape_without_reset']:.2f} % / {r['smape_with_reset']:.2f} %"
        ),
    )
    click.echo(f"wrote {out}/results.md ({len(rows)} variants)")


COMMANDS = [train_baseline, evaluate_command, generate_command, export_command, sweep_command]
