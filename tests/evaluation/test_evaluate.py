"""evaluate, generate, export and sweep on a tiny trained run, against independent computations."""

from __future__ import annotations

import dataclasses
import json
import os

import numpy as np
import pytest
import soundfile as sf
from conftest import REPO, TINY_TRAINING

torch = pytest.importorskip("torch")


from kinectdata.align.audio import load_audio  # noqa: E402
from kinectdata.align.recipe import align_files  # noqa: E402
from kinectdata.core.errors import KinectDataError  # noqa: E402
from kinectdata.evaluation.evaluate import evaluate, format_results  # noqa: E402
from kinectdata.evaluation.metrics import motion_energy, smape  # noqa: E402
from kinectdata.features.stft import PRESETS, StftConfig, stft_features  # noqa: E402
from kinectdata.formats import read_motion  # noqa: E402
from kinectdata.inference.engines import onnxruntime_available  # noqa: E402
from kinectdata.inference.generate import generate  # noqa: E402
from kinectdata.inference.start import recording_start  # noqa: E402
from kinectdata.models.registry import model_kind  # noqa: E402
from kinectdata.models.run import load_model  # noqa: E402
from kinectdata.targets.normalization import Normalizer  # noqa: E402
from kinectdata.targets.specs import TargetSpec  # noqa: E402
from kinectdata.training.config import TrainConfig  # noqa: E402

SONG = REPO / "sample_data" / "synth_002.flac"


def reference_smape(f, a, mask):
    """The paper's SMAPE written out term by term (a 0/0 term counts as 0)."""
    terms = [abs(x - y) / (abs(x) + abs(y)) if abs(x) + abs(y) > 0 else 0.0 for x, y in zip(f[mask], a[mask])]
    return 100.0 * sum(terms) / len(terms)


def test_smape_by_hand():
    f = np.array([[1.0, 0.0, -1.0, 5.0]])
    a = np.array([[3.0, 0.0, 1.0, 7.0]])
    assert smape(f, a) == pytest.approx(100 * (0.5 + 0.0 + 1.0 + 2 / 12) / 4)
    mask = np.array([[True, True, True, False]])
    assert smape(f, a, mask) == pytest.approx(50.0)
    assert smape(np.zeros((2, 2)), np.zeros((2, 2))) == 0.0
    assert np.isnan(smape(f, a, np.zeros_like(mask)))
    rng = np.random.default_rng(0)
    f, a, m = rng.normal(size=(20, 6)), rng.normal(size=(20, 6)), rng.random((20, 6)) > 0.3
    assert smape(f, a, m) == pytest.approx(reference_smape(f, a, m), rel=1e-12)


def test_motion_energy():
    poses = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0]])
    np.testing.assert_allclose(motion_energy(poses), [0.0, 0.5, 2.0])


def stream(run):
    """The exported TorchScript network (stream.ts) stepped frame by frame."""
    module = torch.jit.load(str(run / "stream.ts"))

    def run_frames(features, first, reset_every=None):
        state, pose, out = module.initial_state(), torch.from_numpy(first), []
        with torch.no_grad():
            for i in range(features.shape[0]):
                if reset_every and i % reset_every == 0:
                    state = module.initial_state()  # the states only: the pose fed back carries on
                pose, *state = module(torch.from_numpy(features[i]), pose, *state)
                out.append(pose.numpy())
        return np.array(out)

    return run_frames


@pytest.fixture(scope="module")
def generated(trained_run, tmp_path_factory):
    """(motion, timing, CSV file) of generate on SONG with the trained run: one generation for the
    tests that check what it computed, what it wrote and what ONNX Runtime gives (none changes it)."""
    run, _ = trained_run
    path = tmp_path_factory.mktemp("generated") / "dance.csv"
    motion, timing = generate(run, SONG, path)
    return motion, timing, path


@pytest.fixture(scope="module")
def evaluation(trained_run, sample_dataset, tmp_path_factory):
    run, _ = trained_run
    out = tmp_path_factory.mktemp("evaluation")
    return evaluate(run, sample_dataset, "test", out=out, silence_seconds=3.0, timing_frames=60), out


