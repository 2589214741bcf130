"""Is the pulse's beat the music's? ``python -m benchmarks.bench_pulse --corpus tang2018 PATH``: on
the training and validation songs of a local corpus copy (never its test songs), the tempo the
``listen_to_dance_rhythm`` pulse picks as the beat (:func:`~kinectdata.features.rhythm.predominant_beat`)
frame by frame, against librosa's beat tracker (``evaluate``'s beat, whose metrical levels the
verdicts are built on), for each ``harmonic_weight``: the share of frames at the beat (within 5 %),
at twice it and at half of it. Then the clocks of the levels above the beat (two beats, the bar and
two bars in each song's metre, ``listen_to_dance_rhythm_bars``), from the tempogram's phase at their
tempi and counted from the beat (``listen_to_dance_rhythm_counted``): how many times each turns per
such span of librosa's beats (1: once a level). Last, for each ``beat_hold`` (``--holds``), how
steady the pick is: the share of frames at librosa's beat, how often a minute the pick moves to
another tempo, and the share of frames at which the beat's clock jumps (its turn that frame more than
0.5 rad from its median turn). Skipped, with the reason, without ``--corpus``.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from kinectdata.align.audio import load_audio
from kinectdata.dataset.recipes import prepare_corpus
from kinectdata.evaluation.rhythm import beat_period_s
from kinectdata.features import LISTEN_TO_DANCE_BAR_PULSE, LISTEN_TO_DANCE_COUNTED_PULSE, LISTEN_TO_DANCE_PULSE
from kinectdata.features.beats import music_beats
from kinectdata.features.rhythm import predominant_beat, rhythm_features

from .summary import record

SECONDS = 60.0
"""Seconds of each song looked at, from its dance's start."""
SETTLE_S = 4.0
"""Frames in the first seconds, before the pulse's window holds a few beats, are left out."""
TOLERANCE = np.log2(1.05)
"""A picked tempo within 5 % of a multiple counts as at it (the grid's spacing is 4.4 %)."""


def song_shares(samples: np.ndarray, weights: tuple[float, ...]) -> tuple[float, dict[float, np.ndarray]]:
    """(librosa's beat in BPM, per harmonic weight the shares [3] of frames whose picked beat is at
    it, at twice it and at half of it) for mono 16-kHz ``samples`` [S]."""
    beats, _ = music_beats(samples, 16000)
    bpm = 60.0 / beat_period_s(beats)
    plain = dataclasses.replace(LISTEN_TO_DANCE_PULSE, levels=(), tempo_phases=False)  # the saliences [F, K]
    starts = np.arange(int(SETTLE_S * 30), int(samples.size / 16000 * 30) - 1) * 16000 // 30
    salience, _ = rhythm_features(samples, starts.astype(np.int64), plain)
    shares = {}
    for weight in weights:
        picked = plain.tempi_bpm[predominant_beat(salience, dataclasses.replace(plain, harmonic_weight=weight))]
        octave = np.log2(picked / bpm)
        shares[weight] = np.array([np.mean(np.abs(octave - k) < TOLERANCE) for k in (0, 1, -1)])
    return bpm, shares


CLOCK_SETTLE_S = 12.0
"""The levels' clocks are read after the pulse's window (12 s) has filled."""
CLOCK_SPAN_S = 10.0
"""A song's clocks are read over at least this long after the settling (shorter songs are skipped)."""
CLOCKS = {"tempogram": LISTEN_TO_DANCE_BAR_PULSE, "counted": LISTEN_TO_DANCE_COUNTED_PULSE}
JUMP_RAD = 0.5
"""A clock's turn in one frame this far (radians) from its median turn is a jump."""


