"""The field's metrics equal the peers' own code on tests/data/metrics (values computed by running
the AIST++ API, mint, Bailando and EDGE at the commits its README names; no peer code is here)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO

from kinectdata.core.errors import FormatError, KinectDataError
from kinectdata.core.joint_mapping import load_smpl24_mapping, shipped_smpl24_mappings
from kinectdata.core.jointsets import load_joint_set
from kinectdata.evaluation import metrics as M
from kinectdata.evaluation.field_scores import DanceSequence, FeatureGap, score_sets
from kinectdata.evaluation.motion_sets import DanceReading, load_dance_set
from kinectdata.evaluation.protocols import PROTOCOLS

DATA = Path(__file__).parents[1] / "data" / "metrics"
EXPECTED = json.loads((DATA / "expected.json").read_text())
INPUTS = np.load(DATA / "inputs.npz")
SETS = ("gt", "gen")


def _beats(which: str, i: int) -> np.ndarray:
    beats = INPUTS[f"music_beats_s_{which}"][i]
    return beats[np.isfinite(beats)]


def _zero_start(p: np.ndarray) -> np.ndarray:
    return p - p[:1, :1]


@pytest.mark.parametrize("which", SETS)
def test_features_equal_the_aistpp_api_and_bailando(which):
    for i, joints in enumerate(INPUTS[f"joints_{which}"]):
        expected = EXPECTED["per_sequence"][which][i]
        np.testing.assert_allclose(
            M.kinetic_features(joints, 60.0), expected["aistpp_kinetic_raw_positions"], rtol=1e-5
        )
        np.testing.assert_allclose(
            M.kinetic_features(_zero_start(joints), 60.0), expected["bailando_kinetic_zero_start"], rtol=1e-5
        )
        np.testing.assert_allclose(M.geometric_features(joints), expected["aistpp_manual_raw_positions"], atol=1e-6)
        np.testing.assert_allclose(
            M.geometric_features(_zero_start(joints)), expected["bailando_manual_new_zero_start"], atol=1e-6
        )


def test_the_peers_acceleration_slip_is_kept_and_can_be_turned_off():
    joints = INPUTS["joints_gt"][0]
    moved = joints + np.array([3.0, 0.0, 0.0])
    slip = M.kinetic_features(joints, 60.0)[2::3], M.kinetic_features(moved, 60.0)[2::3]
    fixed = M.kinetic_features(joints, 60.0, peer_acceleration=False)[2::3]
    assert not np.allclose(*slip, rtol=1e-3)  # the peers' third feature depends on where the body is
    np.testing.assert_allclose(fixed, M.kinetic_features(moved, 60.0, peer_acceleration=False)[2::3], rtol=1e-4)
    # the physical value by another route: the windowed mean of second differences, by a loop
    dt, p, j = 1 / 60, joints, 20
    acc = [(p[k + 1, j] - 2 * p[k, j] + p[k - 1, j]) / dt**2 for k in range(1, len(p) - 1)]
    norms = []
    for i in range(1, len(p)):
        window = [acc[k - 1] for k in range(max(1, i - 2), min(len(p) - 2, i + 2) + 1)]
        norms.append(np.linalg.norm(np.mean(window, axis=0)))
    assert fixed[j] == pytest.approx(np.mean(norms), rel=1e-5)


@pytest.mark.parametrize("which", SETS)
def test_beat_align_scores_and_pfc_equal_bailando_and_edge(which):
    for i, joints in enumerate(INPUTS[f"joints_{which}"]):
        expected = EXPECTED["per_sequence"][which][i]
        beats = M.peer_motion_beats(joints, 60.0)
        assert beats.tolist() == expected["motion_beats_frames"]
        music = M.music_beat_frames(_beats(which, i), 60.0, joints.shape[0])
        assert music.tolist() == expected["music_beats_frames_used"]
        assert M.peer_beat_align_score(music, beats, 60.0, "music_to_motion") == pytest.approx(
            expected["bas_music_to_motion_bailando"], rel=1e-9
        )
        assert M.peer_beat_align_score(music, beats, 60.0, "motion_to_music") == pytest.approx(
            expected["bas_motion_to_music_aistpp_direction"], rel=1e-9
        )
        z_up = np.stack([joints[::2, :, 0], -joints[::2, :, 2], joints[::2, :, 1]], axis=-1)  # EDGE's input
        assert M.foot_contact_score(z_up, 30.0) * 1e4 == pytest.approx(expected["edge_pfc_x10000"], rel=1e-9)


def _sequences(which: str) -> list[DanceSequence]:
    return [DanceSequence(f"{which}{i}", j, 60.0, _beats(which, i)) for i, j in enumerate(INPUTS[f"joints_{which}"])]


def test_bailando_protocol_equals_quantized_metrics_ba_score_and_pfc():
    scores = score_sets(_sequences("gen"), _sequences("gt"), PROTOCOLS["bailando"], bootstrap=50)
    peer = EXPECTED["set_metrics"]["bailando_quantized_metrics"]
    sets = EXPECTED["set_metrics"]
    assert scores.metric("FID_k").generated == pytest.approx(peer["fid_k"], rel=1e-5)
    assert scores.metric("FID_g").generated == pytest.approx(peer["fid_m"], rel=1e-5)
    assert scores.metric("Div_k").generated == pytest.approx(peer["div_k"], rel=1e-5)
    assert scores.metric("Div_k").reference == pytest.approx(peer["div_k_gt"], rel=1e-5)
    assert scores.metric("Div_g").generated == pytest.approx(peer["div_m"], rel=1e-5)
    assert scores.metric("Div_g").reference == pytest.approx(peer["div_m_gt"], rel=1e-5)
    assert scores.metric("BAS").generated == pytest.approx(sets["bailando_calc_ba_score_gen"], rel=1e-9)
    assert scores.metric("BAS").reference == pytest.approx(sets["bailando_calc_ba_score_gt"], rel=1e-9)
    assert scores.metric("PFC").generated == pytest.approx(sets["edge_pfc_gen"], rel=1e-9)
    assert scores.metric("PFC").reference == pytest.approx(sets["edge_pfc_gt"], rel=1e-9)
    interval = scores.metric("FID_k").interval
    assert interval.low < scores.metric("FID_k").generated < interval.high
    assert any("singular" in w for w in scores.warnings)  # 6 sequences for 72 features


def test_aist_protocol_equals_mint_and_the_papers_bas_direction():
    scores = score_sets(_sequences("gen"), _sequences("gt"), PROTOCOLS["aist"], bootstrap=0)
    mint = EXPECTED["set_metrics"]["mint_frechet_feature_distance"]
    assert scores.metric("FID_k").generated == pytest.approx(mint["FID_k"], rel=1e-5)
    assert scores.metric("FID_g").generated == pytest.approx(mint["FID_g"], rel=1e-5)
    assert scores.metric("BAS").generated == pytest.approx(EXPECTED["set_metrics"]["bas_motion_to_music_mean_gen"])
    assert scores.metric("FID_k").interval is None


def test_frechet_distance_and_diversity_against_scipy_by_another_route():
    from scipy.linalg import sqrtm

    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(40, 5)), rng.normal(1.0, 2.0, size=(50, 5))
    ca, cb = np.cov(a, rowvar=False), np.cov(b, rowvar=False)
    direct = np.sum((a.mean(0) - b.mean(0)) ** 2) + np.trace(ca + cb - 2 * np.real(sqrtm(ca @ cb)))
    assert M.frechet_distance(a, b) == pytest.approx(direct, rel=1e-9)
    assert M.frechet_distance(a, a) == pytest.approx(0.0, abs=1e-9)
    pairs = [np.linalg.norm(a[i] - a[j]) for i in range(40) for j in range(i + 1, 40)]
    assert M.diversity(a) == pytest.approx(np.mean(pairs))
    # a bootstrap draw never pairs a sequence with its own copy
    assert M.diversity(a[:3], draw=np.array([0, 0, 1])) == pytest.approx(np.linalg.norm(a[0] - a[1]))


def test_the_means_gap_is_the_whole_distance_between_a_set_and_its_shifted_copy():
    """Shifted, a set keeps its covariance: the Fréchet distance is then its means' term alone."""
    rng = np.random.default_rng(5)
    reference = rng.normal(size=(30, 6))
    shift = np.array([0.0, 2.0, 0.0, -0.5, 0.0, 0.0])
    gaps = M.mean_gaps(reference + shift, reference)
    assert gaps == pytest.approx(shift**2)
    assert gaps.sum() == pytest.approx(M.frechet_distance(reference + shift, reference), rel=1e-9)
    with pytest.raises(KinectDataError, match="6 dimensions, reference 5"):
        M.mean_gaps(reference, reference[:, :5])


