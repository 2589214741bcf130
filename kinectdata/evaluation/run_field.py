"""The field's table (FID, diversity, Beat Align Score, PFC) for a trained run's free runs.

``evaluate`` gives every recording of a split to the model, which runs free from its first true
pose. This module turns those runs and the real motion of the same recordings into SMPL-24 joint
sequences and scores the generated set against the real one by a peer's protocol
(:func:`~kinectdata.evaluation.field_scores.score_sets`):

- the whole body is rebuilt from the targets (:func:`kinectdata.targets.skeleton.rebuild_positions`:
  forward kinematics over the dataset's rest skeleton for orientation targets, the target's own
  positions otherwise), in the dataset's joint set, metres, y up;
- it is mapped to SMPL-24 by that joint set's shipped mapping and resampled to the protocol's
  frame rate (:func:`~kinectdata.evaluation.motion_sets.motion_as_dance`);
- a root-centred dataset's motion is put back where each recording's dancer stood (the build's
  ``root_anchor``), so that these are the positions ``generate`` writes for the recording;
- a joint the target never places (yalta65 has no ankle orientations, so no feet) takes its
  nearest placed ancestor's positions, recorded as a stand-in in ``metrics.json``
  (:func:`~kinectdata.evaluation.motion_sets.with_stand_ins`, as for any file ``score`` reads);
- both sets cover frames 1..T-1 (frame 0 is the true pose the model starts from), and the music
  beats are shifted by one frame to match.

``metrics.json`` and the table say which positions were scored (``positions``), and the scored
motion is written beside them (``scored/``: :func:`write_scored_motion`) so that ``kinectdata
score`` reads it back to the same numbers.

Targets that cannot become SMPL-24 joints (2-D pixels, a joint set without a mapping, joints the
target never places) give ``{"unavailable": why}`` instead of a table.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import KinectDataError
from kinectdata.core.motion import Motion
from kinectdata.evaluation.field_scores import FieldScores, score_sets
from kinectdata.evaluation.motion_sets import motion_as_dance
from kinectdata.evaluation.protocols import Protocol
from kinectdata.formats.csv_writer import write_csv
from kinectdata.targets.skeleton import rebuild_positions
from kinectdata.targets.specs import TargetSpec


def run_field_scores(
    generated: dict[str, np.ndarray],
    real: dict[str, tuple[np.ndarray, np.ndarray]],
    beats: dict[str, tuple],
    spec: TargetSpec,
    dataset_config: dict[str, Any],
    protocol: Protocol,
    *,
    anchors: dict[str, np.ndarray] | None = None,
    bootstrap: int = 1000,
    seed: int = 0,
    write_to: str | Path | None = None,
) -> FieldScores:
    """Score free runs against the real motion of the same recordings.

    Args:
        generated: per recording, the free run without reset, denormalised targets [T-1, D]
            (frames 1..T-1).
        real: per recording, (denormalised real targets [T, D], their mask [T, D]).
        beats: per recording, ``(music beat times [B] s from frame 0 or None, source, why not)`` as
            :func:`~kinectdata.evaluation.rhythm_eval.split_beats` gives them.
        spec: the dataset's target spec.
        dataset_config: the run's ``config.json`` ``dataset`` record (``fps``, ``skeleton``,
            ``root_centre``).
        protocol: whose table to reproduce.
        anchors: per recording, where a root-centred dancer stood ([3] metres, the build's
            ``root_anchor``): both motions are put back there. Missing (datasets built before
            anchors): they stay relative to the root's first second, and the record says so.
        bootstrap, seed: as :func:`~kinectdata.evaluation.field_scores.score_sets`.
        write_to: a folder to write the scored motion to, as ``kinectdata score`` reads it back to
            the same table (:func:`write_scored_motion`).

    Raises:
        KinectDataError: the targets cannot be scored as SMPL-24 joints (the message says why).
    """
    if spec.dimensions != 3:
        raise KinectDataError(
            f"the target {spec.name} is {spec.dimensions}-D (pixels); the field's metrics need 3-D joints"
        )
    fps = float(dataset_config["fps"])
    anchors = anchors or {}
    centred = bool(dataset_config.get("root_centre"))
    scored = {}
    for name, values in generated.items():
        real_values, real_mask = real[name]
        music = beats.get(name, (None,))[0]
        shifted = None if music is None else np.asarray(music, np.float64) - 1.0 / fps
        anchor = anchors.get(name)
        scored[name] = (
            target_motion(values, np.ones_like(values, bool), spec, dataset_config, anchor),
            target_motion(real_values[1:], real_mask[1:], spec, dataset_config, anchor),
            shifted,
        )
    if not centred:
        placement = "world: the targets' own positions"
    elif anchors and all(name in anchors for name in scored):
        placement = "world: root-centred targets put back where each recording's dancer stood (its root anchor)"
    else:
        placement = "root-relative: root-centred targets, the root's travel from its first second (no root anchors)"
    placement += ", frames 1..T-1 of each recording (frame 0 is the true pose the model starts from)"
    if write_to is not None:
        write_scored_motion(write_to, scored)
    gen_set = [
        motion_as_dance(g, protocol, name=n, source=f"recording {n}", beats=b) for n, (g, _, b) in scored.items()
    ]
    real_set = [
        motion_as_dance(r, protocol, name=n, source=f"recording {n}", beats=b) for n, (_, r, b) in scored.items()
    ]
    return score_sets(gen_set, real_set, protocol, bootstrap=bootstrap, seed=seed, placement=placement)


def write_scored_motion(folder: str | Path, scored: dict[str, tuple[Motion, Motion, np.ndarray | None]]) -> Path:
    """Write what a table scored: ``generated/<name>.csv`` and ``real/<name>.csv`` (canonical CSV, the
    dataset's joint set carried whole, frame 0 = the recording's frame 1) and ``beats.json`` (each
    song's beats on that clock), so that ``kinectdata score generated real --beats beats.json``
    gives the same table. Returns the folder."""
    folder = Path(folder)
    for which in ("generated", "real"):
        (folder / which).mkdir(parents=True, exist_ok=True)
    beats = {}
    for name, (gen, real, music) in scored.items():
        for which, motion in (("generated", gen), ("real", real)):  # nanometres: a still dancer's jerk is in them
            path = folder / which / f"{name}.csv"
            write_csv(motion, path, "canonical", comments={"scored_by": "kinectdata evaluate"}, decimals=9)
        if music is not None:
            beats[name] = [float(t) for t in music]
    with atomic_output(folder / "beats.json") as tmp:
        Path(tmp).write_text(json.dumps(beats, indent=1))
    return folder


def target_motion(
    values: np.ndarray,
    mask: np.ndarray,
    spec: TargetSpec,
    dataset_config: dict[str, Any],
    anchor: np.ndarray | None,
) -> Motion:
    """The spec's joint set's positions rebuilt from targets [T, D] (NaN where not placed), at the
    dataset's rate, put back at ``anchor`` when given."""
    positions, mask = rebuild_positions(
        np.where(mask, values, np.nan),
        spec,
        dataset_config.get("skeleton") or {},
        root_centred=bool(dataset_config.get("root_centre")),
        anchor=anchor,
    )
    times = np.arange(len(positions)) / float(dataset_config["fps"])
    return Motion(times=times, positions=positions, joint_set=spec.joints, position_mask=mask)
