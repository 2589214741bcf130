"""A dataset whose features hear the song's style (``*_style`` presets): the build fits the music
style classifier on its training songs, tells each training recording its manifest's style and lets
every other recording's music be heard, as a song is at generation."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
from conftest import REPO

pytest.importorskip("librosa")

from kinectdata.align.audio import load_audio  # noqa: E402
from kinectdata.core.errors import ConfigError, SchemaError  # noqa: E402
from kinectdata.dataset.build import build_dataset  # noqa: E402
from kinectdata.dataset.config import BuildConfig  # noqa: E402
from kinectdata.features import feature_config, style_input_of  # noqa: E402
from kinectdata.features.music_style import MusicStyleClassifier, song_descriptors  # noqa: E402

pytestmark = pytest.mark.filterwarnings("ignore::kinectdata.dataset.build.EmptySplitWarning")

SAMPLES = REPO / "sample_data"
STYLES = {"synth_001": ("train", "waltz"), "synth_002": ("train", "rumba"), "synth_003": ("val", "rumba")}


def _manifest(path, **changes):
    doc = []
    for name, (split, style) in STYLES.items():
        truth = json.loads((SAMPLES / f"{name}.truth.json").read_text())
        entry = {"name": name, "recording": str(SAMPLES / f"{name}.csv"), "audio": str(SAMPLES / f"{name}.flac"),
                 "split": split, "offset": truth["offset_s"], "style": style}  # fmt: skip
        doc.append({k: v for k, v in (entry | changes.get(name, {})).items() if v is not None})  # None: left out
    path.write_text(json.dumps(doc))
    return path


def _config() -> BuildConfig:
    return BuildConfig.from_pipeline("yalta2016", features="yalta2016_rhythm_style", target="positions")


def _style_planes(folder, manifest, name):
    record = next(r for r in manifest["recordings"] if r["name"] == name)
    with h5py.File(folder / record["shard"], "r") as f:
        return f["input"][record["start"] : record["start"] + record["frames"], 2:]  # after the STFT and pulse


def test_training_songs_are_told_their_style_and_the_others_heard(tmp_path):
    built = build_dataset(_manifest(tmp_path / "m.json"), tmp_path / "ds", _config(), allow_outside_paths=True)
    part = style_input_of(feature_config(built["config"]["features"]))
    # the classifier: fitted on the two training songs, their descriptors computed here from the files
    songs = {n: load_audio(SAMPLES / f"{n}.flac", 16000).samples for n in STYLES}
    described = {n: song_descriptors(s, 16000) for n, s in songs.items()}
    expected = MusicStyleClassifier.fit(np.stack([described["synth_001"], described["synth_002"]]), ["waltz", "rumba"])
    assert part.classifier == expected and part.styles == ("rumba", "waltz")
    said = {r["name"]: r["style"] for r in built["recordings"]}
    assert said["synth_001"] == {"style": "waltz", "source": "manifest"}
    assert said["synth_002"] == {"style": "rumba", "source": "manifest"}
    heard = expected.predict(described["synth_003"])
    assert said["synth_003"] == {"style": heard, "source": "heard"}
    for name, style in (("synth_001", "waltz"), ("synth_002", "rumba"), ("synth_003", heard)):
        planes = _style_planes(tmp_path / "ds", built, name)
        slot = part.styles.index(style)
        sounding = planes.reshape(len(planes), 4, -1).max(axis=2)
        assert (sounding[:, slot] == 1).mean() > 0.9  # every frame with music (the song starts after the dance)
        assert not np.delete(sounding, slot, axis=1).any()
    # resumed: the same fit, the same keys, every work file reused
    again = build_dataset(_manifest(tmp_path / "m.json"), tmp_path / "ds", _config(), allow_outside_paths=True)
    assert again == built


def test_a_training_song_without_a_style_is_refused_in_one_line(tmp_path):
    listed = _manifest(tmp_path / "m.json", synth_002={"style": None})
    with pytest.raises(ConfigError, match=r"m\.json: the features hear the song's style.*synth_002 give no 'style'"):
        build_dataset(listed, tmp_path / "ds", _config(), allow_outside_paths=True)
    assert not (tmp_path / "ds").exists()  # nothing half-made left behind


def _with_songs(path, songs):
    """The sample manifest written as an object with labelled ``songs`` beside its recordings."""
    recordings = json.loads(_manifest(path).read_text())
    path.write_text(json.dumps({"recordings": recordings, "songs": songs}))
    return path


def _song_file(path, source, gain):
    """A song that is another file than the sample's (its samples at ``gain``): a labelled song of its own."""
    import soundfile as sf

    samples, sr = sf.read(source, dtype="float32")
    sf.write(path, samples * gain, sr)
    return path


