"""A synthesized music track with a clear 4/4 beat, preceded by near-silence and the sync clap.

Everything is rendered on the audio clock (seconds from the first sample). The track is silent
(a faint noise floor around -70 dBFS) until ``music_start_s``, except for one hand clap at
``clap_time_s``; from ``music_start_s`` on it plays drums (kick on beats 1 and 3, snare on 2 and
4, closed hi-hat on the eighths), then from bar :data:`INTRO_BARS` on also bass, a pad and a
pentatonic melody over a four-chord progression. Rendering is vectorised: notes are evaluated
for all samples at once and drum hits are placed by convolving impulse trains with one-shot
samples.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import signal

from kinectdata.core.errors import ConfigError

BEATS_PER_BAR = 4
INTRO_BARS = 2
"""Bars of drums only at the start of the music; the dancer keeps its arms quiet during them."""
PHRASE_BARS = 8
"""Bars per section after the intro (sections alternate ``A``, ``B``)."""

TARGET_PEAK_DBFS = -1.0
NOISE_FLOOR_DBFS = -70.0
CLAP_PEAK_DBFS = -6.0
CLAP_ATTACK_S = 0.0005
"""The clap's envelope rises linearly from ``clap_time_s`` for this long, then decays."""
CLAP_DECAY_TAU_S = 0.007
"""Exponential decay constant of the clap (about -40 dB 30 ms after the onset)."""
CLAP_LENGTH_S = 0.06

_MAJOR = {
    "scale": (0, 2, 4, 5, 7, 9, 11),
    "pentatonic": (0, 2, 4, 7, 9),
    "progressions": (
        ((0, "maj"), (7, "maj"), (9, "min"), (5, "maj")),
        ((0, "maj"), (9, "min"), (5, "maj"), (7, "maj")),
        ((9, "min"), (5, "maj"), (0, "maj"), (7, "maj")),
        ((0, "maj"), (5, "maj"), (7, "maj"), (5, "maj")),
    ),
}
_MINOR = {
    "scale": (0, 2, 3, 5, 7, 8, 10),
    "pentatonic": (0, 3, 5, 7, 10),
    "progressions": (
        ((0, "min"), (8, "maj"), (3, "maj"), (10, "maj")),
        ((0, "min"), (5, "min"), (10, "maj"), (3, "maj")),
        ((0, "min"), (10, "maj"), (8, "maj"), (10, "maj")),
        ((0, "min"), (3, "maj"), (5, "min"), (7, "min")),
    ),
}
_TRIADS = {"maj": (0, 4, 7), "min": (0, 3, 7)}
_NOTE_NAMES = ("C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B")