def test_the_kinetic_feature_furthest_from_the_reference_is_named_with_its_ratio():
    """Dancers whose left ankle moves along the floor at half the speed (a quarter of the mean squared
    speed) of the reference's: FID_k's largest gap is that feature, 0.25 x, below the reference."""
    rng = np.random.default_rng(6)

    def dancer(ankle_speed: float) -> DanceSequence:
        steps = rng.normal(scale=0.01, size=(240, 24, 3))
        steps[:, 7, [0, 2]] = ankle_speed * rng.normal(scale=0.03, size=(240, 2))  # SMPL-24 joint 7: left_ankle
        return DanceSequence("d", np.cumsum(steps, axis=0) + [0.0, 1.0, 0.0], 60.0)

    reference = [dancer(1.0) for _ in range(8)]
    generated = [dancer(0.5) for _ in range(8)]
    fid = score_sets(generated, reference, PROTOCOLS["aist"], bootstrap=0).metrics[0]
    assert fid.name == "FID_k" and fid.mean_term <= fid.generated
    top = fid.gaps[0]
    assert (top.index, top.what) == (3 * 7, "left_ankle's mean squared horizontal speed")
    by_hand = [
        np.mean([M.kinetic_features(s.positions, 60.0)[3 * 7] for s in which]) for which in (generated, reference)
    ]
    assert top.ratio == pytest.approx(by_hand[0] / by_hand[1]) and top.ratio == pytest.approx(0.25, abs=0.05)
    assert top.sds < 0 and "left_ankle's mean squared horizontal speed 0.2" in str(top) and "sd below" in str(top)
    table = score_sets(generated, reference, PROTOCOLS["aist"], bootstrap=0).table()
    assert "FID_k: the means' gap is " in table and "furthest from the reference: left_ankle's" in table
    never = FeatureGap(0, "a relation the dancers never show", 9.0, 0.04, 0.0, 3.2e8)  # the ratio is undefined
    assert str(never) == "a relation the dancers never show 0.04, the reference's 0 (3.2e+08 sd above)"
    assert never.to_dict()["ratio"] is None
    assert M.describe_kinetic_feature(71, load_joint_set("smpl24").names) == "right_hand's mean acceleration"
    with pytest.raises(KinectDataError, match="kinetic feature 72 does not exist for 24 joints"):
        M.describe_kinetic_feature(72, load_joint_set("smpl24").names)


