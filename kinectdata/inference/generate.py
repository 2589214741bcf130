"""``generate``: any audio file -> dance motion, streaming, as a robot would run it live.

The audio is read in blocks (:class:`~kinectdata.align.audio.AudioReader`), the features of each frame
are computed as soon as its audio has arrived (:class:`~kinectdata.features.streaming.StreamingFeatures`)
and, for a model that streams (its kind's ``streams``), the network steps one frame at a time (an
engine of :mod:`~kinectdata.inference.engines`: torch or ONNX Runtime, as the model offers), its
state carried from frame to frame; nothing waits for the end of the audio but the file written at
the end. A model that does not stream runs free (its kind's ``free_run``) over the whole song's
features once they are all computed. The first "previous pose" is the mean training pose, or frame 0 is a
recording's true first pose when the dance is made for a recording (an aligned ``.h5``, a dataset split: as
``evaluate`` runs free), and a root-centred run's motion is put back in the world (:mod:`~kinectdata.inference.start`).
Poses are denormalised and written in the form the target's joint set is read back from (a joint set
kinectdata does not ship travels whole in the file: its joints, bones, roles and SMPL-24 mapping):

- 3-D joint sets (e.g. the yalta model's): kinectdata's canonical CSV (metres, unit quaternions), which
  ``align`` reads: the target spec's joints get their orientations, and every joint the
  orientations reach gets a position by forward kinematics over the dataset's rest skeleton
  (:mod:`kinectdata.targets.skeleton`; runs on datasets built before it have the listed positions only);
  other joints are left empty (masked). An ``out`` named ``.bvh`` is written as BVH instead
  (:func:`~kinectdata.formats.bvh_writer.write_bvh`, centimetres: Blender, MotionBuilder, Unity),
  without the joints no position reaches;
- ``openpose_mpi`` (e.g. the cdhc model's): OpenPose JSON Lines (:mod:`~kinectdata.formats.openpose_writer`)
  with x, y in the target's units: 0..1 of the per-recording min-max scaling for
  ``listen_to_dance``, image axes (y down). The limb lengths are not written (they are the
  model's own estimate of its skeleton; :func:`generate` returns them in ``timing["limb_lengths"]``).
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from kinectdata.align.aligned import AlignedRecording, audio_blocks, audio_length
from kinectdata.align.audio import AudioReader
from kinectdata.align.stretch import stretch_audio
from kinectdata.core.errors import ConfigError, KinectDataError
from kinectdata.core.motion import Motion
from kinectdata.features import feature_config, needs_metre, song_style, style_input_of
from kinectdata.features.metre import recording_metre
from kinectdata.features.silence import silence_features
from kinectdata.features.streaming import StreamingFeatures
from kinectdata.features.style_input import NO_STYLE
from kinectdata.formats.bvh_writer import write_bvh
from kinectdata.formats.csv_writer import write_csv
from kinectdata.formats.openpose_writer import write_openpose_jsonl
from kinectdata.inference.engines import make_engine
from kinectdata.inference.smoothing import run_smoothing, smooth_motion, smoothing_line
from kinectdata.inference.start import StartPose, recording_start, target_poses
from kinectdata.inference.style_tempo import run_style_tempo, style_tempo_factor, style_tempo_line, warp_back
from kinectdata.inference.turning import (
    faced_first_pose,
    run_sway,
    run_travel,
    run_turning,
    travel_generator,
    turn_song,
)
from kinectdata.models.registry import model_kind
from kinectdata.models.run import load_model, model_name
from kinectdata.targets.facing import turn_about_root
from kinectdata.targets.normalization import Normalizer
from kinectdata.targets.specs import TargetSpec
from kinectdata.targets.sway import calm_sway


def _motion(
    values: np.ndarray,
    spec: TargetSpec,
    fps: float,
    metadata: dict[str, Any],
    skeleton: dict | None = None,
    root_centred: bool = False,
    anchor: np.ndarray | None = None,
) -> Motion:
    """A Motion of the spec's joint set from denormalised target vectors [T, D]; with the dataset's
    ``skeleton`` (bone offsets) every joint its orientations reach gets a position
    (:func:`kinectdata.targets.skeleton.rebuild_positions`), else only the spec's listed joints.
    A root-centred 3-D motion is placed in the world at ``anchor``, else by the floor rule
    (:mod:`kinectdata.inference.start`); ``metadata["placement"]`` says which."""
    placement = "the recording's anchor" if anchor is not None else "the floor rule"
    positions, orientations, anchor = target_poses(values, spec, skeleton or {}, root_centred, anchor)
    if anchor is not None:
        metadata = metadata | {"placement": f"{placement}: root started at {np.round(anchor, 3).tolist()} m"}
    return Motion(np.arange(len(values)) / fps, positions, spec.joints, orientations=orientations, metadata=metadata)


def _music(
    audio: str | Path, sample_rate: int, dataset: dict[str, Any], kind: Any
) -> tuple[int, Callable[[], Iterator[np.ndarray]], StartPose | None]:
    """(samples, a function giving them in blocks, the start it gives) of the music to dance to at
    ``sample_rate`` Hz: an audio file, decoded and resampled (no start), or an aligned recording
    (``.h5``): its own audio segment, whose sample 0 is its motion's frame 0, at the rate it was
    aligned at, and its first pose and anchor when its joint set is the run's
    (:func:`~kinectdata.inference.start.recording_start`)."""
    if Path(audio).suffix.lower() in (".h5", ".hdf5"):
        recording = AlignedRecording.load(audio, audio=False)
        if recording.sample_rate != sample_rate:
            raise KinectDataError(
                f"{audio}: its audio is at {recording.sample_rate} Hz, and this run's model hears {sample_rate} Hz: "
                f"align it again with --sample-rate {sample_rate}"
            )
        start = recording_start(recording.motion, dataset, kind) if recording.motion.n_frames else None
        return audio_length(audio), lambda: audio_blocks(audio), start
    reader = AudioReader(audio, sample_rate)
    return reader.n_samples, reader.blocks, None


def _in_blocks(samples: np.ndarray, sample_rate: int) -> Iterator[np.ndarray]:
    """``samples`` [S] in blocks of a second, as an audio reader gives them."""
    for k in range(0, samples.size, sample_rate):
        yield samples[k : k + sample_rate]


def generate(
    run: str | Path,
    audio: str | Path,
    out: str | Path | None = None,
    *,
    engine: str = "torch",
    precision: str = "float32",
    beats_per_bar: int | None = None,
    start: StartPose | None = None,
    turning: bool = True,
    travel: bool = True,
    seed: int = 0,
    style: str | None = None,
) -> tuple[Motion, dict[str, Any]]:
    """Generate motion for ``audio`` with a trained run; write it to ``out`` if given (canonical
    CSV, or OpenPose JSON Lines for 2-D targets: see the module docstring). ``audio``: an audio
    file, or an aligned recording (``.h5``), whose own music is danced to on its timeline: frame k
    of the result is frame k of the recording, to compare or render side by side.

    ``engine``: ``torch`` or ``onnxruntime`` with ``precision`` weights (float32, float16), as the
    run's model offers (its kind's ``engines``; e.g. the yalta model: torch in float32 or float16,
    ONNX Runtime in float32; the cdhc model: torch in float32). Returns the Motion (times k / fps;
    metres and unit quaternions, or the 2-D target's units) and timing figures (per step for a
    model that streams; a model that does not runs once over the song).

    ``beats_per_bar``: the song's metre, for features that count its bars (``listen_to_dance_rhythm_bars``);
    None: estimated from the whole audio file before the stream starts (a live performer would say
    it), else 4. ``timing["metre"]`` says which it was.

    ``style``: the song's dance style, for a run whose features hear it (``*_style`` presets); None:
    heard in the whole audio file by the classifier its dataset fitted on the training songs.
    ``timing["style"]`` says which.

    ``start``: the pose frame 0 is and where a root-centred motion stands
    (:class:`~kinectdata.inference.start.StartPose`); None: an aligned recording's own first pose
    and anchor, else the mean training pose before frame 0 and the floor rule.
    ``timing["start"]`` and ``timing["placement"]`` say which.

    ``turning``, ``travel``: draw the run's turning about the vertical and its travel across the floor
    over the frames the model makes (:mod:`kinectdata.inference.turning`, from generators seeded by
    ``seed``: ``live`` on the same audio and seed turns and travels the same way); a run trained
    without them draws none. A run trained with ``sway`` scales the network's root along the floor
    first (:mod:`kinectdata.targets.sway`). ``timing["turning"]`` says what was drawn. A run trained with ``smooth_hz``
    then low-passes the frames the model made (:mod:`kinectdata.inference.smoothing`);
    ``timing["smoothing"]`` says how. A run trained with ``style_tempo`` dances a song far from its
    heard style's tempo at that tempo and plays the dance back at the song's
    (:mod:`kinectdata.inference.style_tempo`: the whole song is decoded first); ``timing["style_tempo"]`` says how.
    A run with a phrase code (``--latent-dims``: :mod:`kinectdata.models.latent`) draws it from row
    ``seed`` of its table of draws: another seed, another dance to the same music;
    ``timing["phrase_code"]`` says which.
    """
    net, config = load_model(run)
    kind = model_kind(model_name(config))
    draws = kind.takes_draws(config["model"])
    data = config["dataset"]
    fps, sr = data["fps"], data["sample_rate"]
    spec = TargetSpec.from_dict(data["target"])
    wanted = (".jsonl", ".json") if spec.dimensions == 2 else (".csv", ".bvh")
    if out is not None and Path(out).suffix.lower() not in wanted:
        written = "OpenPose JSON Lines" if spec.dimensions == 2 else "canonical CSV or BVH"
        raise KinectDataError(f"{out}: this run's motion is written as {written}; name the file {wanted[0]}")
    norm = Normalizer.from_dict(data["normalisation"])
    n_samples, blocks, given = _music(audio, sr, data, kind)
    start = start or given or StartPose()
    n = int(np.floor(n_samples / sr * fps + 1e-9))
    if n < 1:
        raise KinectDataError(f"{audio}: shorter than one frame ({1 / fps:.3f} s)")
    features_config = feature_config(data["features"])
    song_blocks = blocks
    whole = functools.cache(lambda: np.concatenate([np.zeros(0, np.float32), *song_blocks()]))  # decoded once, if asked
    song_frames, band = n, run_style_tempo(config)
    played = style_tempo_factor(whole(), features_config, band, style)[0] if band is not None and n > 1 else 1.0
    if played != 1.0:  # the network dances the song played at its style's tempo; warped back below
        faster = stretch_audio(whole(), played, sr)
        blocks = functools.partial(_in_blocks, faster, sr)
        n = max(2, int(np.floor(faster.size / sr * fps + 1e-9)))
    true_first = start.pose is not None  # frame 0 is the true pose; the model makes frames 1..n-1
    pose = np.asarray(start.pose if true_first else data["start_pose"], dtype=np.float32)
    poses = np.empty((n, spec.dim), np.float32)
    poses[0] = pose
    heading = 0.0  # a run that learnt facing one way starts from its first pose faced, and turns back after
    if true_first:
        pose, heading = faced_first_pose(config, pose)
    step_times: list[float] = []
    drawing = (turning and config.get("turning") is not None) or (travel and config.get("travel") is not None)
    heard: list[np.ndarray] = []  # every frame's features, when the turning needs to know the silent ones
    if kind.streams:
        stepper = make_engine(net, engine, precision, kind, draw=int(seed))

        def step(k0: int, features: np.ndarray, padded: np.ndarray) -> None:
            nonlocal pose
            if drawing:
                heard.append(np.array(features))
            for k in range(features.shape[0]):
                if true_first and k0 + k == 0:
                    continue
                started = time.perf_counter()
                pose = stepper.step(features[k], pose)
                step_times.append(time.perf_counter() - started)
                poses[k0 + k] = pose

    else:
        if (engine, precision) != ("torch", "float32"):
            raise ConfigError(f"the {kind.name} model does not stream: it runs in torch with float32 weights only")
        song = heard

        def step(k0: int, features: np.ndarray, padded: np.ndarray) -> None:
            song.append(np.array(features))  # a copy: the featurizer may reuse its buffers

    starts = np.round(np.arange(n) * sr / fps).astype(np.int64)
    metre = None
    counts_bars = needs_metre(features_config)
    if counts_bars or (drawing and config.get("drawn_by_metre")):  # the features' bars, or the draws' metre
        metre = recording_metre(None, None if beats_per_bar is not None else whole(), sr, given=beats_per_bar)
    bar = None if metre is None else metre.beats_per_bar
    hears = style is None and style_input_of(features_config) is not None  # the style heard in the whole song
    heard_style, style_said = song_style(features_config, whole() if hears else None, style)
    process = run_turning(config, bar) if turning else None
    moving = run_travel(config, bar) if travel else None
    bars = bar if counts_bars else None
    featurizer = StreamingFeatures(starts, features_config, step, beats_per_bar=bars, style=heard_style or NO_STYLE)
    started = time.perf_counter()
    for block in blocks():
        featurizer.push(block)
    featurizer.finish()
    if not kind.streams:  # frames 1..n-1 from the true first pose, or 0..n-1 from the mean pose before frame 0
        features = np.concatenate(song)
        ran = time.perf_counter()
        drawn_from = {"draw": int(seed)} if draws else {}
        if true_first:
            poses[1:] = kind.free_run(net, features, pose, **drawn_from)
        else:
            poses[:] = kind.free_run(net, np.concatenate([features[:1], features]), pose, **drawn_from)
        step_times = [(time.perf_counter() - ran) / n] * n
    if played != 1.0:  # back onto the song's clock: its frame k is the played dance's frame k / factor
        poses = warp_back(poses, played, song_frames).astype(np.float32)
        if heard:
            at = np.minimum(np.round(np.arange(song_frames) / played).astype(np.int64), n - 1)
            heard = [np.concatenate(heard)[at]]
        n = song_frames
    values = norm.invert(poses, spec)
    made = slice(1 if true_first else 0, n)  # the frames the model made: 1..n-1 after a true first pose
    sway = run_sway(config)
    if sway is not None:
        values[made] = calm_sway(values[made], spec, sway)
    if heading:
        values[made] = turn_about_root(values[made], spec, heading)
    if process is not None or moving is not None:
        rng = np.random.default_rng(int(seed))
        silence = silence_features(data["features"], fps)
        values[made] = turn_song(
            values[made],
            np.concatenate(heard)[made],
            silence,
            spec,
            fps,
            process,
            rng,
            moving,
            travel_generator(seed),
            start.anchor,
        )
    smooth_hz = run_smoothing(config)
    if smooth_hz is not None:
        values[made] = smooth_motion(values[made], spec, fps, smooth_hz)
    seconds = time.perf_counter() - started
    metadata = {"format": "generated", "source": str(audio), "run": str(run)}
    motion = _motion(values, spec, fps, metadata, data.get("skeleton"), data["root_centre"], start.anchor)
    if out is not None and spec.dimensions == 2:
        write_openpose_jsonl(motion, out)
    elif out is not None and Path(out).suffix.lower() == ".bvh":
        write_bvh(motion, out)
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
                "units": "metres, y up",
                "start": start.source,
                **({"placement": motion.metadata["placement"]} if "placement" in motion.metadata else {}),
                "engine": f"{engine} {precision}",
            },
        )
    t = np.array(step_times or [0.0]) * 1e3  # one frame from a true first pose: no step
    timing = {
        "frames": n,
        "seconds": seconds,
        "x_real_time": n / fps / seconds,
        "step_median_ms": float(np.median(t)),
        "step_p95_ms": float(np.percentile(t, 95)),
    }
    if metre is not None:
        timing["metre"] = metre.describe()
    if style_said:
        timing["style"] = style_said
    timing["start"] = start.source
    drawn = [p.describe() for p in (sway, process, moving) if p is not None]
    if drawn and bar is not None and str(bar) in (config.get("drawn_by_metre") or {}):
        drawn.append(f"those of the training dances of {bar} beats a bar")
    timing["turning"] = "; ".join(drawn) if drawn else "none drawn"
    timing["smoothing"] = smoothing_line(config)
    if draws:
        timing["phrase_code"] = f"drawn from row {int(seed)} of the run's table (--seed)"
    timing["style_tempo"] = style_tempo_line(band) + ("" if band is None else f": this song x{played:.2f}")
    if "placement" in motion.metadata:
        timing["placement"] = motion.metadata["placement"]
    if spec.limbs:
        timing["limb_lengths"] = {
            name: float(np.median(values[:, spec.columns(j, "limb")]))
            for j, name in zip(spec.limbs, spec.component_names()[spec.limb_slice])
        }
    return motion, timing
