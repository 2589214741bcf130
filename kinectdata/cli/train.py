"""``train-baseline``, ``evaluate``, ``generate``, ``export`` and ``sweep``: the reference model's commands.

torch is imported inside the commands, so the rest of the command line works without it.
"""

from __future__ import annotations

import dataclasses
import functools

import click

from kinectdata.core.errors import KinectDataError
from kinectdata.dataset.layout import BALANCE_FIELDS


def _torch_or_fail() -> None:
    try:
        import torch  # noqa: F401
    except ImportError:
        raise KinectDataError(
            "these commands need PyTorch: pip install 'kinectdata[train]' (on a CPU-only machine install the CPU "
            "wheel first, e.g. pip install torch==2.13.0)"
        ) from None


_LOOP_OPTIONS = (
    ("sequence", click.IntRange(min=1), "Frames per training sequence (at 30 fps, 150 frames = 5 s)."),
    ("stride", click.IntRange(min=1), "Frames between training sequence starts. Default: --sequence (no overlap)."),
    ("batch_size", click.IntRange(min=1), "Sequences per batch."),
    ("epochs", click.IntRange(min=1), "Passes over the data."),
    ("lr", click.FloatRange(min=0, min_open=True), "Adam learning rate."),
    ("noise_eta", click.FloatRange(min=0), "Gradient noise: variance eta / (1 + step)^gamma; 0 turns it off."),
    ("noise_gamma", click.FloatRange(min=0), "Gradient noise annealing exponent."),
    ("clip_norm", click.FloatRange(min=0, min_open=True), "Clip the gradient's global norm to this before the noise."),
    ("seed", click.IntRange(min=0), "Seed of initialisation, batch order and noise."),
    ("device", click.Choice(["auto", "cpu", "cuda"]), "auto: CUDA when present, else CPU."),
    (
        "previous_noise",
        click.FloatRange(min=0),
        "Noise (standard deviation, normalised units) on the true previous poses fed in training; 0: none.",
    ),
    (
        "max_minutes",
        click.FloatRange(min=0, min_open=True),
        "Time budget: when it runs out, the epoch ends there and the run finishes with a usable model.",
    ),
    (
        "free_weight",
        click.FloatRange(min=0),
        "Weight of the free-running rhythm loss: the model also runs on its own through each window and the "
        "spectra of its motion's changes are matched to the real motion's (how much and how often it moves); 0: none.",
    ),
    (
        "posture_weight",
        click.FloatRange(min=0),
        "Weight of the postures in the free-running loss: each coordinate's mean and spread over the window against "
        "the real motion's.",
    ),
    (
        "jitter_weight",
        click.FloatRange(min=0),
        "Weight of the jitter term in the free-running loss: the motion's accelerations and jerks against the real "
        "motion's, more costing in proportion and less only in log ratio; 0: none.",
    ),
    (
        "periodogram_weight",
        click.FloatRange(min=0),
        "Weight of the whole-window periodogram in the free-running loss: where the motion's periods lie against "
        "the real motion's, finer than the multi-resolution spectra tell (a waltz's bar from a cha-cha's); 0: none.",
    ),
    (
        "low_energy_weight",
        click.FloatRange(min=0),
        "Weight of the slow motion's speed in the free-running loss: the motion below about 1.5 Hz against the real "
        "motion's, per 2 s (large, slow moves: a sway, a step); 0: none.",
    ),
    (
        "bone_jitter_weight",
        click.FloatRange(min=0),
        "Weight of the bones' jitter in the free-running loss: how fast each bone's length changes from frame to "
        "frame against the real motion's, more costing in proportion; 0: none.",
    ),
    (
        "span_weight",
        click.FloatRange(min=0),
        "Weight of the joints' bends in the free-running loss: the mean and spread of each two-bone chain's span "
        "(hip to ankle, shoulder to wrist) against the real motion's, in proportion; 0: none.",
    ),
    (
        "bend_weight",
        click.FloatRange(min=0),
        "Weight of the joints' angles in the free-running loss: the mean and spread of the angle at each "
        "two-bone chain's middle joint (the knee, the elbow) against the real motion's, in radians; 0: none.",
    ),
    (
        "repetition_weight",
        click.FloatRange(min=0),
        "Weight of how the motion repeats in the free-running loss: the autocorrelation of the joints' heights at "
        "lags of 0.2-4.5 s against the real motion's, whatever the phase (at one bar or at two); 0: none.",
    ),
    (
        "world_excess_weight",
        click.FloatRange(min=0),
        "Weight of the joints' excess speed in the world in the free-running loss: each joint's speed along each "
        "axis per 2 s against the real motion's, faster costing in proportion (a foot bouncing up and down); "
        "0: none.",
    ),
    (
        "world_jitter_weight",
        click.FloatRange(min=0),
        "Weight of the joints' excess acceleration in the world in the free-running loss: each joint's mean "
        "squared acceleration and jerk along each axis per 2 s against the real motion's, more costing in "
        "proportion (a trunk swaying faster than the dancers'); 0: none.",
    ),
    (
        "root_band_weight",
        click.FloatRange(min=0),
        "Weight of the root's speed along the floor by band in the free-running loss: at 0.5-1, 1-2 and 2-4 Hz "
        "against the real motion's, whatever the phase (a root swaying at the beat where the dancers sway at "
        "the bar); 0: none.",
    ),
    (
        "root_rise_weight",
        click.FloatRange(min=0),
        "Weight of the root's vertical speed by band in the free-running loss: at 0.5-1, 1-2, 2-4 and 4-8 Hz "
        "against the real motion's, whatever the phase (a waltz's rise and fall); 0: none.",
    ),
    (
        "root_phase_weight",
        click.FloatRange(min=0),
        "Weight of the root's rise and fall out of phase in the free-running loss: one minus the correlation of its "
        "vertical speed with the real motion's at 0.5-1, 1-2, 2-4 and 4-8 Hz, whatever the size (rising when the "
        "dancer rose, to the same music); 0: none.",
    ),
    (
        "step_weight",
        click.FloatRange(min=0),
        "Weight of the feet's speed about the root in the free-running loss: each foot joint's speed along each "
        "axis about the hips over the window against the real motion's, slower costing in proportion (a body "
        "carried along the floor, its feet still: a glide); 0: none.",
    ),
    (
        "bone_weight",
        click.FloatRange(min=0),
        "Weight of the bones' stretch in the free-running loss: how much each bone's length varies against the "
        "real motion's; 0: none.",
    ),
    (
        "world_speed_weight",
        click.FloatRange(min=0),
        "Weight of the joints' speed in the world in the free-running loss: each joint's speed along each axis per "
        "2 s against the real motion's, slower costing more; 0: none.",
    ),
    (
        "foot_weight",
        click.FloatRange(min=0),
        "Weight of the feet's sliding in the free-running loss: EDGE's foot contact score against the real "
        "motion's, more costing in proportion; 0: none.",
    ),
    (
        "component_floor",
        click.BOOL,
        "Floor each component's speed, jitter and bone terms in the free-running loss at 1 % of its own mean, "
        "not of every component's: a component far smaller than the rest in normalised units (the root's sway "
        "along the floor) then costs what it does.",
    ),
    (
        "sway",
        click.BOOL,
        "Once trained, scale the network's sway along the floor to the dancers' wherever the run makes positions: "
        "the ratio of the dancers' root speed along the floor at 1-4 Hz to the network's on the training songs, "
        "never above 1 (a run that draws its travel).",
    ),
    (
        "song_starts",
        click.BOOL,
        "Also train on each song's first frames: windows whose context runs before the recording's start, silence "
        "there, and (the cdhc model) hear that silence before every song generated (a model with a context "
        "otherwise never trains on its songs' first seconds).",
    ),
    (
        "silence_share",
        click.FloatRange(0, 1),
        "Share of training windows whose music goes silent from a random frame on, the pose held (to stop in silence).",
    ),
    (
        "mirror_share",
        click.FloatRange(0, 1),
        "Share of training windows danced by their dancer's mirror image (reflected across x = 0, left and right "
        "swapped), to the same music; 0: none.",
    ),
    (
        "turning",
        click.BOOL,
        "Fit the training dancers' turning about the vertical (its speed and how long it lasts) and draw it "
        "wherever the run makes positions (evaluate, generate, live), held still in silence; root-centred 3-D "
        "position targets only. The music does not tell when dancers turn, so the network cannot.",
    ),
    (
        "travel",
        click.BOOL,
        "Fit the training dancers' travel across the floor (the root's slow velocity: its speed and how long it "
        "lasts) and draw it wherever the run makes positions, held still in silence; root-centred 3-D position "
        "targets only. Which way dancers go is theirs, not the music's.",
    ),
    (
        "facing",
        click.BOOL,
        "Train on poses turned about the vertical to face one way, frame by frame (the hips' and shoulders' "
        "left-right axis along x): the network makes the body, the drawn turning where it faces (needs --turning).",
    ),
    (
        "by_metre",
        click.BOOL,
        "Also fit the drawn turning and travel on the training recordings of each metre (3 or 4 beats a bar, "
        "from the recordings manifest or the build): each song is drawn its metre's, where the run has them.",
    ),
    (
        "smooth_hz",
        click.FloatRange(min=0),
        "Low-pass the motion the run makes at this cutoff, Hz (a causal Butterworth of order 2, after the drawn "
        "turning and travel), wherever it makes positions: evaluate, generate, live; the network trains as without "
        "it. 0: not smoothed.",
    ),
    (
        "style_tempo",
        click.FloatRange(0, 1, max_open=True),
        "Dance a song further than this share of the tempo from its heard style's usual tempo (0.08: 8 %) at "
        "that style's tempo, pitch kept, and play the dance back at the song's own: evaluate and generate (not "
        "live). Needs features that hear the style (*_style). 0: every song at its own tempo.",
    ),
    (
        "context",
        click.IntRange(min=0),
        "Frames of real input before each window that no loss counts (the outputs near a window's start then see "
        "music, not the padding of its edge). Default: the model's own (cdhc: its receptive field; yalta: 0).",
    ),
    (
        "balance",
        click.Choice(["none", *BALANCE_FIELDS]),
        "Draw each epoch's training windows so that every recording, dance style or metre (as the recordings "
        "manifest gives them) has the same share; none: each window once, shuffled.",
    ),
    (
        "weight_average",
        click.FloatRange(0, 1, max_open=True),
        "Decay per step of a moving average of the weights, which validation, the kept epoch and model.pt then "
        "use (0.995: the last 200 steps or so); 0: none.",
    ),
    (
        "precision",
        click.Choice(["float32", "bfloat16"]),
        "Arithmetic of the training step's forward pass: bfloat16 runs it under torch.autocast where the device "
        "computes bfloat16 natively (about twice as fast for convolutions; float32 with a warning elsewhere); "
        "losses, weights, validation and generation stay float32.",
    ),
    (
        "keep",
        click.Choice(["last", "best"]),
        "model.pt: the last epoch, or the one with the best free-running validation rhythm loss among those whose "
        "validation songs, run whole, move at 0.5-2 x the real energy.",
    ),  # fmt: skip
    (
        "keep_energy_weight",
        click.FloatRange(min=0),
        "With --keep best, how much an epoch's energy counts beside its rhythm loss: the epoch kept has the lowest "
        "loss x exp(WEIGHT x |ln energy ratio|); 0: the loss alone.",
    ),
)
"""The training loop's options (:data:`kinectdata.training.config.LOOP_DEFAULTS`): every model's."""

