"""Writing matplotlib figures headless (the Agg backend) as PNG, atomically to a path or into a
binary stream. Each stage that draws figures (training, evaluation, the report) uses these."""

from __future__ import annotations

from pathlib import Path
from typing import BinaryIO

from kinectdata.core.atomic import atomic_output


def pyplot():
    """matplotlib.pyplot on the headless Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_png(fig, out: str | Path | BinaryIO) -> str | Path | BinaryIO:
    """Save ``fig`` as PNG to a path (atomically) or into a binary stream, close it; returns ``out``."""
    if isinstance(out, (str, Path)):
        out = Path(out)
        with atomic_output(out) as tmp:
            fig.savefig(tmp, dpi=110, bbox_inches="tight", format="png")
    else:
        fig.savefig(out, dpi=110, bbox_inches="tight", format="png")
    pyplot().close(fig)
    return out
