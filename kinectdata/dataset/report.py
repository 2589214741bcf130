"""What ``kinectdata report`` finds in a dataset, as typed values: the analysis behind the page
(:mod:`kinectdata.viz.report` draws it).

:func:`scan_dataset` checks a dataset folder (the manifest against its schema, every shard
against the layout, its SHA-256 and the manifest's account of it, as ``kinectdata verify``) and
then, recording by recording (:meth:`DatasetScan.recordings`, streamed: one recording's rows in
memory at a time), gives a :class:`RecordingReport`: its rows as the shards hold them, what
re-reading its sources adds (:class:`SourceEvidence`) and its warnings (:class:`ReportWarning`):

- clipping: normalised targets outside the normalisation's bounds (-0.9..0.9, or 0..1 for
  ``none``: the training split is inside by construction, the others may not be);
- long-gap: target components masked for longer than the build's ``max_gap``;
- offset: an offset estimated with a confidence below :data:`LOW_CONFIDENCE`, or given rather
  than estimated;
- masked: more than :data:`MASKED_WARNING` of a recording's target values masked.

Interpolation flags and the offset's correlation curve need the sources named in the manifest's
``inputs``: an aligned ``.h5`` file (which keeps the flags), or the skeleton recording and audio,
which are then resampled onto the dataset's timeline and their offset re-estimated with
:func:`kinectdata.align.offset.estimate_offset`. That is done when the files are still where the
build found them with the same SHA-256; otherwise the evidence says why not.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from kinectdata.align.aligned import AlignedRecording
from kinectdata.align.audio import AudioReader
from kinectdata.align.envelopes import audio_envelopes
from kinectdata.align.offset import OffsetEstimate, estimate_offset, xcorr_estimate
from kinectdata.align.recipe import DEFAULT_MAX_GAP, DEFAULT_MIN_COVERAGE, plan_timeline, resample_onto
from kinectdata.core.errors import KinectDataError
from kinectdata.core.jointsets import JointSet
from kinectdata.dataset.inputs import RecordingEntry
from kinectdata.dataset.layout import is_copy
from kinectdata.dataset.prepare import source_hashes
from kinectdata.dataset.shards import read_index
from kinectdata.dataset.verify import verified_manifest
from kinectdata.targets.normalization import Normalizer, count_out_of_range
from kinectdata.targets.specs import TargetSpec

LOW_CONFIDENCE = 0.8
"""Offsets estimated with less confidence than this are warned about."""
MASKED_WARNING = 0.05
"""A recording with more than this share of its target values masked is warned about."""
FEATURE_SAMPLE_S = 4.0
"""Seconds of audio features shown per recording (from its middle)."""


@dataclass(frozen=True)
class ReportWarning:
    """A warning at the top of the page: ``kind`` is ``clipping``, ``long-gap``, ``offset`` or
    ``masked``; ``count`` the values (clipping, masked) or spans (long-gap) concerned, 0 for offset."""

    kind: str
    recording: str
    message: str
    count: int = 0


@dataclass
class SourceEvidence:
    """What re-reading a recording's sources adds; ``missing`` says what could not be had, and why."""

    interpolated: np.ndarray | None = None  # [N, D] bool: target components filled across a gap
    gaps: list[dict[str, Any]] = field(default_factory=list)  # gaps longer than max_gap, dataset clock
    estimate: OffsetEstimate | None = None
    curve: tuple[np.ndarray, np.ndarray] | None = None  # (offsets s, cross-correlation score)
    expected: float | None = None  # the offset (s) the evidence should point at
    expected_label: str = ""
    clock: str = ""
    missing: list[str] = field(default_factory=list)


@dataclass
class RecordingReport:
    """One recording as the shards hold it (its clean variant) and the manifest lists it."""

    record: dict[str, Any]  # the manifest's record
    info: dict[str, Any]  # the shard index's info: sources, offset, alignment summary
    current: np.ndarray  # [N, D] float32 normalised targets
    mask: np.ndarray  # [N, D] bool, True where valid
    features: np.ndarray  # [n, ...] float32: the rows of the feature sample
    sample_start: int  # frame of the sample's first row
    copies: list[dict[str, Any]] = field(default_factory=list)  # manifest records of its copies (noisy, stretched)
    evidence: SourceEvidence | None = None
    warnings: list[ReportWarning] = field(default_factory=list)


