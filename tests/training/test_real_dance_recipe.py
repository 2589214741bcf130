"""The parts of the recipe for real dance: the free-running rhythm loss, silenced windows,
keeping the best free-running validation epoch, the papers' settings by name."""

from __future__ import annotations

import csv
import dataclasses
import json
import math

import numpy as np
import pytest
import torch
from click.testing import CliRunner
from conftest import REPO, TINY_TRAINING

from kinectdata.cli import main
from kinectdata.core.errors import ConfigError, KinectDataError
from kinectdata.models.losses import (
    RhythmWeights,
    masked_energy_loss,
    masked_jitter_loss,
    masked_periodogram_loss,
    masked_rhythm_loss,
    masked_rhythm_spectrum_loss,
)
from kinectdata.models.registry import model_kind
from kinectdata.models.run import load_checkpoint
from kinectdata.training.augment import mirror_windows
from kinectdata.training.config import TrainConfig
from kinectdata.training.train import LOG_FIELDS, _better, read_log, train

RECIPE = {**TINY_TRAINING, "sequence": 40, "epochs": 3, "free_weight": 1.0, "silence_share": 0.5, "keep": "best"}


def _sines(freqs_hz, phases, frames=300, fps=30.0, amplitude=0.3):
    t = np.arange(frames) / fps
    return torch.tensor(
        np.stack([amplitude * np.sin(2 * np.pi * f * t + p) for f, p in zip(freqs_hz, phases)], axis=1)[None],
        dtype=torch.float32,
    )


def test_the_rhythm_loss_ignores_phase_but_not_tempo_or_size():
    real = _sines([0.5, 1.0, 2.0], [0.0, 0.3, 1.0])
    mask = torch.ones_like(real, dtype=torch.bool)
    shifted = _sines([0.5, 1.0, 2.0], [2.0, -1.2, 2.9])  # the same moves, other phases
    faster = _sines([0.65, 1.3, 2.6], [0.0, 0.3, 1.0])  # 30 % faster
    smaller = real * 0.3
    still = torch.zeros_like(real)
    motions = {"same": real, "shifted": shifted, "faster": faster, "smaller": smaller, "still": still}
    loss = {name: float(masked_rhythm_spectrum_loss(m, real, mask, 30.0)) for name, m in motions.items()}
    assert loss["same"] == pytest.approx(0.0, abs=1e-6)
    assert loss["shifted"] < 0.15 * min(loss["faster"], loss["smaller"], loss["still"])
    assert loss["still"] > loss["smaller"] > loss["shifted"]


def test_the_rhythm_loss_is_the_documented_spectral_distance():
    """One component, one window length: the spectral convergence plus the log distance, computed
    with numpy's FFT over Hann windows of the frame-to-frame changes a quarter apart."""
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(1, 65, 1)).cumsum(axis=1), rng.normal(size=(1, 65, 1)).cumsum(axis=1)
    mask = np.ones_like(b, bool)
    got = float(masked_rhythm_spectrum_loss(torch.tensor(a), torch.tensor(b), torch.tensor(mask), 30.0, ffts=(32,)))
    n, hop, top = 32, 8, int(6.0 * 32 / 30.0) + 1
    window = 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(n) / n)  # periodic Hann

    def spectra(x):
        d = np.diff(x[0, :, 0])
        return np.abs(np.array([np.fft.rfft(d[s : s + n] * window) for s in range(0, d.size - n + 1, hop)]))[:, 1:top]

    X, Y = spectra(a), spectra(b)
    floor = 1e-2 * Y.mean() + 1e-8
    expected = np.linalg.norm(X - Y) / np.linalg.norm(Y) + np.abs(np.log(X + floor) - np.log(Y + floor)).mean()
    assert got == pytest.approx(expected, rel=1e-5)


def _itakura_saito(real, made):
    ratio = real / made
    return 2.0 * (ratio - np.log(ratio) - 1.0)


def test_the_energy_loss_is_the_itakura_saito_divergence_of_mean_squared_changes():
    real = _sines([0.5, 1.0], [0.0, 0.5])
    mask = torch.ones_like(real, dtype=torch.bool)
    twice = float(masked_energy_loss(real * 2.0, real, mask))
    half = float(masked_energy_loss(real * 0.5, real, mask))
    steps = np.diff(real[0].numpy(), axis=0)
    floor = 1e-2 * np.mean(np.mean(steps**2, axis=0))
    ms = np.mean(steps**2, axis=0)
    assert twice == pytest.approx(np.mean(_itakura_saito(ms + floor, 4 * ms + floor)), rel=1e-5)
    assert half == pytest.approx(np.mean(_itakura_saito(ms + floor, ms / 4 + floor)), rel=1e-5)
    assert half > twice  # moving too little costs more than moving too much
    assert float(masked_energy_loss(real, real, mask)) == pytest.approx(0.0, abs=1e-9)
    from kinectdata.models.losses import ENERGY_CHUNK_S, masked_posture_loss

    combined = masked_rhythm_loss(real * 2.0, real, mask, 30.0, weights=RhythmWeights(posture=7.0))
    posture = float(masked_posture_loss(real * 2.0, real, mask))
    assert posture > 0.1  # twice the spread
    chunk = round(ENERGY_CHUNK_S * 30.0)
    in_chunks = float(masked_energy_loss(real * 2.0, real, mask, chunk))
    steps, made_steps = real[:, 1:] - real[:, :-1], 2.0 * (real[:, 1:] - real[:, :-1])
    changes = float(masked_energy_loss(made_steps, steps, mask[:, 1:], chunk))
    assert changes == pytest.approx(in_chunks, rel=0.05)  # sines: their changes are sines as well
    assert float(combined) == pytest.approx(
        float(masked_rhythm_spectrum_loss(real * 2.0, real, mask, 30.0)) + in_chunks + changes + 7.0 * posture,
        rel=1e-6,
    )


