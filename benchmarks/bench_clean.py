"""Cleaning against a known truth, and what it costs (``python -m benchmarks bench_clean``, or
``python -m benchmarks.bench_clean [--corpus tang2018 PATH]``).

1. **The simulated tracker**: the synthetic dancer (:mod:`kinectdata.synth.dancer`, five seeds, 60 s
   each at 30 fps) seen through the simulated Kinect v2 (:mod:`kinectdata.synth.sensor`: 3 mm of
   position noise, inferred hands 10 mm with a drifting bias, a foot lost, jittered and dropped
   frames). For each cleaning, the mean distance of the joints to the true motion (mm) against the
   sensor's, the bone-length CV, the mean jerk, and how far the sensor's dominant period of the
   vertical motion (:func:`kinectdata.evaluation.beat_following.dominant_period`) moved: to the
   nearest autocorrelation peak after cleaning (the dominant one may change octave where a bar and
   two bars stand almost equally high, which is the estimator's choice, not a change of timing).
   The same dancer then turns round (:mod:`kinectdata.synth.turns`: half turns held 1.5-5 s and whole
   spins, 4 a minute, ten seeds) before a frontal tracker that mirrors her sides while she faces
   away: the mirrored stretches found (precision and recall: a stretch is found when one found
   overlaps it by at least half of their union), and the error in them before and after.
2. **Speed**: cleaning an hour of 25-joint 30-fps skeletons on one core, against one plain
   ``scipy.signal.sosfiltfilt`` pass over the same array in the same run.
3. **Real recordings**: the Kinect v2 CSV in ``tests/data`` (its cleaning report), and with
   ``--corpus tang2018 PATH`` (your local copy; nothing of it is kept) each dance's bone-length CV,
   mean jerk, dominant period and mirrored stretches found, before and after the default cleaning.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from .summary import record

SEEDS = range(5)
SECONDS = 60.0
CLEANINGS = {
    "gaps + wiener": {"bones": False},
    "gaps + butterworth 6 Hz": {"jitter": "butterworth", "bones": False},
    "gaps + savgol 0.2 s": {"jitter": "savgol", "window_s": 0.2, "bones": False},
    "gaps + one_euro (causal)": {"jitter": "one_euro", "bones": False},
    "gaps + wiener + bones (default)": {},
    "gaps + butterworth 6 Hz + bones": {"jitter": "butterworth"},
    "gaps + wiener + bones from the root only": {"spread": False},
    "gaps alone": {"jitter": "none", "bones": False},
    "bones alone": {"jitter": "none", "gaps": False},
    "bones from the root alone": {"jitter": "none", "gaps": False, "spread": False},
}


def _period(motion, fps: float):
    """The dominant period estimate of the vertical motion, with its autocorrelation peaks."""
    from kinectdata.evaluation.beat_following import dominant_period

    return dominant_period(motion.positions, motion.position_mask, fps, max_lag_s=4.5)


def _shift(after, before) -> float:
    """How far the period ``before`` found moved: the relative distance from it to the nearest
    autocorrelation peak after. The dominant peak itself may change octave when two levels (a bar and
    two bars) stand almost equally high, which is the estimator's choice, not a change of timing."""
    if before.period_s is None:
        return 0.0 if after.period_s is None else float("inf")
    lags = [lag for lag, _ in after.peaks]
    return min((abs(lag / before.period_s - 1.0) for lag in lags), default=float("inf"))