def test_evaluate_gives_the_fields_table_and_records_its_protocol(evaluation, tmp_path):
    results, out = evaluation
    record = json.loads((out / "metrics.json").read_text())
    assert results["field"]["metrics_json"] == str(out / "metrics.json")
    assert record["protocol"]["name"] == "bailando" and record["protocol"]["fps"] == 60.0
    assert record["sets"]["generated"]["sequences"] == record["sets"]["reference"]["sequences"] == ["synth_002"]
    mapping = record["joint_mappings"][0]
    assert mapping["source"] == "kinect_v2" and "AnkleLeft" in mapping["stand_ins"]["FootLeft"]  # yalta65: no feet
    assert record["metrics"]["FID_k"]["generated"] is None and "needs 2 sequences" in record["metrics"]["FID_k"]["note"]
    # independent: the real motion rebuilt from its targets scores as the recording aligned and read from its file
    aligned = align_files(REPO / "sample_data" / "synth_002.csv", SONG, tmp_path / "s2.h5")
    assert aligned.n_frames > 300
    from kinectdata.evaluation.field_scores import score_sets
    from kinectdata.evaluation.motion_sets import load_dance_set
    from kinectdata.evaluation.protocols import PROTOCOLS

    from_file = load_dance_set(tmp_path / "s2.h5", PROTOCOLS["bailando"])
    assert from_file[0].music_beats_s is not None  # ground truth beside the song
    bas = score_sets(from_file, from_file, PROTOCOLS["bailando"], bootstrap=0).metric("BAS").generated
    assert record["metrics"]["BAS"]["reference"] == pytest.approx(bas, abs=0.02)
    assert bas > 0.5  # the synthetic dancer bounces on the beat
    printed = format_results(results)
    assert "protocol bailando" in printed and "BAS      higher" in printed


def test_evaluate_scores_against_an_independent_free_run(trained_run, sample_dataset, evaluation):
    import h5py

    run, _ = trained_run
    results, _ = evaluation
    manifest = json.loads((sample_dataset / "manifest.json").read_text())
    (rec,) = [r for r in manifest["recordings"] if r["split"] == "test"]
    with h5py.File(sample_dataset / rec["shard"], "r") as f:
        rows = slice(rec["start"], rec["start"] + rec["frames"])
        features, true, mask = f["input"][rows], f["current"][rows], f["mask"][rows]
    run_frames = stream(run)
    free = run_frames(features[1:], true[0])
    scores = results["smape"]
    assert scores["without_reset"]["smape_normalised"] == pytest.approx(
        reference_smape(free, true[1:], mask[1:]), abs=1e-3
    )
    sequence = TINY_TRAINING["sequence"]
    reset = run_frames(features[1:], true[0], sequence)
    assert not np.allclose(reset, free)  # the resets do change the motion
    assert scores["with_reset"]["smape_normalised"] == pytest.approx(
        reference_smape(reset, true[1:], mask[1:]), abs=1e-3
    )
    config = json.loads((run / "config.json").read_text())
    norm = Normalizer.from_dict(config["dataset"]["normalisation"])
    spec = TargetSpec.from_dict(config["dataset"]["target"])
    metres = norm.invert(free, spec, mask=mask[1:]), norm.invert(true[1:], spec, mask=mask[1:])
    assert scores["without_reset"]["smape_denormalised"] == pytest.approx(reference_smape(*metres, mask[1:]), abs=1e-3)
    assert results["smape_zero_over_zero"] == 0.0 and results["recordings"] == ["synth_002"]


def test_evaluate_reports_timing_silence_and_figures(evaluation):
    results, out = evaluation
    expected = ["torch float32", "torch float16"] + (["onnxruntime float32"] if onnxruntime_available() else [])
    assert list(results["forward_time"]) == expected
    for t in results["forward_time"].values():
        assert 0 < t["median_ms"] <= t["p95_ms"] and t["device"].startswith("cpu") and t["frames"] > 40
    sil = results["silence_test"]
    assert sil["silent_features_identical"] and sil["silent_feature_value"] == pytest.approx(0.1)
    assert sil["silent_frames"] == 90 and sil["energy_inside"] >= 0 and sil["energy_outside"] > 0
    for name in ("trajectories.png", "silence.png"):
        assert (out / name).read_bytes()[:4] == b"\x89PNG"
    assert json.loads((out / "results.json").read_text())["smape"] == results["smape"]
    text = format_results(results)
    for phrase in ("SMAPE without reset", "SMAPE with reset", "forward time", "silence test", "ms median"):
        assert phrase in text


