"""Generate a dance for every recording of a dataset split, each from its own music, in one call.

For each clean recording of the split, the music over its motion frames (sample 0 at frame 0, as
the dataset was built: :func:`~kinectdata.evaluation.rhythm_eval.recording_audio`) is written
beside the dance as ``<name>.wav`` (at the run's sample rate), and the dance is generated from it
(:func:`~kinectdata.inference.generate.generate`): frame k of ``<name>.csv`` (or ``.jsonl`` for a
2-D target) is frame k of the recording in the dataset, to render, score or compare side by side
(``render <name>.csv --audio <name>.wav``). Frame 0 is the recording's true first pose, and the model
runs free from it, as ``evaluate`` runs it; a root-centred run's dance stands where the recording's
dancer stood (:mod:`~kinectdata.inference.start`). The song's metre, for features that count bars, is the
recordings manifest's or the one the dataset build found.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import soundfile

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import KinectDataError
from kinectdata.evaluation.evaluate import split_recordings
from kinectdata.evaluation.rhythm_eval import recording_audio
from kinectdata.inference.generate import generate
from kinectdata.inference.start import StartPose
from kinectdata.models.registry import model_kind
from kinectdata.models.run import load_model, model_name, read_manifest
from kinectdata.targets.specs import TargetSpec


@dataclass(frozen=True)
class GeneratedSong:
    """One dance generated for a recording of the split: its name, the files written (the dance
    and its music) and the timing figures of :func:`~kinectdata.inference.generate.generate`."""

    name: str
    motion: Path
    music: Path
    timing: dict[str, Any]


def generate_split(
    run: str | Path,
    dataset: str | Path,
    split: str,
    out_dir: str | Path,
    *,
    engine: str = "torch",
    precision: str = "float32",
    checksums: bool = True,
    turning: bool = True,
    seed: int = 0,
    progress: Callable[[str], Any] | None = None,
    travel: bool = True,
) -> list[GeneratedSong]:
    """Generate a dance for each clean recording of ``split`` of ``dataset`` with ``run``'s model
    into ``out_dir`` (module docstring). ``progress(name)`` is called before each song;
    ``turning``, ``travel`` and ``seed`` as :func:`~kinectdata.inference.generate.generate`'s.

    Raises:
        KinectDataError: the split has no recordings, or a recording's music cannot be read.
    """
    dataset, out_dir = Path(dataset), Path(out_dir)
    manifest = read_manifest(dataset, checksums=checksums)
    _, config = load_model(run)
    kind = model_kind(model_name(config))
    data = config["dataset"]
    fps, rate = data["fps"], data["sample_rate"]
    suffix = ".jsonl" if TargetSpec.from_dict(data["target"]).dimensions == 2 else ".csv"
    recordings = split_recordings(dataset, manifest, split)
    if not recordings:
        raise KinectDataError(f"{dataset}: the {split} split has no recordings to generate for")
    inputs = {e["name"]: e for e in manifest["inputs"]}
    built = {r["name"]: r.get("metre") or {} for r in manifest["recordings"]}
    out_dir.mkdir(parents=True, exist_ok=True)
    made = []
    for r in recordings:
        if progress is not None:
            progress(r["name"])
        entry = inputs[r["recording"]]
        try:
            samples = recording_audio(entry, r["info"], len(r["current"]), fps, rate)
        except OSError as exc:
            raise KinectDataError(f"{r['name']}: its music cannot be read ({exc.strerror or exc})") from exc
        music = out_dir / f"{r['name']}.wav"
        with atomic_output(music) as tmp:
            soundfile.write(tmp, np.asarray(samples, np.float32), rate, subtype="FLOAT", format="WAV")
        metre = entry.get("beats_per_bar") or built[r["name"]].get("beats_per_bar")
        motion = out_dir / f"{r['name']}{suffix}"
        _, timing = generate(
            run,
            music,
            motion,
            engine=engine,
            precision=precision,
            beats_per_bar=metre,
            start=_start(r, data, kind),
            turning=turning,
            travel=travel,
            seed=seed,
        )
        made.append(GeneratedSong(r["name"], motion, music, timing))
    return made


def _start(recording: dict[str, Any], dataset: dict[str, Any], kind: Any) -> StartPose:
    """The recording's true first pose, filled as ``evaluate`` fills it, and its anchor (where a
    root-centred dancer stood: the build's ``root_anchor``, absent from datasets built before it)."""
    pose = kind.fill_previous(recording["current"][0], recording["mask"][0], dataset["start_pose"])
    anchor = recording["info"].get("root_anchor")
    return StartPose(
        np.asarray(pose, np.float32),
        None if anchor is None else np.asarray(anchor, np.float64),
        "the recording's first pose",
    )
