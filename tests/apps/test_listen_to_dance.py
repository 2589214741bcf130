"""The Listen to Dance pipeline end to end: synthetic OpenPose sessions -> build-dataset
--pipeline listen-to-dance -> CDHC training -> generate -> evaluate with the rhythm report."""

from __future__ import annotations

import json
import shutil

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from kinectdata.align.recipe import align_files
from kinectdata.cli import main
from kinectdata.core.errors import KinectDataError
from kinectdata.core.jointsets import load_joint_set
from kinectdata.dataset.build import build_dataset
from kinectdata.dataset.inputs import read_recordings
from kinectdata.dataset.pipelines import PIPELINES
from kinectdata.dataset.prepare import BuildConfig
from kinectdata.features import PRESETS, mel_features
from kinectdata.formats import read_motion
from kinectdata.targets.specs import load_target_spec

torch = pytest.importorskip("torch")

TINY_CDHC = {"channels": 16, "decoder_channels": 16, "sequence": 60, "batch_size": 8, "epochs": 4, "lr": 2e-3}
TINY_CDHC["context"] = 30  # the short sessions hold no window with the whole receptive field before it


def run_cli(*args):
    result = CliRunner().invoke(main, list(map(str, args)))
    return result


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    """Three synthetic OpenPose sessions (12 s each, 30 fps video) with their truth files."""
    from kinectdata.synth import synthesize_recording, write_openpose_recording

    folder = tmp_path_factory.mktemp("openpose_sessions")
    for seed in (11, 12, 14):
        rec = synthesize_recording(seed=seed, duration_s=12.0)
        write_openpose_recording(rec, folder, f"dance_{seed}")
    return folder


@pytest.fixture(scope="module")
def ltd_dataset(sessions, tmp_path_factory):
    out = tmp_path_factory.mktemp("ltd") / "dataset"
    result = run_cli(
        "build-dataset",
        sessions,
        "-o",
        out,
        "--pipeline",
        "listen-to-dance",
        "--video-fps",
        30,
        "--split-ratios",
        "1,1,1",
    )
    assert result.exit_code == 0, result.output
    return out


def test_folder_sessions_are_openpose_folders_with_their_audio(sessions):
    entries = read_recordings(sessions, video_fps=30.0)
    assert [e.name for e in entries] == ["dance_11", "dance_12", "dance_14"]
    assert all(e.video_fps == 30.0 and e.recording.endswith("_openpose") and e.audio.endswith(".flac") for e in entries)
    assert all(e.video_fps is None for e in read_recordings(sessions))


def test_the_offset_is_found_from_the_clap_in_2d(sessions, tmp_path):
    """The hands meeting in the image, measured in body heights, against the audio's clap."""
    for seed in (11, 12, 14):
        truth = json.loads((sessions / f"dance_{seed}.truth.json").read_text())
        result = align_files(sessions / f"dance_{seed}_openpose", sessions / f"dance_{seed}.flac", video_fps=30.0)
        assert result.offset.source == "clap"
        assert abs(result.offset.seconds - truth["offset_s"]) < 1.5 / 30  # within a video frame and a half
    # seed 13: the detector missed both wrists through the clap: refused, not guessed
    from kinectdata.synth import synthesize_recording, write_openpose_recording

    write_openpose_recording(synthesize_recording(seed=13, duration_s=12.0), tmp_path, "missed")
    with pytest.raises(KinectDataError, match="no clap in the motion.*Give the offset explicitly"):
        align_files(tmp_path / "missed_openpose", tmp_path / "missed.flac", video_fps=30.0)


