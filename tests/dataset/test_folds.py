"""Cross-validation folds of a recordings manifest (kinectdata.dataset.folds, ``kinectdata folds``)."""

from __future__ import annotations

from collections import Counter

import pytest
import yaml
from click.testing import CliRunner
from corpus_copies import make_tang2018_copy

from kinectdata.cli import main
from kinectdata.core.errors import ConfigError
from kinectdata.dataset.folds import deal_folds, write_folds
from kinectdata.dataset.inputs import read_recordings


def _corpus_shaped_entries() -> list[dict]:
    """The real corpus's shape: 3 cha-chas, 5 rumbas, 28 waltzes outside the test split, 7 in it."""
    styles = {"C": ("cha-cha", 4), "R": ("rumba", 4), "W": ("waltz", 3), "T": ("tango", 4)}
    counts = {"C": 3, "R": 5, "W": 28}
    entries = [
        {"name": f"{s}_{i}", "split": "train", "style": styles[s][0], "beats_per_bar": styles[s][1]}
        for s, n in counts.items()
        for i in range(n)
    ]
    entries += [{"name": f"test_{s}_{i}", "split": "test", "style": styles[s][0]} for s in "CCRRTWW" for i in [0]]
    return entries


def test_every_recording_outside_the_test_split_is_validated_on_once_and_each_style_is_spread():
    entries = _corpus_shaped_entries()
    folds = deal_folds(entries, 3, by="style")
    dealt = [name for fold in folds for name in fold]
    assert sorted(dealt) == sorted(e["name"] for e in entries if e["split"] != "test")  # each once, no test
    assert [len(f) for f in folds] == [12, 12, 12]
    for style, count in (("C", 3), ("R", 5), ("W", 28)):
        shares = sorted(sum(n.startswith(style + "_") for n in fold) for fold in folds)
        assert max(shares) - min(shares) <= 1 and sum(shares) == count, (style, shares)
    by_metre = deal_folds(entries, 3, by="beats_per_bar")
    assert sorted(sum(n[0] in "CR" for n in fold) for fold in by_metre) == [2, 3, 3]  # the 8 songs in 4
    assert deal_folds(entries, 3, seed=0) == folds and deal_folds(entries, 3, seed=1) != folds
    assert [len(f) for f in deal_folds(entries, 5, by="none")] == [8, 7, 7, 7, 7]


@pytest.mark.parametrize("count", [1, 37])
def test_fold_counts_outside_two_to_the_recordings_are_refused(count):
    with pytest.raises(ConfigError, match=rf"{count} folds of 36 recordings \(not in the test split\): give 2 to 36"):
        deal_folds(_corpus_shaped_entries(), count)


def test_fold_manifests_sit_beside_the_source_and_build_as_it_does(tmp_path):
    make_tang2018_copy(tmp_path, seconds=0.5)
    result = CliRunner().invoke(main, ["prepare", "tang2018", str(tmp_path / "Music-to-Dance-Motion-Synthesis"),
                                       "-o", str(tmp_path / "tang.yaml"), "--labelled-songs"])  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "listed 3 songs without a dance as labelled music (1 cha-cha, 1 rumba, 1 waltz)" in result.output
    source = yaml.safe_load((tmp_path / "tang.yaml").read_text())
    outside_test = {r["name"] for r in source["recordings"] if r["split"] != "test"}
    made = write_folds(tmp_path / "tang.yaml", 2)
    assert [f.path.name for f in made] == ["tang.fold1of2.yaml", "tang.fold2of2.yaml"]
    validated = []
    for fold in made:
        written = yaml.safe_load(fold.path.read_text())
        assert {k: v for k, v in written.items() if k != "recordings"} == {
            k: v for k, v in source.items() if k != "recordings"
        }
        splits = {r["name"]: r["split"] for r in written["recordings"]}
        assert set(splits) == outside_test and Counter(splits.values()).keys() <= {"train", "val"}
        assert sorted(n for n, s in splits.items() if s == "val") == sorted(fold.validation)
        assert sorted(n for n, s in splits.items() if s == "train") == sorted(fold.training)
        entries = read_recordings(fold.path, allow_outside_paths=True)  # the same files, found from beside it
        assert {e.name: e.recording for e in entries} == {
            e.name: e.recording
            for e in read_recordings(tmp_path / "tang.yaml", allow_outside_paths=True)
            if e.name in outside_test
        }
        validated += fold.validation
    assert sorted(validated) == sorted(outside_test)


def test_the_command_prints_each_fold_and_a_bad_count_is_one_line(tmp_path):
    make_tang2018_copy(tmp_path, seconds=0.5)
    runner = CliRunner()
    runner.invoke(main, ["prepare", "tang2018", str(tmp_path / "Music-to-Dance-Motion-Synthesis"), "-o",
                         str(tmp_path / "tang.yaml")])  # fmt: skip
    result = runner.invoke(main, ["folds", str(tmp_path / "tang.yaml"), "-k", "2", "--by", "beats_per_bar"])
    assert result.exit_code == 0, result.output
    assert f"wrote {tmp_path / 'tang.fold1of2.yaml'}: validates on " in result.output
    result = runner.invoke(main, ["folds", str(tmp_path / "tang.yaml"), "-k", "99"])
    assert result.exit_code == 1 and result.output.count("\n") == 1
    assert "99 folds of 7 recordings (not in the test split): give 2 to 7" in result.output
    assert not (tmp_path / "tang.fold1of99.yaml").exists()


def test_a_fold_that_cannot_be_written_leaves_none(tmp_path, monkeypatch):
    import kinectdata.dataset.folds as folds

    make_tang2018_copy(tmp_path, seconds=0.5)
    CliRunner().invoke(main, ["prepare", "tang2018", str(tmp_path / "Music-to-Dance-Motion-Synthesis"), "-o",
                              str(tmp_path / "tang.yaml")])  # fmt: skip
    (tmp_path / "tang.fold3of3.yaml").mkdir()  # the third fold's name is taken by a folder
    result = CliRunner().invoke(main, ["folds", str(tmp_path / "tang.yaml"), "-k", "3"])
    assert result.exit_code == 1 and "tang.fold3of3.yaml" in result.output
    assert not (tmp_path / "tang.fold1of3.yaml").exists() and not (tmp_path / "tang.fold2of3.yaml").exists()
    assert folds.fold_path(tmp_path / "tang.yaml", 3, 3).is_dir()  # what was there is left as it was
