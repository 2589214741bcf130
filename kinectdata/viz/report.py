"""``kinectdata report``: a dataset on one self-contained HTML page, to look at before training.

:func:`write_report` draws what :mod:`kinectdata.dataset.report` finds (the checks of ``kinectdata
verify``, then per recording its rows, evidence and warnings) as one HTML file whose figures are
embedded as base64 PNG data URIs: no scripts, fonts or other files. The page holds:

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
import io
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
from markupsafe import Markup

from kinectdata.align.recipe import DEFAULT_MAX_GAP
from kinectdata.core.atomic import atomic_output
from kinectdata.core.errors import KinectDataError
from kinectdata.core.version import __version__
from kinectdata.dataset.layout import SPLITS, is_copy
from kinectdata.dataset.pipelines import PIPELINES
from kinectdata.dataset.report import (
    LOW_CONFIDENCE,
    MASKED_WARNING,
    RecordingReport,
    ReportWarning,
    masked_spans,
    offset_used,
    scan_dataset,
    span_union,
)
from kinectdata.features import PRESETS, MelConfig, StackConfig, StftConfig, feature_config
from kinectdata.targets.normalization import Normalizer
from kinectdata.targets.specs import TargetSpec
from kinectdata.viz import plots

__all__ = ["LOW_CONFIDENCE", "MASKED_WARNING", "masked_spans", "write_report"]


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


def _png(draw: Callable[..., Any], *args: Any, **kwargs: Any) -> str:
    """A data URI of the PNG that ``draw(*args, out, **kwargs)`` writes into a stream."""
    buffer = io.BytesIO()
    draw(*args, buffer, **kwargs)
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


@cache
def _template(name: str = "report.html.j2"):
    """One of the page's Jinja2 templates (``templates/``, shipped with the package), autoescaped:
    ``report.html.j2`` the page, ``report_parts.html.j2`` its macros (a recording's section...)."""
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.PackageLoader("kinectdata.viz", "templates"),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
        keep_trailing_newline=True,
    )
    return env.get_template(name)


def _pipeline(config: dict[str, Any]) -> tuple[str, str]:
    """(pipeline name or "custom", feature preset name or "custom") of a build configuration."""
    features = feature_config(config["features"]).to_dict()
    preset = next((n for n, p in PRESETS.items() if p.to_dict() == features), "custom")
    chosen = (preset, config["target"]["name"], config["normalisation"])
    pipeline = next(
        (n for n, p in PIPELINES.items() if (p["features"], p["target"], p["normalisation"]) == chosen), "custom"
    )
    return pipeline, preset


def _summary(root: Path, manifest: dict[str, Any], totals: dict[str, np.ndarray]) -> dict[str, Any]:
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
            f"({int(norm.count.max(initial=0))} rows, augmented copies excluded)",
        ),
        (
            "timeline",
            f"{cfg['fps']:g} fps, audio {cfg['sample_rate']} Hz; max_gap {cfg.get('max_gap', DEFAULT_MAX_GAP):g} s",
        ),
    ]
    rows = []
    for s in SPLITS:
        info = manifest["splits"].get(s, {"recordings": [], "rows": 0, "shards": []})
        copies = sum(1 for r in manifest["recordings"] if r["split"] == s and is_copy(r))
        valid, values, outside = (int(v) for v in totals.get(s, (0, 0, 0)))
        share = f"{100 * valid / values:.2f}" if values else "-"
        rows.append(
            (s, len(info["recordings"]), info["rows"], copies, ", ".join(info["shards"]) or "-", share, outside)
        )
    header = ("split", "recordings", "rows", "augmented copies", "shards", "valid target values (%)", "outside bounds")
    return {"facts": facts, "splits": rows, "header": header}


def _yes(flag: bool) -> str:
    return "yes" if flag else ""


def _tracking(r: RecordingReport, fps: float, max_gap: float, joints: dict[str, set[str]]) -> dict[str, Any]:
    """The tracking-quality figure and facts; ``joints``: per quantity (position, orientation) the
    joints the target is computed from."""
    ev, summary = r.evidence, r.info.get("alignment", {})
    spans = span_union(masked_spans(r.mask, fps, max_gap))
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
    gaps, more = [], ""
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
        gaps = rows[:20]
    return {"uri": uri, "note": note, "facts": facts, "gaps": gaps, "more": more}