def test_silence_test_measures_energy_inside_the_inserted_silence(trained_run):
    """A model that copies its input's loudness moves only with sound: its energy inside the
    silence is 0, outside it is not."""
    from kinectdata.evaluation.evaluate import silence_test
    from kinectdata.models.registry import model_kind

    run, _ = trained_run
    net, config = load_model(run)
    rng = np.random.default_rng(1)
    rec = {"name": "x", "input": rng.uniform(0.1, 0.9, (120, 1, 129, 5)).astype(np.float32)}
    rec["current"] = np.zeros((120, 65), np.float32)

    class Loudness(torch.nn.Module):
        config = net.config

        def encode(self, x):
            return x.mean(dim=(2, 3, 4))[..., None].expand(*x.shape[:2], 65), None

        def decode(self, codes, previous, feedback):
            return codes, None

    yalta = model_kind("yalta")  # the fake network runs free as the yalta model runs its networks
    result = silence_test(Loudness(), config["dataset"]["features"], rec, 30.0, seconds=2.0, kind=yalta)
    assert result["energy_inside"] == 0.0 and result["energy_outside"] > 0 and result["energy_ratio"] == 0.0
    # generated[i] is frame i + 1 of the features with frames 60..119 silent: the energy (the change
    # into generated[i]) is 0 exactly for i in 60..118, and the silence spans generated 59..118
    still = np.flatnonzero(motion_energy(result["generated"]) == 0.0)
    np.testing.assert_array_equal(still[still > 0], np.arange(60, 119))
    assert result["silence_span_s"] == (59 / 30, 119 / 30) and result["settle_seconds"] == 1.0
    with pytest.raises(KinectDataError, match="at least 2 s of silence"):
        silence_test(Loudness(), config["dataset"]["features"], rec, 30.0, seconds=1.5, kind=yalta)


def test_evaluate_refuses_a_dataset_with_other_targets(trained_run, sample_dataset, tmp_path):
    """A dataset whose interface differs from the run's is refused; a manifest edited by hand to
    pretend so no longer matches its own shards, which the verification before reading finds first."""
    import shutil

    from kinectdata.models.run import interface_mismatch, read_config

    run, _ = trained_run
    other = tmp_path / "other"
    shutil.copytree(sample_dataset, other)
    manifest = json.loads((other / "manifest.json").read_text())
    changed = json.loads(json.dumps(manifest))
    changed["normalisation"]["scale"][0] *= 2
    (other / "manifest.json").write_text(json.dumps(changed))
    with pytest.raises(KinectDataError, match="train-00000.h5: attribute 'normalisation' differs from the manifest's"):
        evaluate(run, other, "test", out=tmp_path / "e")
    assert not (tmp_path / "e").exists()
    assert interface_mismatch(read_config(run), other, changed) == ["normalisation"]
    changed = json.loads(json.dumps(manifest))
    changed["config"]["features"] = PRESETS["motion_dance"].to_dict()
    assert interface_mismatch(read_config(run), other, changed) == ["features"]
    (other / "manifest.json").write_text("{")
    with pytest.raises(KinectDataError, match="manifest.json: not valid JSON"):
        evaluate(run, other, "test", out=tmp_path / "e")
    assert not (tmp_path / "e").exists()


def test_generate_streams_what_the_sequence_model_computes_offline(trained_run, generated):
    run, _ = trained_run
    motion, timing, _ = generated
    net, config = load_model(run)
    data = config["dataset"]
    audio = load_audio(SONG, data["sample_rate"]).samples
    n = int(np.floor(audio.size / data["sample_rate"] * data["fps"]))
    starts = np.round(np.arange(n) * data["sample_rate"] / data["fps"]).astype(np.int64)
    features, _ = stft_features(audio, starts, StftConfig.from_dict(data["features"]))
    with torch.no_grad():
        poses = net(torch.from_numpy(features)[None], torch.tensor([data["start_pose"]]), "predicted")[0].numpy()
    spec = TargetSpec.from_dict(data["target"])
    expected = Normalizer.from_dict(data["normalisation"]).invert(poses, spec)
    js = motion.joint_set
    assert motion.n_frames == n == timing["frames"]
    got_positions = np.stack([motion.positions[:, js.index(j)] for j in spec.positions], 1).reshape(n, -1)
    np.testing.assert_allclose(got_positions, expected[:, :9], atol=1e-5)
    got_q = np.stack([motion.orientations[:, js.index(j)] for j in spec.orientations], 1)
    np.testing.assert_allclose(got_q.reshape(n, -1), expected[:, 9:], atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(got_q, axis=-1), 1.0, atol=1e-9)


