"""``bench_pulse``: the pulse's beat against librosa's on audio with a known answer, and on a copy
made in the Dance with Melody corpus's shape (its test songs never looked at)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import REPO
from corpus_copies import make_tang2018_copy
from rhythm_reference import accented_eighths, click_track

pytest.importorskip("librosa")


def test_on_accented_eighth_notes_only_the_harmonic_weight_picks_the_beat(monkeypatch):
    """Eighth notes at 90 BPM, the beat's three times as loud: librosa's beat is 90 BPM; the plain
    pick is at twice it in every frame, the pick with the salience at twice each tempo added at it."""
    monkeypatch.syspath_prepend(str(REPO))
    from benchmarks.bench_pulse import song_shares

    bpm, shares = song_shares(accented_eighths(90.0, seconds=40.0), (0.0, 1.0))
    assert abs(bpm - 90.0) < 2.0, bpm
    assert shares[0.0][1] > 0.9 and shares[0.0][0] < 0.1, shares[0.0]
    assert shares[1.0][0] > 0.9 and shares[1.0][1] < 0.1, shares[1.0]


def test_the_levels_clocks_where_every_beat_sounds_alike(monkeypatch):
    """Clicks at 120 BPM for 30 s, every beat alike, read as a song in 4 with its beat of 0.5 s:
    counted from the beat, the two beats, the bar and two bars turn once a level (within 2 %); the
    tempogram's bar and two bars turn less than a quarter of that (they restart at every click)."""
    monkeypatch.syspath_prepend(str(REPO))
    from benchmarks.bench_pulse import level_clocks

    sr, bpm = 16000, 120.0
    audio, _ = click_track(bpm, seconds=30.0)
    clocks = level_clocks(audio, 4, 60.0 / bpm)
    np.testing.assert_allclose(clocks["counted"], 1.0, atol=0.02)
    assert np.all(np.abs(clocks["tempogram"][2:]) < 0.25), clocks["tempogram"]
    assert level_clocks(audio[: sr * 15], 4, 60.0 / bpm) is None  # too short to read after the pulse settles


def test_a_held_beat_on_a_steady_click_track(monkeypatch):
    """Clicks at 120 BPM for 30 s: picked afresh or held, the beat is librosa's 120 BPM in nearly every
    frame and the beat's clock never jumps; held, the pick moves no more often than afresh."""
    monkeypatch.syspath_prepend(str(REPO))
    from benchmarks.bench_pulse import held_picks

    sr, bpm = 16000, 120.0
    audio, _ = click_track(bpm, seconds=30.0)
    rows = held_picks(audio, 4, bpm, (0.0, 0.3))
    assert rows.shape == (2, 3) and np.all(rows[:, 0] > 0.95), rows
    assert rows[1, 1] <= rows[0, 1] and np.all(rows[:, 2] < 0.01), rows
    assert held_picks(audio[: sr * 15], 4, bpm, (0.0,)) is None


def test_on_a_corpus_copy_it_looks_at_the_training_and_validation_songs_only(tmp_path, monkeypatch, capsys):
    monkeypatch.syspath_prepend(str(REPO))
    from benchmarks.bench_pulse import main, run

    corpus = make_tang2018_copy(tmp_path, seconds=8.0)
    means = run("tang2018", corpus, (0.0, 1.0), (0.0, 0.3))
    printed = capsys.readouterr().out
    listed = [line.split()[0] for line in printed.splitlines() if "BPM" in line and "harmonic" not in line]
    assert sorted(listed) == ["C_6", "C_7", "R_4", "R_5", "W_4", "W_5", "W_6"], listed
    for shares in means.values():
        assert np.all(shares >= 0) and shares.sum() <= 1 + 1e-9
    assert "at the music's beat most often: harmonic weight" in printed
    assert "C_6      4 beats not read: shorter than 22 s" in printed  # the 8-s copies
    assert "no song long enough to read how steady the pick is" in printed
    main([])
    assert "not run: needs --corpus tang2018 PATH" in capsys.readouterr().out