def _offset(r: RecordingReport) -> dict[str, Any]:
    offset = offset_used(r)
    rows = [
        ("offset (audio_time = motion_time + offset)", f"{offset.get('seconds', float('nan')):+.4f} s"),
        ("source", offset.get("source", "?")),
        ("confidence", f"{offset.get('confidence', float('nan')):.2f}"),
    ]
    rows += [
        (f"candidate {i + 1}", f"{o:+.4f} s (score {s:.3f})") for i, (o, s) in enumerate(offset.get("candidates", []))
    ]
    ev = r.evidence
    if ev is None:
        return {"rows": rows, "read": False}
    found: dict[str, Any] = {"rows": rows, "read": True, "estimate": "", "uri": None, "missing": ev.missing}
    est = ev.estimate
    if est is not None:
        found["estimate"] = (
            f"Re-estimated on {ev.clock}: {est.offset:+.4f} s by {est.method}, confidence {est.confidence:.2f}; "
            "candidates " + ", ".join(f"{o:+.3f} s ({s:.3f})" for o, s in est.candidates[:5])
        )
    if ev.curve is not None:
        markers = [(ev.expected, ev.expected_label)]
        markers += [
            (o, f"{est.method} candidate {i + 1}")
            for i, (o, _) in enumerate(est.candidates[:3])
            if abs(o - ev.expected) > 0.01  # one lag step of the curve: the same offset as the one used
        ]
        title = f"{r.record['recording']}: offset evidence"
        found["uri"] = _png(plots.offset_curve, *ev.curve, markers=markers, title=title)
    return found


def _features(r: RecordingReport, manifest: dict[str, Any]) -> dict[str, Any]:
    cfg = feature_config(manifest["config"]["features"])
    fps = float(manifest["config"]["fps"])
    features, after = r.features, ""
    if isinstance(cfg, StackConfig):  # a spectrum with the music's pulse stacked on: the spectrum is drawn
        cfg, features = cfg.parts[0], features[:, : cfg.parts[0].output_shape[0]]
        after = " The pulse stacked after the spectrum is not drawn."
    start, end = r.sample_start / fps, (r.sample_start + features.shape[0]) / fps
    if isinstance(cfg, MelConfig):
        values = features.reshape(features.shape[0], -1).T  # [bands, frames]
        y_extent, ylabel = (0.0, float(values.shape[0])), f"mel band ({cfg.fmin:g}-{cfg.fmax:g} Hz)"
        note = "One column per frame."
    elif isinstance(cfg, StftConfig):
        # [n, 1, bins, S] -> [bins, n * S]: each frame's S STFT frames side by side
        values = np.moveaxis(features[:, 0], 0, 1).reshape(features.shape[2], -1)
        y_extent, ylabel = (0.0, cfg.sample_rate / 2), "frequency (Hz)"
        note = f"Each frame's {cfg.n_frames} STFT frames side by side (hop {cfg.hop_samples} samples)."
    else:  # another extractor's values, as stored
        values = features.reshape(features.shape[0], -1).T
        y_extent, ylabel = (0.0, float(values.shape[0])), "feature value index"
        note = "One column per frame."
    note += after
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
    caption = f"Audio features, frames {r.sample_start}-{r.sample_start + r.features.shape[0] - 1}"
    return {"uri": uri, "caption": caption, "note": note}


def _distributions(r: RecordingReport, norm: Normalizer, names: list[str]) -> str:
    values = [r.current[r.mask[:, c], c] for c in range(r.current.shape[1])]
    uri = _png(
        plots.target_distributions,
        values,
        names,
        norm.bounds,
        title=f"{r.record['recording']} ({r.record['split']}): normalised targets, {norm.method}",
    )
    return uri


def _where(r: RecordingReport, entry: dict[str, Any] | None) -> list[tuple[str, Any]]:
    rec = r.record
    rows = [
        ("split", rec["split"]),
        ("shard", rec["shard"]),
        ("rows", f"{rec['start']}..{rec['start'] + rec['frames'] - 1} ({rec['frames']} frames)"),
    ]
    for c in r.copies:
        kind = "tempo" if c.get("tempo") is not None else "noisy"
        rows.append((f"{kind} copy {c['name']}", f"{c['shard']} rows {c['start']}..{c['start'] + c['frames'] - 1}"))
    if entry is not None:
        rows += [("recording", entry["recording"])] + ([("audio", entry["audio"])] if entry.get("audio") else [])
    if rec.get("flipped_orientations"):
        rows.append(("quaternions negated", ", ".join(rec["flipped_orientations"])))
    return rows


def _section(r: RecordingReport, manifest: dict[str, Any], found: list[ReportWarning]) -> str:
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
    fps, max_gap = float(cfg["fps"]), float(cfg.get("max_gap", DEFAULT_MAX_GAP))
    data = {
        "name": name,
        "warnings": found,
        "where": _where(r, entry),
        "tracking": _tracking(r, fps, max_gap, joints),
        "offset": _offset(r),
        "features": _features(r, manifest),
        "targets_uri": _distributions(r, norm, names),
    }
    return str(_template("report_parts.html.j2").module.recording(data))


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
    scan = scan_dataset(root, sources=sources)
    manifest, total = scan.manifest, scan.clean_recordings
    found: list[ReportWarning] = []
    sections = []
    for r in scan.recordings():
        found += r.warnings
        html = Markup(_section(r, manifest, r.warnings))  # rendered (and escaped) by the template's macro
        sections.append({"name": r.record["recording"], "split": r.record["split"], "html": html})
        if progress:
            progress(len(sections), total)
    page = _template().render(
        name=root.name,
        css=Markup(_CSS),
        version=__version__,
        summary=_summary(root, manifest, scan.totals),
        warnings=found,
        sections=sections,
    )
    with atomic_output(out) as tmp:
        tmp.write_text(page, encoding="utf-8")
    return out