_RESERVED = {"data", "out", "resume", "only", "model"}
"""Parameter names of the commands themselves: a model setting of one of these names gets no option."""


def _shown(value) -> str:
    if value is None:
        return "none"
    return f"{value:g}" if isinstance(value, float) else str(value)


def _per_model(values: list) -> str:
    """The defaults of the models in order, once when they agree: "150 / 300", "0.55"."""
    shown = [_shown(v) for v in values]
    return shown[0] if len(set(shown)) == 1 else " / ".join(shown)


def _setting_type(f, default):
    """The click type of a model setting from its dataclass field (its metadata and default)."""
    meta = f.metadata
    if "choices" in meta:
        return click.Choice(list(meta["choices"]))
    bounds = {k: meta[k] for k in ("min", "max", "min_open", "max_open") if k in meta}
    if isinstance(default, bool):
        return click.BOOL
    if isinstance(default, int):
        return click.IntRange(**bounds) if bounds else click.INT
    if isinstance(default, float):
        return click.FloatRange(**bounds) if bounds else click.FLOAT
    return click.STRING


def train_options(f):
    """The training settings: ``--model`` (the registered models), the training loop's options,
    and every registered model's own settings (from its ``settings_type``; the help names the
    models each applies to). Defaults that depend on the model show each model's, in the order of
    ``--model``'s choices (e.g. "yalta / cdhc")."""
    from kinectdata.models.registry import MODELS
    from kinectdata.training.config import LOOP_DEFAULTS

    kinds = list(MODELS.values())
    names = "; ".join(f"{k.name}: {k.description}" for k in kinds)
    options = [
        click.option(
            "--model",
            default=None,
            type=click.Choice([k.name for k in kinds]),
            help=f"{names}. Default: the dataset's (the model of the pipeline that builds it).",
        )
    ]
    settings: dict[str, list] = {}
    for kind in kinds:
        for field in dataclasses.fields(kind.settings_type):
            if field.name not in _RESERVED and field.name not in LOOP_DEFAULTS:
                settings.setdefault(field.name, []).append((kind, field))
    for name, owners in settings.items():
        defaults = [getattr(kind.settings_type(), name) for kind, _ in owners]
        texts = [field.metadata.get("help", name) for _, field in owners]
        helps = (  # a setting both models share (their phrase code) is said once
            texts[0]
            if len(owners) > 1 and len(set(texts)) == 1
            else "; ".join(f"{kind.name}: {text}" for (kind, _), text in zip(owners, texts))
        )
        options.append(
            click.option(
                f"--{name.replace('_', '-')}",
                name,
                default=None,
                type=_setting_type(owners[0][1], defaults[0]),
                help=f"{helps} [default: {_per_model(defaults)}]",
            )
        )
    for name, kind_type, text in _LOOP_OPTIONS:
        defaults = [{**LOOP_DEFAULTS, **k.training_defaults}[name] for k in kinds]
        shown = "" if name == "stride" else f" [default: {_per_model(defaults)}]"
        options.append(
            click.option(f"--{name.replace('_', '-')}", name, default=None, type=kind_type, help=text + shown)
        )
    for option in reversed(options):
        f = option(f)
    return f