# ---------------------------------------------------------------------------------------------
# Reading and checking the dataset
# ---------------------------------------------------------------------------------------------
def masked_spans(mask: np.ndarray, fps: float, longer_than: float = 0.0) -> list[tuple[float, float, int]]:
    """Runs of masked values per target component.

    Args:
        mask: [N, D] bool, True where valid.
        fps: frames per second; frame k covers k / fps to (k + 1) / fps seconds.
        longer_than: seconds; shorter or equal runs are left out.

    Returns:
        ``(start_s, end_s, component)`` per run of consecutive masked frames, by start then component.
    """
    masked = ~np.asarray(mask, bool)
    pad = np.zeros((1, masked.shape[1]), np.int8)
    edges = np.diff(np.vstack([pad, masked.astype(np.int8), pad]), axis=0).T  # [D, N + 1]
    column, first = np.nonzero(edges == 1)
    _, stop = np.nonzero(edges == -1)  # runs alternate within each column: the i-th stop ends the i-th start
    spans = [(a / fps, b / fps, int(c)) for a, b, c in zip(first, stop, column) if (b - a) / fps > longer_than + 1e-9]
    return sorted(spans, key=lambda s: (s[0], s[2]))


def span_union(spans: list[tuple[float, float, int]]) -> list[tuple[float, float]]:
    """The time intervals (s) covered by any of ``spans``, merged."""
    merged: list[list[float]] = []
    for start, end, _ in sorted(spans):
        if merged and start <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], end)
        else:
            merged.append([start, end])
    return [(a, b) for a, b in merged]


def _recordings(root: Path, manifest: dict[str, Any], totals: dict[str, np.ndarray]) -> Iterator[RecordingReport]:
    """Each clean recording's rows, shard by shard; adds every record's [valid values, values,
    values outside the bounds] (noisy copies included) to ``totals[split]``."""
    bounds = Normalizer.from_dict(manifest["normalisation"]).bounds
    fps = float(manifest["config"]["fps"])
    copies: dict[str, list[dict[str, Any]]] = {}
    for record in manifest["recordings"]:
        if is_copy(record):
            copies.setdefault(record["recording"], []).append(record)
    for shard in manifest["shards"]:
        listed = [r for r in manifest["recordings"] if r["shard"] == shard["file"]]
        with h5py.File(root / shard["file"], "r") as f:
            for record, row in zip(listed, read_index(f)):
                rows = slice(record["start"], record["start"] + record["frames"])
                current, mask = f["current"][rows], f["mask"][rows]
                outside = int(count_out_of_range(current, mask, bounds).sum())
                totals.setdefault(shard["split"], np.zeros(3, np.int64))[:] += (mask.sum(), mask.size, outside)
                if is_copy(record):
                    continue
                n = min(record["frames"], max(1, round(FEATURE_SAMPLE_S * fps)))
                k0 = (record["frames"] - n) // 2
                features = f["input"][record["start"] + k0 : record["start"] + k0 + n]
                yield RecordingReport(
                    record, row["info"], current, mask, features, k0, copies.get(record["recording"], [])
                )


# ---------------------------------------------------------------------------------------------
# Re-reading the sources
# ---------------------------------------------------------------------------------------------
def _component_flags(
    spec: TargetSpec, joint_set: JointSet, positions: np.ndarray, orientations: np.ndarray | None
) -> np.ndarray:
    """[N, D] bool per target component from per-joint flags [N, J] (a limb length from both of its
    joints); orientation components use the position flags when there are no orientation flags."""
    j = joint_set.index
    quats = positions if orientations is None else orientations
    columns = [positions[:, j(name)] for name in spec.positions for _ in spec.position_axes]
    columns += [quats[:, j(name)] for name in spec.orientations for _ in range(4)]
    columns += [positions[:, j(a)] | positions[:, j(b)] for a, b in spec.limb_pairs()]
    return np.stack(columns, axis=1)


