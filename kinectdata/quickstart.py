"""The quickstart: the toolkit's data path run end to end on sample data.

1. ``synth``: synthesise a new session;
2. ``align``: align every session of the sample folder and the new one (``--offset auto``),
   checking each estimated offset against the ground truth;
3. ``build-dataset``: turn the aligned files into a dataset (1x129x5 STFT inputs, yalta65 targets
   normalised into -0.9..0.9, HDF5 shards and a manifest), then ``inspect`` it.

Later stages (training, evaluation) join as they land.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from .align import align_files, format_summary
from .collection import find_sessions
from .dataset.build import build_dataset
from .dataset.inspect import inspect
from .dataset.prepare import BuildConfig
from .errors import KinectDataError
from .features.stft import PRESETS
from .synth import synthesize_recording, write_recording
from .targets import load_target_spec

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

    Returns:
        ``{"sessions": {name: {...}}, "dataset": path, "rows": n}``.

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
    echo(f"[build-dataset] {out / 'aligned'} -> {out / 'dataset'}")
    config = BuildConfig(features=PRESETS["yalta2016"].to_dict(), target=load_target_spec("yalta65").to_dict())
    manifest = build_dataset(out / "aligned", out / "dataset", config)
    echo(f"[inspect] {out / 'dataset'}")
    echo(inspect(out / "dataset", components=6))
    t = manifest["totals"]
    echo(
        f"[done] {len(results)} sessions aligned into {out / 'aligned'}; dataset of {t['rows']} rows in "
        f"{t['shards']} shards in {out / 'dataset'}"
    )
    return {"sessions": results, "dataset": str(out / "dataset"), "rows": t["rows"]}
