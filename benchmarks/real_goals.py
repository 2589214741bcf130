"""Issue 56's goals a-e for a run scored on real dance, each a list of figures with their bounds,
and the same goals read over several seeds (met in every seed, the worst figure, the spread).

- a. alive and human: energy 0.5-2 x the real motion's, jerk and foot contact (PFC) at most 2 x,
  bone-length CV at most the real dancers', the turning at least a quarter of the energy (when
  the real dancers turn at all);
- b. no fixed oscillator: the dominant periods rank with the songs' tempi at least as well as the
  real motion's (their p, spread and the swapped song's change printed beside);
- c. listens: the motion follows the beat, the swapped-song, noise and shifted-audio controls pass,
  silence stops the motion (energy at most 0.1 x), and the tempo control: at least 12 of 14 pairs
  follow (on the folds, following the beat is asked only where the real dancers follow it);
- d. per protocol, FID_k at most 0.8 x the mean training pose + noise baseline's;
- e. varied as the music: Div_k at least half the real dancers', and at least 5 of 6 generated
  dances (those whose style a training dance holds) named as their song's style.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from kinectdata.evaluation.evaluate import VARIED_AT_LEAST, variety
from kinectdata.evaluation.listening import ALIVE_RANGE, SILENCE_STOPS
from kinectdata.evaluation.tempo_control import FOLLOWS_AT_LEAST

TURNING_SHARE = 0.25
"""Goal a: the turning's share of the generated motion's energy, at least."""
FID_SHARE = 0.8
"""Goal d: FID_k at most this share of the mean-pose + noise baseline's."""
STYLE_RIGHT = 5 / 6
"""Goal e: the share of the generated dances named as their song's style, at least."""


@dataclass(frozen=True)
class Figure:
    """One checked figure: its value and the bounds it must lie within (None: open).

    Attributes:
        name: what it is.
        value: the figure (None: not measured, which fails).
        low, high: the bounds, inclusive.
        shown: how the value is printed (default ``f"{value:.3g}"``).
    """

    name: str
    value: float | None
    low: float | None = None
    high: float | None = None
    shown: str = ""

    @property
    def ok(self) -> bool:
        v = self.value
        return (
            v is not None
            and not math.isnan(v)
            and (self.low is None or v >= self.low - 1e-12)
            and (self.high is None or v <= self.high + 1e-12)
        )

    @property
    def margin(self) -> float:
        """How far inside its bounds the value lies, as a share of the nearer bound (negative: outside);
        -inf when not measured."""
        if self.value is None or math.isnan(self.value):
            return -math.inf
        sides = []
        if self.low is not None:
            sides.append((self.value - self.low) / max(abs(self.low), 1e-9))
        if self.high is not None:
            sides.append((self.high - self.value) / max(abs(self.high), 1e-9))
        return min(sides) if sides else math.inf

    def text(self) -> str:
        value = self.shown or ("n/a" if self.value is None else f"{self.value:.3g}")
        return f"{self.name} {value} ({self.wanted()})"

    def wanted(self) -> str:
        if self.low is not None and self.high is not None:
            return f"{self.low:.3g}-{self.high:.3g}"
        if self.low is not None:
            return f">= {self.low:.3g}"
        return f"<= {self.high:.3g}" if self.high is not None else "shown"

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "value": self.value, "low": self.low, "high": self.high, "ok": self.ok}


@dataclass(frozen=True)
class Goal:
    """One goal: its checked figures and what else is printed beside them."""

    key: str
    title: str
    figures: tuple[Figure, ...]
    note: str = ""

    @property
    def met(self) -> bool:
        return bool(self.figures) and all(f.ok for f in self.figures)

    def line(self) -> str:
        shown = "; ".join(f.text() for f in self.figures) or "not measured"
        return (
            f"{self.key}. {self.title}: {'yes' if self.met else 'no'} ({shown}{'; ' + self.note if self.note else ''})"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "key": self.key,
            "title": self.title,
            "met": self.met,
            "figures": [f.to_dict() for f in self.figures],
            "note": self.note,
        }


def _flag(name: str, value: bool | None) -> Figure:
    """A yes-or-no check as a figure (1 yes, 0 no)."""
    return Figure(name, None if value is None else float(bool(value)), low=1.0,
                  shown="n/a" if value is None else ("yes" if value else "no"))  # fmt: skip


def _ratio(metrics: dict[str, Any], name: str) -> float | None:
    row = metrics.get(name, {})
    g, r = row.get("generated"), row.get("reference")
    return None if g is None or not r else g / r