def test_dataset_holds_mel_inputs_and_44_targets_in_0_1(ltd_dataset, sessions):
    manifest = json.loads((ltd_dataset / "manifest.json").read_text())
    assert manifest["feature_shape"] == [80] and manifest["target_dim"] == 44
    assert manifest["config"]["features"]["extractor"] == "mel" and manifest["normalisation"]["method"] == "none"
    spec = load_target_spec("listen_to_dance")
    js = load_joint_set("openpose_mpi")
    for r in manifest["recordings"]:
        with h5py.File(ltd_dataset / r["shard"], "r") as f:
            rows = slice(r["start"], r["start"] + r["frames"])
            x, y, m = f["input"][rows], f["current"][rows], f["mask"][rows]
            assert f.attrs["format"] == "kinectdata.shard"
        assert x.shape == (r["frames"], 80) and 0 <= x.min() and x.max() <= 1
        coords = y[:, :30][m[:, :30]]
        assert coords.min() == 0.0 and coords.max() == 1.0  # min-max per recording, over valid values
        # the limb lengths are those of the stored coordinates (an independent recomputation)
        xy = y[:, :30].reshape(-1, 15, 2)
        for k, joint in enumerate(spec.limbs):
            j, p = js.index(joint), js.parents[js.index(joint)]
            ok = m[:, 30 + k]
            np.testing.assert_allclose(y[ok, 30 + k], np.linalg.norm(xy[ok, j] - xy[ok, p], axis=1), atol=2e-6)
    # the inputs are the mel features of the aligned audio: one recording checked against the extractor
    r = manifest["recordings"][0]
    entry = next(e for e in manifest["inputs"] if e["name"] == r["recording"])
    aligned = align_files(entry["recording"], entry["audio"], video_fps=30.0, offset=r["offset"]["seconds"])
    starts = np.round(np.arange(aligned.n_frames) * 16000 / 30).astype(np.int64)
    expected, _ = mel_features(aligned.audio, starts, PRESETS["listen_to_dance"])
    with h5py.File(ltd_dataset / r["shard"], "r") as f:
        np.testing.assert_allclose(f["input"][r["start"] : r["start"] + r["frames"]], expected, atol=1e-6)


def test_inspect_describes_the_mel_dataset(ltd_dataset):
    result = run_cli("inspect", ltd_dataset)
    assert result.exit_code == 0, result.output
    assert "80 mel bands" in result.output and "14 limbs" in result.output and "out of range: 0 values" in result.output


@pytest.fixture(scope="module")
def cdhc_run(ltd_dataset, tmp_path_factory):
    from kinectdata.training.config import TrainConfig
    from kinectdata.training.train import train

    run = tmp_path_factory.mktemp("cdhc") / "run"
    history = train(ltd_dataset, run, TrainConfig.for_model("cdhc", **TINY_CDHC))
    return run, history


def test_short_cdhc_training_lowers_the_loss(cdhc_run):
    run, history = cdhc_run
    losses = [row["train_loss"] for row in history]
    assert losses[-1] < 0.8 * losses[0], losses
    config = json.loads((run / "config.json").read_text())
    assert config["train"]["model"] == "cdhc" and config["model"]["limbs"][0] == [0, 1]
    assert (run / "model.pt").is_file() and not (run / "stream.ts").exists()


def test_the_papers_settings_train_on_the_papers_dataset(ltd_dataset, tmp_path):
    """``train-baseline --paper`` on a listen-to-dance dataset: the paper's network and loop, none of
    the real-dance recipe's additions (no context window, weights averaged, turning or low-pass)."""
    small = ("--channels", 8, "--decoder-channels", 8, "--sequence", 60, "--batch-size", 8, "--epochs", 1)
    result = run_cli("train-baseline", "--data", ltd_dataset, "--out", tmp_path / "paper", "--paper", *small)
    assert result.exit_code == 0, result.output
    config = json.loads((tmp_path / "paper" / "config.json").read_text())
    train, model = config["train"], config["model"]
    assert (train["lr"], train["clip_norm"], train["noise_eta"], train["keep"]) == (2e-4, 1.0, 0.0, "last")
    assert (train["context"], train["weight_average"], train["free_weight"]) == (0, 0.0, 0.0)
    assert (train["turning"], train["travel"], train["smooth_hz"]) == (False, False, None)
    assert (model["output"], model["inputs"], model["dropout"]) == ("sigmoid", "music-and-poses", 0.05)


