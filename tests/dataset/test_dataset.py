"""build-dataset: features against an independent computation, targets, splits, shards, resume,
determinism, inputs, windows, inspect."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import h5py
import numpy as np
import pytest
from conftest import REPO
from helpers import YALTA_ORIENTATIONS, YALTA_POSITIONS, skip_unless_installed
from scipy import signal
from scipy.spatial.transform import Rotation

from kinectdata.align.audio import load_audio
from kinectdata.align.recipe import align_files
from kinectdata.core.errors import FormatError, KinectDataError, SchemaError
from kinectdata.dataset import build as build_module
from kinectdata.dataset.build import build_dataset
from kinectdata.dataset.inputs import assign_splits, read_recordings
from kinectdata.dataset.inspect import inspect
from kinectdata.dataset.prepare import BuildConfig
from kinectdata.dataset.shards import read_index, validate_shard
from kinectdata.features.stft import PRESETS
from kinectdata.targets.normalization import Normalizer
from kinectdata.targets.specs import extract_targets, load_target_spec

SAMPLES = REPO / "sample_data"


def config(**kw) -> BuildConfig:
    return BuildConfig(features=PRESETS["yalta2016"].to_dict(), target=load_target_spec("yalta65").to_dict(), **kw)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("ds") / "samples"
    manifest = build_dataset(SAMPLES, out, config())
    return out, manifest


def _files_bytes(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def _reference_features(audio: np.ndarray, start: int) -> np.ndarray:
    """Per-slice STFT written independently of the library: scipy.signal.stft on the 534-sample slice,
    log power floored 80 dB under each frame's peak, min-max into 0.1..0.9 per frame."""
    piece = np.zeros(534)
    available = audio[start : start + 534]
    piece[: available.size] = available
    _, _, z = signal.stft(
        piece[:480],
        window=("hamming"),
        nperseg=160,
        noverlap=80,
        nfft=256,
        boundary=None,
        padded=False,
        detrend=False,
        return_onesided=True,
    )
    out = np.empty((129, 5))
    for i in range(5):
        frame = piece[80 * i : 80 * i + 160]
        power_db = 10 * np.log10(np.abs(z[:, i]) ** 2 + 1e-300)
        power_db = np.maximum(power_db, power_db.max() - 80.0)
        lo, hi = power_db.min(), power_db.max()
        silent = 10 * np.log10(np.mean(frame**2) + 1e-300) < -60.0 or hi == lo
        out[:, i] = 0.1 if silent else 0.1 + 0.8 * (power_db - lo) / (hi - lo)
    return out


def test_inputs_equal_an_independent_per_slice_stft(dataset):
    out, manifest = dataset
    rec = next(r for r in manifest["recordings"] if r["name"] == "synth_003")
    aligned = align_files(SAMPLES / "synth_003.csv", SAMPLES / "synth_003.flac", offset=rec["offset"]["seconds"])
    first = round(aligned.summary["audio_trimmed_start_s"] * 16000)
    audio = load_audio(SAMPLES / "synth_003.flac").samples.astype(np.float64)
    with h5py.File(out / rec["shard"], "r") as f:
        rows = f["input"][rec["start"] : rec["start"] + rec["frames"]]
    assert rows.shape == (rec["frames"], 1, 129, 5) and rows.dtype == np.float32
    for k in list(range(0, rec["frames"], 37)) + [rec["frames"] - 1]:
        ref = _reference_features(audio, first + round(k * 16000 / 30))
        np.testing.assert_allclose(rows[k, 0], ref, atol=1e-4, err_msg=f"frame {k}")


def test_targets_are_the_normalised_aligned_motion_and_invert_exactly(dataset):
    out, manifest = dataset
    rec = next(r for r in manifest["recordings"] if r["name"] == "synth_001")
    aligned = align_files(SAMPLES / "synth_001.csv", SAMPLES / "synth_001.flac", offset=rec["offset"]["seconds"])
    spec = load_target_spec("yalta65")
    values, mask = extract_targets(aligned.motion, spec)
    norm = Normalizer.from_dict(manifest["normalisation"])
    with h5py.File(out / rec["shard"], "r") as f:
        current = f["current"][rec["start"] : rec["start"] + rec["frames"]]
        stored_mask = f["mask"][rec["start"] : rec["start"] + rec["frames"]]
    np.testing.assert_array_equal(stored_mask, mask)
    back = norm.invert(current, spec, mask=stored_mask)
    np.testing.assert_allclose(back[:, :9], values[:, :9], atol=1e-5)  # positions, metres
    q = back[:, 9:].reshape(len(back), 14, 4)
    sign = np.array([-1.0 if j in rec["flipped_orientations"] else 1.0 for j in YALTA_ORIENTATIONS])
    np.testing.assert_allclose(q, values[:, 9:].reshape(q.shape) * sign[:, None], atol=1e-5)  # hemisphere
    ok = stored_mask[:, 9::4]
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1)[ok], 1.0, atol=1e-6)
    same = Rotation.from_quat(q[ok]).as_matrix()  # the same rotations whatever the sign
    np.testing.assert_allclose(same, Rotation.from_quat(values[:, 9:].reshape(q.shape)[ok]).as_matrix(), atol=1e-5)


def test_train_targets_fill_the_range_and_inputs_lie_in_0_1_to_0_9(dataset):
    out, manifest = dataset
    train = [s for s in manifest["shards"] if s["split"] == "train"]
    with h5py.File(out / train[0]["file"], "r") as f:
        current, mask, inputs = f["current"][()], f["mask"][()], f["input"][()]
    assert np.abs(current[mask]).max() == pytest.approx(0.9, abs=1e-6)
    assert inputs.min() >= 0.1 - 1e-6 and inputs.max() <= 0.9 + 1e-6
    assert train[0]["targets_out_of_range"] == 0