def simulated(seeds=SEEDS, seconds: float = SECONDS) -> dict[str, dict[str, float]]:
    """Per cleaning: mean error (mm), its ratio to the sensor's, bone CV, jerk, worst period change."""
    import kinectdata as kd
    from kinectdata.synth.dancer import dance
    from kinectdata.synth.sensor import apply_sensor_defects, sensor_frame_times

    rows: dict[str, list[tuple[float, float, float, float, float]]] = {}
    for seed in seeds:
        times, _ = sensor_frame_times(seed=seed, duration_s=seconds)
        beats = np.arange(2.0, seconds + 1.0, 0.5)
        truth = dance(seed=seed, times_s=times, beat_times_s=beats, music_start_s=2.0, clap_time_s=None,
                      tempo_bpm=120.0)  # fmt: skip
        noisy = apply_sensor_defects(truth, seed=seed).motion
        sensor_period = _period(noisy, 30.0)  # what cleaning must not change
        ok = noisy.position_mask  # measured where the sensor gave a sample, before and after
        base = _error(noisy, truth, ok)
        for name, settings in {"the sensor": None, **CLEANINGS}.items():
            cleaned = noisy if settings is None else kd.clean_motion(noisy, kd.CleanConfig(**settings)).motion
            e = _error(cleaned, truth, ok)
            shift = _shift(_period(cleaned, 30.0), sensor_period)
            rows.setdefault(name, []).append((e, e / base, *_quality(cleaned), shift))
    return {
        name: {
            "error_mm": float(np.mean([r[0] for r in rs])),
            "ratio": float(np.mean([r[1] for r in rs])),
            "bone_cv": float(np.mean([r[2] for r in rs])),
            "jerk": float(np.mean([r[3] for r in rs])),
            "period_shift": float(np.max([r[4] for r in rs])),
        }
        for name, rs in rows.items()
    }


SWAP_SEEDS = range(10)


def swaps(seeds=SWAP_SEEDS, seconds: float = SECONDS) -> dict[str, float]:
    """The turning dancer before a frontal tracker (module docstring): stretches mirrored, found,
    matched; the mean error (mm) in the mirrored frames before and after the sides stage."""
    import kinectdata as kd
    from kinectdata.synth.dancer import dance
    from kinectdata.synth.sensor import apply_sensor_defects, sensor_frame_times
    from kinectdata.synth.turns import draw_turns, frontal_tracker, turn_about_vertical

    true_n = found_n = hits_true = hits_found = 0
    before, after, judged = [], [], set()
    for seed in seeds:
        times, _ = sensor_frame_times(seed=seed, duration_s=seconds)
        truth = dance(seed=seed, times_s=times, beat_times_s=np.arange(2.0, seconds + 1.0, 0.5), music_start_s=2.0,
                      clap_time_s=None, tempo_bpm=120.0)  # fmt: skip
        js = truth.joint_set
        truth = turn_about_vertical(truth, draw_turns(times, np.random.default_rng(seed)), js.index("SpineBase"))
        seen, mirrored = frontal_tracker(apply_sensor_defects(truth, seed=seed).motion, "HipLeft", "HipRight")
        cleaned = kd.clean_motion(seen, kd.CleanConfig(gaps=False, jitter="none", bones=False))
        found = [_frames_of(seen.times, a, b) for a, b in cleaned.report.sides.intervals_s]
        judged.add(cleaned.report.sides.judged_by)
        true_n, found_n = true_n + len(mirrored), found_n + len(found)
        hits_true += sum(any(_overlap(t, f) >= 0.5 for f in found) for t in mirrored)
        hits_found += sum(any(_overlap(t, f) >= 0.5 for t in mirrored) for f in found)
        frames = np.zeros(seen.n_frames, bool)
        for a, b in mirrored:
            frames[a : b + 1] = True
        for motion, out in ((seen, before), (cleaned.motion, after)):
            distance = np.linalg.norm(motion.positions - truth.positions, axis=-1)[frames]
            out.append(distance[motion.position_mask[frames]])
    return {
        "mirrored": true_n,
        "found": found_n,
        "precision": hits_found / found_n if found_n else float("nan"),
        "recall": hits_true / true_n if true_n else float("nan"),
        "error_before_mm": float(1e3 * np.concatenate(before).mean()),
        "error_after_mm": float(1e3 * np.concatenate(after).mean()),
        "judged_by": ", ".join(sorted(judged)),
    }


def _frames_of(times: np.ndarray, start_s: float, end_s: float) -> tuple[int, int]:
    return int(np.searchsorted(times, start_s)), int(np.searchsorted(times, end_s))


def _overlap(a: tuple[int, int], b: tuple[int, int]) -> float:
    """Intersection over union of two inclusive frame intervals."""
    inter = min(a[1], b[1]) - max(a[0], b[0]) + 1
    return max(inter, 0) / (max(a[1], b[1]) - min(a[0], b[0]) + 1)


def _error(motion, truth, ok: np.ndarray) -> float:
    """Mean distance, mm, of the joints to the true motion at the same frames, over the samples ``ok``."""
    return float(1e3 * np.linalg.norm(motion.positions - truth.positions, axis=-1)[ok].mean())