def test_generate_writes_openpose_json_lines_the_reader_reads(cdhc_run, sessions, tmp_path):
    run, _ = cdhc_run
    out = tmp_path / "dance.jsonl"
    result = run_cli("generate", "--run", run, sessions / "dance_11.flac", "-o", out)
    assert result.exit_code == 0, result.output
    motion = read_motion(out, video_fps=30.0)
    assert motion.joint_set.name == "openpose_mpi" and motion.n_frames == int(12.0 * 30)
    assert motion.position_mask.all() and 0 <= np.nanmin(motion.positions) and np.nanmax(motion.positions) <= 1
    result = run_cli("generate", "--run", run, sessions / "dance_11.flac", "-o", tmp_path / "dance.csv")
    assert result.exit_code == 1 and "written as OpenPose JSON Lines; name the file .jsonl" in result.output
    result = run_cli("export", "--run", run, "-o", tmp_path / "x.ts")
    assert (
        result.exit_code == 1 and "the cdhc model has no torchscript export (models that have: yalta)" in result.output
    )


def test_the_cdhc_model_dances_live_as_it_generates(cdhc_run, sessions):
    """Its causal convolutions stepped one frame at a time with their caches: on a song played at
    real-time pace (a virtual clock) the poses are generate's; an avatar (VMC) needs 3-D joints."""
    pytest.importorskip("pythonosc")
    from kinectdata.core.errors import KinectDataError
    from kinectdata.inference.generate import generate
    from kinectdata.live.clock import VirtualClock
    from kinectdata.live.session import LiveDancer, run_live
    from kinectdata.live.sources import FileSource
    from kinectdata.live.vmc import VmcSink

    run, _ = cdhc_run
    song = sessions / "dance_11.flac"
    clock = VirtualClock()
    dancer = LiveDancer(run, "torch")
    poses = []

    class Keep:
        def send(self, pose):
            poses.append(pose.positions)

    stats = run_live(dancer, FileSource(song, dancer.sample_rate, 80, clock), [Keep()], clock)
    expected, _ = generate(run, song)
    assert stats.frames == expected.n_frames
    np.testing.assert_allclose(np.stack(poses), expected.positions, atol=1e-5)
    with pytest.raises(KinectDataError, match="openpose_mpi is 2-D .*an avatar's bones need 3-D joints"):
        VmcSink("127.0.0.1:39539", dancer.joint_set)


@pytest.mark.slow
def test_the_cdhc_stream_exports_to_onnx_and_runs_in_onnx_runtime_as_in_torch(cdhc_run, sessions, tmp_path):
    """One cache per highway block, named in the file's metadata; ONNX Runtime steps it as torch does."""
    pytest.importorskip("onnxruntime")
    import onnxruntime as ort

    run, _ = cdhc_run
    result = run_cli("export", "--run", run, "-o", tmp_path / "cdhc.onnx")
    assert result.exit_code == 0, result.output
    session = ort.InferenceSession(str(tmp_path / "cdhc.onnx"), providers=["CPUExecutionProvider"])
    meta = json.loads(session.get_modelmeta().custom_metadata_map["kinectdata"])
    config = json.loads((run / "config.json").read_text())["model"]
    blocks = 2 * len(config["encoder_dilations"]) + len(config["decoder_dilations"])
    names = [i.name for i in session.get_inputs()]
    assert names[:3] == ["features", "previous", "audio0"] and len(names) == 2 + blocks
    assert meta["model"] == "cdhc" and meta["inputs"]["decoder0"] == [1, config["decoder_channels"], 2]

    # the file steps as the torch stream does, caches carried from frame to frame (ONNX Runtime's
    # engine for generate and live exports the same way)
    import torch

    from kinectdata.models.cdhc import FrameCdhc
    from kinectdata.models.run import load_model

    net, _ = load_model(run)
    stream = FrameCdhc(net)
    torch_state, onnx_state = list(stream.initial_state()), [t.numpy() for t in stream.initial_state()]
    pose = onnx_pose = np.asarray(json.loads((run / "config.json").read_text())["dataset"]["start_pose"], np.float32)
    rng = np.random.default_rng(3)
    for _ in range(40):
        features = rng.normal(size=session.get_inputs()[0].shape).astype(np.float32)
        onnx_pose, *onnx_state = session.run(None, dict(zip(names, [features, onnx_pose, *onnx_state])))
        with torch.inference_mode():
            pose, *torch_state = stream(torch.from_numpy(features), torch.as_tensor(pose), *torch_state)
        pose = pose.numpy()
    np.testing.assert_allclose(onnx_pose, pose, atol=1e-5)