def test_generate_with_onnx_runtime_gives_the_torch_motion(trained_run, generated):
    if not onnxruntime_available():
        pytest.skip("onnxruntime and onnxscript not installed")
    run, _ = trained_run
    a, _, _ = generated  # the torch engine's motion
    b, timing = generate(run, SONG, engine="onnxruntime")
    np.testing.assert_allclose(b.positions, a.positions, atol=1e-5)
    np.testing.assert_allclose(b.orientations, a.orientations, atol=1e-5)
    assert timing["step_median_ms"] > 0
    with pytest.raises(KinectDataError, match="float32 weights only"):
        generate(run, SONG, engine="onnxruntime", precision="float16")


def test_generated_csv_reads_back_and_aligns(generated, tmp_path):
    motion, _, written = generated
    back = read_motion(written)
    assert back.joint_set.name == "kinect_v2" and back.n_frames == motion.n_frames
    comments = back.metadata["file_metadata"]
    assert comments["generated_by"] == "kinectdata generate" and comments["target_spec"] == "yalta65"
    js = back.joint_set
    assert back.position_mask[:, js.index("HandLeft")].all()
    # the rest skeleton places what the orientations reach (the head from the neck's frame), not the feet
    assert back.position_mask[:, js.index("Head")].all() and not back.position_mask[:, js.index("FootLeft")].any()
    neck, head = back.positions[:, js.index("Neck")], back.positions[:, js.index("Head")]
    assert np.all(head[:, 1] > neck[:, 1])  # upright: the head above the neck
    np.testing.assert_allclose(
        back.positions[:, js.index("HandLeft")], motion.positions[:, js.index("HandLeft")], atol=1e-6
    )
    q = back.orientations[:, js.index("ElbowLeft")]
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-5)
    rec = align_files(written, SONG, tmp_path / "dance.h5", offset=0.0)
    assert rec.n_frames == motion.n_frames and (tmp_path / "dance.h5").is_file()


def test_generate_dances_to_an_aligned_recordings_own_music(trained_run, tmp_path):
    """An aligned .h5 gives its audio segment and its first pose: the motion starts from that pose
    and equals the one generated from that segment written as a WAV file at the run's rate from the
    same pose, and has the recording's frames on its clock;
    a recording aligned at another rate is refused, naming the fix (the README runs the command)."""
    run, _ = trained_run
    take, music = REPO / "sample_data" / "synth_001.csv", REPO / "sample_data" / "synth_001.flac"
    rec = align_files(take, music, tmp_path / "s1.h5", offset=0.0)
    from_h5, timing = generate(run, tmp_path / "s1.h5", tmp_path / "from_h5.csv")
    assert timing["start"] == "the recording's first pose"
    # frame 0 is the recording's own first pose: its listed positions where the recording has them
    spine = rec.motion.joint_set.index("SpineBase")
    np.testing.assert_allclose(from_h5.positions[0, spine], rec.motion.positions[0, spine], atol=1e-5)
    sf.write(tmp_path / "segment.wav", rec.audio, rec.sample_rate, subtype="FLOAT")
    config = json.loads((run / "config.json").read_text())["dataset"]
    start = recording_start(rec.motion, config, model_kind("yalta"))
    from_wav, _ = generate(run, tmp_path / "segment.wav", start=start)
    assert from_h5.n_frames == from_wav.n_frames == int(np.floor(rec.audio.size / rec.sample_rate * 30 + 1e-9))
    assert abs(from_h5.n_frames - rec.n_frames) <= 1
    np.testing.assert_allclose(from_h5.positions, from_wav.positions, atol=1e-6, equal_nan=True)
    dataclasses.replace(rec, sample_rate=22050).save(tmp_path / "s22.h5")  # as aligned at 22.05 kHz
    with pytest.raises(KinectDataError, match=r"s22.h5: its audio is at 22050 Hz, .* --sample-rate 16000"):
        generate(run, tmp_path / "s22.h5")


def test_generate_refuses_audio_shorter_than_a_frame(trained_run, tmp_path):
    run, _ = trained_run
    sf.write(tmp_path / "blip.wav", np.zeros(100, np.float32), 16000)
    with pytest.raises(KinectDataError, match="blip.wav: shorter than one frame"):
        generate(run, tmp_path / "blip.wav", tmp_path / "x.csv")
    assert not (tmp_path / "x.csv").exists()


