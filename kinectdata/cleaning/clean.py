"""A recording cleaned as a capture studio would, stage by stage, with a report of what each changed.

:func:`clean_motion` runs the stages :class:`CleanConfig` asks for, in this order:

0. **sides** (:mod:`.sides`): the stretches where a frontal tracker mirrored a dancer seen from
   behind (her left joints labelled right) found and swapped back;
1. **gaps** (:mod:`.gaps`): inferred samples that jump away from their tracked neighbours taken out,
   and gaps up to ``max_gap_s`` filled as ``align`` fills them; longer ones left masked and listed;
2. **jitter** (:mod:`.jitter`): the short-time Wiener smoother (the default, :mod:`.wiener`: offline,
   no delay, its cutoff following the motion window by window), a zero-phase Butterworth low-pass,
   a Savitzky-Golay smoother, or the 1-euro filter (causal: what a live system can do, at the price
   of a lag on fast joints), per joint, each sample weighted by its confidence;
3. **bone lengths** (:mod:`.bones`): each bone held to the recording's median length (or one given):
   each bone's error shared by both its ends, then exact from the root out along its direction.

The cleaned recording keeps the joint set, the frame times, the masks (but where gaps were filled),
the confidences (a filled sample's at most 0.5), the orientations (filled across short gaps too, not
filtered) and the metadata (its placement among them), with
``metadata["cleaned"]`` saying what was done. The :class:`CleanReport` gives, for each stage, the
frames and joints it moved and by how much, and for the whole the bone-length CV and the jerk before
and after.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinectdata.cleaning.bones import hold_bone_lengths, lengths_by_name
from kinectdata.cleaning.gaps import GapReport, fill_gaps
from kinectdata.cleaning.jitter import ONE_EURO_DEFAULTS, one_euro, zero_phase
from kinectdata.cleaning.sides import SideSwaps, find_side_swaps
from kinectdata.cleaning.wiener import NOISE_BAND, WIENER_DEFAULTS
from kinectdata.core.body_quality import bone_length_variation, mean_jerk
from kinectdata.core.errors import ConfigError
from kinectdata.core.motion import Motion, frame_clock, sides_exchanged

JITTER_FILTERS = ("one_euro", "butterworth", "savgol", "wiener", "none")
MOVED_M = 1e-4
"""A joint's sample counts as moved by a stage when it moved more than this (a tenth of a millimetre)."""