def test_the_jitter_loss_costs_an_excess_of_acceleration_and_jerk_in_proportion():
    """Real: smooth sines; made: the same plus a 12 Hz tremor. numpy's divergences of the made mean
    squared second and third differences from the real ones', per 2-s stretch, give the loss; too
    much jitter costs more than as much too little, and the term enters the free-running loss
    times its weight."""
    real = _sines([0.5, 1.0], [0.0, 0.5])
    mask = torch.ones_like(real, dtype=torch.bool)
    tremor = real + _sines([12.0, 12.0], [0.2, 1.1], amplitude=0.01)
    chunk = 60

    def expected(made, target):
        total = 0.0
        for order in (2, 3):
            m, r = (np.diff(x[0].numpy().astype(np.float64), order, axis=0) ** 2 for x in (made, target))
            stretches = [(a, min(a + chunk, len(r))) for a in range(0, len(r), chunk)]
            made_e = np.array([m[a:b].mean(axis=0) for a, b in stretches])
            real_e = np.array([r[a:b].mean(axis=0) for a, b in stretches])
            floor = 1e-2 * real_e.mean()
            ratio = (made_e + floor) / (real_e + floor)
            total += np.mean(2 * (ratio - np.log(ratio) - 1))
        return total

    shaking = float(masked_jitter_loss(tremor, real, mask, chunk))
    assert shaking == pytest.approx(expected(tremor, real), rel=1e-4)
    assert float(masked_jitter_loss(real, real, mask, chunk)) == pytest.approx(0.0, abs=1e-9)
    smoother = float(masked_jitter_loss(real, tremor, mask, chunk))  # the same ratio the other way round
    assert shaking > 3 * smoother
    with_term = float(masked_rhythm_loss(tremor, real, mask, 30.0, weights=RhythmWeights(jitter=2.0)))
    without = float(masked_rhythm_loss(tremor, real, mask, 30.0))
    assert with_term - without == pytest.approx(2.0 * shaking, rel=1e-4)


def test_where_the_music_cannot_tell_the_energy_loss_is_least_at_the_mean_speed():
    """Windows whose dancers move at unpredictable speeds (amplitudes 0.1 to 2, one per window) and
    one motion made for all of them: the loss is least when its mean squared change is the
    windows' mean (numpy), not their geometric mean, which is 0.42 of it here."""
    amplitudes = torch.tensor([0.1, 0.2, 0.5, 1.0, 2.0])
    shape = _sines([0.5], [0.0])  # [1, 300, 1]
    real = shape * amplitudes[:, None, None]
    mask = torch.ones_like(real, dtype=torch.bool)
    energies = np.mean(np.diff(real[..., 0].numpy(), axis=1) ** 2, axis=1)
    assert np.exp(np.log(energies).mean()) / energies.mean() < 0.5
    scales = np.linspace(0.2, 2.0, 361)
    losses = [float(masked_energy_loss(shape.expand_as(real) * s, real, mask)) for s in scales]
    best = scales[int(np.argmin(losses))]
    made = np.mean(np.diff(shape[0, :, 0].numpy()) ** 2) * best**2
    assert made == pytest.approx(energies.mean(), rel=0.02)


def test_the_periodogram_tells_a_waltz_bar_from_a_cha_cha_bar():
    """Real: a cha-cha's bar (1.92 s); made: a waltz's (2.07 s), or the cha-cha's at another phase.
    The loss equals numpy's transform of the Hann-windowed changes on 1024 points, 0.1-2 Hz; it costs
    the wrong bar many times the wrong phase, far more than the multi-resolution spectra do; and it
    enters the free-running loss times its weight."""
    cha_cha, waltz = 1 / 1.92, 1 / 2.07
    real = _sines([cha_cha, 2 * cha_cha], [0.0, 0.3])
    mask = torch.ones_like(real, dtype=torch.bool)
    other_phase = _sines([cha_cha, 2 * cha_cha], [1.2, 2.0])
    other_bar = _sines([waltz, 2 * waltz], [0.0, 0.3])

    def expected(made, target):
        x, y = (np.diff(v[0].numpy().astype(np.float64), axis=0).T for v in (made, target))
        window = np.hanning(x.shape[1] + 1)[:-1]  # periodic, as torch's
        low, high = int(0.1 * 1024 / 30) + 1, int(2.0 * 1024 / 30) + 1
        X, Y = (np.abs(np.fft.rfft(v * window, n=1024))[:, low:high] for v in (x, y))
        floor = 1e-2 * Y.mean()
        conv = np.linalg.norm(X - Y, axis=1) / np.linalg.norm(Y, axis=1)
        return float(np.mean(conv + np.abs(np.log(X + floor) - np.log(Y + floor)).mean(axis=1)))

    wrong_bar = float(masked_periodogram_loss(other_bar, real, mask, 30.0))
    assert wrong_bar == pytest.approx(expected(other_bar, real), rel=1e-4)
    wrong_phase = float(masked_periodogram_loss(other_phase, real, mask, 30.0))
    spectra = [float(masked_rhythm_spectrum_loss(made, real, mask, 30.0)) for made in (other_bar, other_phase)]
    # the wrong bar costs 36 x the wrong phase here, 4 x in the rhythm spectra's 0.23-Hz bins
    assert wrong_bar / wrong_phase > 20 > 5 > spectra[0] / spectra[1]
    with_term = float(masked_rhythm_loss(other_bar, real, mask, 30.0, weights=RhythmWeights(periodogram=0.5)))
    without = float(masked_rhythm_loss(other_bar, real, mask, 30.0))
    assert with_term - without == pytest.approx(0.5 * wrong_bar, rel=1e-4)


