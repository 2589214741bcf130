"""The field's table for two sets of dance: FID_k, FID_g, Div_k, Div_g, Beat Align Score, PFC.

:func:`score_sets` takes the generated and the reference sequences as SMPL-24 joints (metres,
y up, on the protocol's frame rate; :mod:`kinectdata.evaluation.motion_sets` reads them from files)
and a :class:`~kinectdata.evaluation.protocols.Protocol`, and returns :class:`FieldScores`: each
metric for both sets where it applies, with a bootstrap interval, warnings when a set is too small
for a stable covariance, and the record of every choice (``metrics.json``).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinectdata.core.errors import KinectDataError
from kinectdata.core.jointsets import load_joint_set
from kinectdata.core.version import __version__
from kinectdata.evaluation.metrics import (
    bone_length_variation,
    bootstrap_interval,
    constant_reference_features,
    describe_feature,
    describe_kinetic_feature,
    diversity,
    foot_contact_score,
    frechet_distance,
    geometric_features,
    kinetic_features,
    mean_jerk,
    music_beat_frames,
    peer_beat_align_score,
    peer_motion_beats,
    standardise_by_reference,
)
from kinectdata.evaluation.metrics.distribution import FAR_FEATURE, Interval, far_from_reference_features, mean_gaps
from kinectdata.evaluation.metrics.foot_contact import SCALE as PFC_SCALE
from kinectdata.evaluation.protocols import Protocol

Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
"""(x, y, z) -> (x, -z, y): the +90 degree rotation about x that EDGE applies to AIST++ joints."""


@dataclass
class DanceSequence:
    """One sequence to score.

    Attributes:
        name: what to call it (the file's stem).
        positions: [T, 24, 3] SMPL-24 joint positions, metres, y up, finite, at ``fps``.
        fps: frames per second (the protocol's).
        music_beats_s: [B] beat times of its music in seconds from frame 0, or None.
        source: where it came from (a path).
        mapping: the joint mapping used (:meth:`JointMapping.describe`), None for SMPL-24 input.
        filled_fraction: share of joint positions that were missing and filled by interpolation.
        native_fps: the frame rate it was recorded or generated at, None when it is ``fps``. Jerk
            is measured at the lower of the two: positions upsampled linearly (a 30 fps Kinect
            recording on a 60 fps protocol) have a kink at every original frame, whose jerk is
            the resampler's, not the dancer's.
    """

    name: str
    positions: np.ndarray
    fps: float
    music_beats_s: np.ndarray | None = None
    source: str = ""
    mapping: dict | None = None
    filled_fraction: float = 0.0
    native_fps: float | None = None


GAPS_SHOWN = 3
"""How many features :attr:`MetricRow.gaps` names: those whose means are furthest apart."""


@dataclass(frozen=True)
class FeatureGap:
    """One feature's part of a Fréchet distance's mean term (:func:`largest_gaps`).

    Attributes:
        index: the feature (0-based, the features' order).
        what: the feature in words (:func:`describe_kinetic_feature`, :func:`describe_feature`).
        gap: the squared difference of the standardised means (its part of the mean term).
        generated, reference: the sets' means, in the feature's units.
        sds: the generated mean's distance from the reference mean, in reference standard
            deviations (signed: below the reference is negative).
    """

    index: int
    what: str
    gap: float
    generated: float
    reference: float
    sds: float

    @property
    def ratio(self) -> float:
        """The generated mean over the reference's (NaN when the reference's is 0)."""
        return self.generated / self.reference if self.reference != 0 else float("nan")

    def to_dict(self) -> dict:
        return {
            "index": self.index,
            "what": self.what,
            "gap": self.gap,
            "generated": self.generated,
            "reference": self.reference,
            "ratio": None if self.reference == 0 else self.ratio,
            "sds": self.sds,
        }

    def __str__(self) -> str:
        side = "below" if self.sds < 0 else "above"
        if self.reference == 0:
            return f"{self.what} {self.generated:.3g}, the reference's 0 ({abs(self.sds):.3g} sd {side})"
        return f"{self.what} {self.ratio:.2f} x the reference's ({abs(self.sds):.3g} sd {side})"


@dataclass(frozen=True)
class MetricRow:
    """One column of the table: a metric of the generated set and, where it has one, of the reference."""

    name: str
    better: str
    generated: float | None
    reference: float | None = None
    interval: Interval | None = None
    note: str = ""
    mean_term: float | None = None
    gaps: tuple[FeatureGap, ...] = ()

    def to_dict(self) -> dict:
        record = {
            "name": self.name,
            "better": self.better,
            "generated": self.generated,
            "reference": self.reference,
            "interval": None if self.interval is None else self.interval.to_dict(),
            "note": self.note,
        }
        if self.mean_term is not None:
            record["mean_term"] = self.mean_term
            record["largest_gaps"] = [g.to_dict() for g in self.gaps]
        return record

    def gaps_line(self) -> str | None:
        """What the distance is made of, in a line (None for a metric that is not a Fréchet distance)."""
        if self.mean_term is None or self.generated is None:
            return None
        share = self.mean_term / self.generated if self.generated > 0 else float("nan")
        return (
            f"{self.name}: the means' gap is {_number(self.mean_term)} of {_number(self.generated)} ({share:.0%}); "
            f"furthest from the reference: {'; '.join(str(g) for g in self.gaps)}"
        )


@dataclass
class FieldScores:
    """The field's metrics of a generated set against a reference set, with the protocol's record."""

    protocol: Protocol
    metrics: list[MetricRow]
    generated: list[str]
    reference: list[str]
    warnings: list[str] = field(default_factory=list)
    per_sequence: dict = field(default_factory=dict)
    mappings: list[dict] = field(default_factory=list)
    positions: dict = field(default_factory=dict)

    def metric(self, name: str) -> MetricRow:
        """The row of a metric by name (``FID_k``, ``BAS``...)."""
        for row in self.metrics:
            if row.name == name:
                return row
        raise KeyError(name)

    def to_dict(self) -> dict:
        """JSON-ready ``metrics.json``: protocol, set sizes, metrics, per-sequence values, warnings."""
        return {
            "kinectdata_version": __version__,
            "protocol": self.protocol.to_dict(),
            "joints": "SMPL-24 (smpl24 joint set), metres, y up",
            "positions": self.positions,
            "joint_mappings": self.mappings,
            "sets": {
                "generated": {"count": len(self.generated), "sequences": self.generated},
                "reference": {"count": len(self.reference), "sequences": self.reference},
            },
            "metrics": {row.name: row.to_dict() for row in self.metrics},
            "per_sequence": self.per_sequence,
            "warnings": self.warnings,
        }

    def table(self) -> str:
        """The table, one line per metric (generated, its 95 % interval, reference), then notes and warnings."""
        lines = [
            f"protocol {self.protocol.name}: {self.protocol.reproduces}",
            *([f"positions: {describe_positions(self.positions)}"] if self.positions else []),
            f"{'metric':<9}{'better':<9}{f'generated ({len(self.generated)})':>16}{'95 % interval':>22}"
            f"{f'reference ({len(self.reference)})':>16}  note",
        ]
        for row in self.metrics:
            lines.append(
                f"{row.name:<9}{_better(row.better):<9}{_number(row.generated):>16}{_span(row.interval):>22}"
                f"{_number(row.reference):>16}  {row.note}".rstrip()
            )
        lines += [line for line in (row.gaps_line() for row in self.metrics) if line]
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def score_sets(
    generated: Sequence[DanceSequence],
    reference: Sequence[DanceSequence],
    protocol: Protocol,
    bootstrap: int = 1000,
    seed: int = 0,
    placement: str = "as the files hold them",
) -> FieldScores:
    """Score a generated set against a reference set by a protocol.

    Args:
        generated: N sequences (SMPL-24, metres, y up, at ``protocol.fps``); FID and Div need N >= 2.
        reference: M sequences, same conventions; FID needs M >= 2.
        protocol: the preprocessing and definitions to use.
        bootstrap: resamples for the 95 % intervals (0: none).
        seed: random seed of the bootstrap.
        placement: which positions these are (world, root-relative...), for the record
            (:func:`positions_record`).

    Returns:
        :class:`FieldScores`. FID and Div use features standardised by the whole reference set;
        the intervals resample sequences with that standardisation fixed.
    """
    if not generated or not reference:
        raise KinectDataError(
            f"scoring needs sequences in both sets, got {len(generated)} generated and {len(reference)} reference"
        )
    for seq in (*generated, *reference):
        _check(seq, protocol)
    warnings: list[str] = []
    per_sequence: dict = {"generated": {}, "reference": {}}
    features = {}
    for which, seqs in (("generated", generated), ("reference", reference)):
        kin, geo = [], []
        for seq in seqs:
            p = _prepared(seq.positions, protocol)
            k = kinetic_features(p, protocol.fps, up_axis=1, peer_acceleration=protocol.peer_acceleration)
            g = geometric_features(p, protocol.fps, peer_velocity=protocol.peer_velocity)
            kin.append(k)
            geo.append(g)
            per_sequence[which][seq.name] = _sequence_values(seq, protocol) | {
                "kinetic_features": k.tolist(),
                "geometric_features": g.tolist(),
            }
        features[which] = (np.stack(kin), np.stack(geo))

    rows = []
    if min(len(generated), len(reference)) < 2:
        warnings.append(
            f"FID and Div need at least 2 sequences per set, got {len(generated)} generated and {len(reference)} "
            "reference: only the per-sequence metrics are given"
        )
    smpl24 = load_joint_set("smpl24").names

    def kinetic_name(index: int) -> str:
        return describe_kinetic_feature(index, smpl24)

    for label, index, dims in (("k", 0, 72), ("g", 1, 32)) if min(len(generated), len(reference)) >= 2 else ():
        gen, ref = features["generated"][index], features["reference"][index]
        constant = constant_reference_features(gen, ref)
        if constant:
            named = f" ({'; '.join(f'{i}: {describe_feature(i)}' for i in constant)})" if label == "g" else ""
            warnings.append(
                f"FID_{label}: feature(s) {constant}{named} are constant over the reference set but vary in the "
                "generated one; standardising by the reference (as the peers do) multiplies them by 1e10"
            )
        g_std, r_std = standardise_by_reference(gen, ref)
        far = far_from_reference_features(g_std, constant)
        if far:
            warnings.append(
                f"FID_{label}: feature(s) {far} of the generated set lie more than {FAR_FEATURE:g} reference standard "
                f"deviations from the reference mean (the reference barely varies in them): they make up nearly all "
                f"of FID_{label}, which then says little about the other features"
            )
        fewest = min(len(generated), len(reference))
        if fewest <= dims:
            warnings.append(
                f"FID_{label}: {len(generated)} generated and {len(reference)} reference sequences for {dims} "
                f"features: a covariance from {fewest} sequences is singular (rank <= {fewest - 1}), so FID_{label} "
                "moves a lot with the choice of sequences (see its interval)"
            )
        fid = frechet_distance(g_std, r_std)
        gaps = mean_gaps(g_std, r_std)
        rows.append(
            MetricRow(
                f"FID_{label}",
                "lower",
                fid,
                None,
                _interval(
                    lambda a, b, g=g_std, r=r_std: frechet_distance(g[a], r[b]), len(gen), len(ref), bootstrap, seed
                ),
                mean_term=float(gaps.sum()),
                gaps=largest_gaps(gen, ref, g_std, gaps, kinetic_name if label == "k" else describe_feature),
            )
        )
        rows.append(
            MetricRow(
                f"Div_{label}",
                "closer to the reference",
                diversity(g_std),
                diversity(r_std),
                _interval(lambda a, b, g=g_std: diversity(g, a), len(gen), len(ref), bootstrap, seed),
            )
        )
    if min(len(generated), len(reference)) < 2:
        rows += [MetricRow(name, better, None, note="needs 2 sequences per set") for name, better in _SET_METRICS]
    rows.append(_mean_row("BAS", "higher", per_sequence, "beat_align_score", bootstrap, seed, _bas_note(protocol)))
    rows.append(
        _mean_row(
            "PFC", "lower", per_sequence, "foot_contact", bootstrap, seed, "EDGE's score x 10 000 at 30 fps", PFC_SCALE
        )
    )
    rows.append(
        _mean_row("bone CV", "lower", per_sequence, "bone_length_cv", bootstrap, seed, "mean per-bone std/mean length")
    )
    rows.append(
        _mean_row("jerk", "lower", per_sequence, "jerk_m_s3", bootstrap, seed, "mean jerk, m/s^3, at the native rate")
    )
    warnings += [_outside_its_interval(row) for row in rows if _outside(row)]
    missing_beats = [s.name for s in generated if s.music_beats_s is None]
    if missing_beats and len(missing_beats) < len(generated):
        warnings.append(
            f"BAS: no music beats for {len(missing_beats)} generated sequence(s): {', '.join(missing_beats)}"
        )
    mappings = []
    for seq in (*generated, *reference):
        if seq.mapping is not None and seq.mapping not in mappings:
            mappings.append(seq.mapping)
    return FieldScores(
        protocol=protocol,
        metrics=rows,
        generated=[s.name for s in generated],
        reference=[s.name for s in reference],
        warnings=warnings,
        per_sequence=per_sequence,
        mappings=mappings,
        positions=positions_record(generated, reference, protocol, placement),
    )


def largest_gaps(
    generated: np.ndarray,
    reference: np.ndarray,
    generated_std: np.ndarray,
    gaps: np.ndarray,
    describe: Callable[[int], str],
    count: int = GAPS_SHOWN,
) -> tuple[FeatureGap, ...]:
    """The ``count`` features whose means lie furthest apart (:func:`mean_gaps` ``gaps`` [D]), each
    with both sets' means in its own units ([N, D] ``generated``, [M, D] ``reference``) and its
    distance in reference standard deviations (``generated_std``, the generated set standardised by
    the reference); ``describe(index)`` names a feature."""
    g_mean, r_mean, away = generated.mean(axis=0), reference.mean(axis=0), generated_std.mean(axis=0)
    return tuple(
        FeatureGap(int(i), describe(int(i)), float(gaps[i]), float(g_mean[i]), float(r_mean[i]), float(away[i]))
        for i in np.argsort(-gaps, kind="stable")[:count]
    )


def positions_record(
    generated: Sequence[DanceSequence], reference: Sequence[DanceSequence], protocol: Protocol, placement: str
) -> dict:
    """What positions a table scores, for ``metrics.json`` and its printout: ``placement`` (world,
    root-relative...), the frame rates the sequences came at and the rate they were scored at, the
    joint sets mapped to SMPL-24, and the joints stood in for by an ancestor."""
    sequences = (*generated, *reference)
    stand_ins: dict[str, str] = {}
    for seq in sequences:
        for joint, note in ((seq.mapping or {}).get("stand_ins") or {}).items():
            stand_ins.setdefault(joint, note)
    return {
        "placement": placement,
        "source_fps": sorted({round(s.native_fps or s.fps, 3) for s in sequences}),
        "scored_fps": protocol.fps,
        "joint_sets": sorted({(s.mapping or {}).get("source", "smpl24") for s in sequences}),
        "stand_ins": stand_ins,
    }


def describe_positions(record: dict) -> str:
    """One line of :func:`positions_record`'s record."""
    rates = ", ".join(f"{r:g}" for r in record["source_fps"])
    line = (
        f"{record['placement']}; {rates} fps resampled to {record['scored_fps']:g}; "
        f"joints of {', '.join(record['joint_sets'])} as SMPL-24"
    )
    if record["stand_ins"]:
        line += f"; never placed, an ancestor stands in: {', '.join(record['stand_ins'])}"
    return line


_SET_METRICS = (
    ("FID_k", "lower"),
    ("Div_k", "closer to the reference"),
    ("FID_g", "lower"),
    ("Div_g", "closer to the reference"),
)


def _check(seq: DanceSequence, protocol: Protocol) -> None:
    p = np.asarray(seq.positions)
    if p.ndim != 3 or p.shape[1:] != (24, 3):
        raise KinectDataError(f"{seq.source or seq.name}: SMPL-24 positions [T, 24, 3] needed, got shape {p.shape}")
    if abs(seq.fps - protocol.fps) > 1e-9:
        raise KinectDataError(
            f"{seq.source or seq.name}: at {seq.fps} fps; protocol {protocol.name} needs {protocol.fps} fps"
        )
    if p.shape[0] < 4:
        raise KinectDataError(f"{seq.source or seq.name}: {p.shape[0]} frames; the metrics need at least 4")
    if not np.all(np.isfinite(p)):
        raise KinectDataError(f"{seq.source or seq.name}: positions must be finite (fill or drop missing frames)")


def _prepared(positions: np.ndarray, protocol: Protocol) -> np.ndarray:
    """The frames the features see: the first ``max_frames``, moved to a zero start if the protocol says."""
    p = np.asarray(positions, dtype=np.float64)
    if protocol.max_frames is not None:
        p = p[: protocol.max_frames]
    return p - p[:1, :1] if protocol.zero_start else p


def _sequence_values(seq: DanceSequence, protocol: Protocol) -> dict:
    """Per-sequence metrics: motion beats, Beat Align Score, PFC, bone CV and jerk."""
    p = np.asarray(seq.positions, dtype=np.float64)
    beats = peer_motion_beats(p, protocol.fps, protocol.motion_beat_smoothing_s)
    values: dict = {"frames": int(p.shape[0]), "source": seq.source, "filled_fraction": seq.filled_fraction}
    values["motion_beats_s"] = (beats / protocol.fps).tolist()
    if seq.music_beats_s is not None:
        music = music_beat_frames(seq.music_beats_s, protocol.fps, p.shape[0])
        score = peer_beat_align_score(music, beats, protocol.fps, protocol.bas_direction, protocol.bas_sigma_s)
        values["music_beats_used"] = int(music.size)
        values["beat_align_score"] = None if not np.isfinite(score) else score
    pfc_positions = _at_rate(p, protocol.fps, protocol.pfc_fps) @ Y_UP_TO_Z_UP.T
    values["foot_contact"] = foot_contact_score(pfc_positions, protocol.pfc_fps, up_axis=2)
    parents = load_joint_set("smpl24").parents
    values["bone_length_cv"] = float(np.nanmean(bone_length_variation(p, parents)))
    jerk_fps = min(protocol.fps, seq.native_fps or protocol.fps)
    values["jerk_m_s3"] = mean_jerk(_at_rate(p, protocol.fps, jerk_fps), jerk_fps)
    values["jerk_fps"] = jerk_fps
    return values


def _at_rate(p: np.ndarray, fps: float, target: float) -> np.ndarray:
    """[T, J, 3] positions at ``target`` fps: every k-th frame for an integer ratio (as EDGE takes
    60 fps AIST++ to 30), else linear interpolation on the target grid."""
    ratio = fps / target
    if abs(ratio - round(ratio)) < 1e-9 and round(ratio) >= 1:
        return p[:: int(round(ratio))]
    times = np.arange(p.shape[0]) / fps
    grid = np.arange(0.0, times[-1] + 1e-9, 1.0 / target)
    flat = p.reshape(p.shape[0], -1)
    return np.stack([np.interp(grid, times, flat[:, c]) for c in range(flat.shape[1])], axis=1).reshape(
        grid.size, *p.shape[1:]
    )


def _outside(row: MetricRow) -> bool:
    """Whether a metric's value lies outside its own bootstrap interval."""
    iv = row.interval
    return iv is not None and row.generated is not None and not iv.low <= row.generated <= iv.high


def _outside_its_interval(row: MetricRow) -> str:
    iv = row.interval
    return (
        f"{row.name}: {row.generated:.4g} lies outside its own {100 * iv.level:.0f} % interval ({iv.low:.4g} to "
        f"{iv.high:.4g}): the interval comes from sets drawn with replacement, a drawn set repeats sequences, and "
        "that moves a set metric (two drawn sets' means lie further apart than the sets', so FID's draws run high); "
        "read the interval as how far the metric moves with the choice of sequences, not as where it lies"
    )


def _interval(statistic, n: int, m: int, resamples: int, seed: int) -> Interval | None:
    if resamples <= 0:
        return None
    try:
        return bootstrap_interval(statistic, n, m, resamples, seed=seed)
    except KinectDataError:
        return None


def _mean_row(
    name: str, better: str, per_sequence: dict, key: str, resamples: int, seed: int, note: str, scale: float = 1.0
) -> MetricRow:
    """A metric that is the mean of per-sequence values, for each set, with an interval for the generated set."""
    means = {}
    generated_values = np.array([])
    for which in ("generated", "reference"):
        values = np.array([v[key] for v in per_sequence[which].values() if v.get(key) is not None], dtype=np.float64)
        values = values[np.isfinite(values)] * scale
        means[which] = float(values.mean()) if values.size else None
        if which == "generated":
            generated_values = values
    interval = None
    if generated_values.size >= 2:
        interval = _interval(lambda a, b: float(generated_values[a].mean()), generated_values.size, 1, resamples, seed)
    if means["generated"] is None and name == "BAS":
        note = "not computed: no music beats given"
    return MetricRow(name, better, means["generated"], means["reference"], interval, note)


def _bas_note(protocol: Protocol) -> str:
    over = (
        "music beats (Bailando's code)"
        if protocol.bas_direction == "music_to_motion"
        else "motion beats (AIST++ paper)"
    )
    return f"averaged over {over}, sigma {protocol.bas_sigma_s:.3f} s"


def _better(better: str) -> str:
    return {"lower": "lower", "higher": "higher"}.get(better, "~ ref")


def _number(value: float | None) -> str:
    if value is None:
        return "-"
    if abs(value) < 5e-5:
        value = 0.0  # round-off around a zero FID printed as 0.0000, not -0.0000
    if abs(value) >= 1e7:  # e.g. FID_g on features constant in the reference: fixed point would fill its column
        return f"{value:.4g}"
    return f"{value:.4f}" if abs(value) < 10 else f"{value:.2f}"


def _span(interval: Interval | None) -> str:
    if interval is None:
        return "-"
    return f"{_number(interval.low)} - {_number(interval.high)}"


def write_metrics_json(scores: FieldScores, path: str | Path) -> Path:
    """Write :meth:`FieldScores.to_dict` to ``path`` atomically (NaN as null); the path written."""
    from kinectdata.core.atomic import atomic_output

    path = Path(path)
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(_json_safe(scores.to_dict()), indent=2) + "\n", encoding="utf-8")
    return path


def _json_safe(value):
    if isinstance(value, dict):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value