def test_a_feature_the_reference_barely_varies_in_is_named_when_it_swamps_fid():
    from kinectdata.evaluation.metrics.distribution import far_from_reference_features

    rng = np.random.default_rng(4)
    reference, generated = rng.normal(size=(6, 4)), rng.normal(size=(5, 4))
    reference[:, 1] = 5.0 + 1e-9 * rng.normal(size=6)  # nearly constant, not exactly
    reference[:, 3] = 2.0  # exactly constant: constant_reference_features names it
    generated[:, 3] = 2.0 + rng.normal(size=5)
    g_std, _ = M.standardise_by_reference(generated, reference)
    assert M.constant_reference_features(generated, reference) == [3]
    assert far_from_reference_features(g_std, [3]) == [1]
    # by hand: feature 1 sits about 5e9 reference standard deviations away
    assert abs(generated[0, 1] - reference[:, 1].mean()) / reference[:, 1].std() > 1e3
    generated[:, 1] = reference[:5, 1]
    assert far_from_reference_features(M.standardise_by_reference(generated, reference)[0], [3]) == []


def test_quality_checks_on_known_answers():
    t = np.arange(100) / 50.0
    p = np.zeros((100, 2, 3))
    p[:, 1, 0] = 1.0 + 0.1 * np.sin(2 * np.pi * t)  # a bone of length 1 +- 0.1
    cv = M.bone_length_variation(p, [-1, 0])
    assert np.isnan(cv[0]) and cv[1] == pytest.approx(np.std(p[:, 1, 0]) / np.mean(p[:, 1, 0]))
    cubic = np.zeros((50, 1, 3))
    cubic[:, 0, 0] = (np.arange(50) / 25.0) ** 3  # x = t^3: jerk 6 m/s^3 everywhere
    assert M.mean_jerk(cubic, 25.0) == pytest.approx(6.0)