def _furthest(entry: dict[str, Any]) -> str:
    """The kinetic feature whose mean lies furthest from the dancers' (``largest_gaps``, scored
    since 2026-12-07), for d's note: what the FID_k is made of."""
    gaps = entry.get("metrics", {}).get("FID_k", {}).get("largest_gaps") or []
    if not gaps:
        return ""
    top = gaps[0]
    at = f"{top['ratio']:.2f} x theirs" if top.get("ratio") is not None else f"{top['generated']:.3g}, theirs 0"
    return f"; furthest from the dancers': {top['what']} {at} ({abs(top['sds']):.1f} sd)"


def goals(results: dict[str, Any], beat_where_real: bool = False) -> list[Goal]:
    """Goals a-e (module docstring) from ``evaluate``'s results. ``beat_where_real``: c asks the
    generated motion to follow the beat only when the real dancers do on the same songs (the folds: a
    fold of ten waltzes at one tempo gives the beat no chance to show, the real dancers' included)."""
    listening = results["listening"]
    field = results["field"]
    metrics = field.get("metrics", {})
    out = []
    if "verdicts" in listening:
        bone = metrics.get("bone CV", {})
        turning = listening.get("turning")
        alive = [
            Figure("energy", listening["energy_ratio"], *ALIVE_RANGE, shown=f"{listening['energy_ratio']:.2f} x"),
            Figure("jerk", _ratio(metrics, "jerk"), high=2.0, shown=_times(_ratio(metrics, "jerk"))),
            Figure("PFC", _ratio(metrics, "PFC"), high=2.0, shown=_times(_ratio(metrics, "PFC"))),
            Figure("bone CV", bone.get("generated"), high=bone.get("reference")),
        ]
        note = ""
        if turning and turning.get("asked"):
            share = turning["generated_share"]
            alive.append(Figure("turning share", share, low=TURNING_SHARE, shown=f"{share:.0%}"))
            rate, real_share = turning["real_rate_rad_s"], turning["real_share"]
            note = f"the real dancers turn {rate:.2f} rad/s, {real_share:.0%} of theirs"
            if "spread_ratio" in turning:  # results scored before the spread was measured have none
                note += f"; the body {turning['spread_ratio']:.2f} x as wide about the vertical"
        out.append(Goal("a", "alive and human", tuple(alive), note))
        gen, real = listening["generated"], listening["real"]
        spread = listening["period_spread"]
        out.append(
            Goal(
                "b",
                "no fixed oscillator",
                (Figure("tempo rank", gen["tempo_correlation"], low=real["tempo_correlation"]),),
                f"p {_num(gen['tempo_p_value'])}; periods spread {_num(spread)} x; the period changed with a swapped "
                f"song in {_pct(listening['swapped_period_changes'])} of runs",
            )
        )
        tempo = listening.get("tempo")
        pairs = None if tempo is None else len(tempo["pairs"])
        beat = _flag("follows the beat", gen["follows_beat"])
        asked = real["follows_beat"] or not beat_where_real
        c = [
            *([beat] if asked else []),
            _flag("a swapped song followed", listening["follows_swapped"]),
            _flag("noise not followed", listening["ignores_noise"]),
            _flag("shifted audio at chance", listening["shifted_at_chance"]),
            Figure(
                "silence",
                listening["silence_energy_ratio"],
                high=SILENCE_STOPS,
                shown=f"{listening['silence_energy_ratio']:.2g} x",
            ),  # fmt: skip
            Figure(
                "tempo pairs followed",
                None if tempo is None else tempo["followed"],
                low=None if pairs is None else math.ceil(FOLLOWS_AT_LEAST * pairs - 1e-9),
                shown=f"not measured: {listening.get('tempo_unavailable')}"
                if tempo is None
                else f"{tempo['followed']} of {pairs}"
                + (f", stretched by {tempo['stretcher']}" if tempo.get("stretcher") else ""),
            ),  # fmt: skip
        ]
        note = _listening_note(listening)
        if not asked:
            in_metre = real["in_metre"]
            note = (f"follows the beat not asked: nor do the real dancers on these songs ({in_metre['value']:.0%} at "
                    f"a metrical level, chance {in_metre['chance']:.0%}, p {_num(in_metre['p_value'])}; the "
                    f"generated {gen['in_metre']['value']:.0%}); {note}")  # fmt: skip
        out.append(Goal("c", "listens", tuple(c), note))
    for name, entry in [("bailando", field), *results.get("field_protocols", {}).items()]:
        versus = entry.get("comparison", {}).get("mean_pose_noise", {})
        fid, baseline = versus.get("FID_k"), versus.get("FID_k_baseline")
        share = None if fid is None or not baseline else fid / baseline
        retrieval = entry.get("comparison", {}).get("retrieval", {}).get("FID_k_baseline")
        out.append(
            Goal(
                "d",
                f"FID_k against the mean pose + noise ({entry.get('protocol', name)})",
                (
                    Figure(
                        "FID_k / the baseline's",
                        share,
                        high=FID_SHARE,
                        shown="n/a" if share is None else f"{fid:.3g} / {baseline:.3g} = {share:.2f}",
                    ),
                ),  # fmt: skip
                entry.get("unavailable", f"retrieval's FID_k {_num(retrieval)}{_furthest(entry)}"),
            )
        )
    divs = variety(field)
    style = results.get("style", {})
    counted = len(style.get("counted", []))
    e = [
        Figure(
            "Div_k / the real dancers'",
            None if divs is None else divs[0] / divs[1],
            low=VARIED_AT_LEAST,
            shown="n/a" if divs is None else f"{divs[0]:.3g} / {divs[1]:.3g} = {divs[0] / divs[1]:.2f}",
        ),  # fmt: skip
        Figure(
            "dances in their song's style",
            style.get("right"),
            low=math.ceil(STYLE_RIGHT * counted - 1e-9) if counted else None,
            shown=f"{style['right']} of {counted}" if "right" in style else f"not measured: {style.get('unavailable')}",
        ),
    ]
    out.append(Goal("e", "as varied as the music", tuple(e), _styles_named(style)))
    return out