@dataclass(frozen=True)
class CleanConfig:
    """What :func:`clean_motion` does.

    Attributes:
        sides: find and swap back the stretches whose left and right labels are mirrored.
        up: the unit vector pointing up in the recording's right-handed coordinates (+y: Kinect
            v1/v2 camera space, BVH; -y: Azure Kinect's camera space), for the sides' feet.
        gaps: take out inferred jumps and fill short gaps.
        max_gap_s: the longest gap filled, seconds.
        jump_m: how far an inferred sample may lie from its tracked neighbours' line, metres.
        jitter: ``butterworth`` (default), ``savgol``, ``one_euro`` or ``none``.
        min_cutoff_hz, beta, d_cutoff_hz: the 1-euro filter's settings (Hz, Hz per m/s, Hz).
        cutoff_hz, order: the Butterworth low-pass (Hz, order before the backward pass).
        window_s: the Savitzky-Golay window, seconds.
        wiener_window_s, over_subtraction: the short-time Wiener smoother (:mod:`.wiener`; seconds,
            and how many times the noise's power is taken away).
        bones: hold each bone to one length.
        spread: share each bone's error in length between its two ends before the exact pass from the
            root out (False: only that pass, every bone keeping its measured direction exactly).
        bone_lengths: ``{child joint: metres}`` for the bones of a measured body (the others the
            recording's own median).
    """

    sides: bool = True
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    gaps: bool = True
    max_gap_s: float = 0.2
    jump_m: float = 0.1
    jitter: str = "wiener"
    min_cutoff_hz: float = ONE_EURO_DEFAULTS["min_cutoff_hz"]
    beta: float = ONE_EURO_DEFAULTS["beta"]
    d_cutoff_hz: float = ONE_EURO_DEFAULTS["d_cutoff_hz"]
    cutoff_hz: float = 6.0
    order: int = 2
    window_s: float = 0.3
    wiener_window_s: float = WIENER_DEFAULTS["window_s"]
    over_subtraction: float = WIENER_DEFAULTS["over_subtraction"]
    bones: bool = True
    spread: bool = True
    bone_lengths: dict[str, float] = field(default_factory=dict)

    @classmethod
    def from_settings(cls, settings: Mapping[str, Any], where: str = "clean") -> CleanConfig:
        """The configuration of ``settings`` (field names to values, as a recordings manifest's
        ``clean`` or a dataset's configuration gives them: lists for ``up``); ConfigError naming
        ``where`` and the first unknown field or bad value."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(settings) - names)
        if unknown:
            raise ConfigError(f"{where}: no cleaning setting {', '.join(unknown)} (known: {', '.join(sorted(names))})")
        given = dict(settings)
        if "up" in given:
            given["up"] = tuple(float(v) for v in given["up"])
        try:
            return cls(**given)
        except ConfigError as error:
            raise ConfigError(f"{where}: {error}") from None

    def settings(self) -> dict[str, Any]:
        """The fields that differ from the defaults (JSON values), as :meth:`from_settings` takes them."""
        default = CleanConfig().resolved()
        return {name: value for name, value in self.resolved().items() if value != default[name]}

    def resolved(self) -> dict[str, Any]:
        """Every field as JSON values: what runs, whatever today's defaults are (a dataset's work
        files are keyed on it, so that a changed default is not taken for the cleaning they had)."""
        out = dataclasses.asdict(self)
        out["up"] = list(out["up"])
        return out

    def __post_init__(self) -> None:
        if len(self.up) != 3 or not np.isclose(np.linalg.norm(self.up), 1.0):
            raise ConfigError(f"up must be a unit vector of 3 numbers, not {self.up!r}")
        if self.jitter not in JITTER_FILTERS:
            raise ConfigError(f"jitter filter {self.jitter!r} is not one of {', '.join(JITTER_FILTERS)}")


@dataclass(frozen=True)
class StageReport:
    """What one stage changed.

    Attributes:
        stage: ``jitter`` or ``bones`` (the gaps have their own report, :class:`~.gaps.GapReport`).
        detail: what it was (``one_euro: min cutoff 1 Hz, beta 0.7 Hz per m/s``).
        samples_moved: joint samples moved by more than :data:`MOVED_M`.
        frames_touched: frames with at least one such sample.
        joints_touched: names of the joints with at least one.
        mean_shift_mm: the mean distance a valid sample moved, millimetres.
        max_shift_mm: the largest, millimetres.
    """

    stage: str
    detail: str
    samples_moved: int
    frames_touched: int
    joints_touched: tuple[str, ...]
    mean_shift_mm: float
    max_shift_mm: float


@dataclass(frozen=True)
class SidesReport:
    """What the sides stage found and swapped back.

    Attributes:
        intervals_s: ``(start, end)`` seconds of each mirrored stretch repaired.
        frames: frames repaired.
        flips: frames where the labels jumped.
        judged_by: ``feet`` or ``majority`` (:class:`~.sides.SideSwaps`).
        skipped: why the stage could not run (a joint set without mirrored pairs), else empty.
    """

    intervals_s: tuple[tuple[float, float], ...]
    frames: int
    flips: int
    judged_by: str
    skipped: str = ""


@dataclass(frozen=True)
class CleanReport:
    """What :func:`clean_motion` did: its stages, the gaps (None when not asked), and the bone-length
    CV (mean over bones) and the mean jerk (m/s^3, on the recording's median frame interval) before
    and after; ``sides`` is None when that stage was not asked for."""

    stages: tuple[StageReport, ...]
    gaps: GapReport | None
    bone_cv_before: float
    bone_cv_after: float
    jerk_before: float
    jerk_after: float
    sides: SidesReport | None = None

    def lines(self) -> list[str]:
        """The report as lines for a person."""
        out = []
        if self.sides is not None and self.sides.skipped:
            out.append(f"sides: not looked at ({self.sides.skipped})")
        elif self.sides is not None and not self.sides.intervals_s:
            out.append("sides: no mirrored stretch found")
        elif self.sides is not None:
            where = ", ".join(f"{a:.2f}-{b:.2f} s" for a, b in self.sides.intervals_s)
            out.append(
                f"sides: {len(self.sides.intervals_s)} mirrored stretches swapped back ({self.sides.frames} frames; "
                f"judged by the {self.sides.judged_by}){': ' + where if where else ''}"
            )
        g = self.gaps
        if g is not None:
            left = f" ({', '.join(g.joints_left)}; the longest {g.longest_left_s:.2f} s)" if g.gaps_left else ""
            out.append(
                f"gaps: {g.jumps_replaced} inferred jumps taken out; {g.gaps_filled} gaps filled ({g.samples_filled} "
                f"samples, up to {g.max_gap_s:g} s); {g.gaps_left} left masked{left}"
            )
        for s in self.stages:
            out.append(
                f"{s.stage}: {s.detail}; moved {s.samples_moved} samples in {s.frames_touched} frames, "
                f"{len(s.joints_touched)} joints, by {s.mean_shift_mm:.1f} mm on average (at most {s.max_shift_mm:.1f})"
            )
        out.append(f"bone-length CV {self.bone_cv_before:.4f} -> {self.bone_cv_after:.4f}")
        out.append(f"mean jerk {self.jerk_before:.1f} -> {self.jerk_after:.1f} m/s^3")
        return out

    def to_json(self) -> str:
        return json.dumps(dataclasses.asdict(self), indent=1, allow_nan=True)


@dataclass(frozen=True)
class Cleaned:
    """A cleaned recording and its report."""

    motion: Motion
    report: CleanReport


def clean_motion(motion: Motion, config: CleanConfig | None = None) -> Cleaned:
    """Clean a 3-D recording (see the module docstring).

    Raises:
        ConfigError: a 2-D joint set, fewer than 4 frames, or settings that do not fit the recording.
    """
    config = config or CleanConfig()
    js = motion.joint_set
    where = f"{motion.metadata['source']}: " if motion.metadata.get("source") else ""
    if js.dimensions != 3:
        raise ConfigError(f"{where}cleaning needs 3-D joints in metres; joint set {js.name} is {js.dimensions}-D")
    if motion.n_frames < 4:
        raise ConfigError(f"{where}cleaning needs at least 4 frames, the recording has {motion.n_frames}")
    interval, _ = frame_clock(motion.times)
    fps = 1.0 / interval
    stages, gaps, sides = [], None, None
    source = motion
    if config.sides:
        motion, sides = _swap_sides(motion, config.up)
    if config.gaps:
        motion, gaps = fill_gaps(motion, config.max_gap_s, config.jump_m)
    mask = motion.position_mask
    positions = np.where(mask[..., None], motion.positions, np.nan)
    if config.jitter != "none":
        if config.jitter == "one_euro":
            detail = (f"one_euro: min cutoff {config.min_cutoff_hz:g} Hz, beta {config.beta:g} Hz per m/s, "
                      f"speed cutoff {config.d_cutoff_hz:g} Hz")  # fmt: skip
            moved = one_euro(positions, motion.times, mask, motion.confidence, min_cutoff_hz=config.min_cutoff_hz,
                             beta=config.beta, d_cutoff_hz=config.d_cutoff_hz)  # fmt: skip
        else:
            detail = {
                "butterworth": f"butterworth: {config.cutoff_hz:g} Hz, order {config.order}, forwards and backwards",
                "savgol": f"savgol: cubic over {config.window_s:g} s",
                "wiener": f"wiener: windows of {config.wiener_window_s:g} s, {config.over_subtraction:g} x the noise "
                f"measured above {NOISE_BAND * fps / 2:.3g} Hz taken away",
            }[config.jitter]
            moved = zero_phase(positions, fps, mask, motion.confidence, method=config.jitter,
                               cutoff_hz=config.cutoff_hz, order=config.order, window_s=config.window_s,
                               times=motion.times, wiener_window_s=config.wiener_window_s,
                               over_subtraction=config.over_subtraction)  # fmt: skip
        stages.append(_stage("jitter", detail, positions, moved, mask, js.names))
        positions = moved
    if config.bones:
        given = lengths_by_name(js.names, config.bone_lengths) if config.bone_lengths else None
        moved, held = hold_bone_lengths(positions, js.parents, mask, given, config.spread)
        told = f" ({len(config.bone_lengths)} given)" if config.bone_lengths else ""
        how = "its error spread over both ends, then exact from the root out" if config.spread else "from the root out"
        detail = f"each bone at its median length{told}: {how}"
        stages.append(_stage("bones", detail, positions, moved, mask, js.names))
        positions = moved
    cleaned = dataclasses.replace(
        motion,
        positions=positions,
        position_mask=mask,
        metadata={**motion.metadata, "cleaned": "; ".join(s.detail for s in stages) or "nothing"},
    )
    report = CleanReport(
        tuple(stages),
        gaps,
        _mean_cv(source.positions, js.parents, source.position_mask),
        _mean_cv(positions, js.parents, mask),
        mean_jerk(source.positions, fps, source.position_mask),
        mean_jerk(positions, fps, mask),
        sides,
    )
    return Cleaned(cleaned, report)


def _swap_sides(motion: Motion, up) -> tuple[Motion, SidesReport]:
    try:
        found: SideSwaps = find_side_swaps(motion.positions, motion.position_mask, motion.joint_set, up)
    except ConfigError as error:  # a joint set with no left and right to swap: nothing to repair
        return motion, SidesReport((), 0, 0, "", str(error))
    frames = found.frames(motion.n_frames)
    t = motion.times
    report = SidesReport(
        tuple((float(t[a]), float(t[b])) for a, b in found.intervals),
        int(frames.sum()),
        len(found.flips),
        found.judged_by,
    )
    return sides_exchanged(motion, frames), report


def _stage(stage: str, detail: str, before: np.ndarray, after: np.ndarray, mask: np.ndarray, names) -> StageReport:
    shift = np.where(mask, np.linalg.norm(np.nan_to_num(after - before), axis=-1), 0.0)
    moved = shift > MOVED_M
    return StageReport(
        stage,
        detail,
        int(moved.sum()),
        int(moved.any(axis=1).sum()),
        tuple(n for n, m in zip(names, moved.any(axis=0)) if m),
        float(1e3 * shift[mask].mean()) if mask.any() else 0.0,
        float(1e3 * shift.max()) if mask.any() else 0.0,
    )


def _mean_cv(positions: np.ndarray, parents, mask: np.ndarray) -> float:
    cv = bone_length_variation(positions, parents, mask)
    return float(np.nanmean(cv)) if np.isfinite(cv).any() else float("nan")
