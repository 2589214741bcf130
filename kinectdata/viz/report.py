"""``kinectdata report``: a dataset on one self-contained HTML page, to look at before training.

:func:`write_report` checks a dataset folder (the manifest against its schema, every shard
against the layout, its SHA-256 and the manifest's account of it) and writes one HTML file whose
figures are embedded as base64 PNG data URIs: no scripts, fonts or other files. The page holds:

- the build (key, pipeline, features, target, normalisation) and each split's recordings and rows;
- warnings, each naming its recording: clipping (normalised targets outside the normalisation's
  bounds, -0.9..0.9 or 0..1 for ``none``: the training split is inside by construction, the
  others may not be), target components masked for longer than the build's ``max_gap``, offsets
  with a confidence below :data:`LOW_CONFIDENCE` or given rather than estimated, and more than
  :data:`MASKED_WARNING` of a recording's target values masked;
- per recording: tracking quality over time, the offset and its evidence, a few seconds of the
  audio features, each target component's distribution against the bounds, and where its rows are.

The shards hold the targets, their mask, the features and the alignment summary. Interpolation
flags and the offset's correlation curve need the sources named in the manifest's ``inputs``: an
aligned ``.h5`` file (which keeps the flags), or the skeleton recording and audio, which are then
resampled onto the dataset's timeline and their offset re-estimated with
:func:`kinectdata.align.offset.estimate_offset`. That is done when the files are still where the build
found them with the same SHA-256; otherwise the page says why not. ``sources=False`` skips it.
"""

from __future__ import annotations

import base64
import html
import io
from collections.abc import Callable, Iterator
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
from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import KinectDataError
from kinectdata.core.jointsets import JointSet
from kinectdata.core.version import __version__
from kinectdata.dataset.inputs import RecordingEntry
from kinectdata.dataset.layout import SPLITS
from kinectdata.dataset.pipelines import PIPELINES
from kinectdata.dataset.prepare import source_hashes
from kinectdata.dataset.shards import read_index
from kinectdata.dataset.verify import verified_manifest
from kinectdata.features import PRESETS, MelConfig, feature_config
from kinectdata.targets.normalization import Normalizer, count_out_of_range
from kinectdata.targets.specs import TargetSpec
from kinectdata.viz import plots

LOW_CONFIDENCE = 0.8
"""Offsets estimated with less confidence than this are warned about."""
MASKED_WARNING = 0.05
"""A recording with more than this share of its target values masked is warned about."""
FEATURE_SAMPLE_S = 4.0
"""Seconds of audio features shown per recording (from its middle)."""


@dataclass(frozen=True)
class _Finding:
    """A warning at the top of the page: ``kind`` is ``clipping``, ``long-gap``, ``offset`` or
    ``masked``; ``count`` the values (clipping, masked) or spans (long-gap) concerned, 0 for offset."""

    kind: str
    recording: str
    message: str
    count: int = 0


@dataclass
class _Evidence:
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
class _Recording:
    """One recording as the shards hold it (its clean variant) and the manifest lists it."""

    record: dict[str, Any]  # the manifest's record
    info: dict[str, Any]  # the shard index's info: sources, offset, alignment summary
    current: np.ndarray  # [N, D] float32 normalised targets
    mask: np.ndarray  # [N, D] bool, True where valid
    features: np.ndarray  # [n, ...] float32: the rows of the feature sample
    sample_start: int  # frame of the sample's first row
    copies: list[dict[str, Any]] = field(default_factory=list)  # manifest records of its noisy copies
    evidence: _Evidence | None = None


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


def _union(spans: list[tuple[float, float, int]]) -> list[tuple[float, float]]:
    """The time intervals (s) covered by any of ``spans``, merged."""
    merged: list[list[float]] = []
    for start, end, _ in sorted(spans):
        if merged and start <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], end)
        else:
            merged.append([start, end])
    return [(a, b) for a, b in merged]


