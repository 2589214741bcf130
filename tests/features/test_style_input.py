"""A song's dance style from its music (kinectdata.features.music_style) and as a network input
(kinectdata.features.style_input): descriptors of synthesized songs of known metre and tempo, the
nearest-centroid classifier against a computation done another way, the one-hot on sounding frames."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("librosa")

from helpers import metre_music  # noqa: E402
from scipy.spatial.distance import cdist  # noqa: E402
from scipy.stats import circmean  # noqa: E402

from kinectdata.core.errors import ConfigError, KinectDataError  # noqa: E402
from kinectdata.features import (  # noqa: E402
    PRESETS,
    compute_features,
    feature_config,
    needs_style,
    song_style,
    style_input_of,
)
from kinectdata.features.music_style import (  # noqa: E402
    DESCRIPTORS,
    MusicStyleClassifier,
    song_descriptors,
    usual_tempo,
)
from kinectdata.features.silence import silence_features, silent_frames  # noqa: E402
from kinectdata.features.streaming import StreamingFeatures  # noqa: E402
from kinectdata.features.style_input import NO_STYLE, StyleInputConfig, style_input_features  # noqa: E402

RATE = 16000
FPS = 30.0


def frames(seconds: float) -> np.ndarray:
    return np.round(np.arange(int(seconds * FPS)) * RATE / FPS).astype(np.int64)


@pytest.mark.parametrize(("bpm", "bars_of"), [(90.0, 3), (126.0, 4)])
def test_descriptors_hear_the_metre_and_the_tempo(bpm, bars_of):
    samples, beats = metre_music(bpm, bars_of, bars=12, seed=0, rate=RATE)
    described = dict(zip(DESCRIPTORS, song_descriptors(samples, RATE)))
    assert (described["metre"] > 0) == (bars_of == 3)  # bar-to-bar similarity at 3 beats above that at 4
    assert described["tempo"] == pytest.approx(np.log2(bpm), abs=np.log2(1.03))  # within 3 % of the true tempo
    assert np.isfinite(list(described.values())).all()


def test_the_classifier_names_the_nearest_style_mean_in_pooled_within_style_units():
    rng = np.random.default_rng(0)
    centres = {"cha-cha": [-1, 7.0, 1, 7, -3], "rumba": [-1, 6.7, 1, 7, -3], "waltz": [1, 6.5, 1, 7, -3]}
    counts = {"cha-cha": 3, "rumba": 4, "waltz": 20}  # a majority that must not win by its size
    styles = [s for s, n in counts.items() for _ in range(n)]
    x = np.array([centres[s] for s in styles]) + rng.normal(0, 0.08, (len(styles), 5))
    x[:6:2, 1] += 1.0  # a cha-cha and two rumbas heard at twice their beat, as librosa's tracker may
    fitted = MusicStyleClassifier.fit(x, styles)
    assert fitted.styles == ("cha-cha", "rumba", "waltz") and fitted.songs == len(styles) and fitted.octave_free
    # the same rule computed another way: scipy's standardised Euclidean distance to each style's mean,
    # the tempo's mean scipy's circular mean over one octave and each tempo moved by whole octaves to it
    label = np.array(styles)
    means = np.stack([x[label == s].mean(0) for s in fitted.styles])
    means[:, 1] = [circmean(x[label == s, 1], high=1.0, low=0.0) for s in fitted.styles]
    within = x - means[[fitted.styles.index(s) for s in styles]]
    within[:, 1] -= np.round(within[:, 1])
    variance = (within**2).sum(0) / (len(styles) - len(counts))
    asked = rng.normal(x.mean(0), 0.3, (50, 5))
    distances = []
    for centre in means:
        near = asked.copy()
        near[:, 1] += np.round(centre[1] - near[:, 1])
        distances.append(cdist(near, centre[None], "seuclidean", V=variance)[:, 0])
    expected = np.array(fitted.styles)[np.argmin(distances, axis=0)]
    assert [fitted.predict(a) for a in asked] == expected.tolist()
    assert fitted.leave_one_out == len(styles)  # well apart: every song named right when left out
    assert MusicStyleClassifier.from_dict(fitted.to_dict()) == fitted


def test_a_classifier_saved_before_octaves_were_set_aside_hears_as_it_did():
    centres = ((0.0, 7.0, 0.0, 0.0, 0.0), (0.0, 6.4, 0.0, 0.0, 0.0))
    older = MusicStyleClassifier(("cha-cha", "waltz"), centres, (0.0,) * 5, (1.0,) * 5).to_dict()
    del older["octave_free"]
    song = np.zeros(5)
    song[1] = 7.35  # a waltz's 87 beats a minute heard at twice: nearer the cha-cha's 128 as is
    assert MusicStyleClassifier.from_dict(older).predict(song) == "cha-cha"
    assert MusicStyleClassifier.from_dict({**older, "octave_free": True}).predict(song) == "waltz"


def test_a_classifier_fitted_on_songs_names_a_new_song():
    songs = [metre_music(bpm, bars_of, bars=10, seed=s, rate=RATE)[0] for bpm, bars_of, s in
             ((88, 3, 1), (92, 3, 2), (125, 4, 3), (129, 4, 4))]  # fmt: skip
    fitted = MusicStyleClassifier.fit(
        np.stack([song_descriptors(s, RATE) for s in songs]), ["waltz", "waltz", "cha-cha", "cha-cha"]
    )
    config = StyleInputConfig(classifier=fitted)
    waltz, _ = metre_music(90.0, 3, bars=10, seed=9, rate=RATE)
    cha_cha, _ = metre_music(127.0, 4, bars=10, seed=8, rate=RATE)
    assert config.style_of(waltz) == "waltz" and config.style_of(cha_cha) == "cha-cha"
    heard, _ = style_input_features(waltz, frames(2.0), config)  # no style given: heard in the song
    assert heard[5].tolist() == [0.0, 1.0, 0.0, 0.0]  # slots in the classifier's order: cha-cha, waltz
    assert song_style(PRESETS["listen_to_dance"], waltz) == (None, "")  # features that hear no style
    stacked = feature_config(
        {**PRESETS["listen_to_dance_rhythm_bars_style"].to_dict(), "parts": [
            *PRESETS["listen_to_dance_rhythm_bars_style"].to_dict()["parts"][:2], config.to_dict()]}
    )  # fmt: skip
    assert song_style(stacked, cha_cha) == ("cha-cha", "cha-cha (heard in the music)")
    assert song_style(stacked, cha_cha, "waltz") == ("waltz", "waltz (given)")
    assert song_style(stacked, None)[0] is None
    assert song_style(stacked, cha_cha[: RATE * 2])[0] is None  # 2 s: too few beats to tell
    with pytest.raises(ConfigError, match="style 'tango': the run knows cha-cha, waltz"):
        song_style(stacked, cha_cha, "tango")


def test_each_sounding_frame_says_the_style_and_silence_stays_silence():
    fitted = MusicStyleClassifier(("rumba", "waltz"), ((0.0,) * 5, (1.0,) * 5), (0.0,) * 5, (1.0,) * 5)
    config = StyleInputConfig(slots=3, classifier=fitted)
    music = np.random.default_rng(0).normal(0, 0.1, 4 * RATE).astype(np.float32)
    music[RATE : 2 * RATE] = 0.0
    starts = frames(4.0)
    made, padded = style_input_features(music, starts, config, style="waltz")
    own_slice = np.array([np.any(np.abs(music[s : s + 534]) > 0) for s in starts])
    assert made.shape == (len(starts), 3) and np.array_equal(made[:, 1], own_slice.astype(np.float32))
    assert not made[:, [0, 2]].any() and padded.tolist() == [s + 534 > music.size for s in starts]
    assert not style_input_features(music, starts, config, style=NO_STYLE)[0].any()
    # the noise has too few beats to tell: heard as no style, not an error
    assert not style_input_features(music, starts, config)[0].any()
    planes, _ = style_input_features(
        music, starts[:4], StyleInputConfig(classifier=fitted, planes=(129, 5)), style="rumba"
    )
    assert planes.shape == (4, 4, 129, 5) and (planes[:, 0] == 1).all() and not planes[:, 1:].any()


def test_the_presets_stack_it_and_the_stream_needs_the_style():
    music = np.random.default_rng(1).normal(0, 0.1, 3 * RATE).astype(np.float32)
    fitted = MusicStyleClassifier(("cha-cha", "waltz"), ((0.0,) * 5, (1.0,) * 5), (0.0,) * 5, (1.0,) * 5)
    for name, shape in (("yalta2016_rhythm_style", (6, 129, 5)), ("listen_to_dance_rhythm_bars_style", (157,))):
        unfitted = PRESETS[name]
        assert unfitted.output_shape == shape and needs_style(unfitted)
        assert style_input_of(unfitted).classifier is None
        part = style_input_of(unfitted)
        config = feature_config(
            {"extractor": "stack", "parts": [p.to_dict() if p is not part else
                                             StyleInputConfig(classifier=fitted, planes=part.planes).to_dict()
                                             for p in unfitted.parts]}
        )  # fmt: skip
        assert feature_config(config.to_dict()) == config
        made, _ = compute_features(music, frames(2.0), config, beats_per_bar=3, style="waltz")
        without, _ = compute_features(music, frames(2.0), PRESETS[name.removesuffix("_style")], beats_per_bar=3)
        assert np.array_equal(made[:, : without.shape[1]], without)  # the parts before it unchanged
        assert made[10, without.shape[1] + 1].min() == 1.0
        quiet = silence_features(config, FPS)
        assert silent_frames(compute_features(np.zeros(RATE, np.float32), frames(0.5), config)[0], quiet).all()
        # streamed in blocks: the same as the whole song with the same style; refused without one
        got = np.zeros_like(made)

        def sink(k0, f, _p, got=got):
            got[k0 : k0 + len(f)] = f

        stream = StreamingFeatures(frames(2.0), config, sink, beats_per_bar=3, style="waltz")
        for block in np.array_split(music, 7):
            stream.push(block)
        stream.finish()
        assert np.allclose(got, made, atol=1e-5)
        with pytest.raises(ConfigError, match="need the song's style"):
            StreamingFeatures(frames(2.0), config, sink, beats_per_bar=3)


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"slots": 0}, "slots must be at least 1"),
        ({"planes": (129,)}, "planes must be"),
        (
            {"slots": 1, "classifier": MusicStyleClassifier(("a", "b"), ((0.0,) * 5,) * 2, (0.0,) * 5, (1.0,) * 5)},
            "hold 2 styles \\(a, b\\), more than its 1 slots",
        ),
    ],
)
def test_bad_settings_are_refused(settings, message):
    with pytest.raises(ConfigError, match=message):
        StyleInputConfig(**settings)
    with pytest.raises(ConfigError, match="no music style classifier yet"):
        StyleInputConfig().style_of(np.zeros(10, np.float32))


def test_each_style_keeps_its_usual_tempo_with_octaves_set_aside():
    # waltzes at 86-88 beats a minute, two of them heard at twice their beat (librosa's tracker does)
    waltzes = [86.0, 2 * 87.0, 88.0, 2 * 86.5]
    x = np.arange(30.0).reshape(6, 5) * 1e-3  # every descriptor varies a little within a style
    x[:, 1] = np.log2(waltzes + [120.0, 126.0])
    fitted = MusicStyleClassifier.fit(x, ["waltz"] * 4 + ["cha-cha"] * 2)
    # computed another way: the geometric mean of the tempi brought into one octave by hand
    by_hand = np.exp(np.mean(np.log([86.0, 87.0, 88.0, 86.5])))
    assert fitted.tempi[fitted.styles.index("waltz")] == pytest.approx(by_hand, rel=1e-4)
    assert fitted.tempi[fitted.styles.index("cha-cha")] == pytest.approx(np.sqrt(120.0 * 126.0), rel=1e-4)
    assert usual_tempo([90.0]) == pytest.approx(90.0)
    assert MusicStyleClassifier.from_dict(fitted.to_dict()) == fitted
    older = {k: v for k, v in fitted.to_dict().items() if k != "tempi"}  # saved before the tempi were kept
    assert MusicStyleClassifier.from_dict(older).tempi == ()
    with pytest.raises(KinectDataError, match="keeps no tempo per style"):
        MusicStyleClassifier.from_dict(older).tempo_factor(x[0], 0.08)


def test_songs_without_a_dance_teach_the_hearing_not_the_tempi():
    # two cha-chas danced at 120 and 126 beats a minute, two without a dance at 100; a waltz danced at 87
    x = np.arange(25.0).reshape(5, 5) * 1e-3
    x[:, 1] = np.log2([120.0, 126.0, 100.0, 100.0, 87.0])
    styles = ["cha-cha", "cha-cha", "cha-cha", "cha-cha", "waltz"]
    fitted = MusicStyleClassifier.fit(x, styles, danced=[True, True, False, False, True])
    assert fitted.tempi[fitted.styles.index("cha-cha")] == pytest.approx(np.sqrt(120.0 * 126.0), rel=1e-4)
    assert (fitted.songs, fitted.undanced) == (5, 2)
    # the hearing is the fit on all five songs: the cha-cha centre is the mean of the four
    every = MusicStyleClassifier.fit(x, styles)
    assert fitted.centres == every.centres and fitted.scale == every.scale
    assert every.tempi[every.styles.index("cha-cha")] < 115.0  # with the undanced songs' tempi it would move
    # a style none of whose songs is danced keeps the tempo of its songs
    only_heard = MusicStyleClassifier.fit(x, styles, danced=[False, False, False, False, True])
    assert only_heard.tempi == every.tempi
    assert MusicStyleClassifier.from_dict(fitted.to_dict()) == fitted
    with pytest.raises(KinectDataError, match="one flag per song"):
        MusicStyleClassifier.fit(x, styles, danced=[True])


@pytest.mark.parametrize("heard_at", [1.0, 2.0])  # the song's beat, or twice it as a tracker may report
def test_the_tempo_factor_brings_a_song_to_the_edge_of_its_styles_band(heard_at):
    fitted = MusicStyleClassifier(("waltz",), ((0.0,) * 5,), (0.0,) * 5, (1.0,) * 5, tempi=(87.0,))
    song = np.zeros(5)
    for bpm, played in ((87.0 * 0.85, 87.0 / 1.08), (87.0 * 1.18, 87.0 * 1.08), (87.0 * 1.05, 87.0 * 1.05)):
        song[1] = np.log2(bpm * heard_at)
        factor, style = fitted.tempo_factor(song, 0.08)
        assert style == "waltz" and bpm * factor == pytest.approx(played)  # within 8 %: as it is
    with pytest.raises(ConfigError, match="one positive tempo per style"):
        MusicStyleClassifier(("waltz",), ((0.0,) * 5,), (0.0,) * 5, (1.0,) * 5, tempi=(87.0, 90.0))


def test_a_style_given_sets_the_tempo_the_song_is_brought_to():
    centres = ((0.0, 7.0, 0.0, 0.0, 0.0), (1.0, 6.4, 1.0, 1.0, 1.0))  # the song below is nearest the cha-cha's
    fitted = MusicStyleClassifier(("cha-cha", "waltz"), centres, (0.0,) * 5, (1.0,) * 5, tempi=(124.0, 87.0))
    song = np.zeros(5)
    song[1] = np.log2(100.0)
    assert fitted.predict(song) == "cha-cha"
    factor, style = fitted.tempo_factor(song, 0.08)
    assert style == "cha-cha" and 100.0 * factor == pytest.approx(124.0 / 1.08)
    factor, style = fitted.tempo_factor(song, 0.08, style="waltz")  # told a waltz: brought to the waltz's
    assert style == "waltz" and 100.0 * factor == pytest.approx(87.0 * 1.08)
    with pytest.raises(ConfigError, match="style 'tango': the classifier knows cha-cha, waltz"):
        fitted.tempo_factor(song, 0.08, style="tango")
