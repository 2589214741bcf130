"""``kinectdata quickstart --corpus tang2018 PATH`` on a copy made in the corpus's shape (the corpus
has no licence): prepared, built with the music's pulse, trained with train-baseline's defaults,
evaluated on the validation dances only, motion generated; and its faults one line each."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner
from corpus_copies import make_tang2018_copy

from kinectdata.cli import main


@pytest.mark.slow
def test_the_real_quickstart_uses_the_real_dance_recipe_and_the_validation_dances(tmp_path):
    pytest.importorskip("torch")
    from kinectdata.apps.real_dance import run_real_quickstart
    from kinectdata.dataset.recipes.tang2018 import KINECTDATA_SPLIT

    corpus = make_tang2018_copy(tmp_path, seconds=8.0)
    lines: list[str] = []
    small = {"units": 16, "sequence": 60, "stride": 60, "epochs": 1}
    summary = run_real_quickstart("tang2018", corpus, tmp_path / "qs", lines.append, minutes=1, **small)
    printed = "\n".join(lines)
    built = json.loads((tmp_path / "qs" / "yalta_dataset" / "manifest.json").read_text())
    assert built["feature_shape"] == [2, 129, 5]  # the spectra with the music's pulse
    assert built["config"]["root_centre"] is True  # as the tang2018 recipe asks
    run = json.loads((tmp_path / "qs" / "run" / "config.json").read_text())
    assert (run["train"]["free_weight"], run["train"]["keep"], run["train"]["silence_share"]) == (1.0, "best", 0.2)
    assert "on the val split (the validation dances" in printed
    evaluated = set(summary["evaluation"]["listening"]["generated"]["recordings"])
    assert evaluated and all(name.split("DANCE_")[-1] in KINECTDATA_SPLIT["val"] for name in evaluated), evaluated
    assert "generated motion is alive: " in printed and "stops in silence: " in printed
    assert (tmp_path / "qs" / "run" / "generated.csv").is_file()


def test_the_real_quickstart_names_a_missing_corpus_in_one_line(tmp_path):
    result = CliRunner().invoke(main, ["quickstart", "--corpus", "tang2018", str(tmp_path / "nowhere")])
    assert result.exit_code != 0
    assert "nowhere" in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1, result.output
    unknown = CliRunner().invoke(main, ["quickstart", "--corpus", "no-such-corpus", str(tmp_path)])
    assert unknown.exit_code != 0 and "unknown corpus 'no-such-corpus'" in unknown.output
    both = CliRunner().invoke(main, ["quickstart", "--corpus", "tang2018", str(tmp_path), "--samples", str(tmp_path)])
    assert both.exit_code == 2 and "--samples" in both.output


@pytest.mark.parametrize("pipeline", ["yalta2016", "listen-to-dance"])
def test_the_real_quickstart_keeps_the_defaults_epochs_with_its_time_budget(tmp_path, monkeypatch, pipeline):
    """Only the budget is set: train-baseline's defaults keep their epochs (the cdhc model trained on
    to 80 epochs kept an epoch that stood nearly still)."""
    import kinectdata.apps.quickstart as quickstart
    import kinectdata.apps.real_dance as real_dance

    seen = {}
    monkeypatch.setattr(
        real_dance,
        "build_corpus_datasets",
        lambda corpus, path, out, models, echo: ({models[0]: tmp_path / "ds"}, {models[0]: {"totals": {"rows": 1}}}),
    )
    monkeypatch.setattr(
        quickstart, "train_evaluate_generate", lambda out, manifest, p, settings, *a, **k: seen.update(settings) or {}
    )
    real_dance.run_real_quickstart(
        "tang2018", tmp_path, tmp_path / "qs", lambda line: None, pipeline=pipeline, minutes=7
    )
    assert seen == {"max_minutes": 7}


@pytest.mark.parametrize("styles", [("waltz", "tango"), ("waltz", None)])
def test_a_corpus_whose_training_songs_are_not_all_told_a_style_is_built_without_the_style_code(
    tmp_path, monkeypatch, styles
):
    import kinectdata.apps.real_dance as real_dance
    from kinectdata.dataset.inputs import RecordingEntry
    from kinectdata.dataset.recipes.manifest import CorpusManifest
    from kinectdata.features import needs_style

    seen = {}
    monkeypatch.setattr(
        real_dance,
        "build_dataset",
        lambda listed, folder, config, **k: seen.update(features=config.features) or {"splits": {}},
    )
    recordings = tuple(
        RecordingEntry(f"d{k}", f"d{k}.csv", split="train", style=style) for k, style in enumerate(styles)
    )
    manifest = CorpusManifest("tang2018", tmp_path, recordings, target="positions")
    real_dance.build_model_dataset(tmp_path / "r.yaml", tmp_path / "ds", "cdhc", manifest, echo=lambda line: None)
    assert needs_style(seen["features"]) == all(styles)