def test_splits_are_by_recording_and_complete(dataset):
    _, manifest = dataset
    seen = {}
    for r in manifest["recordings"]:
        assert seen.setdefault(r["recording"], r["split"]) == r["split"]
    assert sorted(seen) == ["synth_001", "synth_002", "synth_003"]
    assert manifest["splits"]["train"]["rows"] + manifest["splits"]["test"]["rows"] == manifest["totals"]["rows"]


def test_shards_validate_and_index_their_recordings(dataset):
    out, manifest = dataset
    for shard in manifest["shards"]:
        sizes = validate_shard(out / shard["file"])
        assert sizes["D"] == 65 and sizes["N"] == shard["frames"]
        with h5py.File(out / shard["file"], "r") as f:
            index = read_index(f)
            assert f.attrs["split"] == shard["split"]
            assert json.loads(f.attrs["target_spec"])["name"] == "yalta65"
        assert [r["length"] for r in index] == [
            r["frames"] for r in manifest["recordings"] if r["shard"] == shard["file"]
        ]
        info = index[0]["info"]
        assert set(info["sources"]) == {f"{index[0]['name']}.csv", f"{index[0]['name']}.flac"}
        assert info["offset"]["source"] == "clap"


def test_build_is_deterministic_and_a_rerun_is_a_no_op(dataset, tmp_path):
    out, manifest = dataset
    again = build_dataset(SAMPLES, tmp_path / "again", config())
    assert again == manifest
    assert _files_bytes(tmp_path / "again") == _files_bytes(out)
    assert build_dataset(SAMPLES, tmp_path / "again", config()) == manifest  # complete: nothing recomputed


def test_interrupted_build_leaves_no_shard_and_resumes_to_the_same_bytes(dataset, tmp_path, monkeypatch):
    out, _ = dataset
    target = tmp_path / "interrupted"
    real, calls = build_module._prepare, []

    def interrupt_on_second(task):
        calls.append(task[0].name)
        if len(calls) == 2:
            raise KeyboardInterrupt  # as a user's Ctrl-C in the middle of the build
        return real(task)

    monkeypatch.setattr(build_module, "_prepare", interrupt_on_second)
    with pytest.raises(KeyboardInterrupt):
        build_dataset(SAMPLES, target, config())
    assert not (target / "manifest.json").exists() and not list(target.glob("*.h5"))
    assert [p.name for p in (target / ".work").glob("*.h5")] == ["synth_001.h5"]
    assert not list(target.rglob("*.partial"))
    monkeypatch.setattr(build_module, "_prepare", real)
    resumed = []
    monkeypatch.setattr(build_module, "prepare_recording", _spy(build_module.prepare_recording, resumed))
    build_dataset(SAMPLES, target, config())
    assert _files_bytes(target) == _files_bytes(out)
    assert not (target / ".work").exists()


def _spy(fn, calls):
    def wrapped(entry, *a, **kw):
        calls.append(entry.name)
        return fn(entry, *a, **kw)

    return wrapped


