"""What scoring a run costs in its two most repeated computations, against a direct computation
of the same numbers in the same run.

- FID's 95 % interval: 1 000 bootstrap draws of 7 generated and 7 reference sequences of 72
  kinetic features (a 7-song test split, as the real corpus's), each draw's Fréchet distance by
  ``frechet_distance`` (the singular values of an [N, M] product of the centred sets) against
  the textbook formula with ``scipy.linalg.sqrtm`` of the covariances' product (Bailando's and
  EDGE's code).
- The motion's autocorrelation (what every period, metrical level and listening control reads):
  60 s at 30 fps of 23 joints, lags up to 10 s, by ``trajectory_autocorrelation`` (every lag at
  once by FFT) against numpy's ``corrcoef`` of the valid pairs, lag by lag and joint by joint.
- The beat chance levels (every ``evaluate`` computes them five times: the real motion, the
  model's, and three controls): a 60-s song's motion beats against its music's beats shifted by
  1 000 random phases, the Beat Align Score both ways and the F-measure, by ``beat_align_scores``
  and ``beat_fmeasures`` (all phases at once) against ``beat_align_score`` and
  ``mir_eval.beat.f_measure`` phase by phase.
- The yalta model's free runs of two listening controls at once (the songs as they are, and the
  silence control), 7 songs of 40-90 s at 25 fps run as one batch, the 128-unit network on one
  thread: its convolutions on each distinct frame once (the padding and the silence one frame each)
  against every frame convolved.

Each is timed best of 3; the printed ratio is the direct computation's time over kinectdata's,
with the largest difference between their numbers.
"""

from __future__ import annotations

import time

import numpy as np

from .summary import record


def _best(fn, repeats: int = 3) -> tuple[float, object]:
    best, value = float("inf"), None
    for _ in range(repeats):
        start = time.perf_counter()
        value = fn()
        best = min(best, time.perf_counter() - start)
    return best, value


def _sqrtm_fid(generated: np.ndarray, reference: np.ndarray) -> float:
    import warnings

    import scipy.linalg

    mu_g, mu_r = generated.mean(axis=0), reference.mean(axis=0)
    cov_g, cov_r = np.cov(generated, rowvar=False), np.cov(reference, rowvar=False)
    with warnings.catch_warnings():  # a product of covariances from 7 sequences is singular: sqrtm says so
        warnings.simplefilter("ignore")
        root = scipy.linalg.sqrtm(cov_g @ cov_r)
    return float((mu_g - mu_r) @ (mu_g - mu_r) + np.trace(cov_g) + np.trace(cov_r) - 2 * np.trace(root.real))


def _corrcoef_autocorrelation(x: np.ndarray, valid: np.ndarray, max_lag: int) -> np.ndarray:
    """[L + 1, C] the mean over joints of each joint's Pearson correlation over its valid pairs."""
    frames, joints, axes = x.shape
    out = np.zeros((max_lag + 1, axes))
    for lag in range(max_lag + 1):
        both = valid[: frames - lag] & valid[lag:]
        for c in range(axes):
            values = [
                np.corrcoef(x[: frames - lag, j, c][both[:, j]], x[lag:, j, c][both[:, j]])[0, 1] for j in range(joints)
            ]
            out[lag, c] = np.mean(values)
    return out


def _phase_by_phase(music: np.ndarray, motion: np.ndarray) -> np.ndarray:
    """[3, D] the three figures of each shifted beat set, one set at a time."""
    import mir_eval

    from kinectdata.evaluation.rhythm import beat_align_score

    return np.array(
        [
            [beat_align_score(row, motion, 0.05, "music_to_motion") for row in music],
            [beat_align_score(row, motion, 0.05, "motion_to_music") for row in music],
            [mir_eval.beat.f_measure(row, motion, f_measure_threshold=0.1) for row in music],
        ]
    )


def _free_runs_every_frame_and_distinct() -> tuple[float, float, float]:
    """(seconds with each distinct frame once, seconds with every frame, largest pose difference)."""
    import torch

    import kinectdata.models.yalta as yalta

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        torch.manual_seed(0)
        net = yalta.YaltaNet(yalta.YaltaConfig(units=128, output_dim=69)).eval()
        rng = np.random.default_rng(1)
        songs = [rng.random((int(s * 25), 1, 129, 5), dtype=np.float32) for s in (40, 52, 61, 66, 73, 80, 90)]
        silent = [np.full_like(song, 0.05) for song in songs]  # a silent song's features: one frame throughout
        audios, firsts = songs + silent, [np.zeros(69, np.float32)] * 14
        ours, mine = _best(lambda: yalta.free_runs(net, audios, firsts), repeats=2)
        distinct = yalta._each_distinct_frame_once
        yalta._each_distinct_frame_once = lambda convs, frames: convs(frames)
        try:
            direct, theirs = _best(lambda: yalta.free_runs(net, audios, firsts), repeats=1)
        finally:
            yalta._each_distinct_frame_once = distinct
    finally:
        torch.set_num_threads(threads)
    return ours, direct, max(float(np.max(np.abs(a - b))) for a, b in zip(mine, theirs))