def test_exported_files_describe_themselves(trained_run, tmp_path):
    from kinectdata.inference.export import export_run

    run, _ = trained_run
    config = json.loads((run / "config.json").read_text())
    extra = {"kinectdata.json": ""}
    torch.jit.load(str(run / "stream.ts"), _extra_files=extra)
    meta = json.loads(extra["kinectdata.json"])
    assert meta["start_pose"] == config["dataset"]["start_pose"] and meta["fps"] == 30
    assert meta["inputs"]["h1"] == [3, 32] and meta["normalisation"] == config["dataset"]["normalisation"]
    assert meta["foot_lock"] is None  # the run draws no travel
    export_run(run, tmp_path / "half.ts", precision="float16")
    assert torch.jit.load(str(tmp_path / "half.ts")).state_dict()["lstm1.cells.0.weight"].dtype == torch.float16
    with pytest.raises(KinectDataError, match="float32 only"):
        export_run(run, tmp_path / "x.onnx", precision="float16")
    ort = pytest.importorskip("onnxruntime")
    pytest.importorskip("onnxscript")
    export_run(run, tmp_path / "model.onnx")
    session = ort.InferenceSession(str(tmp_path / "model.onnx"), providers=["CPUExecutionProvider"])
    assert json.loads(session.get_modelmeta().custom_metadata_map["kinectdata"]) == meta


@pytest.mark.slow
def test_sweep_writes_the_papers_table_and_reuses_finished_variants(sample_dataset, tmp_path):
    from kinectdata.models.registry import model_kind
    from kinectdata.training.sweep import sweep

    paper = model_kind("yalta").sweep.paper
    base = TrainConfig(**{**TINY_TRAINING, "units": 8, "epochs": 1})
    rows = sweep(sample_dataset, tmp_path / "sweep", base, ["TanH", "50 steps"])
    assert [r["setting"] for r in rows] == ["TanH", "50 steps"]
    assert rows[0]["config"]["activation"] == "tanh" and rows[1]["config"]["sequence"] == 50
    table = (tmp_path / "sweep" / "results.md").read_text()
    assert "| setting | SMAPE % without reset | with reset | training min | forward ms/frame" in table
    assert f"| {paper['TanH'][0]:.2f} | {paper['TanH'][1]:.2f} |" in table
    model = tmp_path / "sweep" / "tanh" / "model.pt"
    before = model.stat().st_mtime_ns
    import kinectdata.training.sweep as sweeping

    scored = sweeping.evaluate
    sweeping.evaluate = lambda *a, **k: pytest.fail("a finished, scored variant was evaluated again")
    try:
        again = sweep(sample_dataset, tmp_path / "sweep", base, ["TanH"])
    finally:
        sweeping.evaluate = scored
    assert model.stat().st_mtime_ns == before and again[0] == rows[0]
    tanh = base.replace(**sweeping.model_sweep(model_kind("yalta")).variants["TanH"])
    assert sweeping._scored_before(model.parent, tanh) == rows[0]
    os.utime(model, ns=(before, before + 1))  # a model file written since it was scored: scored again
    assert sweeping._scored_before(model.parent, tanh) is None
    with pytest.raises(KinectDataError, match="unknown variant"):
        sweep(sample_dataset, tmp_path / "sweep", base, ["Sigmoid"])
    with pytest.raises(KinectDataError, match="tanh: holds a finished run whose units differ"):
        sweep(sample_dataset, tmp_path / "sweep", TrainConfig(**{**TINY_TRAINING, "units": 9, "epochs": 1}), ["TanH"])


def test_generate_writes_bvh_that_reads_back_to_the_same_positions(trained_run, tmp_path):
    run, _ = trained_run
    motion, _ = generate(run, SONG, tmp_path / "dance.bvh")
    back = read_motion(tmp_path / "dance.bvh")
    assert back.metadata["nominal_fps"] == pytest.approx(1 / float(motion.times[1] - motion.times[0]))
    names = list(back.joint_set.names)
    spec = TargetSpec.from_dict(load_model(run)[1]["dataset"]["target"])
    # the hands are the network's own outputs, apart from the chain of rotations: BVH can only put
    # them where the wrist's rotation carries their bone (written to 1e-6 cm)
    chain = [j for j in range(motion.n_joints) if motion.position_mask[:, j].any()]
    chain = [j for j in chain if motion.joint_set.names[j] not in spec.positions[1:]]
    assert len(chain) > 10  # the rest skeleton carried positions beyond the target's own three
    for j in chain:
        got = back.positions[:, names.index(motion.joint_set.names[j])]
        np.testing.assert_allclose(got, motion.positions[:, j], atol=1e-7)
    for joint in spec.positions[1:]:
        assert np.isfinite(back.positions[:, names.index(joint)]).all()
    with pytest.raises(KinectDataError, match="name the file .csv"):
        generate(run, SONG, tmp_path / "dance.txt")
