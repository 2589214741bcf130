"""Estimating the offset between a skeleton recording and its audio.

Convention (used throughout kinectdata): ``audio_time = motion_time + offset``, both in seconds,
``motion_time`` being the recording's own clock (0 at its first frame). A positive offset means
the audio started before the skeleton recording.

Two methods, tried in this order:

``clap``
    The usual sync protocol: the dancer claps once (or a few times) in quiet before the music.
    In the motion, a clap is the moment the hands meet: a minimum of the left-right hand
    distance below :data:`CLAP_DISTANCE_M` reached at a closing speed above
    :data:`CLAP_SPEED_M_S`; its time is where the approach, extrapolated linearly, reaches that
    minimum. In the audio, a clap is an *isolated* transient: energy above 1 kHz (5 ms frames)
    at least :data:`ISOLATION_DB` above the mean level both in the 0.5 s before it and in the
    80-500 ms after it, so a drum hit inside music, or the first beat of the music, does not
    qualify; its time is its onset (the first frame within 10 dB of its peak). Every pairing of a
    motion clap with an audio clap proposes an offset; the offset that matches the most claps
    (within :data:`CLAP_MATCH_S`) wins. Confidence: (matches of the best - matches of the
    runner-up) / matches of the best; when another offset matches as many claps, the audio's
    sharpest transient decides, with confidence (isolation of the best - isolation of the
    runner-up) / :data:`ISOLATION_MARGIN_DB`, so two similar claps leave it ambiguous.

``xcorr``
    Without claps: the normalised cross-correlation of the audio's onset envelope (spectral flux,
    100 Hz) with the motion's energy envelope (summed joint speed, 100 Hz). Music with a steady
    beat correlates almost as well one beat off, so confidence is ``1 - runner_up / best`` over
    the correlation's local maxima more than :data:`MAIN_LOBE_S` from the best; it is low for
    steady music,
    and then the estimate is refused rather than guessed.

An estimate whose confidence is below ``min_confidence`` raises
:class:`~kinectdata.core.errors.AlignmentError` saying what was found; pass the offset explicitly then.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinectdata.align.audio import Audio
from kinectdata.align.envelopes import CLAP_FRAME_S, ONSET_RATE, AudioEnvelopes
from kinectdata.core.errors import AlignmentError
from kinectdata.core.motion import Motion

CLAP_DISTANCE_M = 0.10
CLAP_SPEED_M_S = 0.8
CLAP_MATCH_S = 0.06
IMAGE_BODY_HEIGHT_M = 1.5
"""Metres taken for a dancer's height in the image (head or nose to ankles: about 1.5 m for an
adult) when measuring 2-D hands in metres; a 20% error moves the thresholds by 20%."""
ISOLATION_DB = 20.0
ISOLATION_MARGIN_DB = 20.0
MAIN_LOBE_S = 0.25
"""Correlation peaks closer than this to the best belong to its main lobe, not rivals. Shorter
than the beat period of any dance music (0.33 s at 180 BPM), so a beat away still competes."""


DEFAULT_MIN_CONFIDENCE = 0.5
"""Estimates less confident than this (0..1) are refused rather than used."""


@dataclass(frozen=True)
class OffsetEstimate:
    """An estimated offset (seconds, ``audio_time = motion_time + offset``) and its evidence.

    ``candidates`` lists (offset, score) pairs, best first; ``curve`` holds (lags, scores) for the
    cross-correlation method (for plots); ``detail`` the events found.
    """

    offset: float
    confidence: float
    method: str
    candidates: list[tuple[float, float]] = field(default_factory=list)
    curve: tuple[np.ndarray, np.ndarray] | None = None
    detail: dict[str, Any] = field(default_factory=dict)


@dataclass
class OffsetChoice:
    """The offset an alignment used (``audio_time = motion_time + seconds``) and where it came from.

    Attributes:
        seconds: the offset, s.
        source: ``given`` (by the user or a take's clock stamps), ``clap`` or ``xcorr`` (estimated).
        confidence: 0..1 (1 for a given offset; None where a writer recorded none).
        candidates: estimated offsets' (seconds, score) pairs, best first (None when given).
        events: what the estimate found (claps...), when it reports any.

    Stored in files as the JSON object :meth:`to_dict` gives (``seconds``, ``source``,
    ``confidence``, and ``candidates`` / ``events`` where present), as before it had a type.
    """

    seconds: float
    source: str = "given"
    confidence: float | None = 1.0
    candidates: list | None = None
    events: Any = None

    @classmethod
    def from_estimate(cls, est: OffsetEstimate, keep: int = 5) -> OffsetChoice:
        """The choice of an estimate, keeping its ``keep`` best candidates."""
        candidates = [[float(x) for x in c] for c in est.candidates[:keep]]
        return cls(est.offset, est.method, est.confidence, candidates, est.detail or None)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> OffsetChoice:
        return cls(
            float(d["seconds"]),
            str(d.get("source", "given")),
            None if d.get("confidence", 1.0) is None else float(d.get("confidence", 1.0)),
            d.get("candidates"),
            d.get("events"),
        )

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"seconds": self.seconds, "source": self.source, "confidence": self.confidence}
        if self.candidates is not None:
            d["candidates"] = self.candidates
        if self.events is not None:
            d["events"] = self.events
        return d


# ---------------------------------------------------------------------------------------------
# Clap events
# ---------------------------------------------------------------------------------------------
def motion_claps(motion: Motion) -> list[float]:
    """Times (seconds, motion clock) at which the hands meet in a clap.

    Needs the joint set's ``left_hand`` and ``right_hand`` roles (else returns []). Image-plane
    (2-D) joints are in pixels: they are scaled to metres by taking the dancer's median height in
    the image (the vertical extent of the valid joints per frame, head to ankles) as
    :data:`IMAGE_BODY_HEIGHT_M`.
    """
    js = motion.joint_set
    left, right = js.role("left_hand"), js.role("right_hand")
    if left is None or right is None:
        return []
    valid = motion.position_mask[:, left] & motion.position_mask[:, right]
    t = motion.times[valid]
    if t.size < 5:
        return []
    d = np.linalg.norm(motion.positions[valid, left] - motion.positions[valid, right], axis=-1)
    if js.dimensions == 2:
        seen = motion.position_mask.any(axis=1)
        y = motion.positions[seen, :, 1]
        height = float(np.median(np.nanmax(y, axis=1) - np.nanmin(y, axis=1))) if seen.any() else 0.0
        if not height > 0:
            return []
        d = d * (IMAGE_BODY_HEIGHT_M / height)
    closing = -np.diff(d) / np.diff(t)  # [n-1]: closing speed from sample k to k+1
    claps: list[float] = []
    minima = np.flatnonzero((d[1:-1] <= d[:-2]) & (d[1:-1] < d[2:]) & (d[1:-1] < CLAP_DISTANCE_M)) + 1
    for i in minima:
        fast = np.flatnonzero((closing[:i] >= CLAP_SPEED_M_S) & (t[:i] >= t[i] - 0.3))
        if fast.size == 0:
            continue
        tc = _contact_time(t, d, closing, int(fast[-1]), int(i))
        if claps and tc - claps[-1] < 0.15:
            continue
        claps.append(tc)
    return claps


def _contact_time(t: np.ndarray, d: np.ndarray, closing: np.ndarray, k: int, i: int) -> float:
    """When the hands meet: the last fast approach (samples k -> k+1), extended at its speed to
    the contact distance (the median distance from k+1 to the minimum i). Using the approach
    rather than the lowest sample matters: the hands rest together for a few frames, and sensor
    noise decides which of those frames is lowest.
    """
    level = float(np.median(d[k + 1 : i + 1]))
    tc = t[k] + (d[k] - level) / closing[k]
    return float(np.clip(tc, t[k], t[k + 1] + (t[k + 1] - t[k])))


def audio_claps(audio: Audio | AudioEnvelopes) -> list[tuple[float, float]]:
    """Isolated transients in the audio: (onset time in seconds, isolation in dB), by time."""
    from scipy import ndimage, signal  # slow to import; needed only when estimating

    env = audio if isinstance(audio, AudioEnvelopes) else AudioEnvelopes.of(audio)
    energy = env.clap_energy
    n = energy.size
    if n < 10:
        return []
    floor = max(energy.max() * 1e-6, 1e-12)
    # Mean (not median) energy around each frame: sparse drum hits in a quiet intro must count.
    w = int(round(0.5 / CLAP_FRAME_S))
    mean = ndimage.uniform_filter1d(energy, size=w, mode="nearest")
    half = w // 2
    before = np.concatenate([np.full(w, floor), mean])[np.arange(n) + w - (half + int(0.03 / CLAP_FRAME_S))]
    after = np.concatenate([mean, np.full(w, floor)])[np.arange(n) + half + int(0.08 / CLAP_FRAME_S)]
    background = np.maximum(np.maximum(before, after), floor)
    isolation = 10 * np.log10(np.maximum(energy, 1e-30) / background)
    peaks, _ = signal.find_peaks(energy, distance=int(0.1 / CLAP_FRAME_S))
    loud = energy[peaks] >= energy.max() * 1e-4
    out: list[tuple[float, float]] = []
    for p in peaks[loud & (isolation[peaks] >= ISOLATION_DB)]:
        k = p
        while k > 0 and energy[k - 1] >= energy[p] * 0.1:
            k -= 1
        onset = k * CLAP_FRAME_S
        if out and onset - out[-1][0] < 0.1:  # one event seen from several peaks
            out[-1] = (out[-1][0], max(out[-1][1], float(isolation[p])))
            continue
        out.append((onset, float(isolation[p])))
    return out


def _clap_estimate(
    m_claps: list[float], a_claps: list[tuple[float, float]], max_offset: float | None
) -> OffsetEstimate | None:
    a_times = np.array([a for a, _ in a_claps])
    a_iso = np.array([i for _, i in a_claps])
    proposals: list[tuple[int, float, float]] = []  # (claps matched, least isolation of them, offset)
    for m in m_claps:
        for a in a_times:
            off = a - m
            if max_offset is not None and abs(off) > max_offset:
                continue
            nearest = [int(np.argmin(np.abs(a_times - (mm + off)))) for mm in m_claps]
            matched = [(mm, j) for mm, j in zip(m_claps, nearest) if abs(a_times[j] - (mm + off)) <= CLAP_MATCH_S]
            refined = float(np.mean([a_times[j] - mm for mm, j in matched]))
            proposals.append((len(matched), float(min(a_iso[j] for _, j in matched)), refined))
    if not proposals:
        return None
    proposals.sort(key=lambda p: (-p[0], -p[1]))
    best_n, best_iso, best = proposals[0]
    rivals = [p for p in proposals if abs(p[2] - best) > CLAP_MATCH_S]
    if not rivals or rivals[0][0] < best_n:
        confidence = (best_n - (rivals[0][0] if rivals else 0)) / best_n
    else:  # as many claps matched elsewhere: only a clearly sharper transient decides
        confidence = float(np.clip((best_iso - rivals[0][1]) / ISOLATION_MARGIN_DB, 0.0, 1.0))
    distinct: list[tuple[float, float]] = []
    for n, iso, off in proposals:
        if all(abs(off - o) > CLAP_MATCH_S for o, _ in distinct):
            distinct.append((off, n + iso / 1000.0))
    return OffsetEstimate(
        offset=best,
        confidence=confidence,
        method="clap",
        candidates=distinct,
        detail={
            "motion_claps_s": m_claps,
            "audio_claps_s": a_times.tolist(),
            "audio_clap_isolation_db": a_iso.tolist(),
            "matched": best_n,
        },
    )


# ---------------------------------------------------------------------------------------------
# Cross-correlation of envelopes
# ---------------------------------------------------------------------------------------------
def motion_energy_envelope(motion: Motion, rate: float = ONSET_RATE) -> np.ndarray:
    """Summed joint speed (m/s) on a ``rate`` Hz grid starting at the motion's first frame."""
    grid = np.arange(motion.times[0], motion.times[-1], 1.0 / rate)
    total = np.zeros(grid.size)
    for j in range(motion.n_joints):
        ok = motion.position_mask[:, j]
        if ok.sum() < 2:
            continue
        p = np.stack(
            [np.interp(grid, motion.times[ok], motion.positions[ok, j, d]) for d in range(motion.joint_set.dimensions)],
            -1,
        )
        total[1:] += np.linalg.norm(np.diff(p, axis=0), axis=-1) * rate
    return total


def _zscore(x: np.ndarray) -> np.ndarray:
    s = x.std()
    return (x - x.mean()) / s if s > 0 else x * 0.0


def xcorr_estimate(motion: Motion, env: AudioEnvelopes, max_offset: float | None) -> OffsetEstimate:
    from scipy import ndimage, signal

    rate = ONSET_RATE
    m = motion_energy_envelope(motion, rate)
    if env.onset.size < 2 or m.size < 2:  # nothing to correlate (a one-frame recording, a few samples of audio)
        raise AlignmentError(
            f"the audio ({env.duration:.3f} s) or the motion ({motion.n_frames} frame(s), {motion.duration:.3f} s) "
            "is too short to estimate their offset: give it"
        )
    a = _zscore(env.onset)
    m = _zscore(np.maximum(np.diff(ndimage.uniform_filter1d(m, 5), prepend=m[0]), 0.0))
    corr = signal.correlate(a, m, mode="full", method="fft")
    # corr[k] = sum_n a[n + k - (m.size - 1)] m[n]; m[n] is at motion time times[0] + n / rate
    lags = np.arange(-(m.size - 1), a.size) / rate - motion.times[0]
    overlap = signal.correlate(np.ones(a.size), np.ones(m.size), mode="full", method="fft")
    minimum = 0.5 * min(a.size, m.size)
    score = np.where(overlap >= minimum, corr / np.maximum(overlap, 1.0), -np.inf)
    if max_offset is not None:
        score[np.abs(lags) > max_offset] = -np.inf
    if not np.isfinite(score).any():
        raise AlignmentError("the audio and the motion overlap too little to estimate their offset")
    best = int(np.argmax(score))
    peaks, _ = signal.find_peaks(np.where(np.isfinite(score), score, -1e9))
    far = peaks[np.abs(lags[peaks] - lags[best]) > MAIN_LOBE_S]
    runner = float(score[far].max()) if far.size else 0.0
    p1 = float(score[best])
    conf = 0.0 if p1 <= 0 else float(np.clip(1.0 - max(runner, 0.0) / p1, 0.0, 1.0))
    order = far[np.argsort(score[far])[::-1][:4]]
    finite = np.isfinite(score)
    return OffsetEstimate(
        offset=float(lags[best]),
        confidence=conf,
        method="xcorr",
        candidates=[(float(lags[best]), p1)] + [(float(lags[i]), float(score[i])) for i in order],
        curve=(lags[finite], score[finite]),
    )


def estimate_offset(
    motion: Motion,
    audio: Audio | AudioEnvelopes,
    *,
    max_offset: float | None = None,
    min_confidence: float = DEFAULT_MIN_CONFIDENCE,
) -> OffsetEstimate:
    """Estimate ``offset`` with ``audio_time = motion_time + offset`` (seconds).

    Args:
        motion: the skeleton recording (its own clock).
        audio: the audio (any rate), or its :class:`~kinectdata.align.envelopes.AudioEnvelopes` (computed
            while streaming a long file).
        max_offset: ignore offsets larger than this many seconds in magnitude.
        min_confidence: below this confidence the estimate is refused.

    Raises:
        AlignmentError: no method reaches ``min_confidence``; the message gives the candidates.
    """
    env = audio if isinstance(audio, AudioEnvelopes) else AudioEnvelopes.of(audio)
    m_claps = motion_claps(motion)
    a_claps = audio_claps(env) if m_claps else []
    clap = _clap_estimate(m_claps, a_claps, max_offset) if m_claps and a_claps else None
    if clap is not None and clap.confidence >= min_confidence:
        return clap
    xcorr = xcorr_estimate(motion, env, max_offset)
    if xcorr.confidence >= min_confidence:
        return xcorr
    lines = []
    if clap is not None:
        shown = ", ".join(f"{o:+.3f} s ({int(n)} clap(s) matched)" for o, n in clap.candidates[:3])
        lines.append(
            f"claps: {len(m_claps)} in the motion and {len(a_claps)} isolated in the audio fit about equally "
            f"well at several offsets (confidence {clap.confidence:.2f}): {shown}"
        )
    elif m_claps:
        lines.append(
            f"a clap in the motion at {', '.join(f'{c:.2f} s' for c in m_claps)} but no isolated clap in the audio"
        )
    else:
        lines.append("no clap in the motion (hands meeting fast)")
    shown = ", ".join(f"{o:+.3f} s (score {s:.2f})" for o, s in xcorr.candidates[:3])
    lines.append(
        f"cross-correlation is ambiguous (confidence {xcorr.confidence:.2f} < {min_confidence}): candidates {shown}"
    )
    raise AlignmentError(
        "cannot determine the audio-to-motion offset reliably: "
        + "; ".join(lines)
        + ". Give the offset explicitly (audio_time = motion_time + offset): --offset SECONDS for "
        "kinectdata align, or 'offset' in a recordings manifest."
    )