def clock_frames(samples: np.ndarray) -> np.ndarray | None:
    """The slice starts [F] (16 kHz samples, 30 frames a second) of the frames read after
    :data:`CLOCK_SETTLE_S`, or None for a song shorter than :data:`CLOCK_SETTLE_S` + :data:`CLOCK_SPAN_S`."""
    if samples.size < (CLOCK_SETTLE_S + CLOCK_SPAN_S) * 16000:
        return None
    return (np.arange(int(CLOCK_SETTLE_S * 30), int(samples.size / 16000 * 30) - 1) * 16000 // 30).astype(np.int64)


def level_clocks(samples: np.ndarray, beats_per_bar: int, beat: float) -> dict[str, np.ndarray] | None:
    """Per way of making the levels (:data:`CLOCKS`), [4] how many times the beat's, two beats', the
    bar's and two bars' clocks turn per such span of the music's beats of ``beat`` seconds (the slope
    of each unwrapped phase against time, fitted by numpy, times the level's beats times the beat
    period): 1 when a level turns once a level, 0 when its phase restarts at every beat, 2 or 0.5
    where the pick is at twice or half that beat. ``samples``: [S] mono 16-kHz audio. None for a
    song shorter than :data:`CLOCK_SETTLE_S` + :data:`CLOCK_SPAN_S`."""
    starts = clock_frames(samples)
    if starts is None:
        return None
    t = starts / 16000.0
    out = {}
    for name, config in CLOCKS.items():
        config = dataclasses.replace(config, tempo_phases=False)
        feats, _ = rhythm_features(samples, starts, config, beats_per_bar=beats_per_bar)
        levels = feats[:, config.n_tempi :].reshape(len(feats), -1, 2).transpose(1, 0, 2)
        rates = np.array([np.polyfit(t, np.unwrap(np.arctan2(lv[:, 1], lv[:, 0])), 1)[0] for lv in levels])
        out[name] = rates / (2 * np.pi) * np.asarray(config.beat_multiples(beats_per_bar)) * beat
    return out


def held_picks(samples: np.ndarray, beats_per_bar: int, bpm: float, holds: tuple[float, ...]) -> np.ndarray | None:
    """[holds, 3] per ``beat_hold``: the share of frames whose beat is librosa's ``bpm`` (within 5 %),
    the pick's moves to another tempo per minute, and the share of frames at which the beat's clock
    (``listen_to_dance_rhythm_bars``) jumps (:data:`JUMP_RAD`), read after :data:`CLOCK_SETTLE_S`.
    None for a song shorter than :data:`CLOCK_SETTLE_S` + :data:`CLOCK_SPAN_S`."""
    starts = clock_frames(samples)
    if starts is None:
        return None
    rows = []
    for hold in holds:
        config = dataclasses.replace(LISTEN_TO_DANCE_BAR_PULSE, tempo_phases=False, beat_hold=hold)
        feats, _ = rhythm_features(samples, starts, config, beats_per_bar=beats_per_bar)
        beat = predominant_beat(feats[:, : config.n_tempi].astype(np.float64), config)
        at_beat = np.mean(np.abs(np.log2(config.tempi_bpm[beat] / bpm)) < TOLERANCE)
        moves = np.count_nonzero(np.diff(beat)) / (starts.size / 30 / 60)
        beat_clock = feats[:, config.n_tempi : config.n_tempi + 2]  # the first level (the beat): cosine, sine
        turn = np.angle(np.exp(1j * np.diff(np.arctan2(beat_clock[:, 1], beat_clock[:, 0]))))
        off = np.abs(np.angle(np.exp(1j * (turn - np.median(turn)))))
        rows.append((at_beat, moves, np.mean(off > JUMP_RAD)))
    return np.asarray(rows)


def report_holds(rows: list[np.ndarray | None], holds: tuple[float, ...]) -> None:
    """Print the mean over songs of :func:`held_picks` for each hold."""
    read = np.stack([r for r in rows if r is not None]) if any(r is not None for r in rows) else None
    if read is None:
        print("  no song long enough to read how steady the pick is")
        return
    print(f"  the beat held ({len(read)} songs, after the first {CLOCK_SETTLE_S:g} s):")
    for i, hold in enumerate(holds):
        at_beat, moves, jumps = read[:, i].mean(axis=0)
        print(
            f"  beat_hold {hold:g}: at librosa's beat in {at_beat:.0%} of the frames; the pick moves {moves:.0f} times "
            f"a minute; the beat's clock jumps in {jumps:.1%} of the frames"
        )
        record("pulse", f"beat held {hold:g}", f"moves {moves:.0f} a minute, beat clock jumps in {jumps:.1%} of frames")


def report_clocks(rows: list[tuple[str, int, dict[str, np.ndarray] | None]]) -> dict[str, np.ndarray]:
    """Print the levels' clocks of every song (``(name, metre, level_clocks(...))``) with each way's
    medians and shares within 5 % of turning once a level, and return them per way, [songs, 4]."""
    print("  the levels' clocks: turns per level of librosa's beat (1: once a beat, two beats, bar, two bars)")
    print("  song     metre  " + "  ".join(f"{name}: beat / 2 beats / bar / 2 bars" for name in CLOCKS))
    per_song = {name: [] for name in CLOCKS}
    for name, metre, clocks in rows:
        if clocks is None:
            print(f"  {name:8s} {metre} beats not read: shorter than {CLOCK_SETTLE_S + CLOCK_SPAN_S:g} s")
            continue
        for way in CLOCKS:
            per_song[way].append(clocks[way])
        cells = "  ".join(f"{'':10s}{' / '.join(f'{v:.2f}' for v in c)}" for c in clocks.values())
        print(f"  {name:8s} {metre} beats {cells}")
    result = {name: np.asarray(v).reshape(-1, 4) for name, v in per_song.items()}
    if not len(result["counted"]):
        print("  no song long enough to read the levels' clocks")
        return result
    for name, r in result.items():
        median = np.median(r, axis=0)
        within = np.mean(np.abs(r - 1) < 0.05, axis=0)
        print(
            f"  {name}: medians {' / '.join(f'{m:.2f}' for m in median)} turns per level; within 5 % of once a "
            f"level in {' / '.join(f'{w:.0%}' for w in within)} of the songs"
        )
        record("pulse", f"bar clock, {name}", f"{median[2]:.2f} turns per bar (median), {within[2]:.0%} within 5 %")
    return result


def run(corpus: str, path: Path, weights: tuple[float, ...], holds: tuple[float, ...] = ()) -> dict[float, np.ndarray]:
    manifest = prepare_corpus(corpus, path)
    songs = [e for e in manifest.recordings if e.split in ("train", "val") and e.audio]
    print(f"  {corpus}: {len(songs)} training and validation songs (the test songs are not looked at)")
    print("  song     librosa  " + "  ".join(f"weight {w:g}: beat / 2x / half" for w in weights))
    per_song = {w: [] for w in weights}
    clock_rows, hold_rows = [], []
    for entry in songs:
        audio = load_audio(manifest.root / entry.audio).samples
        first = int(round(float(entry.offset) * 16000))
        segment = audio[first : first + int(SECONDS * 16000)]
        bpm, shares = song_shares(segment, weights)
        metre = int(entry.beats_per_bar or 4)
        clock_rows.append((entry.name, metre, level_clocks(segment, metre, 60.0 / bpm)))
        if holds:
            hold_rows.append(held_picks(segment, metre, bpm, holds))
        for w in weights:
            per_song[w].append(shares[w])
        cells = "  ".join(f"{'':10s}{s[0]:.2f} / {s[1]:.2f} / {s[2]:.2f}" for s in shares.values())
        print(f"  {entry.name:8s} {bpm:5.1f} BPM {cells}", flush=True)
    means = {w: np.mean(per_song[w], axis=0) for w in weights}
    for w, m in means.items():
        print(
            f"  harmonic weight {w:g}: the beat picked at librosa's in {m[0]:.0%} of the frames, at twice it in "
            f"{m[1]:.0%}, at half of it in {m[2]:.0%}"
        )
    best = max(weights, key=lambda w: means[w][0])
    preset = LISTEN_TO_DANCE_PULSE.harmonic_weight
    print(f"  at the music's beat most often: harmonic weight {best:g} (the preset's: {preset:g})")
    for w, m in means.items():
        record(
            "pulse",
            f"beat picked at librosa's, harmonic weight {w:g}",
            f"{m[0]:.0%} of frames (at twice it {m[1]:.0%})",
        )
    report_clocks(clock_rows)
    if holds:
        report_holds(hold_rows, holds)
    return means


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_pulse", description=__doc__.split("\n")[0])
    parser.add_argument("--corpus", nargs=2, metavar=("NAME", "PATH"), default=None)
    parser.add_argument("--weights", default="0,1", help="comma-separated harmonic weights to compare")
    parser.add_argument("--holds", default="0,0.3", help="comma-separated beat holds to compare ('' for none)")
    args = parser.parse_args(argv or [])
    if args.corpus is None:
        print("  not run: needs --corpus tang2018 PATH (a local copy of Dance with Melody, docs/corpora.md)")
        return
    name, path = args.corpus
    holds = tuple(float(h) for h in args.holds.split(",") if h.strip())
    run(name, Path(path), tuple(float(w) for w in args.weights.split(",")), holds)


if __name__ == "__main__":
    import sys

    main(sys.argv[1:])