def make_train_config(model: str | None, data: str | None = None, paper: bool = False, **settings):
    """The TrainConfig of the typed settings over the model's defaults (with ``paper``, its
    published settings); the model defaults to the dataset's
    (:func:`kinectdata.models.registry.model_for_dataset` of ``data``'s manifest)."""
    from kinectdata.models.registry import DEFAULT_MODEL, model_for_dataset
    from kinectdata.models.run import read_manifest
    from kinectdata.training.config import TrainConfig

    if model is None:
        model = DEFAULT_MODEL if data is None else model_for_dataset(read_manifest(data, verify=False))
    return TrainConfig.for_model(model, paper=paper, **settings)


def _row(row: dict) -> str:
    val = "-" if row["val_loss"] is None else f"{row['val_loss']:.5f}"
    smape = "-" if row["val_smape"] is None else f"{row['val_smape']:.2f} %"
    free = ""
    if row.get("val_rhythm") is not None:
        energy = "-" if row.get("val_energy") is None else f"{row['val_energy']:.2f} x the real"
        free = f", free runs: rhythm loss {row['val_rhythm']:.4g}, songs' energy {energy}"
    return (
        f"epoch {row['epoch']:>3}: train loss {row['train_loss']:.5f}, validation loss {val}, "
        f"validation SMAPE {smape}{free} ({row['seconds']:.1f} s, {row['frames_per_second']:.0f} frames/s)"
        + ("; the time budget ran out: training ends here" if row.get("stopped") else "")
    )