def _quality(motion) -> tuple[float, float]:
    from kinectdata.core.body_quality import bone_length_variation, mean_jerk

    cv = bone_length_variation(motion.positions, motion.joint_set.parents, motion.position_mask)
    return float(np.nanmean(cv)), mean_jerk(motion.positions, 30.0, motion.position_mask)


def speed(hours: float = 1.0) -> dict[str, float]:
    """Seconds to clean ``hours`` of 25-joint 30-fps skeletons (one core), and a plain filter pass."""
    from scipy import signal

    import kinectdata as kd

    T = int(hours * 3600 * 30)
    rng = np.random.default_rng(0)
    positions = np.cumsum(rng.normal(0, 0.003, (T, 25, 3)), axis=0)
    motion = kd.Motion(times=np.arange(T) / 30.0, positions=positions, joint_set=kd.load_joint_set("kinect_v2"))
    out = {}
    sos = signal.butter(2, 6.0, fs=30.0, output="sos")
    signal.sosfiltfilt(sos, positions[:300], axis=0)  # warm: scipy's first call loads its pieces
    kd.clean_motion(kd.Motion(times=motion.times[:300], positions=positions[:300], joint_set=motion.joint_set))
    started = time.perf_counter()
    signal.sosfiltfilt(sos, positions, axis=0)
    out["scipy sosfiltfilt"] = time.perf_counter() - started
    for name, settings in (
        ("the default stages", {}),
        ("with butterworth", {"jitter": "butterworth"}),
        ("with one_euro", {"jitter": "one_euro"}),
    ):
        started = time.perf_counter()
        kd.clean_motion(motion, kd.CleanConfig(**settings))
        out[name] = time.perf_counter() - started
    return out


REAL_FILES = (Path(__file__).resolve().parents[1] / "tests" / "data" / "kinect_v2_csv" / "Ges01_wavehand.csv",)
"""Real recordings in the repository (a Kinect v2 CSV of Microsoft's Labanotation Suite, MIT)."""


def real_files(paths=REAL_FILES) -> list[tuple[str, list[str]]]:
    """Each real file's cleaning report lines (default cleaning)."""
    import kinectdata as kd

    return [(path.name, kd.clean_motion(kd.read_motion(path)).report.lines()) for path in paths]


def _pfc(motion) -> float:
    """EDGE's physical foot contact score of one recording (x 10 000), on its SMPL-24 joints at 30 fps."""
    from kinectdata.evaluation.metrics.foot_contact import physical_foot_contact
    from kinectdata.evaluation.motion_sets import smpl24_joints

    return physical_foot_contact([smpl24_joints(motion, 30.0).positions], 30.0, up_axis=1)


def real(path: Path) -> list[tuple[str, float, float, float, float, float]]:
    """Per tang2018 dance: (name, bone CV before, after, jerk before, after, period change, periods,
    mirrored stretches found, (PFC before, after))."""
    import kinectdata as kd
    from kinectdata.align.timeline import resample_motion

    rows = []
    for folder in sorted(p for p in Path(path).glob("DANCE_*") if (p / "skeletons.json").exists()):
        motion = kd.read_motion(folder / "skeletons.json")
        grid = np.arange(0.0, motion.times[-1], 1 / 30.0)
        motion = resample_motion(motion, grid).motion
        cleaned = kd.clean_motion(motion)
        before, after = _quality(motion), _quality(cleaned.motion)
        pfc = (_pfc(motion), _pfc(cleaned.motion))
        periods = (_period(motion, 30.0), _period(cleaned.motion, 30.0))
        rows.append((folder.name, before[0], after[0], before[1], after[1], _shift(periods[1], periods[0]),
                     tuple(p.period_s for p in periods), len(cleaned.report.sides.intervals_s), pfc))  # fmt: skip
    return rows


