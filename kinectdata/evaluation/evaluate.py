"""``evaluate``: a trained run scored on a dataset split as Yalta et al. (2016) score it, with the
rhythm analysis of Lee et al. (2018) and the field's beat metrics.

For every (clean, not noise-augmented) recording of the split the model runs **free** (its kind's
``free_run``: :class:`~kinectdata.models.kind.ModelKind`): it is given the true pose of the
recording's first frame as the previous pose, and from then on its own outputs. For a model that
resets (its kind's ``resets``, e.g. the yalta model) two ways, as in Yalta et al.'s tables:

- **without reset**: the states (the yalta model's LSTM states) carry over the whole recording;
- **with reset**: every ``sequence`` frames (the training sequence length) the states are
  zeroed, as at the start of each training sequence; the model keeps being fed its own poses
  (the paper resets the state only, and its "with reset" scores are the worse ones).

A model without a state to reset (e.g. the cdhc model, whose receptive field is fixed) is scored
"without reset" only.

SMAPE (:func:`~kinectdata.evaluation.metrics.smape`, percent, 0/0 counted as 0) compares frames
1..T-1 with the real poses over valid components, on the normalised targets and on the
denormalised ones (metres and quaternion components). Also reported, for a model that streams:
the per-frame forward time of its stream at batch 1 (median and 95th percentile, in ms, on the
named device) on every engine and precision it runs on (its kind's ``engines``; ONNX Runtime when
installed),
plots of generated against real trajectories (the paper's Figure 6), and the **silence test**:
seconds of silence are inserted into the middle of a recording's features, the model runs
through it, and the motion energy inside the silence is compared with the energy outside (the
paper's Figure 7: the motion stops); the silent frames' features must all be identical.
"""

from __future__ import annotations

import platform
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import torch

from kinectdata.align.stretch import stretch_audio
from kinectdata.core.errors import KinectDataError
from kinectdata.dataset.layout import is_copy, known_metre
from kinectdata.dataset.shards import read_index
from kinectdata.evaluation.baselines import (
    TrainingSong,
    baseline_comparison,
    mean_pose_noise,
    mean_square_steps,
    music_descriptor,
    retrieval,
)
from kinectdata.evaluation.field_scores import write_metrics_json
from kinectdata.evaluation.figures import rhythm_plot, trajectories
from kinectdata.evaluation.listening import HeldOutSong, listening_report
from kinectdata.evaluation.metrics import motion_energy, smape
from kinectdata.evaluation.motion_sets import motion_as_dance
from kinectdata.evaluation.protocols import Protocol, get_protocol
from kinectdata.evaluation.rhythm_eval import (
    recording_audio,
    rhythm_evaluation,
    split_beats,
    summarize_rhythm,
    target_positions,
)
from kinectdata.evaluation.run_field import run_field_scores, target_motion
from kinectdata.evaluation.style import style_features, style_report
from kinectdata.features import compute_features, feature_config, style_input_of
from kinectdata.features.metre import Metre, recording_metre
from kinectdata.inference.engines import engine_pairs, make_engine, onnxruntime_available
from kinectdata.inference.smoothing import NOT_SMOOTHED, smoothing_line
from kinectdata.inference.style_tempo import (
    AS_IT_IS,
    check_band,
    run_style_tempo,
    style_tempo_factor,
    style_tempo_line,
)
from kinectdata.inference.turning import TurnedKind, with_turning
from kinectdata.models.kind import ModelKind
from kinectdata.models.registry import kind_of, model_kind
from kinectdata.models.run import interface_mismatch, load_model, model_name, read_manifest, write_json
from kinectdata.targets.normalization import Normalizer
from kinectdata.targets.skeleton import rebuild_positions
from kinectdata.targets.specs import TargetSpec

SILENCE_S = 5.0


def split_recordings(dataset: Path, manifest: dict, split: str) -> list[dict[str, Any]]:
    """The split's clean recordings with their rows (input, current, mask), their shard index
    entry's ``info`` (alignment summary, sources) and the style the build gave their song (``style``:
    told by the manifest or heard in the whole song; None without one)."""
    out = []
    for r in manifest["recordings"]:
        if r["split"] != split or is_copy(r):
            continue
        with h5py.File(dataset / r["shard"], "r") as f:
            rows = slice(r["start"], r["start"] + r["frames"])
            info = next(x["info"] for x in read_index(f) if x["name"] == r["name"])
            out.append(
                {
                    "name": r["name"],
                    "recording": r["recording"],
                    "info": info,
                    "input": f["input"][rows],
                    "current": f["current"][rows],
                    "mask": f["mask"][rows],
                    "style": (r.get("style") or {}).get("style"),
                }
            )
    return out