def _recordings(root: Path, manifest: dict[str, Any], totals: dict[str, np.ndarray]) -> Iterator[_Recording]:
    """Each clean recording's rows, shard by shard; adds every record's [valid values, values,
    values outside the bounds] (noisy copies included) to ``totals[split]``."""
    bounds = Normalizer.from_dict(manifest["normalisation"]).bounds
    fps = float(manifest["config"]["fps"])
    copies: dict[str, list[dict[str, Any]]] = {}
    for record in manifest["recordings"]:
        if record.get("snr_db") is not None:
            copies.setdefault(record["recording"], []).append(record)
    for shard in manifest["shards"]:
        listed = [r for r in manifest["recordings"] if r["shard"] == shard["file"]]
        with h5py.File(root / shard["file"], "r") as f:
            for record, row in zip(listed, read_index(f)):
                rows = slice(record["start"], record["start"] + record["frames"])
                current, mask = f["current"][rows], f["mask"][rows]
                outside = int(count_out_of_range(current, mask, bounds).sum())
                totals.setdefault(shard["split"], np.zeros(3, np.int64))[:] += (mask.sum(), mask.size, outside)
                if record.get("snr_db") is not None:
                    continue
                n = min(record["frames"], max(1, round(FEATURE_SAMPLE_S * fps)))
                k0 = (record["frames"] - n) // 2
                features = f["input"][record["start"] + k0 : record["start"] + k0 + n]
                yield _Recording(record, row["info"], current, mask, features, k0, copies.get(record["recording"], []))


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


def _offset_of(r: _Recording) -> dict[str, Any]:
    """The offset the build used: ``{"seconds", "source", "confidence", ...}`` (empty if not recorded)."""
    return r.record.get("offset") or r.info.get("offset") or {}


def _evidence(entry: RecordingEntry, r: _Recording, config: dict[str, Any], spec: TargetSpec) -> _Evidence:
    """Re-read a recording's sources: interpolation flags, long gaps and the offset's evidence."""
    ev, record, offset = _Evidence(), r.record, _offset_of(r)
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


def _findings(r: _Recording, manifest: dict[str, Any]) -> list[_Finding]:
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
        found.append(_Finding("clipping", name, message, int(beyond.sum())))
    groups = _groups(masked_spans(r.mask, fps, max_gap), names)
    if groups:
        listed = "; ".join(f"{a:.2f}-{b:.2f} s ({', '.join(g)})" for a, b, g in groups[:6])
        more = f" and {len(groups) - 6} more" if len(groups) > 6 else ""
        message = f"{len(groups)} target span(s) masked for longer than max_gap {max_gap:g} s: {listed}{more}"
        found.append(_Finding("long-gap", name, message, len(groups)))
    offset = _offset_of(r)
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
        found.append(_Finding("offset", name, f"offset {offset.get('seconds', 0.0):+.3f} s {said}{again}"))
    share = 1.0 - float(r.mask.mean())
    if share > MASKED_WARNING:
        message = f"{100 * share:.1f}% of its target values are masked (more than {100 * MASKED_WARNING:g}%)"
        found.append(_Finding("masked", name, message, int((~r.mask).sum())))
    return found


# ---------------------------------------------------------------------------------------------
# The page
# ---------------------------------------------------------------------------------------------
_CSS = """
body { font-family: sans-serif; margin: 2em auto; max-width: 72em; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0; } td, th { border: 1px solid #ccc; padding: 2px 8px; }
th { background: #f0f0f0; text-align: left; } td.n { text-align: right; }
.warning { color: #8a1f11; } .note { color: #555; font-style: italic; }
figure { margin: 0.5em 0; } img { max-width: 100%; } section.recording { border-top: 2px solid #888; }
"""


def _e(value: Any) -> str:
    return html.escape(str(value), quote=True)


def _png(draw: Callable[..., Any], *args: Any, **kwargs: Any) -> str:
    """A data URI of the PNG that ``draw(*args, out, **kwargs)`` writes into a stream."""
    buffer = io.BytesIO()
    draw(*args, buffer, **kwargs)
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


def _figure(uri: str, caption: str) -> str:
    return f'<figure><img src="{uri}" alt="{_e(caption)}"><figcaption>{_e(caption)}</figcaption></figure>'


def _table(rows: list[tuple[Any, ...]], header: tuple[str, ...] | None = None, *, attrs: str = "") -> str:
    """An HTML table; numbers right-aligned; ``attrs`` go into the opening tag as they are."""
    head = "" if header is None else "<tr>" + "".join(f"<th>{_e(h)}</th>" for h in header) + "</tr>"
    body = "".join(
        "<tr>"
        + "".join(f'<td class="n">{_e(v)}</td>' if isinstance(v, (int, float)) else f"<td>{_e(v)}</td>" for v in row)
        + "</tr>"
        for row in rows
    )
    return f"<table {attrs}>{head}{body}</table>"


def _pipeline(config: dict[str, Any]) -> tuple[str, str]:
    """(pipeline name or "custom", feature preset name or "custom") of a build configuration."""
    features = feature_config(config["features"]).to_dict()
    preset = next((n for n, p in PRESETS.items() if p.to_dict() == features), "custom")
    chosen = (preset, config["target"]["name"], config["normalisation"])
    pipeline = next(
        (n for n, p in PIPELINES.items() if (p["features"], p["target"], p["normalisation"]) == chosen), "custom"
    )
    return pipeline, preset


