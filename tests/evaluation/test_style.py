"""Is a generated dance its song's style (kinectdata.evaluation.style): the nearest style's mean of
the real training dances, standardised by them, against scikit-learn's nearest-centroid classifier;
leave-one-out counted against scikit-learn's; the features of a dance do not move with where it is
danced."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.model_selection import LeaveOneOut, cross_val_predict
from sklearn.neighbors import NearestCentroid
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.style import StyleClassifier, style_features, style_report

FPS = 60.0


def clusters(seed: int = 0):
    """Three styles of made-up feature rows, 9, 5 and 3 of them, overlapping a little."""
    rng = np.random.default_rng(seed)
    centres = {"waltz": rng.normal(0, 1, 6), "rumba": rng.normal(0, 1, 6), "cha-cha": rng.normal(0, 1, 6)}
    names, styles, rows = [], [], []
    for style, count in (("waltz", 9), ("rumba", 5), ("cha-cha", 3)):
        for i in range(count):
            names.append(f"{style}_{i}")
            styles.append(style)
            rows.append(centres[style] * [1, 10, 0.1, 1, 5, 1] + rng.normal(0, 0.9, 6) * [1, 10, 0.1, 1, 5, 1])
    return names, styles, np.array(rows)


def reference():
    return make_pipeline(StandardScaler(), NearestCentroid())


def test_the_nearest_standardised_style_mean_names_the_style_as_scikit_learn_does():
    names, styles, rows = clusters()
    asked = np.random.default_rng(5).normal(0, 1, (40, 6)) * [1, 10, 0.1, 1, 5, 1] * 1.5
    classifier = StyleClassifier(tuple(names), tuple(styles), rows)
    named = [style for style, _ in classifier.predict(asked)]
    assert named == list(reference().fit(rows, styles).predict(asked))
    assert classifier.predict(rows[:1])[0][1] == names[0]  # a training dance is its own nearest dance
    # the nearest dance is named beside the style, and need not be of it
    far_waltz = rows[:9].mean(axis=0) * 0.2 + rows[-1] * 0.8
    style, dance = classifier.predict(far_waltz[None])[0]
    assert style == reference().fit(rows, styles).predict(far_waltz[None])[0] and dance in names


def test_leave_one_out_counts_as_scikit_learn_counts():
    for seed in range(4):
        names, styles, rows = clusters(seed)
        loo = cross_val_predict(reference(), rows, np.array(styles), cv=LeaveOneOut())
        assert StyleClassifier(tuple(names), tuple(styles), rows).leave_one_out() == int(np.sum(loo == styles))


def test_a_style_no_training_dance_holds_is_not_counted():
    names, styles, rows = clusters()
    generated = [("C_1", "cha-cha", rows[-1] + 0.01), ("T_5", "tango", rows[0]), ("W_1", "waltz", rows[-2])]
    report = style_report(list(zip(names, styles, rows)), generated)
    assert report.counted == ["C_1", "W_1"] and report.right == 1
    assert report.held == {"cha-cha": 3, "rumba": 5, "waltz": 9}
    assert report.songs["T_5"] == ("tango", "waltz", "waltz_0")
    assert report.verdict().startswith("dances in their song's style: 1 of 2 (C_1 cha-cha -> cha-cha, T_5 tango")
    assert report.to_dict()["leave_one_out"]["dances"] == 17
    assert report.by_style == {"cha-cha": (1, 1), "waltz": (0, 1)}  # the tango is not counted
    assert "; by style cha-cha 1 of 1, waltz 0 of 1; " in report.verdict()
    assert "heard" not in report.verdict()
    # a run that hears the style: how often the music was heard as its own style, of the counted songs
    heard = style_report(list(zip(names, styles, rows)), generated, {"C_1": "cha-cha", "W_1": "rumba", "T_5": "x"})
    said = heard.songs["W_1"][1]  # the waltz, heard as a rumba, is not named a waltz
    assert said != "waltz" and heard.heard_right == 1 and heard.danced_as_heard == 1 + (said == "rumba")
    assert heard.verdict().endswith(
        f"left out; the music heard as its style in 1 of 2, danced as heard in {heard.danced_as_heard} of 2)"
    )
    assert report.heard_right is None and report.danced_as_heard is None and report.hearing() == ""
    assert heard.verdict().endswith(f"; {heard.to_dict()['hearing']})")
    assert heard.to_dict()["heard"] == {"C_1": "cha-cha", "W_1": "rumba", "T_5": "x"}


def test_the_real_dances_of_the_songs_are_named_beside_the_generated_ones():
    """The songs' real dances, named by the same classifier (scikit-learn's nearest centroid as the
    reference): how many a run that danced as the dancers did would have right, of the counted songs
    only; a real dance of a song not generated is left out."""
    names, styles, rows = clusters()
    generated = [("C_1", "cha-cha", rows[-1] + 0.01), ("T_5", "tango", rows[0]), ("W_1", "waltz", rows[-2])]
    real = [("C_1", rows[0] * 0.9), ("W_1", rows[-1] * 1.1), ("T_5", rows[3]), ("R_9", rows[5])]
    report = style_report(list(zip(names, styles, rows)), generated, real=real)
    expected = reference().fit(rows, styles).predict(np.stack([f for _, f in real[:3]]))
    assert report.real == dict(zip(["C_1", "W_1", "T_5"], expected))
    assert report.real_right == (expected[0] == "cha-cha") + (expected[1] == "waltz")
    assert f"; the real dances of these songs named right in {report.real_right} of 2" in report.verdict()
    assert report.to_dict()["real_right"] == report.real_right and report.dancers() in report.verdict()
    plain = style_report(list(zip(names, styles, rows)), generated)
    assert plain.real_right is None and plain.dancers() == "" and "real dances" not in plain.verdict()


def test_too_few_or_broken_training_dances_are_refused():
    with pytest.raises(KinectDataError, match="at least 2 training dances"):
        StyleClassifier(("a",), ("waltz",), np.zeros((1, 3)))
    with pytest.raises(KinectDataError, match="must be finite"):
        StyleClassifier(("a", "b"), ("waltz", "rumba"), np.array([[0.0, np.nan], [1.0, 2.0]]))


def test_the_features_of_a_dance_do_not_move_with_where_it_is_danced():
    rng = np.random.default_rng(1)
    t = np.arange(240) / FPS
    dance = rng.normal(0, 0.3, (1, 24, 3)) + 0.05 * np.sin(2 * np.pi * 1.5 * t)[:, None, None] * rng.normal(
        0, 1, (24, 3)
    )
    dance[..., 1] += 1.0  # off the floor
    here, there = style_features(dance, FPS), style_features(dance + [3.0, 0.0, -2.0], FPS)
    assert here.shape == (104,) and np.allclose(here, there)