def test_the_rhythm_loss_sees_jitter_the_spectra_below_6_hz_miss():
    """A 10 Hz jitter of 0.002 on sines of 0.3: barely more speed, but the changes between frames change a lot."""
    real = _sines([0.5, 1.0], [0.0, 0.5], amplitude=0.3)
    t = torch.arange(300, dtype=torch.float32) / 30.0
    jitter = real + 0.002 * torch.sin(2 * math.pi * 10.0 * t)[None, :, None]
    mask = torch.ones_like(real, dtype=torch.bool)
    spectrum = float(masked_rhythm_spectrum_loss(jitter, real, mask, 30.0))
    speed = float(masked_energy_loss(jitter, real, mask, 60))
    assert spectrum < 0.05 and speed < 0.1
    assert float(masked_rhythm_loss(jitter, real, mask, 30.0)) > 0.5 > 4 * (spectrum + speed)


def test_the_energy_loss_in_stretches_sees_a_burst_then_stillness():
    """Twice the real speed for the first half of a window, then still: the same mean speed over
    the window (a whole-window loss near 0), but per 60-frame stretch every ratio is off."""
    real = _sines([0.5, 1.0], [0.0, 0.5])
    burst = real.clone()
    burst[:, :150] = real[:, :150] * math.sqrt(2.0)  # changes' squares x2 for half the window
    burst[:, 150:] = burst[:, 149:150]
    mask = torch.ones_like(real, dtype=torch.bool)
    steps_real = np.diff(real[0].numpy(), axis=0) ** 2
    steps_made = np.diff(burst[0].numpy(), axis=0) ** 2
    whole = float(masked_energy_loss(burst, real, mask))
    assert whole < 0.05
    chunks = [(a, min(a + 60, 299)) for a in range(0, 299, 60)]
    made = np.array([steps_made[a:b].mean(axis=0) for a, b in chunks])
    ref = np.array([steps_real[a:b].mean(axis=0) for a, b in chunks])
    floor = 1e-2 * ref.mean()
    expected = np.mean(_itakura_saito(ref + floor, made + floor))
    assert float(masked_energy_loss(burst, real, mask, 60)) == pytest.approx(expected, rel=1e-4)
    assert expected > 1.0


def test_the_rhythm_loss_leaves_out_components_invalid_anywhere_in_the_window():
    real = _sines([0.5, 1.0], [0.0, 0.0])
    wrong = real.clone()
    wrong[..., 1] = 0.0  # component 1 stands still
    mask = torch.ones_like(real, dtype=torch.bool)
    assert float(masked_rhythm_spectrum_loss(wrong, real, mask, 30.0)) > 0.5
    mask[0, 10, 1] = False
    assert float(masked_rhythm_spectrum_loss(wrong, real, mask, 30.0)) == pytest.approx(0.0, abs=1e-6)


