"""Is the pulse's beat the music's? ``python -m benchmarks.bench_pulse --corpus tang2018 PATH``: on
the training and validation songs of a local corpus copy (never its test songs), the tempo the
``listen_to_dance_rhythm`` pulse picks as the beat (:func:`~kinectdata.features.rhythm.predominant_beat`)
frame by frame, against librosa's beat tracker (``evaluate``'s beat, whose metrical levels the
verdicts are built on), for each ``harmonic_weight``: the share of frames at the beat (within 5 %),
at twice it and at half of it. Skipped, with the reason, without ``--corpus``.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from kinectdata.align.audio import load_audio
from kinectdata.dataset.recipes import prepare_corpus
from kinectdata.evaluation.rhythm import beat_period_s
from kinectdata.features import LISTEN_TO_DANCE_PULSE
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


def run(corpus: str, path: Path, weights: tuple[float, ...]) -> dict[float, np.ndarray]:
    manifest = prepare_corpus(corpus, path)
    songs = [e for e in manifest.recordings if e.split in ("train", "val") and e.audio]
    print(f"  {corpus}: {len(songs)} training and validation songs (the test songs are not looked at)")
    print("  song     librosa  " + "  ".join(f"weight {w:g}: beat / 2x / half" for w in weights))
    per_song = {w: [] for w in weights}
    for entry in songs:
        audio = load_audio(manifest.root / entry.audio).samples
        first = int(round(float(entry.offset) * 16000))
        bpm, shares = song_shares(audio[first : first + int(SECONDS * 16000)], weights)
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
    return means


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_pulse", description=__doc__.split("\n")[0])
    parser.add_argument("--corpus", nargs=2, metavar=("NAME", "PATH"), default=None)
    parser.add_argument("--weights", default="0,1", help="comma-separated harmonic weights to compare")
    args = parser.parse_args(argv or [])
    if args.corpus is None:
        print("  not run: needs --corpus tang2018 PATH (a local copy of Dance with Melody, docs/corpora.md)")
        return
    name, path = args.corpus
    run(name, Path(path), tuple(float(w) for w in args.weights.split(",")))


if __name__ == "__main__":
    import sys

    main(sys.argv[1:])