def main() -> None:
    from kinectdata.evaluation.metrics.distribution import bootstrap_interval, frechet_distance
    from kinectdata.evaluation.rhythm import trajectory_autocorrelation

    rng = np.random.default_rng(0)
    generated, reference = rng.normal(size=(7, 72)), rng.normal(0.3, 1.2, size=(7, 72))

    def interval(fid):
        return bootstrap_interval(lambda g, r: fid(generated[g], reference[r]), 7, 7, 1000)

    ours, mine = _best(lambda: interval(frechet_distance))
    direct, theirs = _best(lambda: interval(_sqrtm_fid))
    apart = max(abs(mine.low - theirs.low) / theirs.low, abs(mine.high - theirs.high) / theirs.high)
    print(f"  {'computation':<46} {'kinectdata s':>12} {'direct s':>9} {'ratio':>6}  largest difference")
    label = "FID 95 % interval, 1 000 draws (7 x 72)"
    print(f"  {label:<46} {ours:12.3f} {direct:9.3f} {direct / ours:6.1f}  {apart:.1e} relative")

    t = np.arange(1800) / 30.0
    period = rng.uniform(0.4, 2.5, size=(1, 23, 3))
    positions = np.sin(2 * np.pi * t[:, None, None] / period) + 0.3 * rng.normal(size=(1800, 23, 3))
    valid = rng.random((1800, 23)) > 0.05
    ours_ac, mine_ac = _best(lambda: trajectory_autocorrelation(positions, valid, 300, None))
    direct_ac, theirs_ac = _best(lambda: _corrcoef_autocorrelation(positions, valid, 300), repeats=1)
    apart_ac = float(np.max(np.abs(mine_ac - theirs_ac)))
    label = "autocorrelation, 60 s x 23 joints, 300 lags"
    print(f"  {label:<46} {ours_ac:12.3f} {direct_ac:9.3f} {direct_ac / ours_ac:6.1f}  {apart_ac:.1e} absolute")
    from kinectdata.evaluation.beat_scores_rows import beat_align_scores, beat_fmeasures

    beats = np.arange(0.25, 60, 0.5)  # 120 BPM
    music = np.sort(np.mod(beats[None, :] + rng.uniform(0, 0.5, (1000, 1)), 60.0), axis=1)
    motion = np.sort(rng.uniform(0, 60, 110))  # speed minima at no steady rate, some close together

    def all_phases():
        return np.array(
            [
                beat_align_scores(music, motion, 0.05, "music_to_motion"),
                beat_align_scores(music, motion, 0.05, "motion_to_music"),
                beat_fmeasures(music, motion, 0.1),
            ]
        )

    ours_ph, mine_ph = _best(all_phases)
    direct_ph, theirs_ph = _best(lambda: _phase_by_phase(music, motion), repeats=1)
    apart_ph = float(np.max(np.abs(mine_ph - theirs_ph)))
    label = "beat chance levels, 60 s, 1 000 phases"
    print(f"  {label:<46} {ours_ph:12.3f} {direct_ph:9.3f} {direct_ph / ours_ph:6.1f}  {apart_ph:.1e} absolute")
    ours_fr, direct_fr, apart_fr = _free_runs_every_frame_and_distinct()
    label = "yalta free runs, 7 songs and their silence"
    print(f"  {label:<46} {ours_fr:12.3f} {direct_fr:9.3f} {direct_fr / ours_fr:6.1f}  {apart_fr:.1e} absolute")
    record("score", "FID interval (1 000 draws) vs sqrtm", f"{direct / ours:.0f}x faster")
    record("score", "autocorrelation (300 lags) vs corrcoef", f"{direct_ac / ours_ac:.0f}x faster")
    record("score", "beat chance levels (1 000 phases) vs one by one", f"{direct_ph / ours_ph:.0f}x faster")
    record("score", "yalta free runs, songs and silence: distinct frames", f"{direct_fr / ours_fr:.1f}x faster")