def offset_used(r: RecordingReport) -> dict[str, Any]:
    """The offset the build used: ``{"seconds", "source", "confidence", ...}`` (empty if not recorded)."""
    return r.record.get("offset") or r.info.get("offset") or {}


def _evidence(entry: RecordingEntry, r: RecordingReport, config: dict[str, Any], spec: TargetSpec) -> SourceEvidence:
    """Re-read a recording's sources: interpolation flags, long gaps and the offset's evidence."""
    ev, record, offset = SourceEvidence(), r.record, offset_used(r)
    absent = [p for p in (entry.recording, entry.audio) if p is not None and not Path(p).exists()]
    if absent:
        ev.missing.append(f"{absent[0]} is not there any more (moved or deleted)")
        return ev
    if not entry.aligned and "seconds" not in offset:
        ev.missing.append("the dataset does not record the offset it used: nothing to re-align with")
        return ev
    if record.get("sources") and source_hashes(entry) != record["sources"]:
        ev.missing.append(f"{entry.recording} or its audio changed since the build (SHA-256 differs)")
        return ev
    sr, max_gap = int(config["sample_rate"]), float(config.get("max_gap", DEFAULT_MAX_GAP))
    try:
        if entry.aligned:
            rec = AlignedRecording.load(entry.recording)
            motion, n, gaps = rec.motion, rec.n_frames, rec.gaps
            flags = rec.position_interpolated, rec.orientation_interpolated
            envelopes = audio_envelopes([rec.audio], rec.sample_rate)
            ev.expected, ev.expected_label = 0.0, "0 s: the file is aligned"
            ev.clock = "the aligned file's own clocks (0 s once aligned)"
        else:
            motion = entry.read_motion()
            reader = AudioReader(entry.audio, sr)
            ev.expected = float(offset["seconds"])
            ev.expected_label = f"offset used ({offset.get('source', '?')})"
            timeline = plan_timeline(
                motion,
                reader.n_samples,
                sr,
                ev.expected,
                fps=float(config["fps"]),
                min_coverage=float(config.get("min_coverage", DEFAULT_MIN_COVERAGE)),
                audio_name=str(entry.audio),
            )
            resampled, gaps = resample_onto(motion, timeline, max_gap)
            n, flags = timeline.n_frames, (resampled.position_interpolated, resampled.orientation_interpolated)
            envelopes = audio_envelopes(reader.blocks(), sr)
            ev.clock = "the source recording's and audio's clocks"
    except KinectDataError as exc:
        ev.missing.append(f"re-reading the sources failed: {exc}")
        return ev
    if n == record["frames"]:
        ev.interpolated, ev.gaps = _component_flags(spec, motion.joint_set, *flags), gaps
    else:
        ev.missing.append(f"the sources give {n} frames on the dataset's timeline, the dataset {record['frames']}")
    try:
        ev.estimate = estimate_offset(motion, envelopes, min_confidence=0.0)
        ev.curve = ev.estimate.curve if ev.estimate.curve is not None else xcorr_estimate(motion, envelopes, None).curve
    except KinectDataError as exc:
        ev.missing.append(f"the offset could not be re-estimated: {exc}")
    return ev


# ---------------------------------------------------------------------------------------------
# Warnings
# ---------------------------------------------------------------------------------------------
def _groups(spans: list[tuple[float, float, int]], names: list[str]) -> list[tuple[float, float, list[str]]]:
    """Spans at the same times as one (start, end, joints or limbs), by start time."""
    seen: dict[tuple[float, float], list[str]] = {}
    for start, end, c in spans:
        joint = names[c].split(".")[0]
        members = seen.setdefault((start, end), [])
        if joint not in members:
            members.append(joint)
    return [(start, end, members) for (start, end), members in seen.items()]


