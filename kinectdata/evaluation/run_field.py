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
- a joint the target never places (yalta65 has no ankle orientations, so no feet) takes its
  nearest placed ancestor's positions, recorded as a stand-in in ``metrics.json``;
- both sets cover frames 1..T-1 (frame 0 is the true pose the model starts from), and the music
  beats are shifted by one frame to match.

Targets that cannot become SMPL-24 joints (2-D pixels, a joint set without a mapping, joints the
target never places) give ``{"unavailable": why}`` instead of a table.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinectdata.core.errors import KinectDataError
from kinectdata.core.motion import Motion
from kinectdata.evaluation.field_scores import FieldScores, score_sets
from kinectdata.evaluation.motion_sets import motion_as_dance
from kinectdata.evaluation.protocols import Protocol
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
    bootstrap: int = 1000,
    seed: int = 0,
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
        bootstrap, seed: as :func:`~kinectdata.evaluation.field_scores.score_sets`.

    Raises:
        KinectDataError: the targets cannot be scored as SMPL-24 joints (the message says why).
    """
    if spec.dimensions != 3:
        raise KinectDataError(
            f"the target {spec.name} is {spec.dimensions}-D (pixels); the field's metrics need 3-D joints"
        )
    fps = float(dataset_config["fps"])
    joint_set = spec.joints
    gen_set, real_set, stand_ins = [], [], {}
    for name, values in generated.items():
        real_values, real_mask = real[name]
        music = beats.get(name, (None,))[0]
        shifted = None if music is None else np.asarray(music, np.float64) - 1.0 / fps
        for out, targets, mask in (
            (gen_set, values, np.ones_like(values, bool)),
            (real_set, real_values[1:], real_mask[1:]),
        ):
            positions, substituted = _body(targets, mask, spec, dataset_config)
            stand_ins.update(substituted)
            motion = Motion(times=np.arange(len(positions)) / fps, positions=positions, joint_set=joint_set)
            out.append(motion_as_dance(motion, protocol, name=name, source=f"recording {name}", beats=shifted))
    if stand_ins:
        note = {
            joint: f"not in the target {spec.name}: {parent}, its nearest ancestor, stands in"
            for joint, parent in stand_ins.items()
        }
        for seq in (*gen_set, *real_set):
            if seq.mapping is not None:
                seq.mapping = seq.mapping | {"stand_ins": note}
    return score_sets(gen_set, real_set, protocol, bootstrap=bootstrap, seed=seed)


def _body(
    values: np.ndarray, mask: np.ndarray, spec: TargetSpec, dataset_config: dict[str, Any]
) -> tuple[np.ndarray, dict[str, str]]:
    """[T, J, 3] positions of every joint of the spec's joint set, and the joints the target never
    places (e.g. the feet of yalta65, which has no ankle orientations), each filled with its
    nearest placed ancestor's positions: ``{joint: ancestor}``."""
    positions, _ = rebuild_positions(
        np.where(mask, values, np.nan),
        spec,
        dataset_config.get("skeleton") or {},
        root_centred=bool(dataset_config.get("root_centre")),
    )
    joint_set = spec.joints
    placed = np.isfinite(positions).all(axis=2).any(axis=0)
    substituted = {}
    for j in np.flatnonzero(~placed):
        a = joint_set.parents[j]
        while a >= 0 and not placed[a]:
            a = joint_set.parents[a]
        if a >= 0:
            positions[:, j] = positions[:, a]
            substituted[joint_set.names[j]] = joint_set.names[a]
    return positions, substituted