def test_labelled_songs_without_a_recording_teach_the_hearing(tmp_path):
    rumba = _song_file(tmp_path / "another_rumba.wav", SAMPLES / "synth_002.flac", 0.7)
    tango = _song_file(tmp_path / "a_tango.wav", SAMPLES / "synth_001.flac", 0.6)
    songs = [{"audio": str(rumba), "style": "rumba"}, {"name": "T_1", "audio": str(tango), "style": "tango"}]
    listed = _with_songs(tmp_path / "m.json", songs)
    built = build_dataset(listed, tmp_path / "ds", _config(), allow_outside_paths=True)
    part = style_input_of(feature_config(built["config"]["features"]))
    # computed here from the files: the two training songs and the rumba; the tango is of a style no
    # training recording dances, so it is not heard
    described = [
        song_descriptors(load_audio(p, 16000).samples, 16000)
        for p in (SAMPLES / "synth_001.flac", SAMPLES / "synth_002.flac", rumba)
    ]
    expected = MusicStyleClassifier.fit(np.stack(described), ["waltz", "rumba", "rumba"], danced=[True, True, False])
    assert part.classifier == expected and expected.undanced == 1 and part.styles == ("rumba", "waltz")
    # another labelled song makes another dataset; the same ones reuse it
    listed = _with_songs(tmp_path / "m.json", songs[1:])
    fewer = build_dataset(listed, tmp_path / "ds", _config(), allow_outside_paths=True)
    assert fewer["build_key"] != built["build_key"]
    assert style_input_of(feature_config(fewer["config"]["features"])).classifier.undanced == 0


def test_a_labelled_song_that_is_a_recordings_song_or_listed_twice_counts_once(tmp_path):
    # the validation recording's song must not teach the classifier; a training song is told already
    rumba = _song_file(tmp_path / "another_rumba.wav", SAMPLES / "synth_002.flac", 0.7)
    songs = [
        {"name": "S_1", "audio": str(SAMPLES / "synth_003.flac"), "style": "rumba"},
        {"name": "S_2", "audio": str(SAMPLES / "synth_001.flac"), "style": "waltz"},
        {"name": "S_3", "audio": str(rumba), "style": "rumba"},
        {"name": "S_4", "audio": str(rumba), "style": "rumba"},
    ]
    built = build_dataset(_with_songs(tmp_path / "m.json", songs), tmp_path / "ds", _config(), allow_outside_paths=True)
    classifier = style_input_of(feature_config(built["config"]["features"])).classifier
    described = [
        song_descriptors(load_audio(p, 16000).samples, 16000)
        for p in (SAMPLES / "synth_001.flac", SAMPLES / "synth_002.flac", rumba)
    ]
    assert classifier == MusicStyleClassifier.fit(np.stack(described), ["waltz", "rumba", "rumba"], [True, True, False])


@pytest.mark.parametrize(
    ("songs", "message"),
    [
        ([{"audio": "x.wav"}], r"songs: at 0: 'style' is a required property"),
        ([{"audio": "nowhere.wav", "style": "rumba"}], r"songs\[0\]: audio nowhere\.wav does not exist"),
        (
            [{"name": "synth_001", "audio": "song.wav", "style": "rumba"}],
            r"songs\[0\]: name 'synth_001' is already used by recordings\[0\]",
        ),
    ],
)
def test_bad_labelled_songs_are_named_in_one_line(tmp_path, songs, message):
    _song_file(tmp_path / "song.wav", SAMPLES / "synth_002.flac", 0.5)
    listed = _with_songs(tmp_path / "m.json", songs)
    with pytest.raises(SchemaError, match=message):
        build_dataset(listed, tmp_path / "ds", _config(), allow_outside_paths=True)
    assert not (tmp_path / "ds").exists()


def test_a_style_changed_in_the_manifest_builds_again(tmp_path):
    built = build_dataset(_manifest(tmp_path / "m.json"), tmp_path / "ds", _config(), allow_outside_paths=True)
    changed = _manifest(tmp_path / "m.json", synth_002={"style": "cha-cha"}, synth_003={"style": "cha-cha"})
    again = build_dataset(changed, tmp_path / "ds", _config(), allow_outside_paths=True)
    assert again["build_key"] != built["build_key"]
    said = {r["name"]: r["style"] for r in again["recordings"]}
    assert said["synth_002"] == {"style": "cha-cha", "source": "manifest"}


def test_a_dataset_that_hears_the_style_builds_again_when_the_hearing_changes(tmp_path, monkeypatch):
    import kinectdata.dataset.build as build

    built = build_dataset(_manifest(tmp_path / "m.json"), tmp_path / "ds", _config(), allow_outside_paths=True)
    assert style_input_of(feature_config(built["config"]["features"])).classifier.octave_free
    monkeypatch.setattr(build, "HEARING_VERSION", build.HEARING_VERSION + 1)
    again = build_dataset(_manifest(tmp_path / "m.json"), tmp_path / "ds", _config(), allow_outside_paths=True)
    assert again["build_key"] != built["build_key"]
    # a dataset whose features hear no style keeps its key
    plain = BuildConfig.from_pipeline("yalta2016", features="yalta2016", target="positions")
    first = build_dataset(_manifest(tmp_path / "m.json"), tmp_path / "plain", plain, allow_outside_paths=True)
    monkeypatch.setattr(build, "HEARING_VERSION", build.HEARING_VERSION + 1)
    assert build_dataset(_manifest(tmp_path / "m.json"), tmp_path / "plain", plain, allow_outside_paths=True) == first
