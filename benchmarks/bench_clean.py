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
2. **Speed**: cleaning an hour of 25-joint 30-fps skeletons on one core, against one plain
   ``scipy.signal.sosfiltfilt`` pass over the same array in the same run.
3. **Real dances** (``--corpus tang2018 PATH``, your local copy; nothing of it is kept): each dance's
   bone-length CV, mean jerk and dominant period before and after the default cleaning.
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
    "gaps + butterworth 6 Hz": {"bones": False},
    "gaps + savgol 0.2 s": {"jitter": "savgol", "window_s": 0.2, "bones": False},
    "gaps + one_euro (causal)": {"jitter": "one_euro", "bones": False},
    "gaps + butterworth + bones (default)": {},
    "gaps alone": {"jitter": "none", "bones": False},
    "bones alone": {"jitter": "none", "gaps": False},
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
    started = time.perf_counter()
    signal.sosfiltfilt(signal.butter(2, 6.0, fs=30.0, output="sos"), positions, axis=0)
    out["scipy sosfiltfilt"] = time.perf_counter() - started
    for name, settings in (("the default stages", {}), ("with one_euro", {"jitter": "one_euro"})):
        started = time.perf_counter()
        kd.clean_motion(motion, kd.CleanConfig(**settings))
        out[name] = time.perf_counter() - started
    return out


def real(path: Path) -> list[tuple[str, float, float, float, float, float]]:
    """Per tang2018 dance: (name, bone CV before, after, jerk before, after, period change, periods)."""
    import kinectdata as kd
    from kinectdata.align.timeline import resample_motion

    rows = []
    for folder in sorted(p for p in Path(path).glob("DANCE_*") if (p / "skeletons.json").exists()):
        motion = kd.read_motion(folder / "skeletons.json")
        grid = np.arange(0.0, motion.times[-1], 1 / 30.0)
        motion = resample_motion(motion, grid).motion
        cleaned = kd.clean_motion(motion)
        before, after = _quality(motion), _quality(cleaned.motion)
        periods = (_period(motion, 30.0), _period(cleaned.motion, 30.0))
        rows.append((folder.name, before[0], after[0], before[1], after[1], _shift(periods[1], periods[0]),
                     tuple(p.period_s for p in periods)))  # fmt: skip
    return rows


def main(corpus: Path | None = None) -> None:
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    sim = simulated()
    print(f"  the simulated tracker: {len(SEEDS)} synthetic dances of {SECONDS:g} s through the simulated Kinect v2")
    print(f"  {'cleaning':<36} {'error mm':>9} {'x sensor':>9} {'bone CV':>8} {'jerk m/s^3':>11} {'period':>8}")
    for name, r in sim.items():
        print(f"  {name:<36} {r['error_mm']:9.2f} {r['ratio']:9.2f} {r['bone_cv']:8.4f} {r['jerk']:11.1f} "
              f"{100 * r['period_shift']:7.1f}%")  # fmt: skip
    best = sim["gaps + butterworth 6 Hz"]
    half = best["ratio"] <= 0.5
    print(f"  position error at most half the sensor's: {'yes' if half else 'no'} ({best['ratio']:.2f} x with the "
          f"default filter); dominant period kept within 2 %: "
          f"{'yes' if max(r['period_shift'] for r in sim.values()) <= 0.02 else 'no'}")  # fmt: skip
    record("clean", "simulated Kinect: error after the default filter / the sensor's", f"{best['ratio']:.2f} x")
    timed = speed()
    plain = timed["scipy sosfiltfilt"]
    for name, seconds in timed.items():
        print(
            f"  an hour of 25 joints at 30 fps, {name:<20} {seconds:6.2f} s ({seconds / plain:5.1f} x the plain pass)"
        )
    fast = timed["the default stages"]
    print(f"  an hour cleaned within 10 s on one core: {'yes' if fast <= 10 else 'no'} ({fast:.1f} s)")
    record("clean", "an hour of skeletons cleaned (vs one scipy filter pass)", f"{fast:.1f} s ({fast / plain:.0f} x)")
    if corpus is not None:
        rows = real(corpus)
        cv_b, cv_a = np.mean([r[1] for r in rows]), np.mean([r[2] for r in rows])
        jerk_lower = sum(r[4] < r[3] for r in rows)
        kept = sum(r[5] <= 0.02 for r in rows)
        print(f"  tang2018, {len(rows)} dances: bone CV {cv_b:.3f} -> {cv_a:.4f} (goal at most 0.02: "
              f"{'yes' if cv_a <= 0.02 else 'no'}); jerk lower in {jerk_lower} of {len(rows)}; period within 2 % "
              f"in {kept} of {len(rows)}")  # fmt: skip
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