def test_every_shipped_mapping_covers_smpl24_and_names_its_approximations():
    smpl = load_joint_set("smpl24")
    assert set(shipped_smpl24_mappings()) >= {"kinect_v2", "nite", "azure_kinect", "openpose_mpi", "htr"}
    for name in shipped_smpl24_mappings():
        mapping = load_smpl24_mapping(name)
        if name != "htr":  # HTR files bring their own joints: the mapping's are the ones it names
            assert mapping.weights.shape == (24, len(load_joint_set(name)))
        np.testing.assert_allclose(mapping.weights.sum(axis=1), 1.0)
        record = mapping.describe()
        assert len(record["exact"]) + len(record["approximated"]) == len(smpl)
    kinect = load_smpl24_mapping("kinect_v2")
    assert "spine1" in kinect.describe()["approximated"] and "left_knee" in kinect.describe()["exact"]


def test_a_kinect_joint_missing_is_missing_in_every_smpl_joint_made_from_it():
    mapping = load_smpl24_mapping("kinect_v2")
    p = np.random.default_rng(0).normal(size=(4, 25, 3))
    p[1, load_joint_set("kinect_v2").index("SpineMid")] = np.nan
    mapped, valid = mapping.apply(p)
    smpl = load_joint_set("smpl24")
    lost = {smpl.names[k] for k in np.flatnonzero(~valid[1])}
    assert lost == {"spine1", "spine2", "spine3"} and valid[[0, 2, 3]].all()
    assert np.isnan(mapped[1, smpl.index("spine2")]).all()