def main(corpus: Path | None = None) -> None:
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    sim = simulated()
    print(f"  the simulated tracker: {len(SEEDS)} synthetic dances of {SECONDS:g} s through the simulated Kinect v2")
    print(f"  {'cleaning':<42} {'error mm':>9} {'x sensor':>9} {'bone CV':>8} {'jerk m/s^3':>11} {'period':>8}")
    for name, r in sim.items():
        print(f"  {name:<42} {r['error_mm']:9.2f} {r['ratio']:9.2f} {r['bone_cv']:8.4f} {r['jerk']:11.1f} "
              f"{100 * r['period_shift']:7.1f}%")  # fmt: skip
    best = sim["gaps + wiener + bones (default)"]
    half = best["ratio"] <= 0.5
    print(f"  position error at most half the sensor's: {'yes' if half else 'no'} ({best['ratio']:.2f} x with the "
          f"default stages); dominant period kept within 2 %: "
          f"{'yes' if max(r['period_shift'] for r in sim.values()) <= 0.02 else 'no'}")  # fmt: skip
    record("clean", "simulated Kinect: error after the default cleaning / the sensor's", f"{best['ratio']:.2f} x")
    sw = swaps()
    cut = 1.0 - sw["error_after_mm"] / sw["error_before_mm"]
    print(f"  the turning dancer before a frontal tracker ({len(SWAP_SEEDS)} dances of {SECONDS:g} s): "
          f"{sw['mirrored']} mirrored stretches, {sw['found']} found (judged by the {sw['judged_by']}); "
          f"precision {sw['precision']:.2f}, recall {sw['recall']:.2f}; error in them "
          f"{sw['error_before_mm']:.1f} -> {sw['error_after_mm']:.1f} mm ({100 * cut:.1f} % cut)")  # fmt: skip
    met = sw["precision"] >= 0.95 and sw["recall"] >= 0.95 and cut >= 0.9
    verdict = "yes" if met else "no"
    print(f"  swaps found with precision and recall of at least 0.95 and their error cut by 90 %: {verdict}")
    record("clean", "mirrored stretches: precision, recall, error cut",
           f"{sw['precision']:.2f}, {sw['recall']:.2f}, {100 * cut:.1f} %")  # fmt: skip
    timed = speed()
    plain = timed["scipy sosfiltfilt"]
    for name, seconds in timed.items():
        print(
            f"  an hour of 25 joints at 30 fps, {name:<20} {seconds:6.2f} s ({seconds / plain:5.1f} x the plain pass)"
        )
    fast = timed["the default stages"]
    print(f"  an hour cleaned within 10 s on one core: {'yes' if fast <= 10 else 'no'} ({fast:.1f} s)")
    record("clean", "an hour of skeletons cleaned (vs one scipy filter pass)", f"{fast:.1f} s ({fast / plain:.0f} x)")
    for name, lines in real_files():
        print(f"  {name} (a real Kinect v2 recording):")
        for line in lines:
            print(f"    {line}")
    if corpus is not None:
        rows = real(corpus)
        cv_b, cv_a = np.mean([r[1] for r in rows]), np.mean([r[2] for r in rows])
        jerk_lower = sum(r[4] < r[3] for r in rows)
        kept = sum(r[5] <= 0.02 for r in rows)
        print(f"  tang2018, {len(rows)} dances: bone CV {cv_b:.3f} -> {cv_a:.4f} (goal at most 0.02: "
              f"{'yes' if cv_a <= 0.02 else 'no'}); jerk lower in {jerk_lower} of {len(rows)}; period within 2 % "
              f"in {kept} of {len(rows)}; mirrored stretches found {sum(r[7] for r in rows)}")  # fmt: skip
        pfc_b, pfc_a = np.mean([r[8][0] for r in rows]), np.mean([r[8][1] for r in rows])
        print(f"  tang2018 physical foot contact (EDGE's PFC, mean over the dances) {pfc_b:.2f} -> {pfc_a:.2f}; lower "
              f"in {sum(r[8][1] < r[8][0] for r in rows)} of {len(rows)}")  # fmt: skip
        for r in rows:
            if r[5] > 0.02:
                before, after = (f"{p:.2f} s" if p is not None else "none" for p in r[6])
                print(f"    {r[0]}: dominant period {before} -> {after} ({100 * r[5]:.1f} % to the nearest peak)")
        record("clean", "tang2018 bone CV before -> after", f"{cv_b:.3f} -> {cv_a:.4f}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--corpus", nargs=2, metavar=("NAME", "PATH"), help="tang2018 and your local copy")
    args = parser.parse_args()
    main(Path(args.corpus[1]) if args.corpus else None)