@pytest.mark.slow
def test_a_phrase_code_trains_and_its_draws_step_the_same_in_onnx_runtime(ltd_dataset, sessions, tmp_path):
    """``--latent-dims``: the code is inferred in training and drawn in generation; the exported
    stream carries the frame counter that picks each phrase's draw, and ONNX Runtime steps it as
    torch does, from the same draw."""
    pytest.importorskip("onnxruntime")
    import onnxruntime as ort
    import torch

    from kinectdata.models.cdhc import FrameCdhc, generate
    from kinectdata.models.run import load_model
    from kinectdata.training.config import TrainConfig
    from kinectdata.training.train import train

    run = tmp_path / "latent"
    train(
        ltd_dataset, run, TrainConfig.for_model("cdhc", **{**TINY_CDHC, "epochs": 1}, latent_dims=3, phrase_seconds=0.5)
    )
    config = json.loads((run / "config.json").read_text())["model"]
    assert (config["latent_dims"], config["phrase_frames"]) == (3, 15)
    result = run_cli("export", "--run", run, "-o", tmp_path / "latent.onnx")
    assert result.exit_code == 0, result.output
    session = ort.InferenceSession(str(tmp_path / "latent.onnx"), providers=["CPUExecutionProvider"])
    names = [i.name for i in session.get_inputs()]
    assert names[-1] == "phrase_frame"
    meta = json.loads(session.get_modelmeta().custom_metadata_map["kinectdata"])
    assert meta["inputs"]["phrase_frame"] == [1] and meta["phrase_code"]["phrase_frames"] == 15
    net, _ = load_model(run)
    stream = FrameCdhc(net, draw=5)
    torch_state, onnx_state = list(stream.initial_state()), [t.numpy() for t in stream.initial_state()]
    start = np.asarray(json.loads((run / "config.json").read_text())["dataset"]["start_pose"], np.float32)
    pose = onnx_pose = start
    rng = np.random.default_rng(4)
    features = rng.normal(size=(50, *session.get_inputs()[0].shape)).astype(np.float32)
    stepped = []
    for frame in features:
        onnx_pose, *onnx_state = session.run(None, dict(zip(names, [frame, onnx_pose, *onnx_state])))
        with torch.inference_mode():
            pose, *torch_state = stream(torch.from_numpy(frame), torch.as_tensor(pose), *torch_state)
        pose = pose.numpy()
        stepped.append(pose)
    np.testing.assert_allclose(onnx_pose, pose, atol=1e-5)
    np.testing.assert_allclose(np.stack(stepped), generate(net, features, start, draw=5), atol=1e-5)
    assert np.abs(generate(net, features, start, draw=6) - np.stack(stepped)).max() > 1e-4

    # `generate --seed` picks the draw, in either engine; the output says so
    dances = {}
    for seed, engine in ((0, "torch"), (3, "torch"), (3, "onnxruntime")):
        out = tmp_path / f"dance_{seed}_{engine}.jsonl"
        result = run_cli(
            "generate", "--run", run, sessions / "dance_11.flac", "-o", out, "--seed", seed, "--engine", engine
        )
        assert result.exit_code == 0, result.output
        assert f"the phrase code drawn from row {seed} of the run's table (--seed)" in result.output
        dances[seed, engine] = read_motion(out, video_fps=30.0).positions
    np.testing.assert_allclose(dances[3, "onnxruntime"], dances[3, "torch"], atol=1e-4)
    assert np.nanmax(np.abs(dances[0, "torch"] - dances[3, "torch"])) > 1e-3