no_checksums_option = click.option(
    "--no-checksums",
    is_flag=True,
    help="Skip the shards' SHA-256 check (layout, sizes and manifest are still checked): about 1 s per GB saved.",
)


def style_option(help_text: str):
    """``--style NAME`` (default None: heard in the music), with ``help_text``."""
    return click.option("--style", default=None, metavar="NAME", help=help_text)


def beats_per_bar_option(help_text: str):
    """``--beats-per-bar N`` (2-12, default None: estimated from the music), with ``help_text``."""
    return click.option("--beats-per-bar", default=None, type=click.IntRange(2, 12), help=help_text)


DRAWS_SEED_HELP = "Seed of the drawn turning and travel, and the draw of a phrase code (--latent-dims)."


def turning_options(f, seed_help: str = DRAWS_SEED_HELP):
    """``--turning/--no-turning`` and ``--travel/--no-travel`` (default on) and ``--seed`` of their
    draws (``seed_help`` says what else it draws)."""
    f = click.option(
        "--travel/--no-travel",
        default=True,
        show_default=True,
        help="Draw the run's travel across the floor, fitted on its training dancers (none for a run trained "
        "without it); --no-travel: the dancer stays where the network puts it.",
    )(f)
    f = click.option(
        "--turning/--no-turning",
        default=True,
        show_default=True,
        help="Draw the run's turning about the vertical, fitted on its training dancers (none for a run trained "
        "without it); --no-turning: the network's motion alone (smoothed, if the run smooths).",
    )(f)
    return click.option("--seed", default=0, show_default=True, type=click.INT, help=seed_help)(f)