def synthesize_music(
    *,
    seed: int | np.random.SeedSequence,
    duration_s: float,
    tempo_bpm: float,
    music_start_s: float,
    clap_time_s: float | None,
    sample_rate: int = 44100,
) -> tuple[np.ndarray, dict[str, Any]]:
    """Render the track.

    Args:
        seed: seed of the music's random choices (key, progression, melody, velocities, noise).
        duration_s: length of the track, seconds.
        tempo_bpm: beats per minute.
        music_start_s: time of the first downbeat (the first kick), seconds on the audio clock.
        clap_time_s: onset of the sync clap (the instant its envelope starts rising), or None for
            no clap. Meant to lie before ``music_start_s``.
        sample_rate: Hz.

    Returns:
        ``(audio, info)``: ``audio`` [S, 2] float32 in -1..1, S = round(duration_s * sample_rate),
        peak about -1 dBFS; ``info`` with ``tempo_bpm``, ``beat_period_s``, ``beat_times_s`` (every
        beat from ``music_start_s`` until the end, [B] float64), ``downbeat_times_s``,
        ``music_start_s``, ``clap_time_s`` (onset), ``clap_peak_s`` (the clap's envelope peak,
        :data:`CLAP_ATTACK_S` after the onset), ``sections`` (name, start_s, end_s), ``key``,
        ``progression`` (chord names, one per bar), ``sample_rate``, ``duration_s``.
    """
    if duration_s <= 0 or sample_rate <= 0 or tempo_bpm <= 0:
        raise ConfigError("duration_s, sample_rate and tempo_bpm must be positive")
    if not 0 <= music_start_s < duration_s:
        raise ConfigError(f"music_start_s={music_start_s} must lie in [0, duration_s={duration_s})")
    if clap_time_s is not None and not 0 <= clap_time_s <= duration_s - CLAP_LENGTH_S:
        raise ConfigError(f"clap_time_s={clap_time_s} must lie inside the track")

    rng = np.random.default_rng(seed)
    sr = int(sample_rate)
    n = int(round(duration_s * sr))
    period = 60.0 / tempo_bpm
    n_beats = int(np.floor((duration_s - music_start_s) / period - 1e-9)) + 1
    beats = music_start_s + period * np.arange(n_beats)
    n_bars = -(-n_beats // BEATS_PER_BAR)

    mode = _MAJOR if rng.random() < 0.5 else _MINOR
    tonic = int(rng.integers(52, 60))  # E3..B3: the bass plays an octave below, the melody above
    progression = mode["progressions"][int(rng.integers(len(mode["progressions"])))]
    sections = _sections(n_bars)
    section_of_bar = np.array([s for s, b0, b1 in sections for _ in range(b0, b1)])

    left = np.zeros(n)
    right = np.zeros(n)
    send = np.zeros((n, 2))

    def mix(x: np.ndarray, pan: float, gain: float, reverb: float = 0.0) -> None:
        gl, gr = np.cos((pan + 1) * np.pi / 4), np.sin((pan + 1) * np.pi / 4)
        left[:] += gain * gl * x
        right[:] += gain * gr * x
        if reverb:
            send[:, 0] += reverb * gain * gl * x
            send[:, 1] += reverb * gain * gr * x

    # Drums.
    beat_in_bar = np.arange(n_beats) % BEATS_PER_BAR
    kicks = beats[beat_in_bar % 2 == 0]
    snares = beats[beat_in_bar % 2 == 1]
    eighths = music_start_s + 0.5 * period * np.arange(2 * n_beats)
    eighths = eighths[eighths < duration_s]
    kick_vel = np.where(beat_in_bar[beat_in_bar % 2 == 0] == 0, 1.0, 0.93) + rng.normal(0, 0.03, kicks.size)
    snare_vel = 0.9 + rng.normal(0, 0.05, snares.size)
    hat_vel = np.where(np.arange(eighths.size) % 2 == 0, 0.8, 0.55) + rng.normal(0, 0.07, eighths.size)
    # An open hi-hat on the last eighth of every other bar in B sections.
    eighth_bar = np.arange(eighths.size) // (2 * BEATS_PER_BAR)
    open_hat = (np.arange(eighths.size) % (2 * BEATS_PER_BAR) == 7) & (eighth_bar % 2 == 1)
    open_hat &= np.array([section_of_bar[b] == "B" for b in eighth_bar]) if eighths.size else open_hat
    crashes = np.array([b0 * BEATS_PER_BAR * period + music_start_s for name, b0, _ in sections if name != "intro"])
    crashes = crashes[crashes < duration_s]

    mix(_place(n, sr, kicks, kick_vel, _kick(sr, rng)), 0.0, 1.0)
    for i, sample in enumerate(_variants(3, lambda: _snare(sr, rng))):
        mix(_place(n, sr, snares[i::3], snare_vel[i::3], sample), -0.12, 0.75, reverb=0.35)
    closed, opened = ~open_hat, open_hat
    for i, sample in enumerate(_variants(2, lambda: _hat(sr, rng, 0.022))):
        sel = np.flatnonzero(closed)[i::2]
        mix(_place(n, sr, eighths[sel], hat_vel[sel], sample), 0.35, 0.2, reverb=0.1)
    mix(_place(n, sr, eighths[opened], hat_vel[opened], _hat(sr, rng, 0.16)), 0.35, 0.16, reverb=0.1)
    mix(_place(n, sr, crashes, np.full(crashes.size, 1.0), _crash(sr, rng)), -0.35, 0.16, reverb=0.25)

    # Pitched parts start after the intro.
    first = music_start_s + INTRO_BARS * BEATS_PER_BAR * period
    if first < duration_s:
        t0 = int(np.floor(first * sr))
        t = np.arange(t0, n) / sr
        bars = np.arange(INTRO_BARS, n_bars)
        chords = [progression[(b - INTRO_BARS) % len(progression)] for b in bars]
        bar_t = music_start_s + bars * BEATS_PER_BAR * period

        bass = _bass_notes(rng, bar_t, chords, tonic - 12, period, [section_of_bar[b] for b in bars])
        x = _render_line(t, *bass, attack=0.004, decay=0.35, release=0.02, harmonics=((1, 1.0), (2, 0.45), (3, 0.2)))
        x = signal.sosfilt(_butter(2, 900, "low", sr), x)
        mix(_pad(n, t0, x), 0.0, 0.42)

        for voice, pan in zip(range(3), (-0.55, 0.0, 0.55), strict=True):
            starts = bar_t
            durs = np.full(bars.size, BEATS_PER_BAR * period - 0.01)
            freqs = _hz(np.array([tonic + root + _TRIADS[q][voice] for root, q in chords], float))
            freqs *= 2 ** ((voice - 1) * 4 / 1200)  # a few cents of detune between voices
            x = _render_line(
                t,
                starts,
                durs,
                freqs,
                np.full(bars.size, 1.0),
                attack=0.15,
                decay=6.0,
                release=0.12,
                harmonics=((1, 1.0), (2, 0.5), (3, 0.33), (4, 0.22), (5, 0.14), (6, 0.08)),
            )
            x = signal.sosfilt(_butter(2, 250, "high", sr), x)  # leave the lows to bass and kick
            mix(_pad(n, t0, x), pan, 0.08, reverb=0.5)

        melody = _melody_notes(
            rng, bar_t, chords, tonic + 12, mode["pentatonic"], period, [section_of_bar[b] for b in bars]
        )
        x = _render_line(
            t,
            *melody,
            attack=0.008,
            decay=0.45,
            release=0.03,
            harmonics=((1, 1.0), (2, 0.5), (3, 0.3), (4, 0.18), (5, 0.12), (6, 0.06)),
            vibrato=(5.5, 0.004),
        )
        mix(_pad(n, t0, x), -0.3, 0.24, reverb=0.45)

    mixed = np.stack([left, right], axis=1)
    mixed += _reverb(send, sr, rng) * 0.22
    peak = np.max(np.abs(mixed))
    if peak > 0:
        mixed *= 10 ** (TARGET_PEAK_DBFS / 20) / peak

    clap_peak = None
    if clap_time_s is not None:
        clap = _clap(n, sr, clap_time_s, rng)
        mixed += clap[:, None] * np.array([1.0, 0.92])
        clap_peak = clap_time_s + CLAP_ATTACK_S
    noise = rng.normal(0, 1, (n, 2))
    noise = signal.sosfilt(_butter(1, 4000, "low", sr), noise, axis=0)
    noise *= 10 ** (NOISE_FLOOR_DBFS / 20) / np.sqrt(np.mean(noise**2))
    audio = np.clip(mixed + noise, -1.0, 1.0).astype(np.float32)

    bar_len = BEATS_PER_BAR * period
    info: dict[str, Any] = {
        "tempo_bpm": float(tempo_bpm),
        "beat_period_s": period,
        "beat_times_s": beats,
        "downbeat_times_s": beats[::BEATS_PER_BAR],
        "music_start_s": float(music_start_s),
        "clap_time_s": None if clap_time_s is None else float(clap_time_s),
        "clap_peak_s": clap_peak,
        "sections": [
            {
                "name": s,
                "start_s": float(music_start_s + b0 * bar_len),
                "end_s": float(min(duration_s, music_start_s + b1 * bar_len)),
            }
            for s, b0, b1 in sections
        ],
        "key": _NOTE_NAMES[tonic % 12] + (" major" if mode is _MAJOR else " minor"),
        "progression": [_chord_name(tonic, root, q) for root, q in progression],
        "sample_rate": sr,
        "duration_s": float(duration_s),
    }
    return audio, info


# -- structure ---------------------------------------------------------------------------------
def _sections(n_bars: int) -> list[tuple[str, int, int]]:
    """(name, first bar, end bar) of each section: the intro, then 8-bar A and B alternating."""
    out = [("intro", 0, min(INTRO_BARS, n_bars))]
    b, k = INTRO_BARS, 0
    while b < n_bars:
        out.append(("AB"[k % 2], b, min(b + PHRASE_BARS, n_bars)))
        b, k = b + PHRASE_BARS, k + 1
    return out


def _chord_name(tonic: int, root: int, quality: str) -> str:
    return _NOTE_NAMES[(tonic + root) % 12] + ("m" if quality == "min" else "")


def _hz(midi: np.ndarray) -> np.ndarray:
    return 440.0 * 2 ** ((np.asarray(midi, float) - 69) / 12)


def _bass_notes(rng, bar_t, chords, base, period, section_names):
    """Roots on the beats, with softer eighth-note pickups (pattern chosen per section)."""
    patterns = {  # (eighth slot, octave up?, velocity)
        "A": ((0, 0, 1.0), (2, 0, 0.9), (3, 0, 0.6), (4, 0, 0.95), (6, 0, 0.9), (7, 1, 0.6)),
        "B": (
            (0, 0, 1.0),
            (1, 1, 0.55),
            (2, 0, 0.9),
            (3, 1, 0.55),
            (4, 0, 0.95),
            (5, 1, 0.55),
            (6, 0, 0.9),
            (7, 1, 0.55),
        ),
    }
    starts, durs, notes, vels = [], [], [], []
    for t_bar, (root, _), name in zip(bar_t, chords, section_names, strict=True):
        pat = patterns["B" if name == "B" else "A"]
        slots = [p[0] for p in pat] + [8]
        for (slot, octave, vel), nxt in zip(pat, slots[1:], strict=True):
            starts.append(t_bar + slot * period / 2)
            durs.append((nxt - slot) * period / 2 - 0.015)
            notes.append(base + root % 12 + 12 * octave)
            vels.append(vel * (1 + rng.normal(0, 0.04)))
    return np.array(starts), np.array(durs), _hz(np.array(notes)), np.array(vels)


def _melody_notes(rng, bar_t, chords, base, pentatonic, period, section_names):
    """A seeded two-bar pentatonic motif per section type, repeated with a varied ending.

    Strong eighths (the beats) snap to a chord tone of the bar's chord when one is near.
    """
    scale = np.array([base + o * 12 + p for o in range(-1, 2) for p in pentatonic])
    motifs = {}
    for name in ("A", "B"):
        onsets = rng.random(16) < np.tile([0.9, 0.35, 0.7, 0.4, 0.8, 0.35, 0.6, 0.3], 2)
        onsets[0] = True
        steps = rng.choice([-2, -1, 0, 1, 2], size=16, p=[0.15, 0.3, 0.1, 0.3, 0.15])
        start = 5 if name == "A" else 7
        degrees = np.clip(start + np.cumsum(steps), 2, scale.size - 3)
        variant = degrees.copy()
        variant[12:] = np.clip(degrees[12:] + rng.choice([-2, -1, 1, 2], 4), 2, scale.size - 3)
        motifs[name] = (onsets, degrees, variant)
    starts, durs, notes, vels = [], [], [], []
    for i, (t_bar, (root, quality), name) in enumerate(zip(bar_t, chords, section_names, strict=True)):
        onsets, degrees, variant = motifs["B" if name == "B" else "A"]
        half = i % 2  # which bar of the two-bar motif
        deg = variant if (i // 2) % 2 == 1 else degrees
        chord_pcs = {(root + iv) % 12 for iv in _TRIADS[quality]}
        slots = np.flatnonzero(onsets[half * 8 : (half + 1) * 8])
        for j, slot in enumerate(slots):
            nxt = slots[j + 1] if j + 1 < slots.size else 8
            note = int(scale[deg[half * 8 + slot]])
            if slot % 2 == 0:
                near = [m for m in scale if (m - base) % 12 in chord_pcs and abs(m - note) <= 3]
                if near:
                    note = int(min(near, key=lambda m: abs(m - note)))
            starts.append(t_bar + slot * period / 2)
            durs.append(min(nxt - slot, 3) * period / 2 - 0.02)
            notes.append(note)
            vels.append((1.0 if slot % 2 == 0 else 0.8) * (1 + rng.normal(0, 0.06)))
    return np.array(starts), np.array(durs), _hz(np.array(notes)), np.array(vels)


# -- sound sources -----------------------------------------------------------------------------
_CHUNK = 1 << 18  # samples rendered at a time: bounds the temporaries of long tracks


def _render_line(t, starts, durs, freqs, vels, **kw):
    """A monophonic line of notes evaluated at every sample time ``t`` [N] (seconds).

    Each sample belongs to the latest note started before it; the note's envelope (linear
    attack, exponential decay, linear release that ends at the note's end) is zero at both ends,
    so consecutive notes join without clicks. Rendered in chunks (every sample is computed on its
    own, so chunking changes nothing but memory).
    """
    out = np.zeros_like(t)
    if len(starts) == 0:
        return out
    for s in range(0, t.size, _CHUNK):
        out[s : s + _CHUNK] = _render_chunk(t[s : s + _CHUNK], starts, durs, freqs, vels, **kw)
    return out


def _render_chunk(t, starts, durs, freqs, vels, *, attack, decay, release, harmonics, vibrato=None):
    idx = np.searchsorted(starts, t, side="right") - 1
    on = idx >= 0
    idx = np.maximum(idx, 0)
    tau = t - starts[idx]
    remaining = starts[idx] + durs[idx] - t
    env = np.clip(tau / attack, 0, 1) * np.exp(-tau / decay) * np.clip(remaining / release, 0, 1) * vels[idx]
    env[~on] = 0.0
    phase = 2 * np.pi * freqs[idx] * tau
    if vibrato is not None:
        rate, depth = vibrato
        phase += depth * freqs[idx] / rate * (1 - np.cos(2 * np.pi * rate * np.maximum(tau - 0.15, 0)))
    # sin(k*phase) by the Chebyshev recurrence: one sin and one cos instead of one sin per harmonic.
    s1, c1 = np.sin(phase), np.cos(phase)
    wave = np.zeros_like(t)
    prev, cur = np.zeros_like(t), s1
    for k in range(1, max(k for k, _ in harmonics) + 1):
        a = dict(harmonics).get(k, 0.0)
        if a:
            wave += a * cur
        prev, cur = cur, 2 * c1 * cur - prev
    return env * wave


def _butter(order: int, cutoff_hz, kind: str, sr: int) -> np.ndarray:
    """Butterworth sections with every cutoff kept below 0.45 * sr, so any output rate works."""
    top = 0.45 * sr
    cutoff = [min(c, top) for c in cutoff_hz] if isinstance(cutoff_hz, list) else min(cutoff_hz, top)
    return signal.butter(order, cutoff, kind, fs=sr, output="sos")


def _pad(n: int, t0: int, x: np.ndarray) -> np.ndarray:
    out = np.zeros(n)
    out[t0:] = x
    return out


def _place(n: int, sr: int, times: np.ndarray, vels: np.ndarray, sample: np.ndarray) -> np.ndarray:
    """One-shot ``sample`` started at each time (rounded to the nearest sample) with gain ``vels``."""
    out = np.zeros(n)
    for i, v in zip(np.round(np.asarray(times) * sr).astype(int), np.asarray(vels), strict=True):
        if 0 <= i < n:  # one slice per hit (a few hundred hits), not per sample
            m = min(sample.size, n - i)
            out[i : i + m] += v * sample[:m]
    return out


def _variants(k: int, make) -> list[np.ndarray]:
    return [make() for _ in range(k)]


def _decay(sr: int, length_s: float, tau: float, attack_s: float = 0.001) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(int(length_s * sr)) / sr
    return t, np.minimum(t / attack_s, 1.0) * np.exp(-t / tau)


def _kick(sr: int, rng) -> np.ndarray:
    t, env = _decay(sr, 0.45, 0.11, 0.001)
    phase = 2 * np.pi * (50 * t + 70 * 0.015 * (1 - np.exp(-t / 0.015)))  # 120 Hz falling to 50 Hz
    body = np.sin(phase) * env
    click = signal.sosfilt(_butter(2, 3000, "high", sr), rng.normal(0, 1, t.size))
    click *= np.exp(-t / 0.002) * 0.25
    return body + click


def _snare(sr: int, rng) -> np.ndarray:
    t, env_tone = _decay(sr, 0.35, 0.05)
    tone = (np.sin(2 * np.pi * 185 * t) + 0.5 * np.sin(2 * np.pi * 330 * t)) * env_tone * 0.6
    noise = signal.sosfilt(_butter(2, [1500, 8000], "band", sr), rng.normal(0, 1, t.size))
    return tone + noise * _decay(sr, 0.35, 0.11)[1] * 0.8


def _hat(sr: int, rng, tau: float) -> np.ndarray:
    t, env = _decay(sr, max(0.1, 6 * tau), tau, 0.0005)
    noise = signal.sosfilt(_butter(4, 7000, "high", sr), rng.normal(0, 1, t.size))
    return noise * env * 0.6


def _crash(sr: int, rng) -> np.ndarray:
    t, env = _decay(sr, 2.0, 0.5, 0.001)
    noise = signal.sosfilt(_butter(2, 4500, "high", sr), rng.normal(0, 1, t.size))
    return noise * env * 0.5


def _reverb(send: np.ndarray, sr: int, rng) -> np.ndarray:
    """A small room: 15 ms pre-delay, exponentially decaying noise tail (RT60 about 1 s) per channel."""
    t, env = _decay(sr, 1.0, 0.15, 0.01)
    ir = rng.normal(0, 1, (t.size, 2)) * env[:, None]
    ir = signal.sosfilt(_butter(1, 5000, "low", sr), ir, axis=0)
    ir /= np.sqrt(np.sum(ir**2, axis=0))
    ir = np.concatenate([np.zeros((int(0.015 * sr), 2)), ir])
    # overlap-add in blocks: one convolution of a 10-minute track would need gigabytes
    wet = np.zeros((send.shape[0] + ir.shape[0] - 1, send.shape[1]))
    for s in range(0, send.shape[0], _CHUNK):
        block = signal.oaconvolve(send[s : s + _CHUNK], ir, axes=0)
        wet[s : s + block.shape[0]] += block
    return wet[: send.shape[0]]


def _clap(n: int, sr: int, onset_s: float, rng) -> np.ndarray:
    """The sync clap: band-passed noise (0.9-3 kHz) under a 0.5 ms linear attack starting exactly at
    ``onset_s`` (sub-sample accurate) and an exponential decay; peak at :data:`CLAP_PEAK_DBFS`."""
    i0 = max(int(np.floor(onset_s * sr)) - 1, 0)
    i1 = min(i0 + int(CLAP_LENGTH_S * sr) + 2, n)
    # Filter a longer noise stretch so that the band-pass has settled before the onset.
    pre = int(0.02 * sr)
    noise = signal.sosfilt(_butter(2, [900, 3000], "band", sr), rng.normal(0, 1, pre + i1 - i0))[pre:]
    tau = np.arange(i0, i1) / sr - onset_s
    env = np.where(
        tau < 0,
        0.0,
        np.minimum(tau / CLAP_ATTACK_S, 1.0) * np.exp(-np.maximum(tau - CLAP_ATTACK_S, 0) / CLAP_DECAY_TAU_S),
    )
    burst = noise * env
    burst *= 10 ** (CLAP_PEAK_DBFS / 20) / np.max(np.abs(burst))
    out = np.zeros(n)
    out[i0:i1] = burst
    return out