@pytest.mark.slow
def test_a_run_keeps_its_best_free_running_epoch(sample_dataset, tmp_path):
    run = tmp_path / "r"
    history = train(sample_dataset, run, TrainConfig(**RECIPE))
    with (run / "log.csv").open() as f:
        rows = list(csv.DictReader(f))
    rhythm = [float(r["val_rhythm"]) for r in rows]
    energy = [float(r["val_energy"]) for r in rows]
    assert all(math.isfinite(v) for v in rhythm + energy) and len(rows) == 3
    alive = [i for i in range(3) if 0.5 <= energy[i] <= 2.0] or list(range(3))
    best = min(alive, key=lambda i: rhythm[i])
    assert [r["kept"] for r in rows] == ["best" if i == best else "" for i in range(3)]
    assert [h.get("kept") for h in history] == ["best" if i == best else None for i in range(3)]
    assert read_log(run) == [{k: h.get(k) for k in LOG_FIELDS} for h in history]  # the log reads back whole
    lines = (run / "log.csv").read_text().splitlines()
    lines[2] = ",".join(["2", "two", *lines[2].split(",")[2:]])  # the second epoch's step
    (run / "log.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(KinectDataError, match=r"log.csv, line 3: not a row of a run's log"):
        read_log(run)
    kept = load_checkpoint(run / "model.pt")["model"]
    stored = load_checkpoint(run / "checkpoint.pt")
    assert int(stored["best_epoch"]) == best + 1
    for name, value in kept.items():
        assert torch.equal(value, stored["best_model"][name]), name
    parts = tmp_path / "parts"  # interrupted after its first epoch and resumed: the same kept weights
    train(sample_dataset, parts, TrainConfig(**RECIPE), stop_after=1)
    train(sample_dataset, parts, TrainConfig(**RECIPE), resume=True)
    resumed = load_checkpoint(parts / "model.pt")["model"]
    for name, value in kept.items():
        assert torch.equal(value, resumed[name]), name
    if best != 2:  # the last epoch's weights are the checkpoint's, not the kept ones
        assert any(not torch.equal(kept[k], stored["model"][k]) for k in kept)


def test_an_epoch_that_moves_is_kept_before_a_still_one_with_a_lower_rhythm_loss():
    def epochs(*figures):
        return [{"epoch": i + 1, "val_rhythm": r, "val_energy": e} for i, (r, e) in enumerate(figures)]

    assert not _better(epochs((40.0, 0.9), (15.4, 0.05)))  # nearly still: not kept over a moving epoch
    assert _better(epochs((15.4, 0.05), (40.0, 0.9)))  # the first alive epoch wins whatever its loss
    assert _better(epochs((15.4, 0.05), (40.0, 0.9), (30.0, 1.8)))  # then the lowest loss among the alive
    assert not _better(epochs((15.4, 0.05), (30.0, 0.9), (40.0, 1.1)))
    assert _better(epochs((20.0, 0.05), (15.0, 3.0)))  # none alive yet: the lowest loss, as before
    assert not _better(epochs((20.0, 0.9), (None, None)))  # an epoch without free runs is never kept
    assert _better(epochs((20.0, None), (19.0, None)))  # runs written before val_energy: the loss alone


def test_the_energy_weight_keeps_a_livelier_epoch_of_about_the_lowest_loss():
    def epochs(*figures):
        return [{"epoch": i + 1, "val_rhythm": r, "val_energy": e} for i, (r, e) in enumerate(figures)]

    # 22.25 * exp(0.5 * |ln 0.55|) = 30.0 against 22.7 * exp(0.5 * |ln 0.73|) = 26.6
    assert not _better(epochs((22.25, 0.55), (22.7, 0.73)))
    assert _better(epochs((22.25, 0.55), (22.7, 0.73)), energy_weight=0.5)
    assert not _better(epochs((22.25, 0.55), (40.0, 0.73)), energy_weight=0.5)  # far worse loss: not kept
    # the distance from the real energy counts both ways: 1.6 x is as far as 1 / 1.6 = 0.625 x
    assert not _better(epochs((20.0, 0.625), (20.0, 1.6)), energy_weight=0.5)
    assert _better(epochs((20.0, 1.6), (19.9, 0.625)), energy_weight=0.5)
    assert not _better(epochs((20.0, 0.9), (19.0, 0.05)), energy_weight=0.5)  # the alive rule still first
    assert not _better(epochs((20.0, 0.3), (19.0, 0.0)), energy_weight=0.5)  # a still epoch is never best


@pytest.fixture(scope="module")
def pulse_mel_dataset(tmp_path_factory):
    """The sample sessions with log-mel and pulse inputs and maxabs-normalised 3-D positions: what
    the cdhc model learns real dance from."""
    from kinectdata.dataset.build import build_dataset
    from kinectdata.dataset.config import BuildConfig

    out = tmp_path_factory.mktemp("pulse_mel") / "dataset"
    config = BuildConfig.from_pipeline(
        "listen-to-dance", features="listen_to_dance_rhythm", target="kinect_v2_positions", normalisation="maxabs",
        split_ratios=(1 / 3, 1 / 3, 1 / 3),
    )  # fmt: skip
    build_dataset(REPO / "sample_data", out, config)
    return out


def test_the_cdhc_model_trains_free_too(pulse_mel_dataset, tmp_path):
    config = TrainConfig(
        "cdhc", channels=16, decoder_channels=16, sequence=40, stride=None, batch_size=4, epochs=1, lr=1e-3, context=20,
        free_weight=1.0, silence_share=0.5, keep="best",
    )  # fmt: skip
    history = train(pulse_mel_dataset, tmp_path / "c", config)
    assert math.isfinite(history[0]["train_loss"]) and history[0]["val_rhythm"] is not None


def test_song_starts_train_the_first_seconds_of_each_song(pulse_mel_dataset, tmp_path, monkeypatch):
    """With ``song_starts`` the training windows (not the validation ones) also start up to the
    context before each recording, and such windows are trained on, with the bones' jitter term."""
    import kinectdata.training.train as training
    from kinectdata.dataset.windows import WindowDataset

    leads, early = {}, []

    class Spy(WindowDataset):
        def __init__(self, dataset, split, *args, **kwargs):
            super().__init__(dataset, split, *args, **kwargs)
            leads[split] = kwargs.get("lead", 0)

        def __getitem__(self, i):
            _, row, first = self.windows[i]
            early.append(row < first + 1)
            return super().__getitem__(i)

    monkeypatch.setattr(training, "WindowDataset", Spy)
    config = TrainConfig(
        "cdhc", channels=8, decoder_channels=8, sequence=40, stride=20, batch_size=4, epochs=1, context=20,
        song_starts=True, bone_jitter_weight=1.0,
    )  # fmt: skip
    history = train(pulse_mel_dataset, tmp_path / "c", config)
    assert math.isfinite(history[0]["train_loss"])
    assert leads == {"train": 20, "val": 0} and any(early)
    written = json.loads((tmp_path / "c" / "config.json").read_text())
    assert written["train"]["song_starts"] is True
    assert written["model"]["start_silence"] == 20  # generation hears the silence the windows had


def test_a_run_resumed_keeps_the_network_it_was_started_with(pulse_mel_dataset, tmp_path, monkeypatch):
    """A song-start run written before generation heard the silence (here: the hook switched off for
    its first epoch) keeps generating without it when resumed: the network config is the checkpoint's."""
    kind = type(model_kind("cdhc"))
    config = TrainConfig(
        "cdhc", channels=8, decoder_channels=8, sequence=40, stride=20, batch_size=4, epochs=2, context=20
    )
    with monkeypatch.context() as patch:
        patch.setattr(kind, "with_song_starts", lambda self, model, lead: model)
        train(pulse_mel_dataset, tmp_path / "r", config, stop_after=1)
    assert json.loads((tmp_path / "r" / "config.json").read_text())["model"].get("start_silence", 0) == 0
    history = train(pulse_mel_dataset, tmp_path / "r", resume=True)
    assert len(history) == 2
    assert json.loads((tmp_path / "r" / "config.json").read_text())["model"].get("start_silence", 0) == 0
    train(pulse_mel_dataset, tmp_path / "new", config, stop_after=1)  # config.json is written before epoch 1
    assert json.loads((tmp_path / "new" / "config.json").read_text())["model"]["start_silence"] == 20


@pytest.mark.slow
def test_the_songs_metre_reaches_the_features_at_build_and_at_generate(tmp_path):
    """With the bar levels in the song's metre (``listen_to_dance_rhythm_bars``), the sample songs say
    no metre: the build estimates each (the synthesized music is in 4) and records it; generate
    estimates the song's, or takes the one it is given, and the bar levels then differ (3 beats
    against 4) while the rest of the input does not. Without bar levels nothing is recorded."""
    from kinectdata.dataset.build import build_dataset
    from kinectdata.dataset.config import BuildConfig
    from kinectdata.features import compute_features, feature_config
    from kinectdata.inference.generate import generate

    build = BuildConfig.from_pipeline(
        "listen-to-dance", features="listen_to_dance_rhythm_bars", target="kinect_v2_positions",
        normalisation="maxabs", split_ratios=(1 / 3, 1 / 3, 1 / 3),
    )  # fmt: skip
    manifest = build_dataset(REPO / "sample_data", tmp_path / "d", build)
    assert {json.dumps(r["metre"]) for r in manifest["recordings"]} == {'{"beats_per_bar": 4, "source": "estimated"}'}
    config = TrainConfig("cdhc", channels=8, decoder_channels=8, sequence=40, stride=None, batch_size=4, epochs=1)
    train(tmp_path / "d", tmp_path / "r", config)
    song = REPO / "sample_data" / "synth_001.flac"
    _, estimated = generate(tmp_path / "r", song)
    assert estimated["metre"].startswith("4 beats per bar (estimated;")
    given = CliRunner().invoke(
        main,
        ["generate", "--run", str(tmp_path / "r"), str(song), "-o", str(tmp_path / "g.csv"), "--beats-per-bar", "3"],
    )
    assert given.exit_code == 0 and "metre: 3 beats per bar (given)" in given.output, given.output
    features = feature_config(manifest["config"]["features"])
    audio = np.random.default_rng(0).normal(0, 0.1, 16000 * 14).astype(np.float32)
    starts = np.arange(0, audio.size - 534, 534)
    in3, in4 = (compute_features(audio, starts, features, beats_per_bar=b)[0] for b in (3, 4))
    differs = np.flatnonzero(np.abs(in3 - in4).max(axis=0) > 0)
    assert differs.size and differs.min() >= 153 - 4  # only the bar and two-bar phasors
    with pytest.raises(ConfigError, match="beats_per_bar must be at least 1"):
        compute_features(audio, starts, features, beats_per_bar=0)


def test_the_cdhc_models_context_is_as_far_back_as_an_output_sees(pulse_mel_dataset):
    from kinectdata.models.registry import model_kind

    kind = model_kind("cdhc")
    manifest = json.loads((pulse_mel_dataset / "manifest.json").read_text())
    config = TrainConfig("cdhc", channels=8, decoder_channels=8)
    assert config.context is None  # the model's own
    network = kind.network_config(config.settings, manifest)
    context = kind.context_frames(network)
    assert context == kind.context_frames(kind.network_config(TrainConfig("cdhc").settings, manifest)) == 264
    net = kind.build(network).eval()
    torch.manual_seed(0)
    audio = torch.randn(1, 400, manifest["feature_shape"][0])
    previous = torch.randn(1, 400, manifest["target_dim"])
    last = 399
    with torch.no_grad():
        base = net(audio, previous)[0, last]

        def seen(lag):  # does output `last` change when the inputs `lag` frames before it change?
            moved_audio, moved_previous = audio.clone(), previous.clone()
            moved_audio[0, last - lag] += 5.0
            moved_previous[0, last - lag] += 5.0
            return not torch.allclose(net(moved_audio, moved_previous)[0, last], base)

        assert seen(context) and not seen(context + 1)
    assert model_kind("yalta").context_frames({}) == 0


def test_the_cdhc_recipe_trains_on_the_free_run_it_will_dance(pulse_mel_dataset):
    """No dropout by default: the free run the rhythm loss sees in training is the one generation
    makes (with dropout's noise the training free run moved and the evaluated one stood still)."""
    from kinectdata.models.registry import model_kind

    kind = model_kind("cdhc")
    manifest = json.loads((pulse_mel_dataset / "manifest.json").read_text())
    torch.manual_seed(0)
    audio = torch.randn(2, 80, manifest["feature_shape"][0])
    previous = torch.randn(2, 80, manifest["target_dim"])
    for paper, same in ((False, True), (True, False)):
        config = TrainConfig.for_model("cdhc", paper=paper, channels=8, decoder_channels=8)
        net = kind.build(kind.network_config(config.settings, manifest))
        with torch.no_grad():
            training = kind.predict_free(net.train(), audio, previous, config.settings)[1]
            generating = kind.predict_free(net.eval(), audio, previous, config.settings)[1]
        assert torch.equal(training, generating) is same, paper


def test_the_losses_do_not_count_the_context_frames(pulse_mel_dataset):
    from kinectdata.dataset.windows import WindowDataset
    from kinectdata.models.registry import model_kind
    from kinectdata.training.train import validate

    config = TrainConfig("cdhc", channels=8, decoder_channels=8, sequence=40, batch_size=4, context=25)
    kind = model_kind("cdhc")
    manifest = json.loads((pulse_mel_dataset / "manifest.json").read_text())
    torch.manual_seed(0)
    net = kind.build(kind.network_config(config.settings, manifest))
    windows = WindowDataset(pulse_mel_dataset, "val", 65, 40, verify=False)
    clean = validate(net, windows, config, torch.device("cpu"), context=25)

    class Spoiled(WindowDataset):  # other poses in the context frames: what the losses must not see
        def __getitem__(self, i):
            item = super().__getitem__(i)
            item["pose"][:25] = 0.123
            return item

    spoiled = Spoiled(pulse_mel_dataset, "val", 65, 40, verify=False)
    assert validate(net, spoiled, config, torch.device("cpu"), context=25) == pytest.approx(clean, rel=1e-6)
    assert validate(net, spoiled, config, torch.device("cpu"), context=0)[0] != pytest.approx(
        validate(net, windows, config, torch.device("cpu"), context=0)[0], rel=1e-3
    )


def test_windows_too_short_for_the_context_are_refused_naming_both(pulse_mel_dataset, tmp_path):
    config = TrainConfig("cdhc", channels=8, decoder_channels=8, sequence=400, epochs=1, song_starts=False)
    with pytest.raises(KinectDataError, match=r"no training window of 664 frames \(400 \+ 264 of context\)"):
        train(pulse_mel_dataset, tmp_path / "r", config)
    from kinectdata.dataset.windows import WindowDataset

    # with song starts (the default) the same recordings give windows whose context runs before them
    led = WindowDataset(pulse_mel_dataset, "train", 664, 75, verify=False, lead=264)
    assert len(led) > 0 and all(row < first + 1 for _, row, first in led.windows)


def test_a_model_that_cannot_run_free_in_training_is_refused():
    from kinectdata.models.kind import ModelKind
    from kinectdata.models.registry import MODELS

    class Rigid(ModelKind):
        name = "rigid-test"
        settings_type = type(TrainConfig().settings)

    MODELS["rigid-test"] = Rigid()
    try:
        with pytest.raises(ConfigError, match="the rigid-test model cannot run free in training"):
            TrainConfig("rigid-test", free_weight=1.0)
        assert TrainConfig("rigid-test", free_weight=0.0).free_weight == 0.0
    finally:
        del MODELS["rigid-test"]


@pytest.mark.parametrize(
    ("setting", "value"),
    [
        ("free_weight", -1.0),
        ("silence_share", 1.5),
        ("keep", "first"),
        ("context", -3),
        ("bone_jitter_weight", -0.5),
        ("span_weight", -0.5),
        ("repetition_weight", -1.0),
        ("song_starts", "yes"),
    ],
)
def test_bad_recipe_settings_are_refused(setting, value):
    with pytest.raises(ConfigError, match=setting):
        TrainConfig(**{setting: value})


def test_the_bone_loss_measures_stretch_as_a_share_of_the_bone():
    """Two joints, one bone: the real bone is 0.5 m long throughout; the prediction's swings between
    0.4 and 0.6 m (normalised by maxabs-like scales): the loss is its mean |length - 0.5| / 0.5."""
    from kinectdata.models.losses import masked_bone_loss

    frames = 20
    lengths = np.where(np.arange(frames) % 2 == 0, 0.4, 0.6)
    scale = torch.tensor([2.0, 1.0, 3.0, 2.0, 1.0, 3.0])
    offset = torch.tensor([0.1, 0.0, -0.2, 0.1, 0.0, -0.2])
    real = np.zeros((1, frames, 6))
    real[0, :, 4] = 0.5  # joint 1 half a metre above joint 0
    made = real.copy()
    made[0, :, 4] = lengths
    normalise = lambda x: (torch.tensor(x, dtype=torch.float32) - offset) * scale  # noqa: E731
    mask = torch.ones(1, frames, 6, dtype=torch.bool)
    got = float(masked_bone_loss(normalise(made), normalise(real), mask, [(1, 0)], scale, offset))
    assert got == pytest.approx(np.mean(np.abs(lengths - 0.5)) / 0.5, abs=1e-6)
    mask[0, 3, 5] = False  # a bone invalid somewhere in the window is not counted
    assert float(masked_bone_loss(normalise(made), normalise(real), mask, [(1, 0)], scale, offset)) == 0.0


def test_the_bone_jitter_loss_costs_bones_changing_length_fast_not_bones_moving():
    """Two joints, one bone, normalised as the targets are. The real bone's length alternates
    0.50 / 0.51 m; a motion whose bone alternates 0.50 / 0.52 m changes its length twice as fast
    (four times the mean squared change): numpy's Itakura-Saito divergence turned round, per 2-s
    stretch, with the 1 % floor, gives the loss. Joints that swing through the room on rigid bones
    cost nothing (where the coordinates' jitter term costs them), and the term enters the
    free-running loss times its weight."""
    from kinectdata.models.losses import Body, masked_bone_jitter_loss

    frames, chunk = 120, 60
    scale = torch.tensor([2.0, 1.0, 3.0, 2.0, 1.0, 3.0])
    offset = torch.tensor([0.1, 0.0, -0.2, 0.1, 0.0, -0.2])
    normalise = lambda x: (torch.tensor(x, dtype=torch.float32) - offset) * scale  # noqa: E731

    def bone(lengths, swing=0.0):  # joint 0 sways along x; joint 1 above it by `lengths`
        x = np.zeros((1, frames, 6))
        x[0, :, 0] = x[0, :, 3] = swing * np.sin(np.arange(frames) / 3.0)
        x[0, :, 4] = lengths
        return x

    alternate = np.arange(frames) % 2
    real, made = bone(0.50 + 0.01 * alternate), bone(0.50 + 0.02 * alternate)
    mask = torch.ones(1, frames, 6, dtype=torch.bool)
    got = float(masked_bone_jitter_loss(normalise(made), normalise(real), mask, [(1, 0)], scale, offset, chunk=chunk))
    real_e = np.full(2, 0.01**2)  # every change +-1 cm, in both stretches (60 and 59 changes)
    made_e = np.full(2, 0.02**2)
    floor = 1e-2 * real_e.mean()
    ratio = (made_e + floor) / (real_e + floor)
    assert got == pytest.approx(np.mean(2 * (ratio - np.log(ratio) - 1)), rel=1e-3)
    assert got > 1.0

    rigid, still = bone(np.full(frames, 0.5), swing=0.4), bone(np.full(frames, 0.5))
    moving = masked_bone_jitter_loss(normalise(rigid), normalise(still), mask, [(1, 0)], scale, offset, chunk=chunk)
    assert float(moving) == pytest.approx(0.0, abs=1e-6)
    assert float(masked_jitter_loss(normalise(rigid), normalise(still), mask, chunk)) > 1.0

    body = Body(bones=[(1, 0)], scale=scale, offset=offset)
    with_term = float(
        masked_rhythm_loss(normalise(made), normalise(real), mask, 30.0, body, RhythmWeights(bone_jitter=3.0))
    )
    without = float(masked_rhythm_loss(normalise(made), normalise(real), mask, 30.0, body))
    assert with_term - without == pytest.approx(3.0 * got, rel=1e-4)


def test_position_bones_leave_out_the_root_when_it_is_centred():
    from kinectdata.core.jointsets import load_joint_set
    from kinectdata.targets.specs import generic_target

    spec = generic_target("positions", load_joint_set("tang2018"))
    names = spec.positions
    everything = {(names[c], names[p]) for c, p in spec.position_bones()}
    centred = {(names[c], names[p]) for c, p in spec.position_bones(root_centred=True)}
    assert ("spine", "pelvis") in everything and ("spine", "pelvis") not in centred
    assert everything - centred == {(j, "pelvis") for j in ("spine",)}
    assert ("right_knee", "right_hip") in centred and len(everything) == 24


def test_the_posture_loss_compares_means_and_spreads_not_timing():
    """Known answers: the same motion late by a quarter period costs nothing; a copy moved by 0.3
    costs 0.3; a still copy costs its spread (the std of a sine of amplitude a is a / sqrt(2));
    frames masked out do not count."""
    from kinectdata.models.losses import masked_posture_loss

    t = torch.arange(300, dtype=torch.float32) / 30.0
    real = (0.5 * torch.sin(2 * np.pi * t))[None, :, None].repeat(1, 1, 2)  # whole periods: mean 0
    mask = torch.ones_like(real, dtype=torch.bool)
    late = (0.5 * torch.cos(2 * np.pi * t))[None, :, None].repeat(1, 1, 2)
    assert float(masked_posture_loss(late, real, mask)) == pytest.approx(0.0, abs=1e-4)
    assert float(masked_posture_loss(real + 0.3, real, mask)) == pytest.approx(0.3, abs=1e-5)
    still = torch.zeros_like(real)
    assert float(masked_posture_loss(still, real, mask)) == pytest.approx(0.5 / np.sqrt(2), abs=1e-3)
    wild = real.clone()
    wild[:, 150:] = 100.0
    mask[:, 150:] = False
    assert float(masked_posture_loss(wild, real, mask)) == pytest.approx(
        float(masked_posture_loss(real[:, :150], real[:, :150], mask[:, :150])), abs=1e-6
    )


def test_a_run_with_mirrored_windows_resumes_exactly_and_a_target_with_orientations_is_refused(
    pulse_mel_dataset, sample_dataset, tmp_path, monkeypatch
):
    """Every training batch goes through the mirror at the share asked; its draws are restored on
    resume (their own generator, in the checkpoint); a dataset whose targets hold orientations is
    refused before anything is written."""
    import kinectdata.training.train as training

    shares = []

    def counted(batch, mirror, share, generator):
        shares.append(share)
        return mirror_windows(batch, mirror, share, generator)

    monkeypatch.setattr(training, "mirror_windows", counted)
    config = TrainConfig(
        "cdhc", channels=8, decoder_channels=8, sequence=40, batch_size=4, epochs=2, context=20, mirror_share=0.5
    )
    whole = train(pulse_mel_dataset, tmp_path / "whole", config)
    assert len(shares) == whole[-1]["step"] and set(shares) == {0.5}
    train(pulse_mel_dataset, tmp_path / "part", config, stop_after=1)
    resumed = train(pulse_mel_dataset, tmp_path / "part", resume=True)
    assert [r["train_loss"] for r in resumed] == [r["train_loss"] for r in whole]
    with pytest.raises(ConfigError, match="target 'yalta65': only positions and limb lengths can be mirrored"):
        train(sample_dataset, tmp_path / "refused", TrainConfig(**{**TINY_TRAINING, "mirror_share": 0.5}))
    assert not (tmp_path / "refused").exists()


def test_each_training_weight_reaches_its_own_term_of_the_free_running_loss():
    """``TrainConfig.rhythm_weights`` hands each ``*_weight`` to its own term: raising one weight by
    1.7 raises the loss by 1.7 times that term, computed here by the term's own function."""
    from kinectdata.models import losses

    rng = np.random.default_rng(5)
    fps, frames, joints = 30.0, 96, 4
    real = torch.from_numpy(rng.normal(0, 0.3, (2, frames, 3 * joints)).astype(np.float32))
    made = torch.from_numpy(rng.normal(0, 0.45, (2, frames, 3 * joints)).astype(np.float32))  # its feet slide more
    mask = torch.ones_like(real, dtype=torch.bool)
    scale, offset = torch.full((3 * joints,), 0.5), torch.zeros(3 * joints)
    feet = torch.zeros(4, joints)
    feet[0, 2] = feet[1, 2] = feet[2, 3] = feet[3, 3] = 1.0  # left ankle and foot: joint 2; right: joint 3
    body = losses.Body(bones=[(1, 0), (2, 1), (3, 0)], scale=scale, offset=offset, feet=feet, root=0)
    chunk = max(1, round(losses.ENERGY_CHUNK_S * fps))
    terms = {
        "posture": lambda: losses.masked_posture_loss(made, real, mask),
        "jitter": lambda: losses.masked_jitter_loss(made, real, mask, chunk),
        "periodogram": lambda: losses.masked_periodogram_loss(made, real, mask, fps),
        "low_energy": lambda: losses.masked_low_band_energy_loss(made, real, mask, fps, chunk),
        "bone_jitter": lambda: losses.masked_bone_jitter_loss(
            made, real, mask, body.bones, scale, offset, body.dims, chunk
        ),
        "span": lambda: losses.masked_span_loss(made, real, mask, body.bones, scale, offset, body.dims),
        "bend": lambda: losses.masked_bend_loss(made, real, mask, body.bones, scale, offset, body.dims),
        "repetition": lambda: losses.masked_repetition_loss(made, real, mask, body, fps),
        "world_excess": lambda: losses.masked_world_speed_loss(made, real, mask, body, chunk, excess=True),
        "world_jitter": lambda: losses.masked_world_jitter_loss(made, real, mask, body, chunk),
        "root_band": lambda: losses.masked_root_band_loss(made, real, mask, body, fps),
        "root_rise": lambda: losses.masked_root_rise_loss(made, real, mask, body, fps),
        "root_phase": lambda: losses.masked_root_phase_loss(made, real, mask, body, fps),
        "step": lambda: losses.masked_step_loss(made, real, mask, body),
        "bone": lambda: losses.masked_bone_loss(made, real, mask, body.bones, scale, offset, body.dims),
        "world_speed": lambda: losses.masked_world_speed_loss(made, real, mask, body, chunk),
        "foot": lambda: losses.masked_foot_loss(made, real, mask, feet, scale, offset, 0),
    }
    assert set(terms) == {f.name for f in dataclasses.fields(RhythmWeights)}
    config = TrainConfig.for_model("cdhc")
    for name, term in terms.items():
        base = config.replace(**{f"{name}_weight": 0.0})
        raised = config.replace(**{f"{name}_weight": 1.7})
        assert getattr(raised.rhythm_weights, name) == 1.7
        gained = masked_rhythm_loss(made, real, mask, fps, body, raised.rhythm_weights) - masked_rhythm_loss(
            made, real, mask, fps, body, base.rhythm_weights
        )
        assert float(term()) > 1e-3, name  # each term is awake on these windows
        assert float(gained) == pytest.approx(1.7 * float(term()), rel=1e-4), name