@click.command("train-baseline")
@click.option("--data", required=True, type=click.Path(exists=True, file_okay=False), help="Dataset folder.")
@click.option("--out", required=True, type=click.Path(file_okay=False), help="Run folder to write.")
@click.option("--resume", is_flag=True, help="Continue the run in --out from its last checkpoint, exactly.")
@click.option(
    "--paper",
    is_flag=True,
    help="Start from the model's published settings (yalta: 500 units, its own outputs fed back, Adam 1e-4, "
    "batches of 50, sequences of 150, gradient noise; cdhc: 256 channels, Adam 2e-4, batches of 16) instead of the "
    "recipe for real dance; options typed beside it still apply.",
)
@no_checksums_option
@train_options
def train_baseline(data, out, resume, paper, no_checksums, **options) -> None:
    """Train a registered model on a dataset (by default the dataset's): the DCNN + deep LSTM of
    Yalta et al. (2016) or the CDHC encoder-decoder of Lee et al. (2018). The defaults are the
    recipe for real dance on a CPU (docs/training.md, "Learning real dance": teacher-forced
    loss plus a free-running rhythm loss, a fifth of the windows silenced, windows of 10 s,
    batches of 8, Adam 1e-3, the best free-running validation epoch kept); --paper gives the
    papers' settings (yalta: Adam 1e-4, MSE, its own outputs fed back, sequences of 150, batches
    of 50, 10 epochs, annealed gradient noise; cdhc: teacher forcing, L1 + limb-length loss, Adam
    2e-4, sequences of 300, batches of 16, 20 epochs). On real dance build the dataset with the
    music's pulse (build-dataset --features yalta2016_rhythm, or listen_to_dance_rhythm_bars for cdhc).

    Writes into --out: config.json, checkpoint.pt (each epoch, atomically), log.csv, loss.png,
    and at the end model.pt and what the model adds (yalta: stream.ts, TorchScript of the
    streaming network). With --resume the run's own settings are used; --epochs (to train longer)
    and --device may be given."""
    _torch_or_fail()
    from kinectdata.models.registry import model_kind
    from kinectdata.training.train import train

    if resume:  # the run's settings, with what was typed on the command line checked against them
        from kinectdata.models.run import read_config
        from kinectdata.training.config import TrainConfig

        if paper:
            raise click.UsageError("--paper starts a run; --resume continues one with its own settings")
        typed = {k: v for k, v in options.items() if v is not None}
        config = TrainConfig.from_dict(read_config(out)["train"]).replace(**typed)
    else:
        config = make_train_config(data=data, paper=paper, **options)
    import warnings

    from kinectdata.training.train import TrainingWarning

    with warnings.catch_warnings():
        warnings.simplefilter("always", TrainingWarning)
        warnings.showwarning = lambda message, *_a, **_k: click.echo(f"warning: {message}", err=True)
        history = train(
            data, out, config, resume=resume, progress=lambda r: click.echo(_row(r)), checksums=not no_checksums
        )
    from kinectdata.training.distributed import World

    if World.from_environment().main:  # under torchrun, one line from rank 0
        files = ", ".join(["log.csv", "loss.png", "model.pt", *model_kind(config.model).run_exports])
        click.echo(f"run: {out} ({len(history)} epochs; {files})")
        from kinectdata.inference.turning import run_sway
        from kinectdata.models.run import read_config

        sway = run_sway(read_config(out))
        if sway is not None:
            click.echo(f"  {sway.describe()}")


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
@click.option(
    "--protocol",
    default="bailando",
    show_default=True,
    type=click.Choice(["aist", "bailando", "edge"]),
    help="Whose table the field's metrics (FID, Div, BAS, PFC) reproduce; see docs/metrics.md.",
)
@click.option("--bootstrap", default=1000, show_default=True, type=click.IntRange(min=0),
              help="Resamples for the field's metrics' 95 %% intervals (0: none).")  # fmt: skip