def _styles_named(style: dict[str, Any]) -> str:
    """Each dance's song style and the style named, with the style heard where the run heard another
    (:class:`~kinectdata.evaluation.style.StyleReport`): a run that dances what it hears names no
    more songs right than it hears; and how many of the songs' real dances are named right (the
    figure a run that danced as the dancers did would reach)."""
    songs, heard = style.get("songs", {}), style.get("heard", {})
    named = ", ".join(
        f"{n} {s['style']} -> {s['named']}" + (f" (heard {heard[n]})" if heard.get(n, s["style"]) != s["style"] else "")
        for n, s in songs.items()
    )
    if style.get("dancers"):
        named += f"; {style['dancers']}"
    if style.get("hearing"):
        named += f"; {style['hearing']}"
    return named


def _listening_note(listening: dict[str, Any]) -> str:
    noise = listening["noise"]
    return (
        f"swapped song at the new song's metre {_pct(listening['swapped_follows_new'])}, the old one's "
        f"{_pct(listening['swapped_follows_old'])}; noise at a metrical level "
        f"{_pct(None if noise is None else noise['in_metre']['value'])}; shifted audio's Beat Align Score "
        f"{listening['shifted']['beat_align_music']['value']:.3f} (chance "
        f"{listening['shifted']['beat_align_music']['chance']:.3f})"
    )


def across_seeds(per_seed: dict[int, Sequence[Goal]]) -> list[str]:
    """Each goal over the seeds: met in how many (and which missed), then each figure's worst value
    (the seed where it lies least inside its bounds) and its range over the seeds."""
    seeds = list(per_seed)
    lines = []
    for i, goal in enumerate(per_seed[seeds[0]]):
        runs = {s: per_seed[s][i] for s in seeds}
        missed = [s for s, g in runs.items() if not g.met]
        head = f"{goal.key}. {goal.title}: met in {len(seeds) - len(missed)} of {len(seeds)} seeds" + (
            f" (missed in seed {', '.join(map(str, missed))})" if missed else ""
        )
        parts = []
        for k in range(len(goal.figures)):
            taken = {s: g.figures[k] for s, g in runs.items() if k < len(g.figures)}
            worst_seed = min(taken, key=lambda s: taken[s].margin)
            values = [f.value for f in taken.values() if f.value is not None and not math.isnan(f.value)]
            spread = ""
            if len(values) > 1:
                low, high = f"{min(values):.3g}", f"{max(values):.3g}"
                spread = ", the same in every seed" if low == high else f", over the seeds {low}-{high}"
            parts.append(f"{taken[worst_seed].text()} at worst (seed {worst_seed}){spread}")
        lines.append(head + ("; " + "; ".join(parts) if parts else ""))
    met_everywhere = sum(all(per_seed[s][i].met for s in seeds) for i in range(len(per_seed[seeds[0]])))
    lines.append(f"goals met in every seed: {met_everywhere} of {len(per_seed[seeds[0]])}")
    return lines


def _times(v: float | None) -> str:
    return "n/a" if v is None else f"{v:.2f} x"


def _pct(v: float | None) -> str:
    return "n/a" if v is None else f"{v:.0%}"


def _num(v: Any) -> str:
    return "n/a" if v is None else f"{v:.3g}"