def test_sets_of_files_arrays_z_up_and_pickles(tmp_path):
    protocol = PROTOCOLS["bailando"]
    for i in range(2):
        joints = INPUTS["joints_gen"][i]
        np.save(tmp_path / f"a{i}.npy", joints)
        np.savez(tmp_path / f"b{i}.npz", full_pose=np.stack([joints[..., 0], -joints[..., 2], joints[..., 1]], -1))
    a = load_dance_set(tmp_path, protocol)
    assert [s.name for s in a] == ["a0", "a1", "b0", "b1"]
    np.testing.assert_allclose(a[0].positions, INPUTS["joints_gen"][0])
    z = load_dance_set(tmp_path / "b0.npz", protocol, DanceReading(array_up="z"))
    np.testing.assert_allclose(z[0].positions, INPUTS["joints_gen"][0], atol=1e-12)
    half = load_dance_set(tmp_path / "a0.npy", PROTOCOLS["edge"], DanceReading(array_fps=120.0))  # resampled to 60 fps
    assert half[0].positions.shape[0] == 120
    np.save(tmp_path / "dict.npy", {"pred_position": INPUTS["joints_gen"][0].reshape(240, 72)}, allow_pickle=True)
    with pytest.raises(FormatError, match="allow-pickle"):
        load_dance_set(tmp_path / "dict.npy", protocol)
    assert load_dance_set(tmp_path / "dict.npy", protocol, DanceReading(allow_pickle=True))[0].positions.shape == (
        240,
        24,
        3,
    )
    import pickle

    planted = tmp_path / "planted.txt"
    (tmp_path / "evil.pkl").write_bytes(pickle.dumps({"pred_position": _Planted(str(planted))}))
    with pytest.raises(
        FormatError,
        match=r"evil.pkl: not readable \(refused: the pickle asks for pathlib.Path.write_text, not a numpy array",
    ):
        load_dance_set(tmp_path / "evil.pkl", protocol, DanceReading(allow_pickle=True))
    assert not planted.exists()
    np.save(tmp_path / "bad.npy", np.zeros((10, 17, 3)))
    with pytest.raises(FormatError, match=r"bad.npy: joint array of shape \(10, 17, 3\)"):
        load_dance_set(tmp_path / "bad.npy", protocol)


class _Planted:
    """An object whose unpickling would write a file: what a malicious pickle does."""

    def __init__(self, path: str) -> None:
        self.path = path

    def __reduce__(self):
        return (Path.write_text, (Path(self.path), "ran"))


def test_a_kinect_recording_is_scored_through_its_mapping(fixture_csv):
    seq = load_dance_set(fixture_csv, PROTOCOLS["aist"])[0]
    assert seq.positions.shape[1:] == (24, 3) and np.isfinite(seq.positions).all()
    assert seq.mapping["source"] == "kinect_v2" and "spine1" in seq.mapping["approximated"]


def test_one_sequence_gets_the_per_sequence_metrics_and_says_why_no_fid():
    one = score_sets(_sequences("gen")[:1], _sequences("gt"), PROTOCOLS["bailando"], bootstrap=0)
    both = score_sets(_sequences("gen"), _sequences("gt"), PROTOCOLS["bailando"], bootstrap=0)
    assert one.metric("FID_k").generated is None and one.metric("FID_k").note == "needs 2 sequences per set"
    assert any("at least 2 sequences per set" in w for w in one.warnings)
    first = next(iter(both.per_sequence["generated"].values()))["beat_align_score"]
    assert one.metric("BAS").generated == pytest.approx(first)
    with pytest.raises(KinectDataError, match="sequences in both sets"):
        score_sets([], _sequences("gt"), PROTOCOLS["bailando"])


def _console_blocks(doc: Path) -> list[str]:
    text = doc.read_text(encoding="utf-8")
    return [block.split("```", 1)[0] for block in text.split("```console\n")[1:]]


def test_the_shell_examples_of_docs_metrics_run(tmp_path):
    import shlex

    from click.testing import CliRunner

    from kinectdata.cli import main

    repo = Path(__file__).parents[2]
    runner = CliRunner()
    commands = [line for block in _console_blocks(repo / "docs" / "metrics.md") for line in block.splitlines() if line]
    assert len(commands) == 4
    with runner.isolated_filesystem(temp_dir=tmp_path):
        Path("sample_data").symlink_to(repo / "sample_data")
        for command in commands:
            args = shlex.split(command)
            assert args[0] == "kinectdata"
            result = runner.invoke(main, args[1:])
            assert result.exit_code == 0, (command, result.output)
        record = json.loads(Path("metrics.json").read_text())
        assert record["protocol"]["name"] == "aist" and record["sets"]["reference"]["count"] == 2
        assert record["metrics"]["BAS"]["reference"] is not None  # aligned recordings bring their beats
        assert "spine1" in record["joint_mappings"][0]["approximated"]


