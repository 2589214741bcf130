"""``generate``: any audio file -> dance motion, streaming, as a robot would run it live.

The audio is read in blocks (:class:`~kinectdata.align.audio.AudioReader`), the features of each frame
are computed as soon as its audio has arrived (:class:`~kinectdata.features.streaming.StreamingFeatures`)
and the network steps one frame at a time (an engine of :mod:`~kinectdata.inference.engines`: torch
or ONNX Runtime), its state carried from frame to frame; nothing waits for the end of the audio but the file
written at the end. The first "previous pose" is the mean training pose. Poses are denormalised
and written in the form the target's joint set is read back from:

- 3-D joint sets (the yalta model): kinectdata's canonical CSV (metres, unit quaternions), which
  ``align`` reads: the target spec's joints get their orientations, and every joint the
  orientations reach gets a position by forward kinematics over the dataset's rest skeleton
  (:mod:`kinectdata.targets.skeleton`; runs on datasets built before it have the listed positions only);
  other joints are left empty (masked);
- ``openpose_mpi`` (the cdhc model): OpenPose JSON Lines (:mod:`~kinectdata.formats.openpose_writer`)
  with x, y in the target's units: 0..1 of the per-recording min-max scaling for
  ``listen_to_dance``, image axes (y down). The limb lengths are not written (they are the
  model's own estimate of its skeleton; :func:`generate` returns them in ``timing["limb_lengths"]``).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.align.audio import AudioReader
from kinectdata.core.errors import KinectDataError
from kinectdata.core.jointsets import load_joint_set
from kinectdata.core.motion import Motion
from kinectdata.features import feature_config
from kinectdata.features.streaming import StreamingFeatures
from kinectdata.formats.csv_writer import write_csv
from kinectdata.formats.openpose_writer import write_openpose_jsonl
from kinectdata.inference.engines import make_engine
from kinectdata.models.run import load_model
from kinectdata.targets.normalization import Normalizer
from kinectdata.targets.skeleton import rebuild_positions
from kinectdata.targets.specs import TargetSpec


def _motion(
    values: np.ndarray,
    spec: TargetSpec,
    fps: float,
    metadata: dict[str, Any],
    skeleton: dict | None = None,
    root_centred: bool = False,
) -> Motion:
    """A Motion of the spec's joint set from denormalised target vectors [T, D]; with the dataset's
    ``skeleton`` (bone offsets) every joint its orientations reach gets a position
    (:func:`kinectdata.targets.skeleton.rebuild_positions`), else only the spec's listed joints."""
    js = load_joint_set(spec.joint_set)
    T, J = values.shape[0], len(js)
    positions = np.full((T, J, spec.dimensions), np.nan)
    for joint in spec.positions:
        positions[:, js.index(joint)] = values[:, spec.columns(joint, "position")]
    if skeleton:
        positions, _ = rebuild_positions(values, spec, skeleton, root_centred=root_centred)
    orientations = np.full((T, J, 4), np.nan)
    for joint in spec.orientations:
        orientations[:, js.index(joint)] = values[:, spec.columns(joint, "orientation")]
    return Motion(
        np.arange(T) / fps, positions, js, orientations=orientations if spec.orientations else None, metadata=metadata
    )


def generate(
    run: str | Path,
    audio: str | Path,
    out: str | Path | None = None,
    *,
    engine: str = "torch",
    precision: str = "float32",
) -> tuple[Motion, dict[str, Any]]:
    """Generate motion for ``audio`` with a trained run; write it to ``out`` if given (canonical
    CSV, or OpenPose JSON Lines for 2-D targets: see the module docstring).

    ``engine``: ``torch`` (``precision`` float32 or float16 weights) or ``onnxruntime`` (float32;
    the yalta model only). Returns the Motion (times k / fps; metres and unit quaternions, or the
    2-D target's units) and timing figures.
    """
    net, config = load_model(run)
    data = config["dataset"]
    fps, sr = data["fps"], data["sample_rate"]
    spec = TargetSpec.from_dict(data["target"])
    wanted = (".jsonl", ".json") if spec.dimensions == 2 else (".csv",)
    if out is not None and Path(out).suffix.lower() not in wanted:
        kind = "OpenPose JSON Lines" if spec.dimensions == 2 else "canonical CSV"
        raise KinectDataError(f"{out}: this run's motion is written as {kind}; name the file {wanted[0]}")
    norm = Normalizer.from_dict(data["normalisation"])
    reader = AudioReader(audio, sr)
    n = int(np.floor(reader.n_samples / sr * fps + 1e-9))
    if n < 1:
        raise KinectDataError(f"{audio}: shorter than one frame ({1 / fps:.3f} s)")
    stepper = make_engine(net, engine, precision)
    pose = np.asarray(data["start_pose"], dtype=np.float32)
    poses = np.empty((n, spec.dim), np.float32)
    step_times: list[float] = []

    def step(k0: int, features: np.ndarray, padded: np.ndarray) -> None:
        nonlocal pose
        for k in range(features.shape[0]):
            started = time.perf_counter()
            pose = stepper.step(features[k], pose)
            step_times.append(time.perf_counter() - started)
            poses[k0 + k] = pose

    starts = np.round(np.arange(n) * sr / fps).astype(np.int64)
    featurizer = StreamingFeatures(starts, feature_config(data["features"]), step)
    started = time.perf_counter()
    for block in reader.blocks():
        featurizer.push(block)
    featurizer.finish()
    seconds = time.perf_counter() - started
    values = norm.invert(poses, spec)
    metadata = {"format": "generated", "source": str(audio), "run": str(run)}
    motion = _motion(values, spec, fps, metadata, data.get("skeleton"), data["root_centre"])
    if out is not None and spec.dimensions == 2:
        write_openpose_jsonl(motion, out)
    elif out is not None:
        write_csv(
            motion,
            out,
            "canonical",
            comments={
                "generated_by": "kinectdata generate",
                "run": str(Path(run).resolve()),
                "audio": str(Path(audio).resolve()),
                "target_spec": spec.name,
                "root_centred": str(data["root_centre"]).lower(),
                "engine": f"{engine} {precision}",
            },
        )
    t = np.array(step_times) * 1e3
    timing = {
        "frames": n,
        "seconds": seconds,
        "x_real_time": n / fps / seconds,
        "step_median_ms": float(np.median(t)),
        "step_p95_ms": float(np.percentile(t, 95)),
    }
    if spec.limbs:
        timing["limb_lengths"] = {
            name: float(np.median(values[:, spec.columns(j, "limb")]))
            for j, name in zip(spec.limbs, spec.component_names()[spec.limb_slice])
        }
    return motion, timing