def test_evaluate_reports_rhythm_with_the_real_motion_peaking_at_the_beat(cdhc_run, ltd_dataset, tmp_path):
    run, _ = cdhc_run
    result = run_cli("evaluate", "--run", run, "--data", ltd_dataset, "--out", tmp_path / "ev")
    assert result.exit_code == 0, result.output
    assert "(real motion: " in result.output and "with reset" not in result.output
    assert "generated motion follows the beat: " in result.output and "listens to the music: " in result.output
    results = json.loads((tmp_path / "ev" / "results.json").read_text())
    listening = results["listening"]
    (name, real), *_ = listening["real"]["recordings"].items()
    assert real["in_metre"] and real["level"] in ("beat", "two beats")  # the dancer bounces each beat, steps each two
    assert abs(real["beat_period_s"] - 60 / real_tempo(ltd_dataset, name)) < 1e-6
    assert set(listening["generated"]["recordings"]) == set(listening["real"]["recordings"])
    (name, rec), *_ = results["rhythm"]["recordings"].items()
    assert rec["beat_source"] == "ground truth"
    real = rec["real"]
    assert abs(real["beat_period_s"] - 60 / real_tempo(ltd_dataset, name)) < 1e-6
    y = real["axes"]["y"]
    assert y["peak_at_beat"] and abs(y["nearest_peak"]["error_percent"]) < 10  # the paper's observation
    assert not real["axes"]["x"]["peak_at_beat"]
    assert {"beat_align_score", "direction", "sigma_s", "f_measure", "window_s"} <= set(real["beat_alignment"])
    assert (tmp_path / "ev" / "rhythm_real.png").is_file() and (tmp_path / "ev" / "rhythm_generated.png").is_file()


def real_tempo(dataset, name) -> float:
    manifest = json.loads((dataset / "manifest.json").read_text())
    audio = next(e["audio"] for e in manifest["inputs"] if e["name"] == name)
    return json.loads(open(audio.replace(".flac", ".truth.json")).read())["tempo_bpm"]


def test_the_model_follows_the_dataset_and_mismatches_are_refused(ltd_dataset, sample_dataset, tmp_path):
    from kinectdata.training.config import TrainConfig
    from kinectdata.training.train import train

    with pytest.raises(KinectDataError, match="yalta model takes STFT inputs.*use --model cdhc"):
        train(ltd_dataset, tmp_path / "a", TrainConfig(epochs=1))
    with pytest.raises(KinectDataError, match="cdhc model takes per-frame feature vectors.*use --model yalta"):
        train(sample_dataset, tmp_path / "b", TrainConfig.for_model("cdhc", epochs=1))
    result = run_cli("sweep", "--data", ltd_dataset, "--out", tmp_path / "s", "--model", "cdhc")
    assert result.exit_code == 2 and "the cdhc model has none (models with a sweep: yalta)" in result.output
    result = run_cli("sweep", "--data", ltd_dataset, "--out", tmp_path / "s")
    assert result.exit_code == 2 and "is a cdhc dataset" in result.output
    assert PIPELINES["listen-to-dance"]["model"] == "cdhc"


def test_cdhc_needs_0_1_or_normalised_targets_and_limbs_in_one_frame(sessions, tmp_path):
    from kinectdata.training.config import TrainConfig
    from kinectdata.training.train import train

    cases = (
        (["--target", "positions", "--normalisation", "none"], "covers 0..1 for targets left unnormalised"),
        (["--root-centre"], "without --root-centre"),
    )
    for option, words in cases:
        out = tmp_path / option[0].strip("-")
        args = ["build-dataset", sessions, "-o", out, "--pipeline", "listen-to-dance", "--video-fps", 30]
        assert run_cli(*args, "--split-ratios", "1,1,1", *option).exit_code == 0
        with pytest.raises(KinectDataError, match=words):
            train(out, tmp_path / f"run-{option[0]}", TrainConfig.for_model("cdhc", epochs=1))