def test_score_command_on_arrays_and_bad_input(tmp_path):
    from click.testing import CliRunner

    from kinectdata.cli import main

    for which in SETS:
        (tmp_path / which).mkdir()
        for i, joints in enumerate(INPUTS[f"joints_{which}"]):
            np.save(tmp_path / which / f"{which}{i}.npy", joints)
    beats = {f"{w}{i}": _beats(w, i).tolist() for w in SETS for i in range(6)}
    (tmp_path / "beats.json").write_text(json.dumps(beats))
    out = tmp_path / "m.json"
    result = CliRunner().invoke(
        main,
        ["score", str(tmp_path / "gen"), str(tmp_path / "gt"), "--beats", str(tmp_path / "beats.json"),
         "--bootstrap", "20", "-o", str(out)],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    record = json.loads(out.read_text())
    assert record["metrics"]["FID_k"]["generated"] == pytest.approx(
        EXPECTED["set_metrics"]["bailando_quantized_metrics"]["fid_k"], rel=1e-5
    )
    assert record["metrics"]["BAS"]["generated"] == pytest.approx(EXPECTED["set_metrics"]["bailando_calc_ba_score_gen"])
    assert record["protocol"]["bas_direction"] == "music_to_motion" and record["sets"]["generated"]["count"] == 6
    assert "FID_k" in result.output and "BAS" in result.output
    np.save(tmp_path / "gen" / "broken.npy", np.zeros((5, 3)))
    result = CliRunner().invoke(main, ["score", str(tmp_path / "gen"), str(tmp_path / "gt"), "-o", str(out)])
    assert result.exit_code == 1 and "broken.npy: joint array of shape (5, 3)" in result.output
    assert "Traceback" not in result.output


def test_the_python_example_of_docs_metrics_runs(monkeypatch, capsys):
    repo = Path(__file__).parents[2]
    text = (repo / "docs" / "metrics.md").read_text(encoding="utf-8")
    blocks = [block.split("```", 1)[0] for block in text.split("```python\n")[1:]]
    assert len(blocks) == 1
    monkeypatch.chdir(repo)
    exec(compile(blocks[0], "docs/metrics.md python block", "exec"), {})
    assert "FID_k" in capsys.readouterr().out


MOTIONBUILDER = {  # segment: (parent, offset from the parent in cm, y up)
    "Hips": ("GLOBAL", (0, 95, 0)),
    "Spine": ("Hips", (0, 10, 0)),
    "Neck": ("Spine", (0, 45, 0)),
    "Head": ("Neck", (0, 10, 0)),
    "LeftShoulder": ("Spine", (3, 40, 0)),
    "LeftArm": ("LeftShoulder", (15, 0, 0)),
    "LeftForeArm": ("LeftArm", (28, 0, 0)),
    "LeftHand": ("LeftForeArm", (25, 0, 0)),
    "RightShoulder": ("Spine", (-3, 40, 0)),
    "RightArm": ("RightShoulder", (-15, 0, 0)),
    "RightForeArm": ("RightArm", (-28, 0, 0)),
    "RightHand": ("RightForeArm", (-25, 0, 0)),
    "LeftUpLeg": ("Hips", (9, -5, 0)),
    "LeftLeg": ("LeftUpLeg", (0, -42, 0)),
    "LeftFoot": ("LeftLeg", (0, -40, 0)),
    "LeftToeBase": ("LeftFoot", (0, -6, 13)),
    "RightUpLeg": ("Hips", (-9, -5, 0)),
    "RightLeg": ("RightUpLeg", (0, -42, 0)),
    "RightFoot": ("RightLeg", (0, -40, 0)),
    "RightToeBase": ("RightFoot", (0, -6, 13)),
}


def _motionbuilder_htr(path: Path, frames: int = 90) -> Path:
    """An HTR file as Brekel's tools lay it out, MotionBuilder segment names, the hips walking
    along x at 1 m/s (30 fps, cm)."""
    lines = [
        "[Header]", "FileType htr", "DataType HTRS", "FileVersion 1", f"NumSegments {len(MOTIONBUILDER)}",
        f"NumFrames {frames}", "DataFrameRate 30", "EulerRotationOrder ZYX", "CalibrationUnits cm",
        "RotationUnits Degrees", "GlobalAxisofGravity Y", "BoneLengthAxis Y", "ScaleFactor 1.000000",
        "[SegmentNames&Hierarchy]",
    ]  # fmt: skip
    lines += [f"{name}\t{parent}" for name, (parent, _) in MOTIONBUILDER.items()]
    lines.append("[BasePosition]")
    lines += [f"{name}\t{x}\t{y}\t{z}\t0\t0\t0\t10" for name, (_, (x, y, z)) in MOTIONBUILDER.items()]
    for name in MOTIONBUILDER:
        lines.append(f"[{name}]")
        step = 100 / 30 if name == "Hips" else 0.0
        lines += [f"{f + 1}\t{step * f:.6f}\t0\t0\t0\t0\t0\t1" for f in range(frames)]
    lines.append("[EndOfFile]")
    path.write_text("\r\n".join(lines) + "\r\n")
    return path


def test_an_htr_file_with_motionbuilder_names_maps_through_the_shipped_mapping(tmp_path):
    htr = _motionbuilder_htr(tmp_path / "walk.htr")
    seq = load_dance_set(htr, PROTOCOLS["aist"])[0]
    assert seq.mapping["source"] == "htr" and seq.positions.shape == (179, 24, 3)  # 3 s at 60 fps
    smpl = load_joint_set("smpl24")
    p = seq.positions
    # independent: the segment origins summed from the base offsets, in metres, hips moving 1 m/s
    np.testing.assert_allclose(
        p[:, smpl.index("pelvis")], np.c_[np.arange(179) / 60, np.full(179, 0.95), np.zeros(179)], atol=1e-9
    )
    np.testing.assert_allclose(p[0, smpl.index("left_knee")], [0.09, 0.48, 0.0], atol=1e-9)
    np.testing.assert_allclose(p[0, smpl.index("left_foot")], [0.09, 0.02, 0.13], atol=1e-9)
    np.testing.assert_allclose(p[0, smpl.index("spine3")], [0, 0.95 + 0.10 + 0.30, 0], atol=1e-9)
    assert seq.native_fps == pytest.approx(30.0)


def test_an_htr_file_with_other_names_asks_for_a_mapping_file():
    with pytest.raises(
        FormatError, match=r"two_segments.htr: its htr joints cannot be mapped.*it has Hips, Spine\).*--mapping FILE"
    ):
        load_dance_set(REPO / "tests" / "data" / "htr" / "two_segments.htr", PROTOCOLS["aist"])


def test_a_mapping_file_follows_the_joint_order_of_the_file_it_maps(tmp_path):
    """A user's mapping for an HTR file names its joints in another order than the file: the weights
    must follow the file's (Spine is its second segment, the mapping names it first)."""
    smpl = load_joint_set("smpl24")
    joints = {name: {"from": {"Spine": 1}, "exact": False} for name in smpl.names}
    joints["pelvis"] = {"from": {"Hips": 1}, "exact": True}
    (tmp_path / "two.json").write_text(json.dumps({"joint_set": "htr", "target": "smpl24", "joints": joints}))
    htr = REPO / "tests" / "data" / "htr" / "two_segments.htr"
    seq = load_dance_set(htr, PROTOCOLS["aist"], DanceReading(mapping=tmp_path / "two.json"))[0]
    from kinectdata.formats import read_motion

    raw = read_motion(htr)
    np.testing.assert_allclose(seq.positions[0, smpl.index("pelvis")], raw.positions[0, raw.joint_set.index("Hips")])
    np.testing.assert_allclose(seq.positions[0, smpl.index("head")], raw.positions[0, raw.joint_set.index("Spine")])


def test_smpl24_writes_the_joint_array_score_reads_back_alike(tmp_path):
    """kinectdata smpl24: a Kinect take as the field's [T, 24, 3] array at 60 fps, y up; scoring reads
    the array (--fps 60, --up y) as the same sequence it makes of the take itself."""
    from click.testing import CliRunner
    from conftest import REPO

    from kinectdata.cli import main
    from kinectdata.evaluation.motion_sets import DanceReading, load_dance_sequence
    from kinectdata.evaluation.protocols import get_protocol

    take = REPO / "sample_data" / "synth_001.csv"
    out = tmp_path / "take.npy"
    result = CliRunner().invoke(main, ["smpl24", str(take), "-o", str(out)])
    assert result.exit_code == 0, result.output
    joints = np.load(out)
    assert joints.dtype == np.float32 and joints.shape[1:] == (24, 3)
    protocol = get_protocol("bailando")  # 60 fps
    direct = load_dance_sequence(take, protocol)
    back = load_dance_sequence(out, protocol, DanceReading(60.0, "y"))
    np.testing.assert_allclose(back.positions, direct.positions, atol=1e-6)
    result = CliRunner().invoke(main, ["smpl24", str(REPO / "sample_data"), "-o", str(tmp_path / "x.npy")])
    assert result.exit_code != 0 and "Traceback" not in result.output


def test_a_value_outside_its_own_interval_is_said_and_explained():
    """A set against itself: FID is 0 exactly, and every pair of sets drawn with replacement from it
    differs, so all the draws are above 0 and the interval excludes the value: the table says so and
    why. On the fixture's sets the values lie inside their intervals and nothing is said."""
    same = score_sets(_sequences("gt"), _sequences("gt"), PROTOCOLS["bailando"], bootstrap=100)
    fid = same.metric("FID_k")
    assert fid.generated == pytest.approx(0.0, abs=1e-3) and fid.interval.low > 0.1
    said = [w for w in same.warnings if w.startswith("FID_k: ") and "outside" in w]
    assert len(said) == 1 and "lies outside its own 95 % interval" in said[0] and "drawn with replacement" in said[0]
    assert any(line == f"warning: {said[0]}" for line in same.table().splitlines())
    apart = score_sets(_sequences("gen"), _sequences("gt"), PROTOCOLS["bailando"], bootstrap=100)
    assert not [w for w in apart.warnings if "outside its own" in w]


def test_a_geometric_feature_is_described_by_what_sets_it():
    """Stretching the spine fast sets exactly the features whose description says so."""
    pose = INPUTS["joints_gt"][0][:1].repeat(60, axis=0)  # one real pose held still
    still = M.geometric_features(pose)
    stretched = pose.copy()
    spine = stretched[:, 9] - stretched[:, 3]  # chest (spine3) from belly (spine1)
    stretched[1::2, 9] += 0.5 * spine[1::2]  # the chest jumps along the spine every other frame
    changed = np.flatnonzero(M.geometric_features(stretched) != still)
    described = [i for i in range(32) if M.describe_feature(i).startswith("chest moving along belly->chest")]
    assert described == [4, 5] and set(described) <= set(changed.tolist())


def test_a_huge_figure_keeps_the_tables_columns_apart():
    """FID_g reaches 1e15 when a geometric feature never changes in the reference set; printed in
    fixed point, it ran into its interval's column ("1412944216380743.5091.59 - ...")."""
    from kinectdata.evaluation.field_scores import Interval, MetricRow

    scores = score_sets(_sequences("gen"), _sequences("gt"), PROTOCOLS["bailando"], bootstrap=0)
    huge = MetricRow("FID_g", "lower", 1.4129442e15, interval=Interval(91.59, 4.1795e15, 0.95, 100))
    scores.metrics[:] = [huge]
    line = next(row for row in scores.table().splitlines() if row.startswith("FID_g "))
    assert line.split() == ["FID_g", "lower", "1.413e+15", "91.59", "-", "4.18e+15", "-"], line
