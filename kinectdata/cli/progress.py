"""The one progress bar of the commands: library functions report ``progress(done, total)`` through
a callback (they never print), and the command shows it with tqdm (hidden when not a terminal)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

from tqdm import tqdm

Progress = Callable[[int, int], None]


@contextmanager
def progress_bar(desc: str, unit: str) -> Iterator[Progress]:
    """A ``progress(done, total)`` callback drawing a tqdm bar on stderr for the ``with`` block."""
    with tqdm(total=None, unit=unit, desc=desc, disable=None) as bar:

        def progress(done: int, total: int) -> None:
            bar.total = total
            bar.update(done - bar.n)

        yield progress