def test_killed_build_process_resumes_to_the_same_bytes(dataset, tmp_path):
    out, _ = dataset
    target = tmp_path / "killed"
    cmd = [sys.executable, "-m", "kinectdata", "build-dataset", str(SAMPLES), "-o", str(target)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        for _ in range(2000):  # kill -9 as soon as the first recording is prepared
            if list((target / ".work").glob("*.h5")) or proc.poll() is not None:
                break
            subprocess.run(["sleep", "0.005"])
        proc.kill()
    finally:
        proc.wait()
    assert not (target / "manifest.json").exists() or proc.returncode == 0
    result = subprocess.run(cmd, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert _files_bytes(target) == _files_bytes(out)
    assert not list(target.rglob("*.partial")) and not (target / ".work").exists()


def test_parallel_build_gives_the_same_bytes(dataset, tmp_path):
    out, _ = dataset
    build_dataset(SAMPLES, tmp_path / "par", config(), jobs=2)
    assert _files_bytes(tmp_path / "par") == _files_bytes(out)


def test_small_shard_size_rolls_over_without_splitting_recordings(tmp_path):
    manifest = build_dataset(SAMPLES, tmp_path / "small", config(shard_size_mb=0.5, split_ratios=(1, 0, 0)))
    train = [s for s in manifest["shards"] if s["split"] == "train"]
    assert len(train) == 3 and [s["recordings"] for s in train] == [1, 1, 1]
    for s in train:
        validate_shard(tmp_path / "small" / s["file"])


def test_augmented_copies_only_in_train_with_the_same_targets(tmp_path):
    manifest = build_dataset(SAMPLES, tmp_path / "aug", config(augment_snr=(5.0, 20.0)))
    names = {r["name"]: r for r in manifest["recordings"]}
    train = manifest["splits"]["train"]["recordings"]
    for rec in train:
        assert f"{rec}~snr5dB" in names and f"{rec}~snr20dB" in names
    test = manifest["splits"]["test"]["recordings"][0]
    assert f"{test}~snr5dB" not in names
    rec = train[0]
    with h5py.File(tmp_path / "aug" / names[rec]["shard"], "r") as f:

        def rows(name):
            r = names[name]
            return f["input"][r["start"] : r["start"] + r["frames"]], f["current"][
                r["start"] : r["start"] + r["frames"]
            ]

        clean, noisy5, noisy20 = rows(rec), rows(f"{rec}~snr5dB"), rows(f"{rec}~snr20dB")
    np.testing.assert_array_equal(clean[1], noisy5[1])
    d5, d20 = np.abs(noisy5[0] - clean[0]).mean(), np.abs(noisy20[0] - clean[0]).mean()
    assert d5 > d20 > 0.001  # louder noise changes the features more


def test_explicit_splits_and_manifest_formats(tmp_path):
    rows = [("synth_001", "train"), ("synth_002", "val"), ("synth_003", "test")]
    (tmp_path / "sessions").mkdir()
    for name, _ in rows:  # under the manifests' folder: their paths are relative to it
        for ext in (".csv", ".flac"):
            shutil.copy(SAMPLES / f"{name}{ext}", tmp_path / "sessions" / f"{name}{ext}")
    lines = ["recording,audio,split,offset"] + [f"sessions/{n}.csv,sessions/{n}.flac,{s},auto" for n, s in rows]
    (tmp_path / "recs.csv").write_text("\n".join(lines) + "\n")
    entries = read_recordings(tmp_path / "recs.csv")
    assert [(e.name, e.split) for e in entries] == rows
    assert [e.recording for e in entries] == [str((tmp_path / "sessions" / f"{n}.csv").resolve()) for n, _ in rows]
    docs = [{"recording": f"sessions/{n}.csv", "audio": f"sessions/{n}.flac", "split": s} for n, s in rows]
    (tmp_path / "recs.json").write_text(json.dumps(docs))
    import yaml

    (tmp_path / "recs.yaml").write_text(yaml.safe_dump({"recordings": docs}))
    for name in ("recs.json", "recs.yaml"):
        assert [(e.name, e.split) for e in read_recordings(tmp_path / name)] == rows
    manifest = build_dataset(tmp_path / "recs.yaml", tmp_path / "ds", config())
    assert {s: v["recordings"] for s, v in manifest["splits"].items()} == {
        "train": ["synth_001"],
        "val": ["synth_002"],
        "test": ["synth_003"],
    }


def test_bad_recordings_manifests_name_the_file_and_record(tmp_path):
    for name in ("a.csv", "a.wav", "b.wav"):
        (tmp_path / name).write_text("x")
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "a.csv").write_text("x")
    bad = tmp_path / "bad.json"
    for doc, expected in [
        ([{"recording": "a.csv", "audio": "a.wav", "split": "training"}], "split"),
        ([{"audio": "a.wav"}], "'recording' is a required property"),
        ([{"recording": "a.csv"}], r"recordings\[0\]: a.csv needs an 'audio'"),
        ([{"recording": "a.csv", "audio": "missing.wav"}], r"recordings\[0\]: audio missing.wav does not exist"),
        (
            [{"recording": "a.csv", "audio": "a.wav"}, {"recording": "b/a.csv", "audio": "b.wav"}],
            r"recordings\[1\]: name 'a' is already used by recordings\[0\]",
        ),
        ([{"recording": "a.csv", "audio": "a.wav", "name": "a~snr5dB"}], "name: 'a~snr5dB' does not match"),
    ]:
        bad.write_text(json.dumps(doc))
        with pytest.raises(SchemaError, match=expected) as err:
            read_recordings(bad)
        assert str(bad) in str(err.value)
    (tmp_path / "bad.yaml").write_text("recordings: [\n  {recording: a.csv\n")
    with pytest.raises(SchemaError, match=r"bad\.yaml.*invalid YAML"):
        read_recordings(tmp_path / "bad.yaml")
    csv_bad = tmp_path / "bad.csv"
    csv_bad.write_text("recording,audio,split\na.csv,a.wav,train\na.csv,b.wav,test,extra\n")
    with pytest.raises(SchemaError, match=r"bad\.csv, line 3: more fields than the header's 3"):
        read_recordings(csv_bad)
    csv_bad.write_text("recording,audio,split\na.csv,a.wav,train\nb/a.csv,b.wav,later\n")
    with pytest.raises(SchemaError, match=r"bad\.csv, line 3: .*split"):
        read_recordings(csv_bad)


def test_drawn_splits_follow_the_seed_and_keep_explicit_ones():
    from kinectdata.dataset.inputs import RecordingEntry

    entries = [RecordingEntry(f"r{i:02d}", "x.csv", "x.wav") for i in range(20)]
    entries[3] = RecordingEntry("r03", "x.csv", "x.wav", split="test")
    a, b = assign_splits(entries, (0.8, 0.1, 0.1), 1), assign_splits(entries, (0.8, 0.1, 0.1), 1)
    assert a == b and a["r03"] == "test"
    counts = {s: sum(v == s for k, v in a.items() if k != "r03") for s in ("train", "val", "test")}
    assert counts == {"train": 15, "val": 2, "test": 2}
    assert assign_splits(entries, (0.8, 0.1, 0.1), 2) != a


def test_folder_of_aligned_files_gives_the_same_inputs(dataset, tmp_path):
    out, manifest = dataset
    aligned = tmp_path / "aligned"
    for name in ("synth_001", "synth_002", "synth_003"):
        align_files(SAMPLES / f"{name}.csv", SAMPLES / f"{name}.flac", aligned / f"{name}.h5")
    other = build_dataset(aligned, tmp_path / "from_aligned", config())
    assert other["splits"] == manifest["splits"]
    for shard in manifest["shards"]:
        with h5py.File(out / shard["file"], "r") as f, h5py.File(tmp_path / "from_aligned" / shard["file"], "r") as g:
            np.testing.assert_array_equal(f["input"][()], g["input"][()])
            np.testing.assert_allclose(f["current"][()], g["current"][()], atol=1e-6)


def test_recording_without_orientations_is_refused_clearly(tmp_path, fixture_csv):
    import soundfile as sf

    sf.write(tmp_path / "Ges01_wavehand.wav", np.zeros(16000 * 7, np.float32), 16000)
    shutil.copy(fixture_csv, tmp_path / "Ges01_wavehand.csv")
    (tmp_path / "recs.json").write_text(
        json.dumps([{"recording": "Ges01_wavehand.csv", "audio": "Ges01_wavehand.wav", "offset": 0.5}])
    )
    with pytest.raises(KinectDataError, match=r"Ges01_wavehand\.csv.*orientation"):
        build_dataset(tmp_path / "recs.json", tmp_path / "ds", config())
    manifest = build_dataset(
        tmp_path / "recs.json",
        tmp_path / "ds",
        config().__class__(
            features=PRESETS["yalta2016"].to_dict(), target=load_target_spec("kinect_v2_positions").to_dict()
        ),
    )
    assert manifest["target_dim"] == 75 and not (tmp_path / "ds" / ".work").exists()


def test_damaged_shards_are_caught(dataset, tmp_path):
    out, manifest = dataset
    shard = tmp_path / "s.h5"
    shutil.copy(out / manifest["shards"][0]["file"], shard)
    with h5py.File(shard, "a") as f:
        del f["mask"]
    with pytest.raises(FormatError, match=r"s\.h5: missing dataset 'mask'"):
        validate_shard(shard)
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    with h5py.File(copy / manifest["shards"][0]["file"], "a") as f:
        f["current"][0, 0] = 0.5
    with pytest.raises(FormatError, match="checksum differs"):
        inspect(copy)


def test_inspect_reports_layout_ranges_and_statistics(dataset):
    out, _ = dataset
    text = inspect(out, components=None)
    assert "input [N, 1, 129, 5] float32" in text and "current [N, 65] float32" in text
    assert "input    min 0.1000  max 0.9000" in text
    assert text.count("SpineBase.qw") == 2  # train and test tables
    assert "out of range: 0 values" in text  # the training split


def test_windows_never_cross_recordings_and_carry_previous_and_next(dataset):
    from kinectdata.dataset.windows import WindowDataset

    out, manifest = dataset
    ds = WindowDataset(out, "train", length=60, stride=25)
    expected = sum(len(range(1, r["frames"] - 60, 25)) for r in manifest["recordings"] if r["split"] == "train")
    assert len(ds) == expected
    rec = next(r for r in manifest["recordings"] if r["split"] == "train")
    with h5py.File(out / rec["shard"], "r") as f:
        current, inputs = f["current"][()], f["input"][()]
    item = ds[1]  # second window of the first recording: frames 26..85
    s = rec["start"] + 26
    np.testing.assert_array_equal(item["pose"].numpy(), current[s : s + 60])
    np.testing.assert_array_equal(item["previous"].numpy(), current[s - 1 : s + 59])
    np.testing.assert_array_equal(item["next"].numpy(), current[s + 1 : s + 61])
    np.testing.assert_array_equal(item["audio"].numpy(), inputs[s : s + 60])
    for (shard, row, _), name in zip(ds.windows, ds.recordings):
        r = next(x for x in manifest["recordings"] if x["name"] == name)
        assert shard == r["shard"] and r["start"] + 1 <= row and row + 60 + 1 <= r["start"] + r["frames"]


def test_led_windows_start_before_a_recording_padded_as_generation_pads(dataset):
    """With a lead of 40 frames, each recording also gets windows from frame -39 (every 25 frames
    while they start before frame 1): their frames before the recording are silence for the model
    (audio zeros, padded) and no pose (masked); from frame 0 on they are the file's rows."""
    from kinectdata.dataset.windows import WindowDataset

    out, manifest = dataset
    plain = WindowDataset(out, "train", length=60, stride=25)
    led = WindowDataset(out, "train", length=60, stride=25, lead=40)
    train = [r for r in manifest["recordings"] if r["split"] == "train"]
    assert len(led) == len(plain) + len(train) * len(range(-39, 1, 25))  # frames -39 and -14
    rec = train[0]
    first = next(i for i, (_, row, start) in enumerate(led.windows) if start == rec["start"])
    with h5py.File(out / rec["shard"], "r") as f:
        current, inputs, mask = f["current"][()], f["input"][()], f["mask"][()]
    for i, begin in ((first, -39), (first + 1, -14)):
        item, ahead = led[i], -begin  # rows of the window before frame 0
        s = rec["start"]
        assert led.windows[i][1] == s + begin
        assert not item["audio"][:ahead].any() and item["padded"][:ahead].all()
        np.testing.assert_array_equal(item["audio"][ahead:].numpy(), inputs[s : s + 60 - ahead])
        assert not item["mask"][:ahead].any() and not item["previous_mask"][: ahead + 1].any()
        np.testing.assert_array_equal(item["pose"][ahead:].numpy(), current[s : s + 60 - ahead])
        np.testing.assert_array_equal(item["mask"][ahead:].numpy(), mask[s : s + 60 - ahead])
        np.testing.assert_array_equal(item["previous"][ahead + 1 :].numpy(), current[s : s + 59 - ahead])
        np.testing.assert_array_equal(item["next"][ahead - 1 :].numpy(), current[s : s + 61 - ahead])
    for lead in (-1, 60):  # a window all before its recording would hold no pose
        with pytest.raises(KinectDataError, match="lead must be at least 0 frames and shorter than the window"):
            WindowDataset(out, "train", length=60, lead=lead)


def test_windows_load_in_worker_processes(dataset):
    import torch

    from kinectdata.dataset.windows import WindowDataset

    out, _ = dataset
    loader = torch.utils.data.DataLoader(WindowDataset(out, "train", length=150), batch_size=4, num_workers=2)
    batch = next(iter(loader))
    assert tuple(batch["audio"].shape) == (4, 150, 1, 129, 5) and tuple(batch["pose"].shape) == (4, 150, 65)


def test_yalta65_targets_against_a_hand_computation(dataset):
    """The 65 values from the aligned motion with plain numpy and scipy: SpineBase, HandLeft,
    HandRight positions and 14 sign-continuous quaternion tracks, each put in the hemisphere of
    the training split's mean rotation of that joint (scipy's Rotation.mean, signed so its largest
    component is positive), scaled by 0.9 / max|x| over the training split."""
    from kinectdata.core.quaternions import make_continuous

    out, manifest = dataset
    pos_joints, q_joints = YALTA_POSITIONS, YALTA_ORIENTATIONS
    raw = {}
    for r in manifest["recordings"]:
        rec = align_files(
            SAMPLES / f"{r['recording']}.csv", SAMPLES / f"{r['recording']}.flac", offset=r["offset"]["seconds"]
        )
        m, js = rec.motion, rec.motion.joint_set
        pos = np.stack([m.positions[:, js.index(j)] for j in pos_joints], 1).reshape(m.n_frames, 9)
        qs, oks = [], []
        for j in q_joints:
            q, ok = m.orientations[:, js.index(j)], m.orientation_mask[:, js.index(j)]
            qs.append(np.where(ok[:, None], make_continuous(np.nan_to_num(q), ok), 0.0))
            oks.append(ok)
        raw[r["name"]] = (np.nan_to_num(pos), np.stack(qs, 1), np.stack(oks, 1), r)
    reference = []
    for k in range(len(q_joints)):
        train = np.concatenate([q[ok[:, k], k] for _, q, ok, r in raw.values() if r["split"] == "train"])
        mean = Rotation.from_quat(train).mean().as_quat()
        reference.append(mean * np.sign(mean[np.argmax(np.abs(mean))]))
    np.testing.assert_allclose(list(manifest["orientation_reference"].values()), reference, atol=1e-6)
    rows = {}
    for name, (pos, q, ok, r) in raw.items():
        sign = np.where(np.einsum("tki,ki->k", q, np.array(reference)) < 0, -1.0, 1.0)
        valid = np.concatenate(
            [
                np.repeat(np.isfinite(pos.reshape(-1, 3, 3)).all(-1) & (pos.reshape(-1, 3, 3) != 0).any(-1), 3, 1),
                np.repeat(ok, 4, 1),
            ],
            1,
        )
        rows[name] = (np.concatenate([pos, (q * sign[:, None]).reshape(len(q), -1)], 1), valid, r)
    train_rows = [v for v, ok, r in rows.values() if r["split"] == "train"]
    train_ok = [ok for v, ok, r in rows.values() if r["split"] == "train"]
    maxabs = np.max(np.abs(np.where(np.concatenate(train_ok), np.concatenate(train_rows), 0)), axis=0)
    for values, ok, r in rows.values():
        with h5py.File(out / r["shard"], "r") as f:
            stored = f["current"][r["start"] : r["start"] + r["frames"]]
        np.testing.assert_allclose(stored[ok], (values * 0.9 / maxabs)[ok], atol=2e-6)
    assert all(r["flipped_orientations"] == [] for r in manifest["recordings"])  # the synthesiser is consistent


def test_a_recording_with_every_quaternion_negated_gives_the_same_dataset(dataset, tmp_path):
    """q and -q are the same rotation: a file storing the other sign must not change the targets."""
    out, manifest = dataset
    samples = tmp_path / "samples"
    shutil.copytree(SAMPLES, samples)
    path = samples / "synth_002.csv"
    lines = path.read_text().splitlines()
    negated = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        cells[5:9] = [f"{-float(c):.6f}" for c in cells[5:9]]
        negated.append(",".join(cells))
    path.write_text("\n".join(negated) + "\n")
    other = build_dataset(samples, tmp_path / "ds", config())
    flipped = {r["name"]: r["flipped_orientations"] for r in other["recordings"]}
    assert flipped["synth_002"] == YALTA_ORIENTATIONS and flipped["synth_001"] == flipped["synth_003"] == []
    assert other["orientation_reference"] == manifest["orientation_reference"]
    for a, b in zip(manifest["shards"], other["shards"]):
        with h5py.File(out / a["file"], "r") as fa, h5py.File(tmp_path / "ds" / b["file"], "r") as fb:
            np.testing.assert_array_equal(fa["current"][()], fb["current"][()])


def test_a_failing_recording_in_a_parallel_build_is_a_clear_error(tmp_path):
    import soundfile as sf

    sf.write(tmp_path / "short.wav", np.zeros(16000, np.float32), 16000)  # 1 s: shorter than the motion
    docs = [
        {"recording": str(SAMPLES / f"synth_00{i}.csv"), "audio": str(SAMPLES / f"synth_00{i}.flac")} for i in (1, 2)
    ]
    docs.append({"recording": str(SAMPLES / "synth_003.csv"), "audio": "short.wav", "offset": 0.0})
    (tmp_path / "recs.json").write_text(json.dumps(docs))
    with pytest.raises(KinectDataError, match=r"recording 'synth_003' of .*recs\.json: .*short\.wav.*covers only"):
        build_dataset(tmp_path / "recs.json", tmp_path / "ds", config(), jobs=2, allow_outside_paths=True)
    assert not (tmp_path / "ds" / "manifest.json").exists()


def test_a_failed_rebuild_keeps_the_previous_dataset(dataset, tmp_path):
    out, manifest = dataset
    copy = tmp_path / "copy"
    shutil.copytree(out, copy)
    (tmp_path / "recs.json").write_text(
        json.dumps([{"recording": str(SAMPLES / "synth_001.csv"), "audio": "nowhere.flac"}])
    )
    with pytest.raises(SchemaError, match="does not exist"):
        build_dataset(tmp_path / "recs.json", copy, config(), allow_outside_paths=True)
    assert _files_bytes(copy) == _files_bytes(out)


def test_cleanup_removes_only_our_own_files(dataset, tmp_path):
    out, manifest = dataset
    target = tmp_path / "mixed"
    shutil.copytree(out, target)
    users = target / "dance-00001.h5"
    shutil.copy(out / manifest["shards"][0]["file"], users)  # the user's own file, shard-like name
    lookalike = target / "val-00007.h5"
    lookalike.write_bytes(b"not ours")
    stale = target / "val-00003.h5"
    shutil.copy(out / manifest["shards"][0]["file"], stale)  # a shard of ours no longer planned
    (target / ".train-00000.h5.abc.partial").write_bytes(b"half")
    build_dataset(SAMPLES, target, config())  # already complete: only the cleanup runs
    assert users.exists() and lookalike.exists() and not stale.exists()
    assert not list(target.glob("*.partial"))


def test_changing_the_configuration_in_the_same_folder_gives_a_fresh_build(dataset, tmp_path):
    out, _ = dataset
    target = tmp_path / "changing"
    shutil.copytree(out, target)
    other = config(normalisation="minmax", seed=3)
    build_dataset(SAMPLES, target, other)
    build_dataset(SAMPLES, tmp_path / "fresh", other)
    assert _files_bytes(target) == _files_bytes(tmp_path / "fresh")


def test_only_val_and_test_or_the_same_files_twice_are_refused(tmp_path):
    rows = [
        {"recording": str(SAMPLES / f"synth_00{i}.csv"), "audio": str(SAMPLES / f"synth_00{i}.flac"), "split": s}
        for i, s in ((1, "val"), (2, "test"))
    ]
    (tmp_path / "a.json").write_text(json.dumps(rows))
    with pytest.raises(KinectDataError, match="no recording is in the train split"):
        build_dataset(tmp_path / "a.json", tmp_path / "ds", config(), allow_outside_paths=True)
    twice = [rows[0] | {"split": "train"}, rows[0] | {"split": "test", "name": "again"}]
    (tmp_path / "b.json").write_text(json.dumps(twice))
    with pytest.raises(KinectDataError, match=r"'synth_001' \(train\) and 'again' \(test\) are the same files"):
        build_dataset(tmp_path / "b.json", tmp_path / "ds", config(), allow_outside_paths=True)


def test_an_edited_schema_file_is_read_again(tmp_path):
    from kinectdata.formats.csv_schema import load_csv_schema

    schema = load_csv_schema("dumpkinectskeleton").document | {"name": "mine"}
    (tmp_path / "mine.json").write_text(json.dumps(schema))
    offset = json.loads((SAMPLES / "synth_001.truth.json").read_text())["offset_s"]  # centimetres hide the clap
    rec = [
        {
            "recording": str(SAMPLES / "synth_001.csv"),
            "audio": str(SAMPLES / "synth_001.flac"),
            "schema": "mine.json",
            "offset": offset,
        }
    ]
    (tmp_path / "recs.json").write_text(json.dumps(rec))
    first = build_dataset(tmp_path / "recs.json", tmp_path / "ds", config(), allow_outside_paths=True)
    schema["position"] = {"columns": ["x", "y", "z"], "unit": "cm"}
    (tmp_path / "mine.json").write_text(json.dumps(schema))
    second = build_dataset(tmp_path / "recs.json", tmp_path / "ds", config(), allow_outside_paths=True)
    assert first["build_key"] != second["build_key"]
    assert second["normalisation"]["scale"][0] == pytest.approx(
        100 * first["normalisation"]["scale"][0]
    )  # cm: 100x smaller


def test_features_must_fit_the_sample_rate_and_frame_rate():
    with pytest.raises(KinectDataError, match="defined at 16000 Hz"):
        config(sample_rate=22050)
    with pytest.raises(KinectDataError, match="at 60 fps a frame is 266.7 samples"):
        config(fps=60.0)


def test_a_stem_that_is_not_a_valid_name_must_be_named(tmp_path):
    for ext in (".csv", ".flac"):
        shutil.copy(SAMPLES / f"synth_001{ext}", tmp_path / f"take~1{ext}")
    with pytest.raises(SchemaError, match=r"take~1\.csv: name 'take~1' may hold only"):
        read_recordings(tmp_path)


def test_inspect_catches_a_manifest_that_misstates_its_shards(dataset, tmp_path):
    out, manifest = dataset
    copy = tmp_path / "lying"
    shutil.copytree(out, copy)
    lie = json.loads((copy / "manifest.json").read_text())
    lie["recordings"][0]["frames"] += 5
    (copy / "manifest.json").write_text(json.dumps(lie))
    with pytest.raises(FormatError, match=r"manifest\.json: its recordings in .* differ from the shard's own index"):
        inspect(copy)


def test_shard_json_attributes_must_describe_the_datasets(dataset, tmp_path):
    out, manifest = dataset
    for key, value, expected in [
        ("target_spec", "{}", "is not a target spec"),
        ("normalisation", "[]", "must hold 'scale' and 'offset'"),
        ("features", "1", "is not a feature configuration"),
    ]:
        shard = tmp_path / f"{key}.h5"
        shutil.copy(out / manifest["shards"][0]["file"], shard)
        with h5py.File(shard, "a") as f:
            f.attrs[key] = value
        with pytest.raises(FormatError, match=expected):
            validate_shard(shard)


def test_inspect_reports_the_training_statistics_behind_the_normalisation(dataset):
    out, manifest = dataset
    text = inspect(out, components=2)
    raw = manifest["normalisation_stats"]
    assert "raw min" in text and f"{raw['min'][0]:10.4f}".strip() in text


def test_inspect_shows_a_dash_for_a_component_masked_in_every_row():
    from kinectdata.dataset.inspect import _Moments, _report, _SplitStats

    st = _SplitStats(rows=3, recordings=1, padded=0, inputs=_Moments(1), targets=_Moments(2), beyond=np.zeros(2, int))
    st.inputs.add(np.array([[0.5], [0.25], [0.0]]))
    st.targets.add(np.array([[0.1, 9.0], [0.3, 9.0], [0.2, 9.0]]), np.array([[True, False]] * 3))
    lines = _report("train", st, ["a.x", "b.qw"], None)
    masked = next(line for line in lines if line.strip().startswith("b.qw"))
    assert masked.split()[1:5] == ["-", "-", "-", "-"] and "inf" not in " ".join(lines)
    seen = next(line for line in lines if line.strip().startswith("a.x"))
    assert [float(v) for v in seen.split()[1:3]] == [0.1, 0.3]


def _entries(n: int, split: str | None = None):
    from types import SimpleNamespace

    return [SimpleNamespace(name=f"r{i:02d}", split=split) for i in range(n)]


def test_split_counts_are_what_assign_splits_draws():
    from kinectdata.dataset.inputs import split_counts

    for ratios in [(0.8, 0.1, 0.1), (0.6, 0.2, 0.2), (1, 1, 1), (1, 0, 0), (0.5, 0, 0.5)]:
        for n in range(1, 25):
            drawn = list(assign_splits(_entries(n), ratios, seed=3).values())
            assert split_counts(n, ratios) == tuple(drawn.count(s) for s in ("train", "val", "test"))


@pytest.mark.parametrize(
    ("n", "empty", "lost"),
    [(3, "val", "training has no validation loss"), (6, "test", "evaluate has no recordings to score")],
)
def test_the_empty_split_warning_names_the_split_and_what_to_change(n, empty, lost):
    from kinectdata.dataset.build import empty_split_message

    ratios = (0.8, 0.1, 0.1)
    entries = _entries(n)
    splits = assign_splits(entries, ratios, seed=0)
    assert empty not in splits.values()
    said = empty_split_message("recs.yaml", entries, splits, ratios)
    assert said.startswith(f"recs.yaml: {n} recordings drawn at split ratios (0.8, 0.1, 0.1) leave the {empty} split")
    assert f"({lost}): add recordings (8 or more drawn at these ratios fill every split), change --split-ratios" in said
    # the 8 is right: from 8 recordings on every split gets one, and 7 leave one empty
    for m in range(8, 60):
        assert set(assign_splits(_entries(m), ratios, seed=1).values()) == {"train", "val", "test"}
    assert set(assign_splits(_entries(7), ratios, seed=1).values()) != {"train", "val", "test"}
    full = _entries(10)
    assert empty_split_message("recs.yaml", full, assign_splits(full, ratios, seed=0), ratios) is None


def test_no_empty_split_warning_for_a_split_emptied_on_purpose_and_one_for_a_manifest_that_names_none():
    from kinectdata.dataset.build import empty_split_message

    entries = _entries(4)
    for ratios in [(1, 0, 0), (0.5, 0, 0.5)]:  # the user asked for no val (and no test) split
        assert empty_split_message("s", entries, assign_splits(entries, ratios, seed=0), ratios) is None
    said = empty_split_message("s", entries, assign_splits(entries, (0.5, 0.5, 0), 0), (0.5, 0.5, 0))
    assert said is None
    said = empty_split_message("s", entries[:1], assign_splits(entries[:1], (0.5, 0, 0.5), 0), (0.5, 0, 0.5))
    assert said.startswith("s: 1 recording drawn at split ratios (0.5, 0, 0.5) leaves the test split empty")
    assert "(2 or more drawn at these ratios fill every split)" in said and "val split" not in said
    explicit = _entries(3, split="train")
    said = empty_split_message("recs.csv", explicit, assign_splits(explicit, (0.8, 0.1, 0.1), 0), (0.8, 0.1, 0.1))
    assert said.startswith("recs.csv: the recordings manifest puts no recording in the val and test splits")
    assert "give some recordings split: val" in said


def test_an_empty_split_is_warned_about_on_the_command_line(tmp_path):
    from click.testing import CliRunner

    from kinectdata.cli import main

    result = CliRunner().invoke(main, ["build-dataset", str(SAMPLES), "-o", str(tmp_path / "d")])
    assert result.exit_code == 0
    warned = [line for line in result.stderr.splitlines() if line.startswith("warning: ")]
    assert len(warned) == 1 and "leave the val split empty (training has no validation loss)" in warned[0]
    assert "--split-ratios" in warned[0]


def test_tempo_copies_are_the_dance_and_its_song_played_faster(tmp_path):
    """A copy at tempo 0.8 is the clean recording slowed: its targets are the clean ones read at 0.8
    of the time (after the best shift, within interpolation), its music's features too, and only
    training recordings get copies."""
    manifest = build_dataset(SAMPLES, tmp_path / "tempo", config(augment_tempo=(0.8,)))
    names = {r["name"]: r for r in manifest["recordings"]}
    train = manifest["splits"]["train"]["recordings"]
    assert all(f"{rec}~tempo0.8" in names for rec in train)
    assert not any(f"{rec}~tempo0.8" in names for s in ("val", "test") for rec in manifest["splits"][s]["recordings"])
    assert manifest["config"]["augment_tempo"] == [0.8]
    clean, copy = names[train[0]], names[f"{train[0]}~tempo0.8"]
    assert copy["tempo"] == 0.8 and copy["snr_db"] is None and copy["recording"] == train[0]
    assert copy["frames"] == pytest.approx(clean["frames"] / 0.8, abs=3)
    # the offset (given or estimated) scales with the times
    assert copy["offset"]["seconds"] == pytest.approx(clean["offset"]["seconds"] / 0.8, abs=1.5 / 30)

    def rows(record, name):
        with h5py.File(tmp_path / "tempo" / record["shard"], "r") as f:
            return f[name][record["start"] : record["start"] + record["frames"]].astype(np.float64)

    def best_misfit(slow: np.ndarray, fast: np.ndarray, factor: float = 0.8) -> float:
        """The least mean |slow[k] - fast read at factor k + s| over shifts s (frames), in units of
        fast's mean change from one frame to the next (interpolating twice costs a fraction of it)."""
        k = np.arange(len(slow))
        misfits = []
        for s in np.arange(-4, 4, 0.05):
            at = factor * k + s
            inside = (at >= 0) & (at <= len(fast) - 1)
            read = np.stack([np.interp(at[inside], np.arange(len(fast)), col) for col in fast.T], axis=1)
            misfits.append(np.abs(slow[inside] - read).mean())
        return min(misfits) / np.abs(np.diff(fast, axis=0)).mean()

    slow, fast = rows(copy, "current"), rows(clean, "current")
    assert best_misfit(slow, fast) < 0.5 < 2 < best_misfit(slow, fast, 0.78)  # read 2.5 % off, it drifts away
    loudness = lambda r: rows(r, "input").reshape(r["frames"], -1).mean(axis=1, keepdims=True)  # noqa: E731
    # the song's loudness per frame: each frame's spectrum comes from a window of the slowed audio,
    # not an interpolation, so less exactly; read 2.5 % off it is three times as far
    assert (
        best_misfit(loudness(copy), loudness(clean)) < 0.65 < 1.5 < best_misfit(loudness(copy), loudness(clean), 0.78)
    )
    with pytest.raises(ValueError, match="augment_tempo: 1 is not a tempo factor"):
        config(augment_tempo=(1.0,))


def _spectrum_scale(clean: np.ndarray, copy: np.ndarray) -> float:
    """The factor s (0.7-1.15) by which the frequency axis of ``clean``'s mean STFT spectrum [F, 1,
    129, 5] best maps onto ``copy``'s: 0.8 for a song played as a turntable plays it at 0.8, 1 for
    the same notes."""
    bins = np.arange(129.0)
    a, b = (x.reshape(len(x), 129, 5).mean(axis=(0, 2)) for x in (clean, copy))
    scales = np.arange(0.7, 1.151, 0.01)
    fits = [np.corrcoef(np.interp(bins / s, bins, a)[5:100], b[5:100])[0, 1] for s in scales]
    return float(scales[int(np.argmax(fits))])


def test_tempo_copies_with_the_pitch_kept_are_the_same_notes_faster(tmp_path):
    """--tempo-pitch kept: the copy at 0.8 has the clean recording's spectrum (a turntable's copy has
    it 0.8 times as high), and its dance and timing are the slowed dance's as before."""
    from kinectdata.align.stretch import available_stretcher

    skip_unless_installed(None if available_stretcher() else "neither sox nor librosa installed", "SoX")
    built = {}
    for pitch in ("turntable", "kept"):
        built[pitch] = build_dataset(SAMPLES, tmp_path / pitch, config(augment_tempo=(0.8,), tempo_pitch=pitch))
    assert "tempo_pitch" not in built["turntable"]["config"] and built["kept"]["config"]["tempo_pitch"] == "kept"
    for pitch, manifest in built.items():
        names = {r["name"]: r for r in manifest["recordings"]}

        def rows(record, name, pitch=pitch):
            with h5py.File(tmp_path / pitch / record["shard"], "r") as f:
                return f[name][record["start"] : record["start"] + record["frames"]].astype(np.float64)

        for rec in manifest["splits"]["train"]["recordings"]:
            clean, copy = names[rec], names[f"{rec}~tempo0.8"]
            assert copy["frames"] == pytest.approx(clean["frames"] / 0.8, abs=3)
            assert copy["offset"]["seconds"] == pytest.approx(clean["offset"]["seconds"] / 0.8, abs=1.5 / 30)
            scale = _spectrum_scale(rows(clean, "input"), rows(copy, "input"))
            assert scale == pytest.approx(0.8 if pitch == "turntable" else 1.0, abs=0.025)
            if pitch == "kept":  # the dance slowed as the turntable's copy has it: the same targets
                turntable = {r["name"]: r for r in built["turntable"]["recordings"]}[copy["name"]]
                with h5py.File(tmp_path / "turntable" / turntable["shard"], "r") as f:
                    slowed = f["current"][turntable["start"] : turntable["start"] + turntable["frames"]]
                n = min(len(slowed), copy["frames"])
                drift = np.abs(rows(copy, "current")[:n] - slowed[:n]).mean()
                assert drift < 0.5 * np.abs(np.diff(slowed, axis=0)).mean()
    with pytest.raises(ValueError, match="tempo_pitch must be one of turntable, kept"):
        config(tempo_pitch="vinyl")