@beats_per_bar_option(
    "The songs' metre (a waltz 3), for those whose recordings-manifest entry gives none; default: estimated "
    "from each song."
)
@no_checksums_option
@functools.partial(
    turning_options,
    seed_help="Seed of the turning and travel drawn in every free run (each song's draws keyed by its music too): "
    "score a run trained with --seed N on its own draws with --seed N.",
)
@click.option(
    "--sway/--no-sway",
    default=True,
    show_default=True,
    help="Scale the network's sway along the floor by the run's gain (train --sway; none for a run trained "
    "without it); --no-sway: the network's root as it made it.",
)
@click.option(
    "--style-tempo",
    default=None,
    type=click.FloatRange(0, 1, max_open=True),
    help="Dance a song further than this share of the tempo from its style's usual tempo at that tempo, then "
    "play the dance back at the song's (docs/training.md); 0: every song at its own tempo, the network alone. "
    "Default: the run's.",
)
def evaluate_command(
    run_dir,
    data,
    split,
    out,
    silence,
    protocol,
    bootstrap,
    beats_per_bar,
    no_checksums,
    turning,
    travel,
    seed,
    sway,
    style_tempo,
) -> None:
    """Score a run as the paper does: SMAPE (%) free-running without and with reset, on normalised
    and denormalised values; per-frame forward time; generated-against-real plots; the silence test;
    beat following with its chance levels and the listening controls; and the field's table (FID,
    diversity, Beat Align Score, PFC) of the generated motion against the real, in metrics.json."""
    _torch_or_fail()
    from kinectdata.evaluation.evaluate import evaluate, format_results

    results = evaluate(
        run_dir,
        data,
        split,
        out=out,
        silence_seconds=silence,
        protocol=protocol,
        bootstrap=bootstrap,
        checksums=not no_checksums,
        beats_per_bar=beats_per_bar,
        turning=turning,
        travel=travel,
        sway=sway,
        style_tempo="run" if style_tempo is None else style_tempo,
        draw_seed=seed,
    )
    click.echo(format_results(results))


