"""The listening controls on models with known behaviour: one that dances to the beats it hears, one
that ignores the audio."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from helpers import skip_unless_installed

from kinectdata.evaluation.listening import (
    MIN_SHIFT_S,
    HeldOutSong,
    listening_report,
    motion_energy_per_s,
    shift_frames,
)

FPS = 30.0
RATE = 1000  # audio samples per second of the fake feature extractor
PERIODS = (0.75, 0.6, 0.5, 0.42)
SECONDS = 40.0


def bounce(lowest_frames: np.ndarray, frames: int, joints: int = 6) -> np.ndarray:
    """[frames, J, 3]: every joint lowest at the given frames, a cosine between them; still without them."""
    y = np.zeros(frames)
    if len(lowest_frames) >= 2:
        t = np.arange(frames)
        phase = np.interp(t, lowest_frames, np.arange(len(lowest_frames)))  # beat count
        y = -0.05 * np.cos(2 * np.pi * phase)
    pos = np.zeros((frames, joints, 3))
    pos[:, :, 0] = np.arange(joints) * 0.1
    pos[:, :, 1] = y[:, None] + np.arange(joints) * 0.2
    pos[:, :, 2] = 2.5
    return pos


def features_of(samples: np.ndarray) -> np.ndarray:
    """[T, 1]: the mean absolute sample per motion frame (an onset shows as 1.0 in the songs' features)."""
    per_frame = RATE / FPS
    frames = int(len(samples) / per_frame)
    return np.array([[np.abs(samples[int(k * per_frame) : int((k + 1) * per_frame)]).mean()] for k in range(frames)])


features_of.sample_rate = RATE


def songs(periods: tuple[float, ...] = PERIODS, dance=bounce) -> list[HeldOutSong]:
    """A song per beat period (s): an onset on every beat in its features, its real motion made by
    ``dance(lowest_frames, frames)`` on those beats."""
    out = []
    frames = int(SECONDS * FPS)
    for i, period in enumerate(periods):
        beats = np.arange(0.4, SECONDS, period)
        beats = beats[np.round(beats * FPS) < frames]
        features = np.zeros((frames, 1))
        features[np.round(beats * FPS).astype(int), 0] = 1.0
        real = dance(beats * FPS, frames)
        out.append(HeldOutSong(f"song{i}", features, real[0], real, None, beats, FPS, rms=0.1))
    return out


def listener(features: np.ndarray, first_pose: np.ndarray) -> np.ndarray:
    """Frames 1..T-1, lowest on every onset it hears."""
    onsets = np.flatnonzero(features[:, 0] > 0.5)
    return bounce(onsets, len(features))[1:]


def deaf(features: np.ndarray, first_pose: np.ndarray) -> np.ndarray:
    """Frames 1..T-1, a bounce every 0.93 s whatever it hears."""
    return bounce(np.arange(0, len(features) + 60, 0.93 * FPS), len(features))[1:]


def test_a_model_that_listens_passes_every_control():
    result = listening_report(songs(), listener, features_of, draws=100)
    assert result.generated.follows_beat and result.generated.on_beat
    assert result.generated.tempo_correlation == pytest.approx(1.0)
    assert result.swapped_follows_new == 1.0 and result.swapped_follows_old == 0.0
    assert result.noise is not None and not result.noise.follows_beat
    assert not result.shifted.on_beat  # against the beats the motion was paired with
    assert result.silence_energy_ratio < 0.01
    assert result.energy_ratio == pytest.approx(1.0, rel=0.05) and result.alive
    assert result.phase_ratio == pytest.approx(1.0, rel=0.05) and result.in_phase
    assert result.baselines["mean_pose_noise"] < result.generated.beat_align_music.value
    assert result.listens and result.follows_swapped and result.ignores_noise
    # no fixed oscillator: the periods spread with the tempi, follow them as the real motion's do,
    # and every swapped run takes the new song's period
    assert result.period_spread > 1.2 and result.swapped_period_changes == 1.0 and result.no_fixed_oscillator
    assert result.shifted_at_chance
    text = "\n".join(result.verdicts())
    assert "generated motion follows the beat: yes" in text and "listens to the music: yes" in text
    assert "stops in silence: yes" in text and "is alive: yes" in text
    assert "generated motion is no fixed oscillator: yes" in text


def test_a_model_that_ignores_the_audio_fails_them():
    result = listening_report(songs(), deaf, features_of, draws=100)
    assert not result.generated.follows_beat
    assert not result.listens and not result.in_phase
    assert result.silence_energy_ratio == pytest.approx(1.0, rel=0.05)
    assert result.period_spread == pytest.approx(1.0, abs=0.05) and result.swapped_period_changes == 0.0
    assert not result.no_fixed_oscillator
    text = "\n".join(result.verdicts())
    assert "generated motion follows the beat: no" in text and "listens to the music: no" in text
    assert "stops in silence: no" in text and "generated motion is no fixed oscillator: no" in text


def test_motion_energy_is_the_mean_squared_speed():
    t = np.arange(300) / FPS
    pos = np.zeros((300, 1, 3))
    pos[:, 0, 0] = 0.5 * t  # 0.5 m/s
    assert motion_energy_per_s(pos, None, FPS) == pytest.approx(0.25)


# the metre of each song: a song is swapped with the song whose period at the generated motion's
# level differs most; at the beat or in one metre those are (0, 3), (1, 3), (2, 0) and (3, 0), each
# pair a song in 3 with one in 4; at the bar (2.25, 1.8, 2.0, 1.68 s) (0, 3), (1, 0) and (3, 0)
METRES = (3, 3, 4, 4)


def metred_songs(metres: tuple[int, ...]) -> list[HeldOutSong]:
    """songs() with the given metres; each real motion carries its song's index in its depth (z = 2.5 + i)."""
    out = []
    for i, (song, metre) in enumerate(zip(songs(), metres)):
        real = song.real_positions.copy()
        real[:, :, 2] += i
        out.append(HeldOutSong(song.name, song.features, real[0], real, None, song.beats_s, FPS, 0.1, metre))
    return out


def waltzer(features: np.ndarray, first_pose: np.ndarray) -> np.ndarray:
    """Frames 1..T-1, lowest on every sixth onset it hears: two bars of a waltz."""
    onsets = np.flatnonzero(features[:, 0] > 0.5)
    return bounce(onsets[::6], len(features))[1:]


def bar_dancer(features: np.ndarray, first_pose: np.ndarray) -> np.ndarray:
    """Frames 1..T-1, deaf: it dances one bar of the song its first pose comes from (known from the
    pose's depth), whatever music it is given."""
    i = int(round(first_pose[0, 2] - 2.5))
    lowest = np.arange(0, len(features) + 200, METRES[i] * PERIODS[i] * FPS)
    return bounce(lowest, len(features))[1:]


def test_a_waltz_is_at_two_bars_only_when_its_songs_are_known_to_be_in_three():
    result = listening_report(metred_songs((3, 3, 3, 3)), waltzer, features_of, draws=30)
    assert result.generated.levels == {"two bars": 4} and result.generated.follows_beat
    assert [r.beats_per_bar for r in result.generated.recordings] == [3] * 4
    assert result.swapped_follows_new == 1.0  # two bars of the new song, in its metre
    assert [r.beats_per_bar for r in result.real.recordings + result.noise.recordings] == [3] * 8
    assert [r.beats_per_bar for r in result.shifted.recordings + result.swapped.recordings] == [3] * 8
    in_four = listening_report(metred_songs((4, 4, 4, 4)), waltzer, features_of, draws=30)
    assert in_four.generated.levels == {"none": 4} and not in_four.generated.follows_beat
    assert in_four.swapped_follows_new == 0.0


def test_the_swapped_control_measures_the_old_song_in_its_own_metre():
    """A deaf dancer repeats one bar of its original song whatever it hears: the swapped runs follow
    the old song (in 3 or in 4, as that song is), not the new one (in the other metre)."""
    result = listening_report(metred_songs(METRES), bar_dancer, features_of, draws=30)
    assert result.generated.levels == {"bar": 4}
    assert result.swapped_follows_old == 1.0
    # paired by their bars, which differ by more than 20 %, the new songs' metres are never met
    assert result.swapped_follows_new == 0.0
    assert [r.beats_per_bar for r in result.swapped.recordings] == [METRES[j] for j in (3, 0, 0)]  # the new songs'
    assert not result.follows_swapped and not result.listens


def accented_songs(periods: tuple[float, ...], metres: tuple[int, ...]) -> list[HeldOutSong]:
    """Songs whose features show each beat as 1.0 and each downbeat as 2.0, with a real dancer lowest
    on every downbeat (once a bar)."""
    out = []
    frames = int(SECONDS * FPS)
    for i, (period, metre) in enumerate(zip(periods, metres)):
        beats = np.arange(0.4, SECONDS, period)
        features = np.zeros((frames, 1))
        features[np.round(beats * FPS).astype(int), 0] = 1.0
        features[np.round(beats[::metre] * FPS).astype(int), 0] = 2.0
        real = bounce(beats[::metre] * FPS, frames)
        out.append(HeldOutSong(f"song{i}", features, real[0], real, None, beats, FPS, 0.1, metre))
    return out


def bar_listener(features: np.ndarray, first_pose: np.ndarray) -> np.ndarray:
    """Frames 1..T-1, lowest on every downbeat it hears: once a bar of the music it is given."""
    return bounce(np.flatnonzero(features[:, 0] > 1.5), len(features))[1:]


def test_a_dancer_at_the_bar_is_swapped_between_songs_whose_bars_differ():
    """A waltz at 86 BPM (bar 2.1 s) and songs in 4 at 120 and 92 BPM (bars 2.0 and 2.6 s): paired by
    their beats (0.70 against 0.50 s) the waltz and the faster song would make a swap whose bars
    differ by 5 %, where a dancer at the bar cannot show that it listens; paired at the bar, every
    swap changes the period and takes the new song's bar."""
    result = listening_report(accented_songs((0.7, 0.5, 0.65), (3, 4, 4)), bar_listener, features_of, draws=30)
    assert result.generated.levels == {"bar": 3}
    assert [r.beats_per_bar for r in result.swapped.recordings] == [4, 4, 4]  # partners 2, 2, 1
    assert result.swapped_period_changes == 1.0
    assert result.swapped_follows_new == 1.0 and result.swapped_follows_old == 0.0


def test_songs_whose_beat_is_read_at_twice_its_tempo_are_not_swapped_for_each_other():
    """Two waltzes at 0.69 s a beat, the beat tracker reading the second at twice its tempo (0.345 s,
    as librosa reads some of Dance with Melody's waltzes), and a cha-cha at 0.48 s: a dancer at two
    beats moves alike to both waltzes (1.38 s), so swapping one for the other could not show that it
    listens. By the tracker's beats the first waltz's most different partner would be the second
    (1.38 against 0.69 s at two beats); counted as the same period, each waltz gets the cha-cha, and
    every swap changes the period."""
    frames = int(SECONDS * FPS)
    out = []
    for i, (period, read, metre) in enumerate(((0.69, 0.69, 3), (0.69, 0.345, 3), (0.48, 0.48, 4))):
        beats = np.arange(0.4, SECONDS, period)
        features = np.zeros((frames, 1))
        features[np.round(beats * FPS).astype(int), 0] = 1.0
        real = bounce(beats[::2] * FPS, frames)
        read_beats = np.arange(0.4, SECONDS, read)
        out.append(HeldOutSong(f"song{i}", features, real[0], real, None, read_beats, FPS, 0.1, metre))

    def two_beats(features: np.ndarray, first_pose: np.ndarray) -> np.ndarray:
        return bounce(np.flatnonzero(features[:, 0] > 0.5)[::2], len(features))[1:]

    result = listening_report(out, two_beats, features_of, draws=30)
    assert result.generated.dominant_level == "two beats"
    names = [r.name for r in result.swapped.recordings]
    assert names[:2] == ["song0 with song2's music", "song1 with song2's music"], names
    assert result.swapped_period_changes == 1.0


MUSIC_RATE = 8000


def songs_with_music() -> list[HeldOutSong]:
    """:func:`songs` with their music at :data:`MUSIC_RATE`: a burst of a 400-Hz tone on every beat."""
    out = []
    for song in songs():
        t = np.arange(int(SECONDS * MUSIC_RATE)) / MUSIC_RATE
        music = np.zeros(t.size, np.float32)
        for beat in song.beats_s:
            burst = (t >= beat) & (t < beat + 0.03)
            music[burst] = np.sin(2 * np.pi * 400 * t[burst])
        out.append(HeldOutSong(song.name, song.features, song.first_pose, song.real_positions, None, song.beats_s,
                               FPS, rms=0.1, samples=music))  # fmt: skip
    return out


def tempo_features_of(samples: np.ndarray, beats_per_bar: int | None = None) -> np.ndarray:
    """[T, 1]: 1.0 at the frames where a burst begins (the features :func:`listener` hears)."""
    per_frame = MUSIC_RATE / FPS
    frames = int(len(samples) / per_frame)
    loud = np.array([np.abs(samples[int(k * per_frame) : int((k + 1) * per_frame)]).max() for k in range(frames)])
    on = loud > 0.3 * loud.max()
    return (on & ~np.concatenate([[False], on[:-1]])).astype(float)[:, None]


tempo_features_of.sample_rate = MUSIC_RATE


def test_the_tempo_control_runs_on_songs_whose_music_is_given():
    skip_unless_installed(None if shutil.which("sox") else "no sox on the PATH", "SoX")
    heard = listening_report(songs_with_music(), listener, tempo_features_of, draws=30)
    assert heard.tempo is not None and len(heard.tempo.pairs) == 2 * len(PERIODS)
    assert heard.tempo.followed == len(heard.tempo.pairs) and heard.tempo.keeps_time
    assert "keeps time with the song at other tempi: yes (8 of 8 pairs follow" in "\n".join(heard.verdicts())
    ignored = listening_report(songs_with_music(), deaf, tempo_features_of, draws=30)
    assert ignored.tempo.followed == 0 and not ignored.tempo.keeps_time
    assert ignored.to_dict()["tempo"]["followed"] == 0
    without = listening_report(songs(), listener, features_of, draws=30)  # no music given: not measured
    assert without.tempo is None
    assert "keeps time with the song at other tempi: not measured (the music of some songs could not be read)" in (
        "\n".join(without.verdicts())
    )


@pytest.mark.parametrize("beat_s", np.linspace(0.3, 1.0, 36))
def test_the_shifted_audio_lands_between_the_original_beats(beat_s):
    frames = int(SECONDS * FPS)
    for fraction in (0.25, 0.5, 0.75):
        shift_s = shift_frames(frames, beat_s, FPS, fraction) / FPS
        assert shift_s >= MIN_SHIFT_S
        off = shift_s / beat_s % 1.0  # where the shifted beats fall between the original ones
        assert fraction - 0.5 / FPS / beat_s - 1e-9 <= off <= fraction + 0.5 / FPS / beat_s + 1e-9
    short = int(4 * beat_s * FPS)  # four beats: rolled by a third at most, still off the grid
    shift = shift_frames(short, beat_s, FPS, 0.5)
    assert 1 <= shift <= short / 3 + 1 and abs(shift / FPS / beat_s % 1.0 - 0.5) <= 0.5 / FPS / beat_s + 1e-9


def glide(still_frames: np.ndarray, frames: int, joints: int = 6) -> np.ndarray:
    """[frames, J, 3]: every joint gliding along x, still once a beat at the given frames (a bounce
    is still twice, at its bottom and its top); still without them."""
    count = np.zeros(frames)
    if len(still_frames) >= 2:
        count = np.interp(np.arange(frames), still_frames, np.arange(len(still_frames)))  # beats so far
    pos = np.zeros((frames, joints, 3))
    pos[:, :, 0] = 0.1 * (count - np.sin(2 * np.pi * count) / (2 * np.pi))[:, None] + np.arange(joints) * 0.1
    pos[:, :, 1] = np.arange(joints) * 0.2
    pos[:, :, 2] = 2.5
    return pos


def glider(features: np.ndarray, first_pose: np.ndarray) -> np.ndarray:
    """Frames 1..T-1, gliding and still on every onset it hears."""
    return glide(np.flatnonzero(features[:, 0] > 0.5), len(features))[1:]


def test_a_listener_at_tempi_that_two_seconds_do_not_divide_has_its_shifted_audio_at_chance():
    # 2 s is 2.78 beats of 0.72 s, 5.56 of 0.36 s and 4.35 of 0.46 s: 2 s and a quarter to three
    # quarters of a beat more could put the shifted beats back on the original ones
    tempo_songs = songs((0.72, 0.36, 0.46, 0.72, 0.36, 0.46), dance=glide)
    for seed in range(4):
        result = listening_report(tempo_songs, glider, features_of, seed=seed, draws=100)
        assert result.generated.on_beat
        own = {r.name: r.beat_align_music for r in result.generated.recordings}
        assert all(r.beat_align_music < 0.5 * own[r.name] for r in result.shifted.recordings)
        assert result.shifted_at_chance