def forward_times(
    net: torch.nn.Module,
    frames: np.ndarray,
    engine: str = "torch",
    precision: str = "float32",
    *,
    first_pose: np.ndarray | None = None,
    kind: ModelKind | None = None,
) -> dict:
    """Per-frame time of a streaming engine (:mod:`~kinectdata.inference.engines`) at batch 1 over
    ``frames`` (the network's inputs [N, ...]), its own outputs fed back after ``first_pose`` [D]
    (default: 0.5 everywhere, for networks whose ``config`` has ``output_dim``)."""
    stepper = make_engine(net, engine, precision, kind)
    if first_pose is None:
        first_pose = np.full(net.config.output_dim, 0.5)
    pose = np.asarray(first_pose, np.float32)
    times = []
    for k in range(frames.shape[0]):
        x = np.ascontiguousarray(frames[k], dtype=np.float32)
        start = time.perf_counter()
        pose = stepper.step(x, pose)
        times.append(time.perf_counter() - start)
    t = np.array(times[min(10, len(times) // 10) :]) * 1e3  # the first calls warm caches up
    return {
        "median_ms": float(np.median(t)),
        "p95_ms": float(np.percentile(t, 95)),
        "frames": int(t.size),
        "engine": engine,
        "precision": precision,
        "device": _device_name(),
        "threads": 1 if engine == "onnxruntime" else torch.get_num_threads(),
    }


def default_engines(kind: ModelKind) -> list[tuple[str, str]]:
    """(engine, precision) pairs timed by :func:`evaluate`: every one the model runs on (none for
    a model that does not stream), ONNX Runtime when installed."""
    if not kind.streams:
        return []
    return [(e, p) for e, p in engine_pairs(kind) if e != "onnxruntime" or onnxruntime_available()]


def _device_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return "cpu: " + line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "cpu: " + (platform.processor() or platform.machine())


def silence_test(
    net: torch.nn.Module,
    features_config: dict,
    rec: dict,
    fps: float,
    seconds: float = SILENCE_S,
    *,
    kind: ModelKind | None = None,
) -> dict:
    """Insert ``seconds`` of silence in the middle of a recording's features and compare the
    generated motion's energy (mean squared frame-to-frame change, normalised targets) inside the
    silence, after a second to settle, with the energy outside it. The network runs free as its
    model (``kind``, or found from the network) runs it."""
    cfg = feature_config(features_config)
    kind = kind or kind_of(net)
    n_silent = int(round(seconds * fps))
    settle = int(round(fps))  # the motion is given a second to stop
    if n_silent < 2 * settle:
        raise KinectDataError(
            f"the silence test needs at least 2 s of silence (1 s to settle, then measured), not {seconds:g} s"
        )
    starts = np.round(np.arange(n_silent) * cfg.sample_rate / fps).astype(np.int64)
    silent, _ = compute_features(np.zeros(int(starts[-1]) + cfg.span[1], np.float32), starts, cfg)
    identical = bool((silent == silent[0]).all())
    mid = rec["input"].shape[0] // 2
    audio = np.concatenate([rec["input"][:mid], silent, rec["input"][mid:]])
    generated = kind.free_run(net, audio, rec.get("first_pose", rec["current"][0]))  # frames 1..T-1
    energy = motion_energy(generated)  # index i: the change into frame i + 1 of the combined features
    begin, end = mid - 1, mid - 1 + n_silent  # the silence, in those indices
    inside = np.zeros(energy.size, bool)
    inside[begin + settle : end] = True
    outside = np.ones(energy.size, bool)
    outside[begin:end] = False
    outside[0] = False
    return {
        "recording": rec["name"],
        "silence_seconds": seconds,
        "silent_frames": n_silent,
        "silent_features_identical": identical,
        "silent_feature_value": float(silent[0].flat[0]),
        "energy_inside": float(energy[inside].mean()),
        "energy_outside": float(energy[outside].mean()),
        "energy_ratio": float(energy[inside].mean() / max(energy[outside].mean(), 1e-30)),
        "settle_seconds": settle / fps,
        "generated": generated,
        "silence_span_s": (begin / fps, end / fps),
    }


def evaluate(
    run: str | Path,
    dataset: str | Path,
    split: str = "test",
    *,
    out: str | Path | None = None,
    silence_seconds: float = SILENCE_S,
    timing_frames: int = 300,
    engines: list[tuple[str, str]] | None = None,
    protocol: str | Protocol = "bailando",
    bootstrap: int = 1000,
    checksums: bool = True,
    beats_per_bar: int | None = None,
    more_protocols: tuple[str, ...] = (),
    baselines: bool = True,
    turning: bool = True,
    travel: bool = True,
    sway: bool = True,
    tempo_rates: tuple[float, ...] | None = None,
    style_tempo: float | None | str = "run",
    draw_seed: int = 0,
) -> dict[str, Any]:
    """Score a run on a dataset split; write ``results.json``, ``metrics.json`` (the field's table)
    and figures into ``out`` (default ``RUN/evaluation``); return the results. ``engines``: the
    (engine, precision) pairs whose forward time is measured (default :func:`default_engines`;
    pairs the run's model does not run on are left out). ``protocol``: whose table the field's
    metrics reproduce (:data:`~kinectdata.evaluation.protocols.PROTOCOLS`), with ``bootstrap``
    resamples for their intervals (:mod:`kinectdata.evaluation.run_field`). The dataset folder is
    verified first (``checksums=False`` skips the shards' SHA-256). ``beats_per_bar``: the metre
    of the songs whose recordings-manifest entry gives none (default: estimated from each song,
    :mod:`~kinectdata.features.metre`). ``more_protocols``: other protocols whose tables are
    made too (``metrics_<name>.json``). ``baselines``: also score the mean training pose with noise
    at the training dances' speed (and, as an oracle, at each song's own real speed) and the
    retrieval baseline (:mod:`~kinectdata.evaluation.baselines`, :func:`baseline_runs`) by the same
    protocols, beside the model. ``turning``, ``travel``: draw the run's turning about the vertical and
    its travel across the floor in every free run (:mod:`kinectdata.inference.turning`; a run trained
    without them draws none); False: the network's motion alone. ``sway``: scale the network's sway
    along the floor by the run's gain (:mod:`kinectdata.targets.sway`; a run trained without it keeps
    none). ``results["turning"]`` says which. A
    run trained with ``smooth_hz`` smooths every free run after them (:mod:`kinectdata.inference.smoothing`;
    not the runs reset every L frames); ``results["smoothing"]`` says how.
    ``tempo_rates``: the tempo control's factors (None: its own; empty: no tempo control).
    ``style_tempo``: the band within which a song is danced at its own tempo, and beyond which at its
    style's (:mod:`kinectdata.inference.style_tempo`): ``"run"``, the run's; None or 0, every song as
    it is (the network alone); a share (0.08), that band. It plays the split's songs and the tempo
    control's; ``results["style_tempo"]`` says how and which songs were played faster or slower.
    ``draw_seed``: the seed of the turning and travel drawn in every free run (each song's draws are
    keyed by its music too, :func:`~kinectdata.inference.turning.song_generator`), which
    ``results["draw_seed"]`` records: a model trained with another seed is scored on other draws by
    giving it that seed, since the drawn turning and travel are as much a part of its dance as its
    weights."""
    protocol = get_protocol(protocol) if isinstance(protocol, str) else protocol
    run, dataset = Path(run), Path(dataset)
    net, config = load_model(run)
    if style_tempo != "run":
        if style_tempo is not None:
            check_band(style_tempo, feature_config(config["dataset"]["features"]))
        config.setdefault("train", {})["style_tempo"] = style_tempo
    for drawn, asked in (("turning", turning), ("travel", travel), ("sway", sway)):
        if not asked:  # every free run below then makes without it
            config.pop(drawn, None)
    manifest = read_manifest(dataset, checksums=checksums)
    differ = interface_mismatch(config, dataset, manifest)
    if differ:
        raise KinectDataError(
            f"{dataset}: its {', '.join(differ)} differ from those {run} was trained on "
            f"({config['dataset']['path']}); scores would be meaningless"
        )
    recordings = split_recordings(dataset, manifest, split)
    if not recordings:
        raise KinectDataError(f"{dataset}: the {split} split holds no recording")
    kind = with_turning(model_kind(model_name(config)), config, seed=draw_seed)
    beats = split_beats(recordings, manifest, config["dataset"]["fps"])
    played = _tell_kind(kind, recordings, beats, manifest, config, beats_per_bar)
    for rec in recordings:  # the true first pose, masked values as the model's fill_previous says
        rec["first_pose"] = kind.fill_previous(rec["current"][0], rec["mask"][0], config["dataset"]["start_pose"])
    out = Path(out) if out is not None else run / "evaluation"
    out.mkdir(parents=True, exist_ok=True)
    spec = TargetSpec.from_dict(config["dataset"]["target"])
    norm = Normalizer.from_dict(config["dataset"]["normalisation"])
    fps = config["dataset"]["fps"]
    sequence = config["train"]["sequence"]
    results: dict[str, Any] = {
        "run": str(run),
        "dataset": str(dataset),
        "split": split,
        "recordings": [r["name"] for r in recordings],
        "smape_zero_over_zero": 0.0,
        "turning": kind.describe() if isinstance(kind, TurnedKind) else None,
        "draw_seed": int(draw_seed),
        "smoothing": smoothing_line(config),
        "style_tempo": {
            "band": run_style_tempo(config),
            "line": style_tempo_line(run_style_tempo(config)),
            "played": played,
        },
    }
    scores = {}
    first = None
    free: dict[str, np.ndarray] = {}  # denormalised free runs without reset, for the rhythm analysis
    modes = (("without_reset", None), ("with_reset", sequence)) if kind.resets else (("without_reset", None),)
    for mode, reset in modes:
        generated, real, masks = [], [], []
        runs = kind.free_runs(net, [r["input"] for r in recordings], [r["first_pose"] for r in recordings], reset)
        for rec, g in zip(recordings, runs):
            if reset is None:
                free[rec["name"]] = norm.invert(g, spec)
            generated.append(g)
            real.append(rec["current"][1:])
            masks.append(rec["mask"][1:])
            if first is None:
                first = (rec, g)
        g, r, m = np.concatenate(generated), np.concatenate(real), np.concatenate(masks)
        scores[mode] = {
            "smape_normalised": smape(g, r, m),
            "smape_denormalised": smape(norm.invert(g, spec, mask=m), norm.invert(r, spec, mask=m), m),
        }
    results["smape"] = scores
    rec, generated = first
    frames = rec["input"][: min(timing_frames, rec["input"].shape[0])]
    offered = set(engine_pairs(kind)) if kind.streams else set()
    results["forward_time"] = {
        f"{engine} {precision}": forward_times(net, frames, engine, precision, first_pose=rec["first_pose"], kind=kind)
        for engine, precision in (engines or default_engines(kind))
        if (engine, precision) in offered
    }
    names = spec.component_names()
    shown = _shown_components(names)
    unit = "0..1 of the recording's range" if norm.method == "none" else "normalised value"
    fig6 = trajectories(
        rec["current"][1:, shown],
        generated[:, shown],
        [names[i] for i in shown],
        fps,
        out / "trajectories.png",
        title=f"{rec['name']}: generated (free-running) against real",
        unit=unit,
    )
    sil = silence_test(net, config["dataset"]["features"], rec, fps, silence_seconds, kind=kind)
    fig7 = trajectories(
        None,
        sil.pop("generated")[:, shown],
        [names[i] for i in shown],
        fps,
        out / "silence.png",
        title=f"{rec['name']} with {silence_seconds:g} s of silence inserted",
        unit=unit,
        shade=sil["silence_span_s"],
    )
    results["silence_test"] = sil
    results["figures"] = [str(fig6), str(fig7)]
    real = {r["name"]: (norm.invert(r["current"], spec, mask=r["mask"]), r["mask"]) for r in recordings}
    per_recording = rhythm_evaluation(recordings, free, real, spec, beats, fps)
    results["rhythm"] = {"summary": summarize_rhythm(per_recording), "recordings": per_recording}
    results["listening"] = listening_controls(
        net,
        recordings,
        beats,
        manifest,
        config,
        free=free,
        beats_per_bar=beats_per_bar,
        tempo_rates=tempo_rates,
        kind=kind,
    )
    anchors = {r["name"]: np.asarray(r["info"]["root_anchor"]) for r in recordings if "root_anchor" in r["info"]}
    runs, retrieved = {"generated": free}, {}
    if baselines:
        made, retrieved = baseline_runs(dataset, manifest, recordings, real, config, norm)
        runs |= made
    for number, chosen in enumerate([protocol, *(get_protocol(p) for p in more_protocols)]):
        try:
            field = {
                name: run_field_scores(
                    motions,
                    real,
                    beats,
                    spec,
                    config["dataset"],
                    chosen,
                    anchors=anchors,
                    bootstrap=bootstrap,
                    write_to=out / "scored" if (name, number) == ("generated", 0) else None,
                )
                for name, motions in runs.items()
            }
            scored = field["generated"]
            record = scored.to_dict()
            entry = {
                "scored_motion": str(out / "scored"),
                "positions": record["positions"],
                "metrics_json": str(
                    write_metrics_json(scored, out / ("metrics.json" if number == 0 else f"metrics_{chosen.name}.json"))
                ),
                "protocol": chosen.name,
                "metrics": record["metrics"],
                "warnings": record["warnings"],
                "table": scored.table(),
            }
            if baselines:
                entry["baselines"] = {name: f.to_dict()["metrics"] for name, f in field.items() if name != "generated"}
                entry["retrieved"] = retrieved
                entry["comparison"] = baseline_comparison(field)
        except KinectDataError as exc:  # 2-D targets, a joint set without a mapping, joints never placed
            entry = {"unavailable": str(exc)}
        if number == 0:
            results["field"] = entry
        else:
            results.setdefault("field_protocols", {})[chosen.name] = entry
    results["style"] = style_scores(dataset, manifest, free, config, norm, protocol, anchors, real)
    shown_rhythm = next((name for name, r in per_recording.items() if "real" in r), None)
    if shown_rhythm is not None:
        for which in ("real", "generated"):
            fig = rhythm_plot(
                per_recording[shown_rhythm][which],
                out / f"rhythm_{which}.png",
                title=f"{shown_rhythm}: {which} motion, autocorrelation of joint trajectories",
            )
            results["figures"].append(str(fig))
    write_json(out / "results.json", results)
    return results


def baseline_runs(
    dataset: Path,
    manifest: dict[str, Any],
    recordings: list[dict[str, Any]],
    real: dict[str, tuple[np.ndarray, np.ndarray]],
    config: dict[str, Any],
    norm: Normalizer,
    seed: int = 0,
) -> tuple[dict[str, dict[str, np.ndarray]], dict[str, str]]:
    """The baselines' motion for each recording (:mod:`~kinectdata.evaluation.baselines`), as
    denormalised targets [T-1, D] like a free run, and which training recording each retrieval took:
    ``{"mean_pose_noise": {...}, "mean_pose_noise_own_speed": {...}, "retrieval": {...}}``. The mean
    pose is the run's mean training pose; the noise moves at the training split's speed (the
    baseline a model must beat) and, as an oracle, at each song's own real speed; retrieval searches
    the dataset's training split. Without training recordings only the oracle is made."""
    spec = TargetSpec.from_dict(config["dataset"]["target"])
    fps = config["dataset"]["fps"]
    rng = np.random.default_rng(seed)
    mean_pose = norm.invert(np.asarray(config["dataset"]["start_pose"], np.float32)[None], spec)[0]
    training, moves = [], []
    for r in manifest["recordings"]:
        if r["split"] != "train" or is_copy(r):
            continue
        with h5py.File(dataset / r["shard"], "r") as f:
            rows = slice(r["start"], r["start"] + r["frames"])
            mask = f["mask"][rows]
            values = norm.invert(f["current"][rows], spec, mask=mask)
            training.append(TrainingSong(r["name"], music_descriptor(f["input"][rows]), values))
            moves.append((values, mask))
    speed = mean_square_steps(moves) if moves else None
    noise, own_speed, retrieval_runs, retrieved = {}, {}, {}, {}
    for rec in recordings:
        values, mask = real[rec["name"]]
        if speed is not None:
            noise[rec["name"]] = mean_pose_noise(mean_pose, speed, len(values), fps, rng)
        own_speed[rec["name"]] = mean_pose_noise(mean_pose, mean_square_steps([(values, mask)]), len(values), fps, rng)
        if training:
            motion, source = retrieval(music_descriptor(rec["input"]), len(values), training)
            retrieval_runs[rec["name"]], retrieved[rec["name"]] = motion, source
    runs = {"mean_pose_noise": noise} if training else {}
    runs["mean_pose_noise_own_speed"] = own_speed
    if training:
        runs["retrieval"] = retrieval_runs
    return runs, retrieved


def style_scores(
    dataset: Path,
    manifest: dict[str, Any],
    free: dict[str, np.ndarray],
    config: dict[str, Any],
    norm: Normalizer,
    protocol: Protocol,
    anchors: dict[str, np.ndarray],
    real: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
) -> dict[str, Any]:
    """Whether each free run is recognisably its song's style (:mod:`~kinectdata.evaluation.style`):
    the classifier fitted on the dataset's real training dances, the styles the recordings manifest
    gives; ``{"unavailable": why}`` when the manifest gives no styles, the target cannot become
    SMPL-24 joints or fewer than two training dances have a style. ``real``: the scored songs' real
    dances (denormalised values and mask, [T, D] each), named by the same classifier beside them."""
    spec = TargetSpec.from_dict(config["dataset"]["target"])
    styles = {e["name"]: e.get("style") for e in manifest["inputs"]}
    style_of = {r["name"]: styles.get(r["recording"]) for r in manifest["recordings"]}

    def features(values: np.ndarray, mask: np.ndarray, name: str, anchor: np.ndarray | None) -> np.ndarray:
        motion = target_motion(values, mask, spec, config["dataset"], anchor)
        return style_features(motion_as_dance(motion, protocol, name=name, source=f"recording {name}").positions,
                              protocol.fps)  # fmt: skip

    try:
        training = []
        for r in manifest["recordings"]:
            if r["split"] != "train" or is_copy(r) or not style_of.get(r["name"]):
                continue
            with h5py.File(dataset / r["shard"], "r") as f:
                rows = slice(r["start"], r["start"] + r["frames"])
                info = next(x["info"] for x in read_index(f) if x["name"] == r["name"])
                mask = f["mask"][rows][1:]
                values = norm.invert(f["current"][rows][1:], spec, mask=mask)
            anchor = np.asarray(info["root_anchor"]) if "root_anchor" in info else None
            training.append((r["name"], style_of[r["name"]], features(values, mask, r["name"], anchor)))
        if len(training) < 2:
            return {"unavailable": "fewer than two training dances have a style in the recordings manifest"}
        generated = [
            (name, style_of[name], features(values, np.ones_like(values, bool), name, anchors.get(name)))
            for name, values in free.items()
            if style_of.get(name)
        ]
        if not generated:
            return {"unavailable": "the recordings manifest gives no style for the songs scored"}
        heard = {
            r["name"]: r["style"]["style"]
            for r in manifest["recordings"]
            if isinstance(r.get("style"), dict) and r["style"].get("source") == "heard" and r["name"] in free
        }
        dancers = [
            (name, features(values, mask, name, anchors.get(name)))
            for name, (values, mask) in (real or {}).items()
            if name in free and style_of.get(name)
        ]
        return style_report(training, generated, heard, dancers).to_dict()
    except KinectDataError as exc:  # 2-D targets, a joint set without an SMPL-24 mapping
        return {"unavailable": str(exc)}


@dataclass
class SongSet:
    """A split's recordings ready for the listening controls.

    Attributes:
        songs: the recordings whose music's beats are known (ground truth or tracked).
        generate_many: ``generate_many([(features [T, ...], first_pose [D]), ...]) -> [positions
            [T-1, J, C], ...]``, the network run free as its model runs it (the songs together),
            denormalised into the target's units; :meth:`generate` for one song.
        features_of: ``features_of(samples [S], beats_per_bar=None) -> features [T, ...]`` of mono
            audio at ``features_of.sample_rate``, on the motion clock, bars counted in
            ``beats_per_bar`` where the features count them (None: the extractor's default, 4); a
            run with ``style_tempo`` then dances those features from the audio played at its
            style's tempo (:mod:`kinectdata.inference.style_tempo`).
        unavailable: why no recording has beats ("" when some have).
        metres: per song, its metre and where it came from (manifest, given, estimated).
    """

    songs: list[HeldOutSong]
    generate_many: Callable[[list[tuple[np.ndarray, np.ndarray]]], list[np.ndarray]]
    features_of: Callable[[np.ndarray], np.ndarray]
    unavailable: str = ""
    metres: dict[str, Metre] = field(default_factory=dict)

    def generate(self, features: np.ndarray, first_pose: np.ndarray) -> np.ndarray:
        """One song's positions [T-1, J, C] (see ``generate_many``)."""
        return self.generate_many([(features, first_pose)])[0]


def body_positions(
    values: np.ndarray, mask: np.ndarray, spec: TargetSpec, dataset_config: dict[str, Any]
) -> tuple[np.ndarray, np.ndarray]:
    """The body's joint positions [T, J, C] and mask [T, J] from denormalised target vectors [T, D]
    and their mask: every joint the target's orientations reach, by forward kinematics over the
    dataset's rest skeleton (:func:`~kinectdata.targets.skeleton.rebuild_positions`), when the
    target has orientations and the dataset a skeleton; else the target's own positions. The
    rhythm of a dance lives in the whole body (knees, feet, head), not only in the few joints a
    target positions."""
    skeleton = dataset_config.get("skeleton")
    if not (spec.orientations and skeleton and spec.dimensions == 3):
        return target_positions(values, mask, spec)
    positions, placed = rebuild_positions(
        np.where(mask, values, np.nan), spec, skeleton, root_centred=bool(dataset_config.get("root_centre"))
    )
    used = placed.any(axis=0)
    return positions[:, used], placed[:, used]


def _travel_joint(spec: TargetSpec, dataset_config: dict[str, Any]) -> int | None:
    """The index, among :func:`body_positions`' joints, of the root of root-centred targets given as
    they are (its value the dancer's travel from its first second, the others offsets from it); None
    when every joint is a place on the body (world positions, or rebuilt by forward kinematics)."""
    rebuilt = bool(spec.orientations and dataset_config.get("skeleton") and spec.dimensions == 3)
    if dataset_config.get("root_centre") and spec.root in spec.positions and not rebuilt:
        return spec.positions.index(spec.root)
    return None


def _recording_metre(
    r: dict[str, Any],
    entry: dict[str, Any],
    music: np.ndarray | None,
    beats_per_bar: int | None,
    sample_rate: int,
    fps: float,
    samples: np.ndarray | None = None,
) -> Metre:
    """A split recording's metre (:func:`~kinectdata.features.metre.recording_metre`): what the
    dataset says of it (:func:`~kinectdata.dataset.layout.known_metre`), else ``beats_per_bar``, else
    estimated from its music ``samples`` (read here when not given and needed) at its beats
    ``music`` (seconds). Kept as ``r["metre"]``: a recording's metre is found once per evaluation."""
    if r.get("metre") is None:
        listed, found = known_metre(entry, r["info"])
        if samples is None and listed is None and beats_per_bar is None and found is None:
            try:
                samples = recording_audio(entry, r["info"], len(r["current"]), fps, sample_rate)
            except (KinectDataError, OSError):
                samples = None
        r["metre"] = recording_metre(listed, samples, sample_rate, music, beats_per_bar, found)
    return r["metre"]


def _tell_kind(
    kind: Any,
    recordings: list[dict[str, Any]],
    beats: dict[str, tuple],
    manifest: dict[str, Any],
    config: dict[str, Any],
    beats_per_bar: int | None,
) -> dict[str, float]:
    """Tell a :class:`~kinectdata.inference.turning.TurnedKind` what it must know of each recording
    before it dances it: its metre (:func:`_recording_metre`), where the run draws its turning and
    travel by the song's metre (``drawn_by_metre``), and the features of its music played at its
    style's tempo, where the run has ``style_tempo`` and the song is far from that tempo
    (:mod:`kinectdata.inference.style_tempo`; recordings whose music cannot be read are danced as
    they are), and where its dancer stood, from which its travel is pulled towards the floor's centre
    (:meth:`~kinectdata.inference.turning.TurnedKind.know_place`). Returns each played recording's
    factor; nothing for any other kind."""
    by_metre, band = bool(config.get("drawn_by_metre")), run_style_tempo(config)
    if not isinstance(kind, TurnedKind):
        return {}
    for r in recordings:
        kind.know_place(r["input"], r["info"].get("root_anchor"))
    if not (by_metre or band is not None):
        return {}
    cfg = feature_config(config["dataset"]["features"])
    fps = config["dataset"]["fps"]
    inputs = {e["name"]: e for e in manifest["inputs"]}
    features_of = _features_maker(cfg, fps, kind, config)
    played = {}
    for r in recordings:
        entry, samples = inputs[r["recording"]], None
        if band is not None:
            try:
                samples = recording_audio(entry, r["info"], len(r["current"]), fps, cfg.sample_rate)
            except (KinectDataError, OSError):
                samples = None
        music = beats.get(r["name"], (None,))[0]
        metre = _recording_metre(r, entry, music, beats_per_bar, cfg.sample_rate, fps, samples)
        if by_metre:
            kind.know_metre(r["input"], metre.beats_per_bar)
        if samples is not None and _played_factor(r, samples, features_of, metre) != 1.0:
            played[r["name"]] = r["played_factor"]
    return played


def _played_factor(r: dict[str, Any], samples: np.ndarray, features_of: Callable[..., Any], metre: Metre) -> float:
    """The factor a split recording's music is played at (:mod:`kinectdata.inference.style_tempo`; 1.0:
    as it is), its kind told once (``features_of.play``); kept as ``r["played_factor"]``. The style is
    the one the build gave the song (heard in the whole song, as its features were made), not heard
    again in the stretch of it the dance covers."""
    if "played_factor" not in r:
        r["played_factor"] = features_of.play(samples, r["input"], metre.beats_per_bar, r.get("style"))
    return r["played_factor"]


def _features_maker(cfg: Any, fps: float, kind: Any, config: dict[str, Any]) -> Callable[..., np.ndarray]:
    """``features_of(samples [S], beats_per_bar=None) -> features [T, ...]`` on the motion clock at
    ``fps``, as the run hears a whole song: a song of a known metre is drawn its metre's turning and
    travel (``drawn_by_metre``), and a run with ``style_tempo`` dances a song far from its style's
    tempo played at it (the kind is told, :meth:`~kinectdata.inference.turning.TurnedKind.know_played`).
    ``features_of.play(samples, features, beats_per_bar, style=None)`` tells the kind for features
    made already and returns the factor (1.0: as it is); ``style``: the song's, when the build gave it
    one the classifier knows (else heard in ``samples``)."""
    by_metre = isinstance(kind, TurnedKind) and bool(config.get("drawn_by_metre"))
    band = run_style_tempo(config) if isinstance(kind, TurnedKind) else None
    part = style_input_of(cfg)
    known = part.styles if part is not None else ()  # a style given that the run does not know is heard

    def compute(samples: np.ndarray, beats_per_bar: int | None, style: str | None = None) -> np.ndarray:
        frames = int(len(samples) / cfg.sample_rate * fps)
        starts = np.round(np.arange(frames) * cfg.sample_rate / fps).astype(np.int64)
        return compute_features(np.asarray(samples, np.float32), starts, cfg, beats_per_bar=beats_per_bar, style=style)[
            0
        ]

    def play(samples: np.ndarray, features: np.ndarray, beats_per_bar: int | None, style: str | None = None) -> float:
        if band is None:
            return 1.0
        factor, style = style_tempo_factor(samples, cfg, band, style if style in known else None)
        if factor != 1.0:  # the style input as the song is heard, not as the played music would be
            played = compute(stretch_audio(samples, factor, cfg.sample_rate), beats_per_bar, style)
            kind.know_played(features, played, factor)
        return factor

    def features_of(samples: np.ndarray, beats_per_bar: int | None = None) -> np.ndarray:
        features = compute(samples, beats_per_bar)
        if by_metre and beats_per_bar is not None:  # a song of that metre (stretched): drawn its metre's
            kind.know_metre(features, beats_per_bar)
        play(samples, features, beats_per_bar)
        return features

    features_of.sample_rate = cfg.sample_rate  # type: ignore[attr-defined]
    features_of.play = play  # type: ignore[attr-defined]
    return features_of


def _song_set(
    net: torch.nn.Module,
    recordings: list[dict[str, Any]],
    beats: dict[str, tuple],
    manifest: dict[str, Any],
    config: dict[str, Any],
    beats_per_bar: int | None = None,
    kind: Any = None,
) -> SongSet:
    kind = kind or with_turning(model_kind(model_name(config)), config)
    by_metre = isinstance(kind, TurnedKind) and bool(config.get("drawn_by_metre"))
    spec = TargetSpec.from_dict(config["dataset"]["target"])
    norm = Normalizer.from_dict(config["dataset"]["normalisation"])
    fps = config["dataset"]["fps"]
    cfg = feature_config(config["dataset"]["features"])
    inputs = {e["name"]: e for e in manifest["inputs"]}
    features_of = _features_maker(cfg, fps, kind, config)

    def body(values: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return body_positions(values, mask, spec, config["dataset"])

    def generate_many(jobs: list[tuple[np.ndarray, np.ndarray]]) -> list[np.ndarray]:
        runs = kind.free_runs(net, [f for f, _ in jobs], [p for _, p in jobs])
        return [body(v, np.ones_like(v, bool))[0] for v in (norm.invert(g, spec) for g in runs)]

    travel = _travel_joint(spec, config["dataset"])
    songs, metres = [], {}
    for r in recordings:
        music = beats[r["name"]][0]
        if music is None:
            continue
        try:
            samples = recording_audio(inputs[r["recording"]], r["info"], len(r["current"]), fps, cfg.sample_rate)
            rms = float(np.sqrt(np.mean(np.square(samples, dtype=np.float64)))) if samples.size else None
        except (KinectDataError, OSError):
            samples, rms = None, None
        metre = _recording_metre(r, inputs[r["recording"]], music, beats_per_bar, cfg.sample_rate, fps, samples)
        metres[r["name"]] = metre
        if by_metre:
            kind.know_metre(r["input"], metre.beats_per_bar)
        if isinstance(kind, TurnedKind):
            kind.know_place(r["input"], r["info"].get("root_anchor"))
        if samples is not None:  # as evaluate's own free runs (held_out_following calls this alone)
            _played_factor(r, samples, features_of, metre)
        first = r.get("first_pose")
        if first is None:
            first = kind.fill_previous(r["current"][0], r["mask"][0], config["dataset"]["start_pose"])
        positions, pmask = body(norm.invert(r["current"], spec, mask=r["mask"]), r["mask"])
        songs.append(
            HeldOutSong(
                r["name"], r["input"], first, positions, pmask, music, fps, rms, metre.beats_per_bar, travel, samples
            )
        )
    why = "" if songs else "no recording of the split has music beats (ground truth or tracked)"
    return SongSet(songs, generate_many, features_of, why, metres)


def split_songs(
    net: torch.nn.Module,
    run_config: dict[str, Any],
    dataset: str | Path,
    split: str = "test",
    *,
    beats_per_bar: int | None = None,
    checksums: bool = True,
    draw_seed: int = 0,
) -> SongSet:
    """The clean recordings of a dataset split as :class:`SongSet` for a network trained with
    ``run_config`` (a run's ``config.json``): e.g. to measure beat following during training.
    ``beats_per_bar``: the metre of the songs whose manifest entry does not give one (default:
    estimated from the music). ``draw_seed``: :func:`evaluate`'s."""
    dataset = Path(dataset)
    manifest = read_manifest(dataset, checksums=checksums)
    recordings = split_recordings(dataset, manifest, split)
    beats = split_beats(recordings, manifest, run_config["dataset"]["fps"])
    kind = with_turning(model_kind(model_name(run_config)), run_config, seed=draw_seed)
    return _song_set(net, recordings, beats, manifest, run_config, beats_per_bar, kind)


def listening_controls(
    net: torch.nn.Module,
    recordings: list[dict[str, Any]],
    beats: dict[str, tuple],
    manifest: dict[str, Any],
    config: dict[str, Any],
    *,
    seed: int = 0,
    free: dict[str, np.ndarray] | None = None,
    beats_per_bar: int | None = None,
    tempo_rates: tuple[float, ...] | None = None,
    kind: Any = None,
) -> dict[str, Any]:
    """The beat-following figures with their chance levels and the listening controls
    (:func:`~kinectdata.evaluation.listening.listening_report`) over the recordings whose beats are
    known (ground truth or tracked), as JSON-ready figures with ``verdicts``; ``{"unavailable": why}``
    when no recording has beats or the motion is too short for them. ``free``: per recording, its
    free run without reset, denormalised [T-1, D], when the caller has made it (not run again). ``kind``:
    the model kind the free runs are made with (default: the run's, its turning and travel drawn)."""
    found = _song_set(net, recordings, beats, manifest, config, beats_per_bar, kind)
    if not found.songs:
        return {"unavailable": found.unavailable}
    try:
        spec = TargetSpec.from_dict(config["dataset"]["target"])
        done = {
            name: body_positions(values, np.ones_like(values, bool), spec, config["dataset"])[0]
            for name, values in (free or {}).items()
        }
        report = listening_report(
            found.songs,
            found.generate,
            found.features_of,
            seed=seed,
            generated=done,
            generate_many=found.generate_many,
            tempo_rates=tempo_rates,
        ).to_dict()
        report["metres"] = {
            name: {"beats_per_bar": m.beats_per_bar, "source": m.source, "scores": m.scores}
            for name, m in found.metres.items()
        }
        return report
    except KinectDataError as exc:  # too short for two bars of lags, too few beats
        return {"unavailable": str(exc)}


def _shown_components(names: list[str]) -> list[int]:
    """A few telling components: the first position's height and the hands', and a joint's qw."""
    wanted = [n for n in names if n.endswith(".y")][:3] + [n for n in names if n.endswith(".qw")][1:2]
    return [names.index(n) for n in wanted] or list(range(min(4, len(names))))


def format_results(results: dict[str, Any]) -> str:
    """The lines ``kinectdata evaluate`` prints."""
    s = results["smape"]
    lines = [
        f"split {results['split']}: {len(results['recordings'])} recordings, free-running from the first true pose"
    ]
    if results.get("turning"):
        lines.append(f"  {results['turning']}; drawn with seed {results.get('draw_seed', 0)}")
    if results.get("smoothing", NOT_SMOOTHED) != NOT_SMOOTHED:
        lines.append(f"  the motion {results['smoothing']}")
    tempo = results.get("style_tempo") or {"line": AS_IT_IS, "played": {}}
    if tempo["line"] != AS_IT_IS:
        moved = ", ".join(f"{name} x{factor:.2f}" for name, factor in tempo["played"].items())
        lines.append(f"  {tempo['line']}: {moved or 'no song of the split needed it'}")
    for mode, v in s.items():
        lines.append(
            f"  SMAPE {mode.replace('_', ' '):<14} {v['smape_normalised']:6.2f} % normalised, "
            f"{v['smape_denormalised']:6.2f} % denormalised (0/0 counts as 0)"
        )
    for name, t in results["forward_time"].items():
        lines.append(
            f"  forward time   {t['median_ms']:.3f} ms median, {t['p95_ms']:.3f} ms p95 per frame "
            f"(batch 1, streaming, {name}, {t['device']}, {t['threads']} thread{'' if t['threads'] == 1 else 's'})"
        )
    sil = results["silence_test"]
    lines.append(
        f"  silence test   {sil['silence_seconds']:g} s inserted in {sil['recording']}: motion energy inside "
        f"{sil['energy_inside']:.3g} vs outside {sil['energy_outside']:.3g} (ratio {sil['energy_ratio']:.2g}); "
        f"silent features identical: {sil['silent_features_identical']} (all {sil['silent_feature_value']:g})"
    )
    rhythm = results.get("rhythm", {}).get("summary", {})
    listening = results.get("listening", {})
    if listening.get("metres"):
        said = ", ".join(f"{name} {m['beats_per_bar']} ({m['source']})" for name, m in listening["metres"].items())
        lines.append(f"  metre          beats per bar: {said}")
    if "verdicts" in listening:
        lines += [f"  {line}" for line in listening["verdicts"]]
    elif listening:
        lines.append(f"  listening      not measured: {listening['unavailable']}")
    field = results.get("field", {})
    if "table" in field:
        lines.append("  the field's metrics, generated against the real motion of the same songs (metrics.json):")
        lines += [f"    {line}" for line in field["table"].splitlines()]
        scored = field["scored_motion"]
        lines.append(
            f"    the scored motion: {scored} (the same table: kinectdata score {scored}/generated {scored}/real "
            f"--beats {scored}/beats.json --protocol {field['protocol']})"
        )
    elif field:
        lines.append(f"  field metrics  not measured: {field['unavailable']}")
    for entry in [field, *results.get("field_protocols", {}).values()]:
        lines += _comparison_lines(entry)
    lines += _variety_lines(field, results.get("style", {}))
    if rhythm.get("unavailable"):
        lines.append(f"  rhythm         {rhythm['unavailable']} recordings without beats (see results.json)")
    lines.append("  figures        " + ", ".join(results["figures"]))
    return "\n".join(lines)


BASELINE_NAMES = {
    "mean_pose_noise": "the mean training pose + noise at the training dances' speed",
    "retrieval": "a training dance chosen by its music (retrieval)",
    "mean_pose_noise_own_speed": "the same noise at each song's own speed (an oracle: it knows the answer's speed)",
}
"""How :func:`format_results` names the baselines of :func:`baseline_runs`."""


VARIED_AT_LEAST = 0.5
"""Generated dances are as varied as the music when their Div_k is at least this share of the real dancers'."""


def variety(field: dict[str, Any]) -> tuple[float, float] | None:
    """(Div_k of the generated dances, Div_k of the real dances of the same songs) from a field entry
    of :func:`evaluate`'s results, or None when not scored."""
    row = field.get("metrics", {}).get("Div_k")
    if row is None or row.get("generated") is None or not row.get("reference"):
        return None
    return float(row["generated"]), float(row["reference"])


def _variety_lines(field: dict[str, Any], style: dict[str, Any]) -> list[str]:
    """The variety verdict (Div_k against the real dancers') and the style verdict."""
    lines = []
    divs = variety(field)
    if divs is not None:
        made, real = divs
        lines.append(
            f"  as varied as the real dancers: {'yes' if made >= VARIED_AT_LEAST * real else 'no'} (Div_k {made:.3g} "
            f"against the real dancers' {real:.3g} = {made / real:.2f} x; wanted at least {VARIED_AT_LEAST:g} x)"
        )
    if "verdict" in style:
        lines.append(f"  {style['verdict']}")
    elif style:
        lines.append(f"  style          not measured: {style['unavailable']}")
    return lines


def _comparison_lines(entry: dict[str, Any]) -> list[str]:
    """One line per baseline: does the model beat it (lower FID_k and FID_g) under the entry's protocol."""

    def number(v: float | None) -> str:
        return "n/a" if v is None else f"{v:.3g}"

    lines = []
    for name, row in entry.get("comparison", {}).items():
        lines.append(
            f"  beats {BASELINE_NAMES.get(name, name)} ({entry['protocol']}): {'yes' if row['beats'] else 'no'} "
            f"(FID_k {number(row['FID_k'])} vs {number(row['FID_k_baseline'])}, "
            f"FID_g {number(row['FID_g'])} vs {number(row['FID_g_baseline'])})"
        )
    return lines
