"""train-baseline: losses fall, exact resume, the run folder, gradient noise, refusals."""

from __future__ import annotations

import csv
import dataclasses
import json
import math

import h5py
import numpy as np
import pytest
from conftest import TINY_TRAINING

torch = pytest.importorskip("torch")

from kinectdata.core.errors import ConfigError, KinectDataError  # noqa: E402
from kinectdata.models.registry import model_kind  # noqa: E402
from kinectdata.models.run import load_checkpoint, load_model  # noqa: E402
from kinectdata.training.config import LOOP_DEFAULTS, TrainConfig  # noqa: E402
from kinectdata.training.train import LOG_FIELDS, _add_gradient_noise, train  # noqa: E402


def test_two_epochs_lower_the_training_and_validation_loss(trained_run):
    run, history = trained_run
    assert [r["epoch"] for r in history] == [1, 2]
    first, second = history
    assert second["train_loss"] < first["train_loss"]
    assert second["val_loss"] < first["val_loss"]
    assert 0 < second["val_smape"] < 100 and second["frames_per_second"] > 0


def test_the_run_folder_holds_everything(trained_run, sample_dataset):
    run, history = trained_run
    names = {p.name for p in run.iterdir()}
    assert {"config.json", "checkpoint.pt", "log.csv", "loss.png", "model.pt", "stream.ts"} <= names
    assert not [n for n in names if n.endswith(".partial")]
    assert (run / "loss.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with open(run / "log.csv") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == LOG_FIELDS and len(rows) == 2
    assert float(rows[1]["train_loss"]) == pytest.approx(history[1]["train_loss"])
    config = json.loads((run / "config.json").read_text())
    assert config["train"] == TrainConfig(**TINY_TRAINING).to_dict()
    assert config["model"] == {
        "output_dim": 65,
        "units": 32,
        "activation": "elu",
        "input_shape": [1, 129, 5],
        "inputs": "music-and-poses",
        "side_channels": 0,
    }
    manifest = json.loads((sample_dataset / "manifest.json").read_text())
    assert config["dataset"]["normalisation"] == manifest["normalisation"]
    assert config["dataset"]["build_key"] == manifest["build_key"]
    net, _ = load_model(run)
    assert net.config.units == 32 and not net.training


def test_start_pose_is_the_mean_training_pose(trained_run, sample_dataset):
    run, _ = trained_run
    manifest = json.loads((sample_dataset / "manifest.json").read_text())
    (rec,) = [r for r in manifest["recordings"] if r["split"] == "train"]
    with h5py.File(sample_dataset / rec["shard"], "r") as f:
        current = f["current"][rec["start"] : rec["start"] + rec["frames"]].astype(np.float64)
        mask = f["mask"][rec["start"] : rec["start"] + rec["frames"]]
    expected = [current[mask[:, c], c].mean() for c in range(current.shape[1])]
    config = json.loads((run / "config.json").read_text())
    np.testing.assert_allclose(config["dataset"]["start_pose"], expected, atol=1e-9)


def test_checkpoints_load_without_unpickling(trained_run, tmp_path):
    run, _ = trained_run
    state = torch.load(run / "checkpoint.pt", weights_only=True)
    assert {"model", "optimizer", "step", "order_rng", "noise_rng", "torch_rng", "history", "config"} <= set(state)
    (tmp_path / "bad.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(KinectDataError, match="bad.pt: not a readable kinectdata checkpoint"):
        load_checkpoint(tmp_path / "bad.pt")
    with pytest.raises(KinectDataError, match="not a training run"):
        load_model(tmp_path)


@pytest.mark.slow
def test_a_resumed_run_equals_an_uninterrupted_one(sample_dataset, tmp_path):
    """With gradient noise on and predicted feedback, so every random generator must be restored;
    resumed once after an interruption (with the run's own settings) and once to train longer."""
    config = TrainConfig(**{**TINY_TRAINING, "units": 16, "epochs": 2, "noise_eta": 1e-4, "clip_norm": 1.0})
    whole = train(sample_dataset, tmp_path / "whole", config)
    part = train(sample_dataset, tmp_path / "part", config, stop_after=1)
    assert len(part) == 1 and not (tmp_path / "part" / "model.pt").exists()
    resumed = train(sample_dataset, tmp_path / "part", resume=True)
    shorter = dataclasses.replace(config, epochs=1)
    train(sample_dataset, tmp_path / "longer", shorter)
    longer = train(sample_dataset, tmp_path / "longer", config, resume=True)
    assert json.loads((tmp_path / "longer" / "config.json").read_text())["train"]["epochs"] == 2
    a = torch.load(tmp_path / "whole" / "model.pt", weights_only=True)["model"]
    for name, history in (("part", resumed), ("longer", longer)):
        assert [r["train_loss"] for r in history] == [r["train_loss"] for r in whole]
        assert [r["val_smape"] for r in history] == [r["val_smape"] for r in whole]
        b = torch.load(tmp_path / name / "model.pt", weights_only=True)["model"]
        assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a), name


def test_a_run_folder_is_never_overwritten_and_resume_checks_the_configuration(trained_run, sample_dataset):
    run, _ = trained_run
    with pytest.raises(KinectDataError, match="already holds a run; use --resume"):
        train(sample_dataset, run, TrainConfig(**TINY_TRAINING))
    with pytest.raises(KinectDataError, match=r"cannot resume with other settings: lr 0.0001 \(the run's: 0.003\)"):
        train(sample_dataset, run, TrainConfig(**{**TINY_TRAINING, "lr": 1e-4}), resume=True)
    with pytest.raises(KinectDataError, match="has trained 2 epochs already, more than 1"):
        train(sample_dataset, run, TrainConfig(**{**TINY_TRAINING, "epochs": 1}), resume=True)


def test_resume_refuses_another_dataset(trained_run, sample_dataset, tmp_path):
    import shutil

    run, _ = trained_run
    other = tmp_path / "other"
    shutil.copytree(sample_dataset, other)
    manifest = json.loads((other / "manifest.json").read_text())
    manifest["build_key"] = "0" * 32
    (other / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(KinectDataError, match="cannot resume on .*other: the run was trained on"):
        train(other, run, resume=True)


OLD_FLAT = {  # a run's train settings as config.json held them before each model had its own
    **{"units": 32, "activation": "elu", "feedback": "predicted", "sequence": 30, "stride": None, "batch_size": 8},
    **{"epochs": 2, "lr": 3e-3, "noise_eta": 0.0, "noise_gamma": 0.55, "clip_norm": None, "seed": 0},
    **{"device": "auto", "channels": 256, "decoder_channels": 128, "dropout": 0.05, "limb_weight": 1.0},
}


def test_runs_written_before_still_load_and_resume(trained_run, sample_dataset, tmp_path):
    """A run whose config.json has every model's settings side by side and no model name (as runs
    before the cdhc model): its model is yalta, it loads, resumes and is rewritten in today's form."""
    import shutil

    run = tmp_path / "old"
    shutil.copytree(trained_run[0], run)
    config = json.loads((run / "config.json").read_text())
    config["train"] = OLD_FLAT
    (run / "config.json").write_text(json.dumps(config))
    state = torch.load(run / "checkpoint.pt", weights_only=True)
    state.pop("sha256", None)  # checkpoints before digests had none
    torch.save({**state, "config": json.dumps(config)}, run / "checkpoint.pt")
    then = {**TINY_TRAINING, "stride": None, "clip_norm": None, "feedback": "predicted", "posture_weight": 10.0}
    then["context"] = 0  # trained without context: the yalta model needs none, and runs before it had none
    then["song_starts"] = False  # runs before it had none
    then["turning"] = False  # nor a turning drawn at generation
    then["travel"] = False  # nor a travel
    then["precision"] = "float32"  # and trained in float32
    then["style_path"] = "convs"  # and any style planes were convolved with the spectra
    assert TrainConfig.from_dict(OLD_FLAT) == TrainConfig(**then)
    net, _ = load_model(run)
    assert net.config.units == 32
    (run / "model.pt").unlink()
    history = train(sample_dataset, run, TrainConfig(**{**then, "epochs": 3}), resume=True)
    assert [r["epoch"] for r in history] == [1, 2, 3]
    assert json.loads((run / "config.json").read_text())["train"] == TrainConfig(**{**then, "epochs": 3}).to_dict()
    cdhc = TrainConfig.from_dict({**OLD_FLAT, "model": "cdhc", "feedback": "teacher"})
    assert cdhc.model == "cdhc" and cdhc.channels == 256 and "units" not in cdhc.to_dict()
    with pytest.raises(KinectDataError, match="unknown training settings colour"):
        TrainConfig.from_dict({**OLD_FLAT, "colour": "red"})


def test_damaged_run_files_are_named(trained_run, tmp_path):
    import shutil

    run = tmp_path / "run"
    shutil.copytree(trained_run[0], run)
    config = json.loads((run / "config.json").read_text())
    config["model"]["units"] = 33
    (run / "config.json").write_text(json.dumps(config))
    with pytest.raises(KinectDataError, match="model.pt: does not match the model of .*config.json"):
        load_model(run)
    (run / "config.json").write_text("{not json")
    with pytest.raises(KinectDataError, match="config.json: not valid JSON"):
        load_model(run)


def test_settings_are_validated(sample_dataset, tmp_path):
    with pytest.raises(KinectDataError, match="feedback must be predicted or teacher"):
        TrainConfig(feedback="oracle")
    with pytest.raises(KinectDataError, match="positive"):
        TrainConfig(sequence=0)
    with pytest.raises(KinectDataError, match="no training window of 5000 frames"):
        train(sample_dataset, tmp_path / "r", TrainConfig(**{**TINY_TRAINING, "sequence": 5000}))
    with pytest.raises(KinectDataError, match="not a dataset"):
        train(tmp_path, tmp_path / "r", TrainConfig(**TINY_TRAINING))
    assert not (tmp_path / "r").exists()


def test_the_paper_settings_are_the_papers_and_its_authors_code():
    """The paper: Adam 1e-4, 150 steps, batches of 50, 10 epochs, "gradient noise"; the noise's
    eta 0.01 is the authors' later code's, gamma 0.55 Neelakantan et al.'s."""
    c = TrainConfig(paper=True)
    assert (c.lr, c.sequence, c.batch_size, c.epochs, c.noise_eta, c.noise_gamma) == (1e-4, 150, 50, 10, 0.01, 0.55)
    assert (c.units, c.feedback, c.clip_norm, c.free_weight, c.silence_share) == (500, "predicted", None, 0.0, 0.0)
    assert TrainConfig(paper=True, lr=3e-4).lr == 3e-4  # what is typed beside it still applies
    cdhc = TrainConfig("cdhc", paper=True)
    assert (cdhc.channels, cdhc.decoder_channels, cdhc.lr, cdhc.batch_size, cdhc.epochs) == (256, 128, 2e-4, 16, 20)
    # the paper draws no turning or travel and does not smooth: those are this project's additions
    assert (cdhc.turning, cdhc.travel, cdhc.facing, cdhc.by_metre, cdhc.smooth_hz) == (False, False, False, False, None)
    # nor averages weights or reads context before each window (DC-TTS's loop does neither)
    assert (cdhc.weight_average, cdhc.context) == (0.0, 0)


@pytest.mark.parametrize("model", ["yalta", "cdhc"])
def test_no_real_dance_default_leaks_into_the_paper_settings(model):
    """``--paper`` is the published settings over the loop's base: a recipe default the paper does
    not name is the base's, whatever the model's ``training_defaults`` say."""
    kind = model_kind(model)
    paper = TrainConfig(model, paper=True).to_dict()
    unnamed = [k for k in kind.training_defaults if k not in kind.paper]
    assert {k: paper[k] for k in unnamed} == {k: LOOP_DEFAULTS[k] for k in unnamed}
    assert {k: paper[k] for k in kind.paper if k in LOOP_DEFAULTS} == {
        k: v for k, v in kind.paper.items() if k in LOOP_DEFAULTS
    }


def test_every_free_running_term_has_a_setting_an_option_and_is_off_in_the_papers_loop():
    """The weights are listed once (RhythmWeights' fields): each is a training setting, the train
    command's option, 0 in the published loop, and a run written before it trained without it
    (but the posture term, at 10 before it was a setting)."""
    from kinectdata.cli.train import train_baseline
    from kinectdata.models.losses import RhythmWeights

    options = {p.name for p in train_baseline.params}
    fields = {f.name for f in dataclasses.fields(TrainConfig)}
    for term in dataclasses.fields(RhythmWeights):
        name = f"{term.name}_weight"
        assert name in fields and name in options, name
        with pytest.raises(ConfigError, match=f"{name} must be at least 0"):
            TrainConfig("cdhc", **{name: -1.0})
    assert TrainConfig("cdhc", paper=True).rhythm_weights == RhythmWeights(
        posture=0.0, bone=0.0, world_speed=0.0, foot=0.0
    )
    assert TrainConfig.from_dict({"model": "cdhc"}).rhythm_weights == RhythmWeights(posture=10.0)


def test_the_defaults_are_the_recipe_that_learns_real_dance():
    for model in ("yalta", "cdhc"):
        c = TrainConfig(model)
        assert (c.sequence, c.stride, c.batch_size, c.lr, c.noise_eta, c.clip_norm) == (300, 75, 8, 1e-3, 0.0, 1.0)
        assert (c.free_weight, c.posture_weight, c.silence_share, c.keep) == (1.0, 3.0, 0.2, "best")
    assert (TrainConfig().units, TrainConfig().feedback) == (128, "teacher")
    assert (TrainConfig("yalta").epochs, TrainConfig("cdhc").epochs) == (12, 40)  # the cdhc model's epochs are short
    assert (TrainConfig("yalta").smooth_hz, TrainConfig("cdhc").smooth_hz) == (None, 6.0)


def test_a_smoothing_of_0_turns_the_models_default_off():
    assert TrainConfig("cdhc", smooth_hz=0).smooth_hz is None
    assert TrainConfig.for_model("cdhc", smooth_hz=0.0).smooth_hz is None
    assert TrainConfig.for_model("cdhc", smooth_hz=None).smooth_hz == 6.0  # None: the default
    assert TrainConfig.for_model("cdhc", smooth_hz=4).smooth_hz == 4


def test_a_run_written_before_the_rhythm_loss_resumes_without_it():
    added = ("free_weight", "silence_share", "keep")
    old = {k: v for k, v in TrainConfig(paper=True).to_dict().items() if k not in added}
    read = TrainConfig.from_dict(old)
    assert (read.free_weight, read.silence_share, read.keep) == (0.0, 0.0, "last")


@pytest.mark.parametrize("step", [0, 9, 99])
def test_gradient_noise_has_the_annealed_variance(step):
    """Neelakantan et al. (2015): N(0, eta / (1 + t)^gamma) added to every gradient."""
    config = dataclasses.replace(TrainConfig(paper=True), noise_eta=0.01, noise_gamma=0.55)
    p = torch.nn.Parameter(torch.zeros(200_000))
    p.grad = torch.zeros_like(p)
    _add_gradient_noise([p], step, config, torch.Generator().manual_seed(0))
    expected = math.sqrt(0.01 / (1 + step) ** 0.55)
    assert float(p.grad.std()) == pytest.approx(expected, rel=0.01)
    assert abs(float(p.grad.mean())) < 4 * expected / math.sqrt(p.numel())


def test_teacher_feedback_trains_too(sample_dataset, tmp_path):
    history = train(sample_dataset, tmp_path / "t", TrainConfig(**{**TINY_TRAINING, "feedback": "teacher"}))
    assert history[1]["train_loss"] < history[0]["train_loss"]
    assert math.isfinite(history[1]["val_smape"])


def test_a_time_budget_ends_training_cleanly_with_a_usable_model(sample_dataset, tmp_path):
    calls = []

    def metrics(net):
        calls.append(net.training)
        return {"probe": 1.5}

    config = TrainConfig(**{**TINY_TRAINING, "epochs": 50, "max_minutes": 1e-5})
    history = train(sample_dataset, tmp_path / "t", config, epoch_metrics=metrics)
    assert len(history) == 1 and history[0]["stopped"] == "time budget" and history[0]["step"] >= 1
    assert history[0]["probe"] == 1.5 and calls == [False]  # measured in evaluation mode
    assert (tmp_path / "t" / "model.pt").is_file() and (tmp_path / "t" / "stream.ts").is_file()
    net, _ = load_model(tmp_path / "t")
    rows = list(csv.DictReader((tmp_path / "t" / "log.csv").open()))
    assert rows[0]["stopped"] == "time budget"
    with pytest.raises(KinectDataError, match="max_minutes"):
        TrainConfig(**{**TINY_TRAINING, "max_minutes": 0})


def test_a_run_with_too_few_optimiser_steps_is_warned_about(sample_dataset, tmp_path):
    from kinectdata.training.train import TrainingWarning

    with pytest.warns(TrainingWarning, match=r"optimiser steps? per epoch, \d+ in all .* too few to learn"):
        train(sample_dataset, tmp_path / "t", TrainConfig(**{**TINY_TRAINING, "epochs": 1, "batch_size": 50}))


def test_a_rising_or_exploding_loss_is_said_once_with_what_to_change():
    from kinectdata.training.train import loss_warning

    def rows(losses):
        return [{"epoch": i + 1, "train_loss": v} for i, v in enumerate(losses)]

    said = [loss_warning(rows([0.5, 0.4, 0.45, 0.5, 0.6, 0.7][:n]), 1e-3) for n in range(1, 7)]
    assert said[:4] == [None] * 4 and said[5] is None  # warned once, on the third rise in a row
    assert "rose 3 epochs in a row (0.4 at epoch 2 -> 0.6 at epoch 5)" in said[4] and "--lr 0.0001" in said[4]
    assert loss_warning(rows([0.5, 0.4, 0.5, 0.4, 0.5, 0.4]), 1e-3) is None  # noisy, not rising
    assert "the training loss is inf at epoch 2" in loss_warning(rows([0.5, float("inf")]), 1e-3)
    assert loss_warning(rows([0.5, float("inf"), None]), 1e-3) is None  # already said


def test_a_rising_validation_loss_is_said_once_with_the_best_epoch():
    from kinectdata.training.train import loss_warning

    train_losses = [0.9, 0.7, 0.5, 0.4, 0.3, 0.2, 0.15]
    val_losses = [0.8, 0.6, 0.5, 0.55, 0.6, 0.7, 0.8]
    rows = [{"epoch": i + 1, "train_loss": t, "val_loss": v} for i, (t, v) in enumerate(zip(train_losses, val_losses))]
    said = [loss_warning(rows[:n], 1e-4) for n in range(1, 8)]
    # val rises 0.5 -> 0.55 -> 0.6 -> 0.7: the third rise in a row is at epoch 6, said there only
    assert said[:5] == [None] * 5 and said[6] is None
    assert "validation loss rose 3 epochs in a row (0.5 at epoch 3 -> 0.7 at epoch 6" in said[5]
    assert "lowest 0.5 at epoch 3" in said[5] and "--epochs 3" in said[5] and "--lr 1e-05" in said[5]
    without_val = [{**r, "val_loss": None} for r in rows]  # no val split: nothing to say
    assert all(loss_warning(without_val[:n], 1e-4) is None for n in range(1, 8))
    free = [{**r, "val_rhythm": 5.0 - r["epoch"] / 10} for r in rows]  # judged on its free runs, which improve
    assert all(loss_warning(free[:n], 1e-4) is None for n in range(1, 8))


def test_a_loss_that_ends_above_where_it_started_is_said_at_the_end():
    from kinectdata.training.train import ending_warning

    def rows(train_losses, val_losses):
        pairs = zip(train_losses, val_losses)
        return [{"epoch": i + 1, "train_loss": t, "val_loss": v} for i, (t, v) in enumerate(pairs)]

    assert ending_warning(rows([0.5, 0.4, 0.3], [0.6, 0.7, 0.55]), 1e-3) is None  # both below their start
    said = ending_warning(rows([0.5, 0.3, 0.52], [0.6, 0.5, 0.4]), 1e-3)
    assert said.startswith("the training loss ended above where it started (0.5 at epoch 1 -> 0.52 at epoch 3)")
    assert "validation" not in said and "--lr 0.0001" in said
    said = ending_warning(rows([0.5, 0.3, 0.2], [0.6, 0.9, 0.61]), 1e-3)
    assert said.startswith("the validation loss ended above where it started (0.6 at epoch 1 -> 0.61 at epoch 3)")
    said = ending_warning(rows([0.5, 0.7], [0.6, None]), 1e-3)  # a validation loss gone non-finite is not compared
    assert "training loss ended above" in said and "validation" not in said
    assert ending_warning(rows([0.5, 0.9], [None, None])[:1], 1e-3) is None  # one epoch: nothing to compare
    assert "training loss ended above" in ending_warning(rows([0.5, math.inf], [0.6, 0.5]), 1e-3)
    # with the free-running loss, its validation figure is what is judged: C3's teacher-forced
    # validation loss (0.0188 -> 0.0199) rose while its free-running rhythm loss fell (40.1 -> 15.4)
    learned = [
        {**r, "val_rhythm": v} for r, v in zip(rows([196.5, 26.7, 12.3], [0.0188, 0.0190, 0.0199]), [40.1, 23.7, 15.4])
    ]
    assert ending_warning(learned, 1e-3) is None
    learned[-1]["val_rhythm"] = 41.0
    said = ending_warning(learned, 1e-3)
    assert said.startswith("the free-running validation rhythm loss ended above where it started (40.1 at epoch 1")


def test_train_says_how_the_losses_ended(sample_dataset, tmp_path, monkeypatch):
    """The end-of-run check sees the run's whole log and its word reaches the caller as a TrainingWarning."""
    import kinectdata.training.train as train_module
    from kinectdata.training.train import TrainingWarning

    seen = []

    def planted(history, lr):
        seen.append((json.loads(json.dumps(history)), lr))
        return "planted: the loss ended above where it started"

    monkeypatch.setattr(train_module, "ending_warning", planted)
    with pytest.warns(TrainingWarning, match="planted: the loss ended above"):
        history = train(sample_dataset, tmp_path / "run", TrainConfig(**TINY_TRAINING))
    assert seen == [(history, TINY_TRAINING["lr"])]
    with open(tmp_path / "run" / "log.csv") as f:
        assert [int(r["epoch"]) for r in csv.DictReader(f)] == [r["epoch"] for r in history]


def test_a_run_with_a_weight_average_keeps_the_average_of_its_steps_and_resumes_it(
    sample_dataset, tmp_path, monkeypatch
):
    """model.pt holds the exponential moving average of the weights after every optimiser step,
    computed here by hand from the steps' weights (a = w_1, then a = d a + (1 - d) w_t), across an
    interruption after the first epoch and a resume; the checkpoint keeps the optimiser's own."""
    decay = 0.9
    steps: list[list[torch.Tensor]] = []

    class Recording(torch.optim.Adam):
        def step(self, closure=None):
            result = super().step(closure)
            steps.append([p.detach().clone() for group in self.param_groups for p in group["params"]])
            return result

    monkeypatch.setattr(torch.optim, "Adam", Recording)
    config = TrainConfig(**{**TINY_TRAINING, "units": 16, "weight_average": decay})
    run = tmp_path / "run"
    train(sample_dataset, run, config, stop_after=1)
    history = train(sample_dataset, run, resume=True)
    assert len(steps) == history[-1]["step"] > 2
    average = steps[0]
    for weights in steps[1:]:
        average = [decay * a + (1 - decay) * w for a, w in zip(average, weights)]
    kept = load_checkpoint(run / "model.pt")["model"]
    last = load_checkpoint(run / "checkpoint.pt")["model"]
    net, _ = load_model(run)
    names = [name for name, _ in net.named_parameters()]  # the optimiser's order
    assert list(kept) == list(last) and len(names) == len(steps[0])
    for name, mean, own in zip(names, average, steps[-1]):
        torch.testing.assert_close(kept[name], mean, rtol=1e-5, atol=1e-6)
        assert torch.equal(last[name], own)
    with pytest.raises(ConfigError, match="weight_average must be in"):
        TrainConfig(**{**TINY_TRAINING, "weight_average": 1.0})