def test_masked_previous_poses_become_the_mean_pose_for_cdhc(ltd_dataset):
    from kinectdata.dataset.windows import WindowDataset
    from kinectdata.models.registry import model_kind

    windows = WindowDataset(ltd_dataset, "train", 60)
    item = windows[0]
    assert item["previous_mask"].shape == item["previous"].shape
    start = np.full(44, 0.5, np.float32)
    filled = model_kind("cdhc").fill_previous(item["previous"], item["previous_mask"], start)
    m = item["previous_mask"].numpy()
    assert (~m).any()  # the synthetic detector misses joints
    np.testing.assert_array_equal(filled.numpy()[~m], 0.5)
    np.testing.assert_array_equal(filled.numpy()[m], item["previous"].numpy()[m])
    assert model_kind("yalta").fill_previous(item["previous"], item["previous_mask"], start) is item["previous"]


def test_a_manifest_gives_person_and_video_fps_per_recording(sessions, tmp_path):
    manifest = tmp_path / "recordings.csv"
    manifest.write_text(
        "recording,audio,person,video_fps,split\n"
        f"{sessions / 'dance_11_openpose'},{sessions / 'dance_11.flac'},0,30,train\n"
        f"{sessions / 'dance_12_openpose'},{sessions / 'dance_12.flac'},,thirty,val\n"
    )
    with pytest.raises(KinectDataError, match=r"line 3.*video_fps 'thirty' is not a number"):
        read_recordings(manifest)
    manifest.write_text(manifest.read_text().replace("thirty", "25"))
    entries = read_recordings(manifest, video_fps=30.0, allow_outside_paths=True)  # the sessions lie elsewhere
    assert [(e.person, e.video_fps) for e in entries] == [("0", 30.0), (None, 25.0)]


def test_an_edited_keypoint_file_changes_the_build(sessions, tmp_path):
    """A folder recording's hash covers its files: editing one frame rebuilds, not reuses."""
    src = tmp_path / "src"
    shutil.copytree(sessions, src)
    for extra in ("dance_12", "dance_14"):
        shutil.rmtree(src / f"{extra}_openpose")
    config = BuildConfig(
        features=PRESETS["listen_to_dance"].to_dict(),
        target=load_target_spec("listen_to_dance").to_dict(),
        normalisation="none",
        split_ratios=(1, 0, 0),
    )
    first = build_dataset(src, tmp_path / "ds", config, video_fps=30.0)
    frame = sorted((src / "dance_11_openpose").glob("*_keypoints.json"))[100]
    doc = json.loads(frame.read_text())
    doc["people"] = []
    frame.write_text(json.dumps(doc))
    second = build_dataset(src, tmp_path / "ds", config, video_fps=30.0)
    assert first["build_key"] != second["build_key"]


def test_beats_come_from_the_ground_truth_also_for_aligned_recordings(sessions, tmp_path):
    """An aligned .h5 names the audio it came from; that audio's truth file gives the beats,
    shifted to the recording's first frame."""
    from kinectdata.evaluation.rhythm_eval import recording_beats

    aligned = tmp_path / "a.h5"
    rec = align_files(sessions / "dance_11_openpose", sessions / "dance_11.flac", aligned, video_fps=30.0)
    truth = json.loads((sessions / "dance_11.truth.json").read_text())
    start = rec.summary["audio_trimmed_start_s"]
    beats, source, why = recording_beats({"recording": str(aligned)}, {"alignment": rec.summary}, 300, 30.0, 16000)
    assert source == "ground truth" and why is None
    np.testing.assert_allclose(beats, np.array(truth["beat_times_s"]) - start)
