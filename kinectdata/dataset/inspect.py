"""``inspect``: what a dataset or one shard holds, checked against its layout, with statistics.

A dataset folder is first checked as ``verify`` does (:func:`.verify.verify_dataset`: the manifest
against its schema, every shard against the layout, its checksum and the manifest's account of
it), a shard file against the layout; then, per split: rows, recordings, the input
features' range, mean and standard deviation, padded frames, and per target component the range,
mean and standard deviation over valid values, the share of valid values and how many lie
outside the normalisation's range, ±0.9 (0..1 for ``none``): the training split's are inside by
construction, other splits may exceed it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from kinectdata.dataset.shards import json_attribute, read_index, validate_shard
from kinectdata.dataset.verify import verified_manifest
from kinectdata.targets.normalization import Normalizer, count_out_of_range

_ROWS = 4096  # rows read at a time


@dataclass
class _Moments:
    """Streaming min, max, mean and standard deviation per column."""

    dim: int
    count: np.ndarray = field(init=False)
    total: np.ndarray = field(init=False)
    squares: np.ndarray = field(init=False)
    low: np.ndarray = field(init=False)
    high: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.count = np.zeros(self.dim)
        self.total = np.zeros(self.dim)
        self.squares = np.zeros(self.dim)
        self.low = np.full(self.dim, np.inf)
        self.high = np.full(self.dim, -np.inf)

    def add(self, x: np.ndarray, valid: np.ndarray | None = None) -> None:
        x = x.astype(np.float64)
        valid = np.ones(x.shape, bool) if valid is None else valid
        self.count += valid.sum(axis=0)
        self.total += np.where(valid, x, 0).sum(axis=0)
        self.squares += np.where(valid, x * x, 0).sum(axis=0)
        self.low = np.minimum(self.low, np.where(valid, x, np.inf).min(axis=0))
        self.high = np.maximum(self.high, np.where(valid, x, -np.inf).max(axis=0))

    def mean(self) -> np.ndarray:
        return self.total / np.maximum(self.count, 1)

    def std(self) -> np.ndarray:
        return np.sqrt(np.maximum(self.squares / np.maximum(self.count, 1) - self.mean() ** 2, 0))


@dataclass
class _SplitStats:
    rows: int = 0
    recordings: int = 0
    padded: int = 0
    inputs: _Moments | None = None
    targets: _Moments | None = None
    beyond: np.ndarray | None = None

    def add_shard(self, f: h5py.File) -> None:
        n, dim = f["current"].shape
        if self.targets is None:
            self.inputs, self.targets, self.beyond = _Moments(1), _Moments(dim), np.zeros(dim, np.int64)
        bounds = Normalizer.from_dict(json_attribute(f, "normalisation")).bounds
        self.rows += n
        self.recordings += len(read_index(f))
        self.padded += int(f["audio_padded"][()].sum())
        for s in range(0, n, _ROWS):
            x = f["input"][s : s + _ROWS].reshape(-1, 1)
            self.inputs.add(x)
            cur, mask = f["current"][s : s + _ROWS], f["mask"][s : s + _ROWS]
            self.targets.add(cur, mask)
            self.beyond += count_out_of_range(cur, mask, bounds)


def _report(name: str, st: _SplitStats, components: list[str], limit: int | None, fitted=None) -> list[str]:
    """A split's summary and per-component table; for the training split, ``fitted`` =
    (statistics, normaliser) adds the raw minimum, maximum and scale the normalisation came from."""
    lines = [f"[{name}] {st.rows} rows, {st.recordings} recordings, {st.padded} frames with padded audio"]
    if not st.rows:
        return lines
    i = st.inputs
    lines.append(f"  input    min {i.low[0]:.4f}  max {i.high[0]:.4f}  mean {i.mean()[0]:.4f}  std {i.std()[0]:.4f}")
    t = st.targets
    valid_share = t.count / st.rows
    lines.append(
        f"  current  min {_cell(np.min(t.low)).strip()}  max {_cell(np.max(t.high)).strip()}  "
        f"valid {100 * valid_share.mean():.2f}%  "
        f"out of range: {int(st.beyond.sum())} values in {int((st.beyond > 0).sum())} components"
    )
    header = f"  {'component':<22} {'min':>8} {'max':>8} {'mean':>8} {'std':>8} {'valid%':>7} {'out':>6}"
    if fitted is not None:
        header += f" {'raw min':>10} {'raw max':>10} {'scale':>10}"
    lines.append(header)
    shown = range(len(components)) if limit is None else range(min(limit, len(components)))
    for c in shown:
        values = (t.low[c], t.high[c], t.mean()[c], t.std()[c]) if t.count[c] else (np.nan,) * 4
        row = (
            f"  {components[c]:<22} {' '.join(_cell(v) for v in values)} "
            f"{100 * valid_share[c]:7.2f} {int(st.beyond[c]):6d}"
        )
        if fitted is not None:
            raw, norm = fitted
            lo, hi = raw["min"][c], raw["max"][c]
            row += (
                f" {'-' if lo is None else f'{lo:10.4f}':>10} {'-' if hi is None else f'{hi:10.4f}':>10}"
                f" {norm['scale'][c]:10.4g}"
            )
        lines.append(row)
    if limit is not None and limit < len(components):
        lines.append(f"  ... {len(components) - limit} more components (--components all)")
    return lines


def _components(spec: dict[str, Any]) -> list[str]:
    from kinectdata.targets.specs import TargetSpec

    return TargetSpec.from_dict(spec).component_names()


def inspect(path: str | Path, *, components: int | None = 12) -> str:
    """A report on a dataset folder or a shard file (raises FormatError or SchemaError, the first
    problem found, when either is damaged)."""
    path = Path(path)
    if path.is_dir():
        manifest = verified_manifest(path)
        shards = [(s["split"], path / s["file"]) for s in manifest["shards"]]
        cfg = manifest["config"]
        spec = cfg["target"]
        lines = [
            f"dataset    {path}",
            f"built by   {manifest.get('created_by')}; {manifest['totals']['rows']} rows, "
            f"{manifest['totals']['recordings']} recordings, {manifest['totals']['shards']} shards",
            f"features   input [N, {', '.join(map(str, manifest['feature_shape']))}] float32: "
            f"{_feature_line(cfg['features'])}",
            f"targets    current [N, {manifest['target_dim']}] float32: spec {spec['name']} "
            f"({len(spec['positions'])} positions, {len(spec['orientations'])} quaternions"
            + (f", {len(spec['limbs'])} limbs)" if spec.get("limbs") else ")")
            + (", root-centred" if cfg["root_centre"] else ""),
            f"normalised {_norm_line(manifest['normalisation'])}, fitted on the train split "
            f"({int(max(manifest['normalisation']['count']))} rows, augmented copies excluded)",
            f"timeline   {cfg['fps']:g} fps, audio {cfg['sample_rate']} Hz; seed {cfg['seed']}, "
            f"augmentation SNR {cfg['augment_snr'] or 'none'}, tempo {cfg.get('augment_tempo') or 'none'}",
        ]
        for s in ("train", "val", "test"):
            info = manifest["splits"].get(s, {"recordings": [], "rows": 0, "shards": []})
            lines.append(
                f"split {s:<5}  {len(info['recordings'])} recordings, {info['rows']} rows, "
                f"shards {', '.join(info['shards']) or '-'}"
            )
    else:
        validate_shard(path)
        with h5py.File(path, "r") as f:
            split = str(f.attrs["split"])
            spec = json_attribute(f, "target_spec")
            norm = json_attribute(f, "normalisation")
            feats = json_attribute(f, "features")
            n_in = f["input"].shape
        shards = [(split, path)]
        lines = [
            f"shard      {path} (layout version 1, valid)",
            f"input      {list(n_in)} float32: {_feature_line(feats)}",
            f"current    spec {spec['name']}; {_norm_line(norm)}",
        ]
    names = _components(spec)
    per_split: dict[str, _SplitStats] = {}
    for split, shard in shards:
        with h5py.File(shard, "r") as f:
            per_split.setdefault(split, _SplitStats()).add_shard(f)
    stats = None
    if path.is_dir():
        stats = manifest["normalisation_stats"], manifest["normalisation"]
    for split, st in per_split.items():
        lines += _report(split, st, names, components, stats if split == "train" else None)
    return "\n".join(lines)


def _feature_line(cfg: dict[str, Any]) -> str:
    if cfg.get("extractor") == "mel":
        return (
            f"{cfg.get('n_mels')} mel bands ({cfg.get('fmin')}-{cfg.get('fmax')} Hz), {cfg.get('n_fft')}-sample "
            f"{cfg.get('window')} window centred {cfg.get('centre_offset')} samples into each frame; dB "
            f"{cfg.get('db_range')} -> 0..1"
        )
    return (
        f"{cfg.get('n_frames')} STFT frames of {cfg.get('frame_samples')} samples, hop {cfg.get('hop_samples')}, "
        f"{cfg.get('window')} window, {cfg.get('n_fft')}-point FFT; {cfg.get('power')} power, "
        f"{cfg.get('normalisation')}"
    )


def _norm_line(norm: dict[str, Any]) -> str:
    scale = np.array(norm["scale"], float)
    return f"{norm['method']} (scale {scale.min():.4g}..{scale.max():.4g})"


def _cell(value: float) -> str:
    """A table cell of 8 characters: the value, or "-" where no value was valid (all masked)."""
    return f"{value:8.4f}" if np.isfinite(value) else f"{'-':>8}"