@click.command("generate")
@click.option("--run", "run_dir", required=True, type=click.Path(exists=True, file_okay=False), help="Run folder.")
@click.argument("audio", required=False, type=click.Path(dir_okay=False))
@click.option(
    "-o",
    "--out",
    required=True,
    type=click.Path(),
    help="File to write: canonical CSV or BVH (3-D targets, e.g. yalta: dance.csv, dance.bvh), OpenPose JSON "
    "Lines (2-D targets, e.g. cdhc: dance.jsonl); with --data, the folder to write each song's into.",
)
@click.option(
    "--data",
    default=None,
    type=click.Path(exists=True, file_okay=False),
    help="Instead of AUDIO: a dataset, whose --split recordings each get a dance from their own music "
    "(NAME.wav beside NAME.csv in the folder -o, frame k on the recording's frame k).",
)
@click.option("--split", default="test", show_default=True, help="The split of --data to generate for.")
@click.option(
    "--engine",
    default="torch",
    show_default=True,
    type=click.Choice(["torch", "onnxruntime"]),
    help="What runs the network, as the run's model offers: torch, or ONNX Runtime (yalta; fastest on CPUs; "
    "pip install 'kinectdata[export]').",
)
@click.option(
    "--precision",
    default="float32",
    show_default=True,
    type=click.Choice(["float32", "float16"]),
    help="Weights of the torch engine (float16: half the memory traffic, faster on CPUs).",
)
@beats_per_bar_option(
    "The song's metre (a waltz 3), for a model whose features count bars (listen_to_dance_rhythm_bars); "
    "default: estimated from the song."
)
@style_option(
    "The song's dance style (one the run's training songs hold), for a run whose features hear it "
    "(*_style presets); default: heard in the song."
)
@turning_options
def generate_command(
    run_dir, audio, out, data, split, engine, precision, beats_per_bar, style, turning, travel, seed
) -> None:
    """Generate dance motion for AUDIO (any file libsndfile reads, or an aligned .h5: its own music,
    on its timeline), streaming frame by frame, and
    write it: 3-D targets (a yalta run's: metres, unit quaternions) as the canonical CSV that align
    reads or, named .bvh, as BVH for animation tools; 2-D ones (a cdhc run's: x, y in 0..1, y down)
    as OpenPose JSON Lines that the openpose reader reads. With --data instead of AUDIO: a dance for
    every recording of a dataset split, each from its own music."""
    _torch_or_fail()
    if (audio is None) == (data is None):
        raise click.UsageError("give AUDIO, or --data DATASET (and --split) to generate for a whole split")
    if data is not None:
        for given, option in ((beats_per_bar, "--beats-per-bar"), (style, "--style")):
            if given is not None:
                raise click.UsageError(f"{option} is for AUDIO: a split's songs keep their own")
        _generate_split(run_dir, data, split, out, engine, precision, turning, travel, seed)
        return
    from kinectdata.inference.generate import generate
    from kinectdata.inference.smoothing import NOT_SMOOTHED
    from kinectdata.inference.style_tempo import AS_IT_IS

    motion, timing = generate(
        run_dir,
        audio,
        out,
        engine=engine,
        precision=precision,
        beats_per_bar=beats_per_bar,
        turning=turning,
        travel=travel,
        seed=seed,
        style=style,
    )
    click.echo(
        f"wrote {out}: {timing['frames']} frames ({motion.duration:.2f} s) in {timing['seconds']:.2f} s "
        f"({_ratio(timing['x_real_time'])}x real time; network step {timing['step_median_ms']:.3f} ms median)"
    )
    if "metre" in timing:
        click.echo(f"  metre: {timing['metre']}")
    if "style" in timing:
        click.echo(f"  style: {timing['style']}")
    click.echo(
        f"  starts from {timing['start']}" + (f"; placed by {timing['placement']}" if "placement" in timing else "")
    )
    click.echo(f"  {timing['turning']}")
    if timing["smoothing"] != NOT_SMOOTHED:
        click.echo(f"  the motion {timing['smoothing']}")
    if timing.get("style_tempo", AS_IT_IS) != AS_IT_IS:
        click.echo(f"  {timing['style_tempo']}")
    if "phrase_code" in timing:
        click.echo(f"  the phrase code {timing['phrase_code']}")
    if motion.joint_set.dimensions == 2:
        fps = 1 / float(motion.times[1] - motion.times[0]) if motion.n_frames > 1 else 30.0
        click.echo(f"  (OpenPose JSON Lines hold no frame rate: read or render it with --video-fps {fps:g})")


