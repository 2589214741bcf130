"""The headline figures of every benchmark, gathered for the table ``python -m benchmarks`` ends with."""

from __future__ import annotations

FIGURES: list[tuple[str, str, str]] = []
"""(area, what, figure) in the order recorded."""


def record(area: str, what: str, figure: str) -> None:
    """Add one figure (already formatted, with its unit) to the closing table."""
    FIGURES.append((area, what, figure))


def table() -> str:
    """The recorded figures as a Markdown table."""
    lines = ["| area | what | figure |", "| --- | --- | ---: |"]
    lines += [f"| {area} | {what} | {figure} |" for area, what, figure in FIGURES]
    return "\n".join(lines)