def _summary(root: Path, manifest: dict[str, Any], totals: dict[str, np.ndarray]) -> str:
    """The build and the splits' table; ``totals`` [valid values, values, values outside the bounds] per split."""
    cfg = manifest["config"]
    norm = Normalizer.from_dict(manifest["normalisation"])
    pipeline, preset = _pipeline(cfg)
    spec = cfg["target"]
    facts = [
        ("dataset", str(root.resolve())),
        ("build key", manifest["build_key"]),
        ("built by", manifest.get("created_by", "?")),
        ("pipeline", pipeline),
        ("features", f"{preset}: input [N, {', '.join(map(str, manifest['feature_shape']))}] float32"),
        ("target", f"{spec['name']} ({spec['joint_set']}): current [N, {manifest['target_dim']}]"),
        (
            "normalisation",
            f"{norm.method}, bounds {norm.bounds[0]:g}..{norm.bounds[1]:g}, fitted on the train split "
            f"({int(norm.count.max(initial=0))} rows, noisy copies excluded)",
        ),
        (
            "timeline",
            f"{cfg['fps']:g} fps, audio {cfg['sample_rate']} Hz; max_gap {cfg.get('max_gap', DEFAULT_MAX_GAP):g} s",
        ),
    ]
    rows = []
    for s in SPLITS:
        info = manifest["splits"].get(s, {"recordings": [], "rows": 0, "shards": []})
        copies = sum(1 for r in manifest["recordings"] if r["split"] == s and r.get("snr_db") is not None)
        valid, values, outside = (int(v) for v in totals.get(s, (0, 0, 0)))
        share = f"{100 * valid / values:.2f}" if values else "-"
        rows.append(
            (s, len(info["recordings"]), info["rows"], copies, ", ".join(info["shards"]) or "-", share, outside)
        )
    header = ("split", "recordings", "rows", "noisy copies", "shards", "valid target values (%)", "outside bounds")
    return (
        '<section id="summary"><h2>Dataset</h2>'
        + _table(facts, attrs='class="facts"')
        + "<h3>Splits</h3>"
        + _table(rows, header, attrs='id="splits"')
        + "</section>"
    )


def _warnings(found: list[_Finding]) -> str:
    if not found:
        return '<section id="warnings"><h2>Warnings</h2><p>No warnings.</p></section>'
    items = "".join(
        f'<li class="warning" data-kind="{_e(w.kind)}" data-recording="{_e(w.recording)}" data-count="{w.count}">'
        f'<b>{_e(w.kind)}</b> <a href="#rec-{_e(w.recording)}">{_e(w.recording)}</a>: {_e(w.message)}</li>'
        for w in found
    )
    return f'<section id="warnings"><h2>Warnings ({len(found)})</h2><ul>{items}</ul></section>'


def _yes(flag: bool) -> str:
    return "yes" if flag else ""


def _tracking(r: _Recording, fps: float, max_gap: float, joints: dict[str, set[str]]) -> str:
    """The tracking-quality figure and facts; ``joints``: per quantity (position, orientation) the
    joints the target is computed from."""
    ev, summary = r.evidence, r.info.get("alignment", {})
    spans = _union(masked_spans(r.mask, fps, max_gap))
    interpolated = None if ev is None or ev.interpolated is None else ev.interpolated.mean(axis=1)
    uri = _png(
        plots.tracking_quality,
        r.mask.mean(axis=1),
        fps,
        interpolated_share=interpolated,
        spans=spans,
        title=f"{r.record['recording']}: valid target components per frame",
    )
    if interpolated is not None:
        note = "Interpolated values: from the sources, resampled as the build did."
    else:
        why = "; ".join(ev.missing) if ev is not None and ev.missing else "sources not read (--no-sources)"
        note = (
            "Interpolated values are not marked: the shards keep only the mask, the flags live in aligned "
            f"files and the sources ({why})."
        )
    facts = [
        ("target values masked", f"{100 * (1 - r.mask.mean()):.2f}%"),
        ("spans masked longer than max_gap", len(spans)),
        ("alignment: joint positions interpolated", f"{100 * summary.get('interpolated_share', 0):.2f}%"),
        ("alignment: joint positions masked", f"{100 * summary.get('masked_share', 0):.2f}%"),
        ("alignment: gaps longer than max_gap (any joint)", summary.get("long_gaps", "-")),
    ]
    gaps = ""
    if ev is not None and ev.gaps:
        rows = [
            (
                g["joint"],
                g["quantity"],
                g["start_s"],
                g["end_s"],
                g["length_s"],
                _yes(g["edge"]),
                _yes(g["joint"] in joints.get(g["quantity"], ())),
            )
            for g in sorted(ev.gaps, key=lambda g: (g["start_s"], g["joint"], g["quantity"]))
        ]
        more = f" (the first 20 of {len(rows)})" if len(rows) > 20 else ""
        gaps = f"<p>Gaps longer than max_gap in the sources{more}, seconds on the dataset clock:</p>" + _table(
            rows[:20], ("joint", "quantity", "start", "end", "length", "at an edge", "in the target")
        )
    return _figure(uri, "Tracking quality over time") + f'<p class="note">{_e(note)}</p>' + _table(facts) + gaps


