"""Round trips: raw -> aligned -> dataset -> run -> generate -> (CSV, BVH, smpl24, render) -> read back,
for a joint set kinectdata does not ship (a 19-joint dancer declared by schema files) and for a shipped
one (Kinect v2), with the joint set, its bones and the dance's place in the world compared at each step."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import REPO, TINY_TRAINING
from helpers import DANCER19, write_dancer19_schemas

from kinectdata.align.aligned import AlignedRecording
from kinectdata.cli import main
from kinectdata.core.jointsets import load_joint_set
from kinectdata.formats import read_motion
from kinectdata.viz.render import load_input, render_frame

pytest.importorskip("torch")

FPS = 30
SECONDS = 12
# where each joint sits on a standing dancer (metres, y up; pelvis 0.95 m above the floor)
REST = {
    "pelvis": (0, 0.95, 0),
    "spine1": (0, 1.1, 0),
    "spine2": (0, 1.3, 0),
    "neck": (0, 1.5, 0),
    "head": (0, 1.65, 0),
    "l_shoulder": (0.18, 1.45, 0),
    "l_elbow": (0.22, 1.18, 0),
    "l_wrist": (0.24, 0.95, 0.05),
    "r_shoulder": (-0.18, 1.45, 0),
    "r_elbow": (-0.22, 1.18, 0),
    "r_wrist": (-0.24, 0.95, 0.05),
    "l_hip": (0.1, 0.9, 0),
    "l_knee": (0.11, 0.5, 0.02),
    "l_ankle": (0.12, 0.08, 0),
    "l_toe": (0.12, 0.02, 0.12),
    "r_hip": (-0.1, 0.9, 0),
    "r_knee": (-0.11, 0.5, 0.02),
    "r_ankle": (-0.12, 0.08, 0),
    "r_toe": (-0.12, 0.02, 0.12),
}
STANDS_AT = np.array([0.7, 0.0, 2.6])  # the dancer's place in the sensor's space, far from its origin


def _dancer19_takes(root):
    """Three takes of a bobbing, travelling 19-joint dancer (CSV by a user dialect) with the bundled songs,
    its joint-set file (with its SMPL-24 mapping), and the aligned .h5 of each take."""
    schemas = root / "schemas"
    schemas.mkdir()
    write_dancer19_schemas(schemas)
    rest = np.array([REST[j] for j in DANCER19])
    t = np.arange(FPS * SECONDS) / FPS
    entries = []
    for k, split in ((1, "train"), (2, "test"), (3, "test")):
        bob = 0.04 * np.sin(2 * np.pi * 2.0 * t)[:, None, None] * np.array([0, 1, 0])
        travel = (0.02 * k * t)[:, None, None] * np.array([1, 0, 0])  # walks sideways, 2-6 cm/s
        sway = 0.05 * np.sin(2 * np.pi * 0.5 * k * t[:, None, None] + np.arange(len(DANCER19))[None, :, None])
        pos = rest[None] + STANDS_AT + bob + travel + sway * np.array([1, 0.3, 1])
        header = ["t"] + [f"{j}_{a}" for j in DANCER19 for a in "xyz"]
        rows = [",".join([f"{t[f]:.4f}"] + [f"{v:.5f}" for v in pos[f].ravel()]) for f in range(len(t))]
        raw = root / f"take{k}.csv"
        raw.write_text("\n".join([",".join(header), *rows]) + "\n")
        shutil.copy(REPO / "sample_data" / f"synth_00{k}.flac", root / f"take{k}.flac")
        result = CliRunner().invoke(
            main,
            ["align", str(raw), str(root / f"take{k}.flac"), "--schema", str(schemas / "dancer19_csv.json"),
             "--offset", "0", "-o", str(root / f"take{k}.h5")],
        )  # fmt: skip
        assert result.exit_code == 0, result.output
        entries.append({"recording": f"take{k}.h5", "split": split})
    (root / "recordings.json").write_text(json.dumps(entries))
    return root


def _without_end_sites(motion):
    """The motion without the zero-length End Sites a BVH file gives each leaf (read as ``<leaf>_End``)."""
    from kinectdata.core.jointsets import JointSet
    from kinectdata.core.motion import Motion

    js = motion.joint_set
    keep = [j for j, name in enumerate(js.names) if not name.endswith("_End")]
    names = [js.names[j] for j in keep]
    parents = [None if js.parents[j] < 0 else js.names[js.parents[j]] for j in keep]
    return Motion(motion.times, motion.positions[:, keep], JointSet.custom(js.name, names, parents))


def _same_joint_set(motion, expected) -> None:
    js = motion.joint_set
    assert (js.name, js.names, js.parents) == (expected.name, expected.names, expected.parents)
    assert js.bones() == expected.bones()


@pytest.fixture(scope="module")
def dancer19_run(tmp_path_factory):
    """The 19-joint takes, aligned; a root-centred positions dataset of them; a tiny trained run."""
    from kinectdata.training.config import TrainConfig
    from kinectdata.training.train import train

    root = _dancer19_takes(tmp_path_factory.mktemp("dancer19"))
    built = CliRunner().invoke(
        main, ["build-dataset", str(root / "recordings.json"), "-o", str(root / "ds"), "--target", "positions",
               "--root-centre", "--features", "yalta2016"],
    )  # fmt: skip
    assert built.exit_code == 0, built.output
    train(root / "ds", root / "run", TrainConfig(**TINY_TRAINING))
    return root


def test_a_user_joint_set_and_its_place_in_the_world_survive_every_step(dancer19_run, tmp_path):
    root = dancer19_run
    dancer19 = load_joint_set(root / "schemas" / "dancer19.json")
    aligned = AlignedRecording.load(root / "take3.h5")
    _same_joint_set(aligned.motion, dancer19)  # aligned: the whole joint set, its mapping with it
    assert aligned.motion.joint_set.to_smpl24 == dancer19.to_smpl24 and aligned.motion.joint_set.roles == dancer19.roles

    runner = CliRunner()
    out = tmp_path / "gen"
    out.mkdir()
    made = runner.invoke(
        main, ["generate", "--run", str(root / "run"), str(root / "take3.h5"), "-o", str(out / "a.csv")]
    )
    assert made.exit_code == 0, made.output
    assert "starts from the recording's first pose; placed by the recording's anchor" in made.output
    generated = read_motion(out / "a.csv")
    _same_joint_set(generated, dancer19)
    assert generated.joint_set.to_smpl24 == dancer19.to_smpl24
    assert generated.n_frames == aligned.motion.n_frames
    # frame 0 is the recording's true first pose, where the dancer stood (not around the origin)
    np.testing.assert_allclose(generated.positions[0], aligned.motion.positions[0], atol=2e-3)
    assert np.all(np.abs(generated.positions[:, 0, [0, 2]] - STANDS_AT[[0, 2]]) < 0.5)

    bvh = runner.invoke(
        main, ["generate", "--run", str(root / "run"), str(root / "take3.h5"), "-o", str(out / "a.bvh")]
    )
    assert bvh.exit_code == 0, bvh.output
    back = _without_end_sites(read_motion(out / "a.bvh"))
    assert back.joint_set.names == dancer19.names and back.joint_set.parents == dancer19.parents
    np.testing.assert_allclose(back.positions[:, 0], generated.positions[:, 0], atol=1e-4)  # the root, exactly
    off = np.linalg.norm(back.positions - generated.positions, axis=-1)
    assert np.median(off) < 0.05, np.median(off)  # the rest hang on the BVH's fixed bones

    arrays = {}
    for name, source in (("raw", root / "take3.csv"), ("aligned", root / "take3.h5"), ("generated", out / "a.csv")):
        args = ["smpl24", str(source), "-o", str(out / f"{name}.npy")]
        if name == "raw":
            args += ["--schema", str(root / "schemas" / "dancer19_csv.json")]
        result = runner.invoke(main, args)
        assert result.exit_code == 0, f"{name}: {result.output}"
        arrays[name] = np.load(out / f"{name}.npy")
    np.testing.assert_allclose(arrays["aligned"], arrays["raw"], atol=1e-4)  # same joints, same place
    np.testing.assert_allclose(arrays["generated"][0], arrays["aligned"][0], atol=2e-3)

    for path in (root / "take3.h5", out / "a.csv", out / "a.bvh"):
        drawn = load_input(path, with_audio=False).motion
        kept = _without_end_sites(drawn) if path.suffix == ".bvh" else drawn
        assert kept.joint_set.bones() == dancer19.bones(), path
        frame = render_frame(drawn, 0.5, (160, 120))
        assert frame.shape == (120, 160, 3)


def test_a_shipped_joint_set_comes_back_by_name(trained_run, tmp_path):
    """Kinect v2 (the sample data's): the generated CSV names its joint set, the BVH keeps its bones."""
    run, _ = trained_run
    kinect = load_joint_set("kinect_v2")
    result = CliRunner().invoke(
        main, ["align", str(REPO / "sample_data" / "synth_001.csv"), str(REPO / "sample_data" / "synth_001.flac"),
               "-o", str(tmp_path / "a.h5")],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    for name in ("a.csv", "a.bvh"):
        made = CliRunner().invoke(
            main, ["generate", "--run", str(run), str(tmp_path / "a.h5"), "-o", str(tmp_path / name)]
        )
        assert made.exit_code == 0, made.output
    text = (tmp_path / "a.csv").read_text()
    assert "# joint_set: kinect_v2\n" in text and "joint_set_document" not in text
    generated = read_motion(tmp_path / "a.csv")
    _same_joint_set(generated, kinect)
    back = _without_end_sites(read_motion(tmp_path / "a.bvh"))
    for j, name in enumerate(back.joint_set.names):  # the joints the run places, on Kinect v2's bones
        parent = back.joint_set.parents[j]
        expected = kinect.parents[kinect.index(name)]
        assert (parent < 0 and expected < 0) or back.joint_set.names[parent] == kinect.names[expected], name
    assert len(back.joint_set) >= 15
    smpl = CliRunner().invoke(main, ["smpl24", str(tmp_path / "a.csv"), "-o", str(tmp_path / "a.npy")])
    assert smpl.exit_code == 0, smpl.output
    assert np.load(tmp_path / "a.npy").shape[1:] == (24, 3)


@pytest.mark.slow
def test_evaluate_and_score_give_one_table_on_the_same_positions(dancer19_run, tmp_path):
    """evaluate writes the motion it scored; score reads it back (CSV, the joint set's own mapping,
    the beats file) and gets the same numbers; both say which positions they scored."""
    from kinectdata.evaluation.evaluate import evaluate

    root = dancer19_run
    results = evaluate(
        root / "run", root / "ds", "test", out=tmp_path / "ev", engines=[], bootstrap=40, baselines=False
    )
    field = results["field"]
    assert field["positions"]["placement"].startswith("world: root-centred targets put back where")
    assert field["positions"]["source_fps"] == [30] and field["positions"]["scored_fps"] == 60
    assert field["positions"]["joint_sets"] == ["dancer19"]
    scored = tmp_path / "ev" / "scored"
    # the real motion scored is the aligned recording itself, in the world: frame 0 is its frame 1
    for take in ("take2", "take3"):
        real = read_motion(scored / "real" / f"{take}.csv")
        _same_joint_set(real, load_joint_set(root / "schemas" / "dancer19.json"))
        np.testing.assert_allclose(
            real.positions[0], AlignedRecording.load(root / f"{take}.h5").motion.positions[1], atol=2e-5
        )
    again = CliRunner().invoke(
        main, ["score", str(scored / "generated"), str(scored / "real"), "--beats", str(scored / "beats.json"),
               "--bootstrap", "40", "-o", str(tmp_path / "again.json")],
    )  # fmt: skip
    assert again.exit_code == 0, again.output
    assert "positions: as the files hold them; 30 fps resampled to 60; joints of dancer19 as SMPL-24" in again.output
    mine = json.loads((tmp_path / "ev" / "metrics.json").read_text())["metrics"]
    theirs = json.loads((tmp_path / "again.json").read_text())["metrics"]
    assert mine.keys() == theirs.keys() and {"FID_k", "FID_g", "BAS", "PFC"} <= mine.keys()
    for name, row in mine.items():
        for which in ("generated", "reference"):
            if row[which] is None:
                assert theirs[name][which] is None, name
            else:
                assert theirs[name][which] == pytest.approx(row[which], rel=1e-3, abs=1e-6), (name, which)
