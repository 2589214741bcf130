"""One recording's share of a dataset build: aligned targets and per-frame features, streamed.

For a recording (a skeleton file with its audio, or an aligned ``.h5``) :func:`prepare_recording`
aligns the motion onto the frame grid, extracts the raw (unnormalised) target vectors and their
normalisation statistics, and computes the audio features of every *variant* (the clean audio
and, for training recordings, copies with white noise at given SNRs) in one pass over the audio,
which is streamed in blocks: memory does not grow with the recording's length. Each variant goes
to its own work file, written atomically and named by a key that hashes everything it depends
on, so an interrupted build resumes by skipping the work files already there.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import tempfile
import zlib
from collections.abc import Callable, Iterable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from kinectdata.align.aligned import AlignedRecording, audio_blocks
from kinectdata.align.audio import AudioReader
from kinectdata.align.envelopes import audio_envelopes
from kinectdata.align.recipe import plan_timeline, resample_onto, resolve_offset, summarize
from kinectdata.core.atomic import atomic_hdf5, write_failure
from kinectdata.core.errors import KinectDataError
from kinectdata.core.hashing import file_sha256
from kinectdata.core.motion import Motion
from kinectdata.dataset.config import BuildConfig
from kinectdata.dataset.inputs import RecordingEntry
from kinectdata.features import FeatureConfig, needs_metre, needs_style, song_style
from kinectdata.features.metre import Metre, recording_metre
from kinectdata.features.streaming import StreamingFeatures
from kinectdata.features.style_input import NO_STYLE
from kinectdata.targets.hemispheres import orientation_stats
from kinectdata.targets.normalization import NormStats
from kinectdata.targets.skeleton import bone_offsets
from kinectdata.targets.specs import GenericTarget, extract_targets, root_anchor

WORK_FORMAT = "kinectdata.work.4"  # 2: units carry orientation statistics; 3: and bone offsets; 4: and the target
_BLOCK = 160_000  # samples per block when streaming in-memory audio (10 s at 16 kHz)


@dataclass
class Unit:
    """A prepared recording variant: its work file and what the builder needs to know of it."""

    name: str  # unique in the dataset, e.g. "synth_001" or "synth_001~snr10dB"
    recording: str  # the recording's name
    snr_db: float | None
    file: str
    key: str
    frames: int
    stats: dict[str, Any]
    orientations: dict[str, Any]  # hemispheres.orientation_stats of the targets
    info: dict[str, Any] = field(default_factory=dict)
    skeleton: dict[str, Any] = field(default_factory=dict)  # kinectdata.targets.skeleton.bone_offsets of the motion
    target: dict[str, Any] = field(default_factory=dict)  # the TargetSpec.to_dict() its targets follow
    tempo: float | None = None  # a stretched copy's tempo factor (BuildConfig.augment_tempo)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def variant_name(recording: str, snr_db: float | None, tempo: float | None = None) -> str:
    if tempo is not None:
        return f"{recording}~tempo{tempo:g}"
    return recording if snr_db is None else f"{recording}~snr{snr_db:g}dB"


def unit_key(
    entry: RecordingEntry,
    hashes: dict[str, str],
    config: BuildConfig,
    snr_db: float | None,
    tempo: float | None = None,
    *,
    style: str | None = None,
) -> str:
    """A work file's key: the recording's name, options and contents (not its paths), the
    configuration it depends on, the SNR, the tempo factor and the style it was told."""
    doc = {
        "entry": entry.options(),
        "sources": hashes,
        "config": config.unit_config(snr_db is not None),
        "snr_db": snr_db,
        **({"tempo": tempo} if tempo is not None else {}),
        **({"tempo_pitch": "kept"} if tempo is not None and config.tempo_pitch == "kept" else {}),
    }
    cleaning = cleaning_for(entry, config)
    if cleaning is not None:  # every setting, so that a default changed since is not taken for the old one
        from kinectdata.cleaning import CleanConfig

        doc["cleaning"] = CleanConfig.from_settings(cleaning, f"{entry.recording}: clean").resolved()
    if needs_metre(config.feature_config):  # the features count the song's bars
        doc["beats_per_bar"] = entry.beats_per_bar
    if needs_style(config.feature_config):  # told (a training song), else heard with the classifier in "config"
        doc["style"] = style
    return hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()[:32]


def cleaning_for(entry: RecordingEntry, config: BuildConfig) -> dict[str, Any] | None:
    """The cleaning settings a recording is built with (its manifest entry's ``clean`` if it says,
    else the build's ``clean``), None for none."""
    if entry.clean is None:
        return config.clean
    if isinstance(entry.clean, bool):
        return {} if entry.clean else None
    return entry.clean


def cleaned_for_build(motion: Motion, entry: RecordingEntry, config: BuildConfig) -> Motion:
    """The recording cleaned as :func:`cleaning_for` says (as it is, when it says none)."""
    settings = cleaning_for(entry, config)
    if settings is None:
        return motion
    from kinectdata.cleaning import CleanConfig, clean_motion

    return clean_motion(motion, CleanConfig.from_settings(settings, f"{entry.recording}: clean")).motion


def _read_unit(path: Path) -> Unit | None:
    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("format") != WORK_FORMAT:
                return None
            return Unit(**json.loads(f.attrs["unit"]))
    except (OSError, KeyError, ValueError, TypeError):
        return None  # damaged or foreign: recomputed


@contextmanager
def _scratch(work_dir: Path, name: str) -> Iterator[Path]:
    """A new temporary file ``work_dir/.NAME.XXXX.partial``, removed at the end whatever happens.

    Its name is unique, so a worker orphaned by a killed build never shares it with a rerun."""
    fd, path = tempfile.mkstemp(prefix=f".{name}.", suffix=".partial", dir=work_dir)
    os.close(fd)
    try:
        yield Path(path)
    finally:
        Path(path).unlink(missing_ok=True)


@contextmanager
def _writing(path: Path) -> Iterator[None]:
    """Writes to ``path`` inside: a full disk raises a KinectDataError naming ``path``."""
    try:
        yield
    except OSError as exc:
        failure = write_failure(path, exc)
        if failure is None:
            raise
        raise failure from exc


def _tee(blocks: Iterable[np.ndarray], path: Path) -> Iterator[np.ndarray]:
    """Pass blocks through while appending them to ``path`` as raw float32; a full disk raises a
    KinectDataError naming ``path``."""
    with _writing(path), open(path, "wb") as f:
        for block in blocks:
            f.write(np.asarray(block, np.float32).tobytes())
            yield block


def _raw_blocks(path: Path, block: int = _BLOCK) -> Iterator[np.ndarray]:
    with open(path, "rb") as f:
        while (chunk := np.fromfile(f, dtype=np.float32, count=block)).size:
            yield chunk


@dataclass(frozen=True)
class _PlayedAudio:
    """Audio already decoded to a raw float32 file (``n_samples`` at the build's rate), read as an
    :class:`~kinectdata.align.audio.AudioReader` is."""

    path: Path
    n_samples: int

    def blocks(self) -> Iterator[np.ndarray]:
        return _raw_blocks(self.path)


def _stretched(reader: AudioReader, tempo: float, sample_rate: int, path: Path) -> _PlayedAudio:
    """``reader``'s song played ``tempo`` times as fast with its pitch kept
    (:func:`~kinectdata.align.stretch.stretch_audio`), written to ``path`` as raw float32."""
    from kinectdata.align.stretch import stretch_audio

    song = np.concatenate([np.zeros(0, np.float32), *reader.blocks()])
    played = stretch_audio(song, tempo, sample_rate)
    with _writing(path):
        played.astype(np.float32).tofile(path)
    return _PlayedAudio(path, int(played.size))


def _features_metre(
    entry: RecordingEntry, features: FeatureConfig, song: Callable[[], np.ndarray], sample_rate: int
) -> Metre | None:
    """The song's metre when the features count its bars (None otherwise): the entry's
    ``beats_per_bar``, else estimated from the whole of its audio (``song()``), else 4."""
    if not needs_metre(features):
        return None
    if entry.beats_per_bar is not None:
        return recording_metre(entry.beats_per_bar, None, sample_rate)
    return recording_metre(None, song(), sample_rate)


def _mean_square(blocks: Iterable[np.ndarray]) -> float:
    total, n = 0.0, 0
    for b in blocks:
        b = b.astype(np.float64)
        total, n = total + float(np.dot(b, b)), n + b.size
    return total / max(n, 1)


def source_hashes(entry: RecordingEntry) -> dict[str, str]:
    """SHA-256 of a recording's files by file name: the recording (a file or an OpenPose folder), its
    audio, and the schema or rest-joints file it is read with (an edited one changes what is read)."""
    hashes = {Path(entry.recording).name: file_sha256(entry.recording)}
    for p in (entry.audio, entry.schema, entry.rest_joints):
        if p is not None and Path(p).is_file():
            hashes[Path(p).name] = file_sha256(p)
    return hashes


def prepare_recording(
    entry: RecordingEntry,
    config: BuildConfig,
    work_dir: str | Path,
    snrs: tuple[float, ...] = (),
    hashes: dict[str, str] | None = None,
    tempos: tuple[float, ...] = (),
    style: str | None = None,
) -> list[Unit]:
    """Prepare a recording's variants (clean, then one per SNR, then one per tempo factor) into
    ``work_dir``; skips finished ones.

    ``hashes`` are the recording's :func:`source_hashes`, when the caller has them already.
    ``style``: the song's dance style for features that hear it (a training recording's; None:
    heard from its music by the features' classifier).
    Returns the :class:`Unit` of each variant, clean first.
    """
    work_dir = Path(work_dir)
    variants: list[float | None] = [None, *snrs]
    hashes = source_hashes(entry) if hashes is None else hashes
    keys = {v: unit_key(entry, hashes, config, v, style=style) for v in variants}
    done = {v: _read_unit(work_dir / f"{variant_name(entry.name, v)}.h5") for v in variants}
    if all(u is not None and u.key == keys[v] for v, u in done.items()):
        units = [done[v] for v in variants]
    else:
        with ExitStack() as scratch:
            made = _prepare_variants(entry, config, work_dir, keys, hashes, scratch, style=style)
        units = [made[v] for v in variants]
    for tempo in tempos:
        key = unit_key(entry, hashes, config, None, tempo, style=style)
        unit = _read_unit(work_dir / f"{variant_name(entry.name, None, tempo)}.h5")
        if unit is None or unit.key != key:
            with ExitStack() as scratch:
                unit = _prepare_variants(entry, config, work_dir, {None: key}, hashes, scratch, tempo, style)[None]
        units.append(unit)
    return units


def _prepare_variants(
    entry: RecordingEntry,
    config: BuildConfig,
    work_dir: Path,
    keys: dict[float | None, str],
    hashes: dict[str, str],
    scratch: ExitStack,
    tempo: float | None = None,
    style: str | None = None,
) -> dict[float | None, Unit]:
    """Compute and write the work file of every variant in ``keys`` (SNR in dB, None for the clean
    audio, to its unit key); temporary files are entered in ``scratch``, which removes them.
    ``tempo``: the recording stretched by that factor (``BuildConfig.augment_tempo``; one variant)."""
    variants = list(keys)
    snrs = tuple(v for v in variants if v is not None)
    sources = [entry.recording] + ([] if entry.audio is None else [entry.audio])
    spec = config.target
    feats = config.feature_config
    sr = config.sample_rate
    cache: Path | None = None  # the resampled audio of the first pass, so the second need not decode again
    if tempo is not None and entry.aligned:
        raise KinectDataError(
            f"{entry.recording}: a tempo copy is made from the recording and its song, not from an aligned file: "
            "list the raw recording and its audio"
        )
    if entry.aligned:
        rec = AlignedRecording.load(entry.recording, audio=False)
        if rec.sample_rate != sr or abs(rec.fps - config.fps) > 1e-9:
            raise KinectDataError(
                f"{entry.recording}: aligned at {rec.fps:g} fps and {rec.sample_rate} Hz, but the dataset is built "
                f"at {config.fps:g} fps and {sr} Hz; align it again with --fps / --sample-rate"
            )
        motion, n = cleaned_for_build(rec.motion, entry, config), rec.n_frames
        starts = np.round(np.arange(n) * sr / config.fps).astype(np.int64)
        offset, summary = rec.offset, rec.summary

        def blocks() -> Iterator[np.ndarray]:
            return audio_blocks(entry.recording)

        mean_square = _mean_square(blocks()) if snrs else 0.0
    else:
        source = cleaned_for_build(entry.read_motion(), entry, config)
        kept_pitch = tempo is not None and config.tempo_pitch == "kept"
        reader = AudioReader(entry.audio, sr if tempo is None or kept_pitch else round(sr / tempo))
        given = entry.offset
        if kept_pitch:  # the same notes r times as fast, kept in a scratch file the passes below read
            cache = scratch.enter_context(_scratch(work_dir, f"{entry.name}.audio-f32"))
            played = _stretched(reader, tempo, sr, cache)
            stretch, reader = reader.n_samples / played.n_samples, played
        elif tempo is not None:  # the song read at sr / r and taken as sr: r times as fast (the rate rounded)
            stretch = sr / reader.sample_rate
        if tempo is not None:
            source = dataclasses.replace(source, times=source.times / stretch)
            given = given if given in (None, "auto") else float(given) / stretch
        env = None
        if given == "auto" or snrs:
            played_blocks = reader.blocks()
            if cache is None:  # this pass decodes the song: kept for the second
                cache = scratch.enter_context(_scratch(work_dir, f"{entry.name}.audio-f32"))
                played_blocks = _tee(played_blocks, cache)
            env = audio_envelopes(played_blocks, sr)
        offset = resolve_offset(source, env, given)
        tl = plan_timeline(
            source,
            reader.n_samples,
            sr,
            offset.seconds,
            fps=config.fps,
            min_coverage=config.min_coverage,
            audio_name=str(entry.audio),
        )
        res, long_gaps = resample_onto(source, tl, config.max_gap)
        motion, n, starts = res.motion, tl.n_frames, tl.frame_starts()
        summary = summarize(source, tl, res, long_gaps, offset, reader.n_samples, tl.kept_samples(reader.n_samples))
        del source, res
        mean_square = env.mean_square if env is not None else 0.0

        def blocks() -> Iterator[np.ndarray]:
            return reader.blocks() if cache is None else _raw_blocks(cache)

    if isinstance(spec, GenericTarget):
        spec = spec.resolve(motion.joint_set)
    values, mask = extract_targets(motion, spec, root_centre=config.root_centre)
    stats = NormStats.from_arrays(values, mask, spec.component_names()).to_dict()
    orientations = orientation_stats(values, mask, spec)
    skeleton = bone_offsets(motion, spec)
    song = functools.cache(lambda: np.concatenate([np.zeros(0, np.float32), *blocks()]))  # decoded once, if asked
    metre = _features_metre(entry, feats, song, sr)
    info = {"sources": hashes, "paths": sources, "offset": offset.to_dict(), "alignment": summary}
    if metre is not None:
        info["metre"] = {"beats_per_bar": metre.beats_per_bar, "source": metre.source}
    if needs_style(feats):
        told = style is not None
        if not told:  # heard in the whole song, as generation hears any song
            style, _ = song_style(feats, song())
            style = style or NO_STYLE
        info["style"] = {"style": style, "source": "manifest" if told else "heard"}
    anchor = root_anchor(motion, spec) if config.root_centre else None
    if (
        anchor is not None and np.isfinite(anchor).all()
    ):  # where the dancer stood: generated and scored motion go back there
        info["root_anchor"] = [float(v) for v in anchor]
    if tempo is not None:
        info["augmentation"] = {"tempo": tempo, "exact_factor": stretch}
    units = {
        v: Unit(
            name=variant_name(entry.name, v, tempo),
            recording=entry.name,
            snr_db=v,
            file=f"{variant_name(entry.name, v, tempo)}.h5",
            key=keys[v],
            frames=n,
            stats=stats,
            orientations=orientations,
            info={**info, "augmentation": info.get("augmentation") if v is None else {"white_noise_snr_db": v}},
            skeleton=skeleton,
            target=spec.to_dict(),
            tempo=tempo,
        )
        for v in variants
    }
    with ExitStack() as stack:
        outputs = {}
        for v, unit in units.items():
            f = stack.enter_context(atomic_hdf5(work_dir / unit.file))
            f.attrs["format"] = WORK_FORMAT
            f.attrs["unit"] = json.dumps(unit.to_dict(), default=str)
            f.create_dataset("targets", data=values, track_times=False)
            f.create_dataset("mask", data=mask, track_times=False)
            outputs[v] = (
                f.create_dataset(
                    "input",
                    shape=(n, *feats.output_shape),
                    dtype=np.float32,
                    track_times=False,
                    chunks=(min(256, n), *feats.output_shape),
                ),
                f.create_dataset("audio_padded", shape=(n,), dtype=bool, track_times=False),
            )

        def sink_for(v):
            def sink(k0: int, feats: np.ndarray, padded: np.ndarray) -> None:
                d_in, d_pad = outputs[v]
                d_in[k0 : k0 + feats.shape[0]] = feats
                d_pad[k0 : k0 + feats.shape[0]] = padded

            return sink

        bar = None if metre is None else metre.beats_per_bar
        featurizers = {
            v: StreamingFeatures(starts, feats, sink_for(v), beats_per_bar=bar, style=style) for v in variants
        }
        rngs = {
            v: np.random.default_rng([config.seed, zlib.crc32(entry.name.encode()), int(round(v * 1000)) & 0xFFFFFFFF])
            for v in variants
            if v is not None
        }
        for block in blocks():
            for v, featurizer in featurizers.items():
                if v is None:
                    featurizer.push(block)
                else:
                    sigma = np.sqrt(mean_square / 10 ** (v / 10))
                    featurizer.push((block + sigma * rngs[v].standard_normal(block.size)).astype(np.float32))
        for featurizer in featurizers.values():
            featurizer.finish()
    return units