def _generate_split(run_dir, data, split, out, engine, precision, turning, travel, seed) -> None:
    from kinectdata.apps.split_generation import generate_split

    songs = generate_split(
        run_dir,
        data,
        split,
        out,
        engine=engine,
        precision=precision,
        turning=turning,
        travel=travel,
        seed=seed,
        progress=lambda name: click.echo(f"  {name} ..."),
    )
    for song in songs:
        click.echo(f"wrote {song.motion} ({song.timing['frames']} frames) to its music {song.music.name}")
    click.echo(f"{len(songs)} dances of the {split} split of {data} in {out}")


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
    self-describing TorchScript or ONNX file for a robot, for a model that exports (yalta): the
    metadata inside gives frame and sample rate, feature settings, target components,
    normalisation and the start pose. ONNX needs pip install 'kinectdata[export]'."""
    _torch_or_fail()
    from kinectdata.inference.export import export_run

    path = export_run(run_dir, out, fmt, precision)
    click.echo(f"wrote {path}")


@click.command("sweep")
@click.option("--data", required=True, type=click.Path(exists=True, file_okay=False), help="Dataset folder.")
@click.option("--out", required=True, type=click.Path(file_okay=False), help="Folder for the runs and results.md.")
@click.option("--only", default=None, help="Comma-separated variants (default: all of the model's table).")
@no_checksums_option
@train_options
def sweep_command(data, out, only, no_checksums, **options) -> None:
    """Train and evaluate the variants of the model's published table (yalta: the paper's Tables
    3-5, TanH/ReLU/ELU, 250/1000 units, 50/100 steps) and write OUT/results.md with the paper's
    columns beside its figures. The training options set the base every variant changes."""
    _torch_or_fail()
    from kinectdata.core.errors import ConfigError
    from kinectdata.models.registry import model_for_dataset, model_kind
    from kinectdata.models.run import read_manifest
    from kinectdata.training.config import TrainConfig
    from kinectdata.training.sweep import model_sweep, sweep

    typed = {k: v for k, v in options.items() if v is not None and k != "model"}
    kind = model_kind(options["model"] or model_for_dataset(read_manifest(data, verify=False)))
    try:
        table = model_sweep(kind)
    except ConfigError as exc:
        raise click.UsageError(f"{exc}{'' if options['model'] else f' ({data} is a {kind.name} dataset)'}") from None
    variants = None if only is None else [v.strip() for v in only.split(",")]

    def shown(r) -> str:
        return " / ".join(f"{v:.2f} %" for v in (r["smape_without_reset"], r["smape_with_reset"]) if v is not None)

    rows = sweep(
        data,
        out,
        TrainConfig(kind.name, paper=True, **{**table.base, **typed}),
        variants,
        progress=lambda name, r: click.echo(f"{name}: SMAPE {shown(r)}"),
        checksums=not no_checksums,
    )
    click.echo(f"wrote {out}/results.md ({len(rows)} variants)")


COMMANDS = [train_baseline, evaluate_command, generate_command, export_command, sweep_command]


def _ratio(value: float) -> str:
    """A speed ratio with the digits it needs: 1234, 12.3, 0.25, 0.0031."""
    return f"{value:.0f}" if value >= 100 else f"{value:.3g}"
