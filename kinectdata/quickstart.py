"""The quickstart: the toolkit's data path run end to end on sample data.

So far: synthesise a session (``synth``), then align every session in the sample folder and the
new one (``align --offset auto``), checking each estimated offset against the ground truth.
Later stages (datasets, training, evaluation) join as they land.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from .align import align_files, format_summary
from .collection import find_sessions
from .errors import KinectDataError
from .synth import synthesize_recording, write_recording

SAMPLE_SEEDS = (1, 2, 3)
SAMPLE_DURATION_S = 22.0
SAMPLE_COMMAND = "kinectdata synth sample_data --seed 1 --count 3 --duration 22"
"""The command that made ``sample_data/`` (also run by the quickstart when the folder is absent)."""

FRAME_S = 1 / 30


def run_quickstart(
    out_dir: str | Path, samples: str | Path | None = None, echo: Callable[[str], Any] = print
) -> dict[str, Any]:
    """Run the quickstart into ``out_dir``; returns per-session results.

    Args:
        out_dir: output folder (``synth/`` and ``aligned/`` are made inside).
        samples: folder of sample sessions; default ``./sample_data`` when it exists, else the
            sample set is synthesised into ``out_dir/sample_data`` with :data:`SAMPLE_COMMAND`'s options.
        echo: where progress lines go.

    Raises:
        KinectDataError: a step failed, or an estimated offset is off by more than one frame.
    """
    out = Path(out_dir)
    if samples is None:
        samples = Path("sample_data")
        if not samples.is_dir():
            samples = out / "sample_data"
            echo(f"[synth] no ./sample_data here: making it in {samples} ({SAMPLE_COMMAND})")
            for seed in SAMPLE_SEEDS:
                rec = synthesize_recording(seed=seed, duration_s=SAMPLE_DURATION_S)
                write_recording(rec, samples, f"synth_{seed:03d}")
    echo(f"[synth] a new session: seed 7, {SAMPLE_DURATION_S:g} s")
    fresh = synthesize_recording(seed=7, duration_s=SAMPLE_DURATION_S)
    write_recording(fresh, out / "synth", "synth_007")

    sessions = find_sessions(samples) + find_sessions(out / "synth")
    if not sessions:
        raise KinectDataError(f"{samples}: no sessions (a skeleton file with audio of the same name)")
    results = {}
    for s in sessions:
        target = out / "aligned" / f"{s.name}.h5"
        echo(f"[align] {s.skeleton} + {s.audio} -> {target}")
        rec = align_files(s.skeleton, s.audio, target, offset="auto")
        echo(format_summary(rec))
        truth = s.load_truth()
        result = {"aligned": str(target), "frames": rec.n_frames, "offset_s": rec.offset["seconds"]}
        if truth is not None:
            error = rec.offset["seconds"] - truth["offset_s"]
            result["offset_error_s"] = error
            echo(f"  offset error against the ground truth: {1000 * error:+.1f} ms")
            if abs(error) > FRAME_S:
                raise KinectDataError(
                    f"{s.name}: estimated offset is {1000 * error:+.1f} ms off the truth (over one frame)"
                )
        results[s.name] = result
    echo(f"[done] {len(results)} sessions aligned into {out / 'aligned'}")
    return results