def _findings(r: RecordingReport, manifest: dict[str, Any]) -> list[ReportWarning]:
    """The warnings about one recording (see the module docstring)."""
    norm = Normalizer.from_dict(manifest["normalisation"])
    lo, hi = norm.bounds
    names = TargetSpec.from_dict(manifest["config"]["target"]).component_names()
    fps = float(manifest["config"]["fps"])
    max_gap = float(manifest["config"].get("max_gap", DEFAULT_MAX_GAP))
    name, split = r.record["recording"], r.record["split"]
    found = []
    beyond = count_out_of_range(r.current, r.mask, norm.bounds)
    if beyond.any():
        excess = np.where(r.mask, np.maximum(r.current - hi, lo - r.current), -np.inf).max(axis=0)
        worst = int(np.argmax(excess))
        column = r.current[r.mask[:, worst], worst]
        value = column[np.argmax(np.abs(column - (lo + hi) / 2))]
        why = "fitted on this split: check the build" if split == "train" else f"not fitted on the {split} split"
        message = (
            f"{int(beyond.sum())} target values in {int((beyond > 0).sum())} components lie outside "
            f"{lo:g}..{hi:g} (the normalisation was {why}); farthest: {names[worst]} = {value:.3f}"
        )
        found.append(ReportWarning("clipping", name, message, int(beyond.sum())))
    groups = _groups(masked_spans(r.mask, fps, max_gap), names)
    if groups:
        listed = "; ".join(f"{a:.2f}-{b:.2f} s ({', '.join(g)})" for a, b, g in groups[:6])
        more = f" and {len(groups) - 6} more" if len(groups) > 6 else ""
        message = f"{len(groups)} target span(s) masked for longer than max_gap {max_gap:g} s: {listed}{more}"
        found.append(ReportWarning("long-gap", name, message, len(groups)))
    offset = offset_used(r)
    given = offset.get("source") == "given"
    if given or float(offset.get("confidence", 1.0)) < LOW_CONFIDENCE:
        said = (
            "was given, not estimated: nothing checked it"
            if given
            else f"was estimated by {offset.get('source')} with confidence {offset.get('confidence', 0):.2f} "
            f"< {LOW_CONFIDENCE:g}"
        )
        est = r.evidence.estimate if r.evidence is not None else None
        again = "" if est is None else f"; re-estimated: {est.offset:+.3f} s ({est.method}, {est.confidence:.2f})"
        found.append(ReportWarning("offset", name, f"offset {offset.get('seconds', 0.0):+.3f} s {said}{again}"))
    share = 1.0 - float(r.mask.mean())
    if share > MASKED_WARNING:
        message = f"{100 * share:.1f}% of its target values are masked (more than {100 * MASKED_WARNING:g}%)"
        found.append(ReportWarning("masked", name, message, int((~r.mask).sum())))
    return found


@dataclass
class DatasetScan:
    """A verified dataset folder being reported on: its manifest, and per split the counts
    [valid values, values, values outside the bounds] of every record (noisy copies included),
    complete once :meth:`recordings` has been gone through."""

    root: Path
    manifest: dict[str, Any]
    sources: bool = True
    totals: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def clean_recordings(self) -> int:
        """How many recordings :meth:`recordings` yields (the noisy copies are not reported apart)."""
        return sum(1 for r in self.manifest["recordings"] if not is_copy(r))

    def recordings(self) -> Iterator[RecordingReport]:
        """Each clean recording with its evidence (when ``sources``) and its warnings."""
        spec = TargetSpec.from_dict(self.manifest["config"]["target"])
        inputs = {e["name"]: e for e in self.manifest["inputs"]}
        for r in _recordings(self.root, self.manifest, self.totals):
            name = r.record["recording"]
            if self.sources and name in inputs:
                r.evidence = _evidence(RecordingEntry(**inputs[name]), r, self.manifest["config"], spec)
            elif self.sources:
                r.evidence = SourceEvidence(missing=["the manifest's inputs do not list this recording"])
            r.warnings = _findings(r, self.manifest)
            yield r


def scan_dataset(dataset: str | Path, *, sources: bool = True) -> DatasetScan:
    """Verify a dataset folder (KinectDataError naming the damaged file) and get ready to report on it."""
    root = Path(dataset)
    return DatasetScan(root, verified_manifest(root), sources)