def _offset(r: _Recording) -> str:
    offset = _offset_of(r)
    rows = [
        ("offset (audio_time = motion_time + offset)", f"{offset.get('seconds', float('nan')):+.4f} s"),
        ("source", offset.get("source", "?")),
        ("confidence", f"{offset.get('confidence', float('nan')):.2f}"),
    ]
    rows += [
        (f"candidate {i + 1}", f"{o:+.4f} s (score {s:.3f})") for i, (o, s) in enumerate(offset.get("candidates", []))
    ]
    parts = [_table(rows)]
    ev = r.evidence
    if ev is None:
        parts.append('<p class="note">Correlation curve not computed: sources not read (--no-sources).</p>')
        return "".join(parts)
    est = ev.estimate
    if est is not None:
        parts.append(
            f"<p>Re-estimated on {_e(ev.clock)}: {est.offset:+.4f} s by {_e(est.method)}, confidence "
            f"{est.confidence:.2f}; candidates "
            + _e(", ".join(f"{o:+.3f} s ({s:.3f})" for o, s in est.candidates[:5]))
            + "</p>"
        )
    if ev.curve is not None:
        markers = [(ev.expected, ev.expected_label)]
        markers += [
            (o, f"{est.method} candidate {i + 1}")
            for i, (o, _) in enumerate(est.candidates[:3])
            if abs(o - ev.expected) > 0.01  # one lag step of the curve: the same offset as the one used
        ]
        uri = _png(plots.offset_curve, *ev.curve, markers=markers, title=f"{r.record['recording']}: offset evidence")
        parts.append(_figure(uri, "Cross-correlation of the audio onsets with the motion energy against the offset"))
    for why in ev.missing:
        parts.append(f'<p class="note">{_e(why)}</p>')
    return "".join(parts)


def _features(r: _Recording, manifest: dict[str, Any]) -> str:
    cfg = feature_config(manifest["config"]["features"])
    fps = float(manifest["config"]["fps"])
    start, end = r.sample_start / fps, (r.sample_start + r.features.shape[0]) / fps
    if isinstance(cfg, MelConfig):
        values = r.features.reshape(r.features.shape[0], -1).T  # [bands, frames]
        y_extent, ylabel = (0.0, float(values.shape[0])), f"mel band ({cfg.fmin:g}-{cfg.fmax:g} Hz)"
        note = "One column per frame."
    else:
        # [n, 1, bins, S] -> [bins, n * S]: each frame's S STFT frames side by side
        values = np.moveaxis(r.features[:, 0], 0, 1).reshape(r.features.shape[2], -1)
        y_extent, ylabel = (0.0, cfg.sample_rate / 2), "frequency (Hz)"
        note = f"Each frame's {cfg.n_frames} STFT frames side by side (hop {cfg.hop_samples} samples)."
    uri = _png(
        plots.feature_heatmap,
        values,
        start,
        end,
        y_extent=y_extent,
        ylabel=ylabel,
        colorbar_label="feature value (as in the shard)",
        title=f"{r.record['recording']}: audio features, {start:.1f}-{end:.1f} s",
    )
    return _figure(uri, f"Audio features, frames {r.sample_start}-{r.sample_start + r.features.shape[0] - 1}") + (
        f'<p class="note">{_e(note)}</p>'
    )


def _distributions(r: _Recording, norm: Normalizer, names: list[str]) -> str:
    values = [r.current[r.mask[:, c], c] for c in range(r.current.shape[1])]
    uri = _png(
        plots.target_distributions,
        values,
        names,
        norm.bounds,
        title=f"{r.record['recording']} ({r.record['split']}): normalised targets, {norm.method}",
    )
    return _figure(uri, "Target value distributions per component (red: some values outside the bounds)")


def _where(r: _Recording, entry: dict[str, Any] | None) -> str:
    rec = r.record
    rows = [
        ("split", rec["split"]),
        ("shard", rec["shard"]),
        ("rows", f"{rec['start']}..{rec['start'] + rec['frames'] - 1} ({rec['frames']} frames)"),
    ]
    rows += [
        (f"noisy copy {c['name']}", f"{c['shard']} rows {c['start']}..{c['start'] + c['frames'] - 1}") for c in r.copies
    ]
    if entry is not None:
        rows += [("recording", entry["recording"])] + ([("audio", entry["audio"])] if entry.get("audio") else [])
    if rec.get("flipped_orientations"):
        rows.append(("quaternions negated", ", ".join(rec["flipped_orientations"])))
    return _table(rows)


def _section(r: _Recording, manifest: dict[str, Any], found: list[_Finding]) -> str:
    cfg = manifest["config"]
    norm = Normalizer.from_dict(manifest["normalisation"])
    spec = TargetSpec.from_dict(cfg["target"])
    names = spec.component_names()
    joints = {
        "position": {*spec.positions, *(j for pair in spec.limb_pairs() for j in pair)},
        "orientation": set(spec.orientations),
    }
    name = r.record["recording"]
    entry = next((e for e in manifest["inputs"] if e["name"] == name), None)
    flagged = "".join(f'<li class="warning">{_e(w.kind)}: {_e(w.message)}</li>' for w in found)
    fps, max_gap = float(cfg["fps"]), float(cfg.get("max_gap", DEFAULT_MAX_GAP))
    return (
        f'<section class="recording" id="rec-{_e(name)}"><h2>{_e(name)}</h2>'
        + (f"<ul>{flagged}</ul>" if flagged else "")
        + "<h3>Where it is</h3>"
        + _where(r, entry)
        + "<h3>Tracking quality</h3>"
        + _tracking(r, fps, max_gap, joints)
        + "<h3>Offset</h3>"
        + _offset(r)
        + "<h3>Audio features</h3>"
        + _features(r, manifest)
        + "<h3>Targets</h3>"
        + _distributions(r, norm, names)
        + "</section>"
    )


def write_report(
    dataset: str | Path,
    out: str | Path,
    *,
    sources: bool = True,
    progress: Callable[[int, int], None] | None = None,
) -> Path:
    """Write the HTML report of a dataset folder (atomically); returns its path.

    Args:
        dataset: a folder written by :func:`kinectdata.dataset.build.build_dataset`.
        out: the ``.html`` (or ``.htm``) file to write.
        sources: re-read each recording's sources, when unchanged, for interpolation flags and the
            offset's correlation curve.
        progress: called as ``progress(done, total)`` after each recording.

    Raises:
        KinectDataError: the output is not an HTML file name, or the dataset is missing or damaged
            (the message names the file); nothing is written then.
    """
    root, out = Path(dataset), Path(out)
    if out.suffix.lower() not in (".html", ".htm"):
        raise KinectDataError(f"{out}: the report is an HTML page; name it *.html")
    manifest = verified_manifest(root)  # the checks of kinectdata verify: schema, checksums, layouts, indexes
    spec = TargetSpec.from_dict(manifest["config"]["target"])
    inputs = {e["name"]: e for e in manifest["inputs"]}
    total = sum(1 for r in manifest["recordings"] if r.get("snr_db") is None)
    totals: dict[str, np.ndarray] = {}
    found: list[_Finding] = []
    sections, contents = [], []
    for r in _recordings(root, manifest, totals):
        name = r.record["recording"]
        if sources and name in inputs:
            r.evidence = _evidence(RecordingEntry(**inputs[name]), r, manifest["config"], spec)
        elif sources:
            r.evidence = _Evidence(missing=["the manifest's inputs do not list this recording"])
        mine = _findings(r, manifest)
        found += mine
        sections.append(_section(r, manifest, mine))
        contents.append(f'<li><a href="#rec-{_e(name)}">{_e(name)}</a> ({_e(r.record["split"])})</li>')
        if progress:
            progress(len(sections), total)
    page = (
        f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>Dataset report: {_e(root.name)}</title>'
        f"<style>{_CSS}</style></head><body><h1>Dataset report: {_e(root.name)}</h1>"
        f'<p class="note">Written by kinectdata {_e(__version__)}. Times are on the dataset clock: frame k at k / fps '
        "seconds.</p>"
        + _summary(root, manifest, totals)
        + _warnings(found)
        + f'<nav id="contents"><h2>Recordings ({len(sections)})</h2><ul>{"".join(contents)}</ul></nav>'
        + "".join(sections)
        + "</body></html>\n"
    )
    with atomic_output(out) as tmp:
        tmp.write_text(page, encoding="utf-8")
    return out
