"""librosa, imported one process at a time the first time a process needs it.

librosa compiles a few functions with numba's ``guvectorize(..., cache=True)`` when its ``util``
module is first imported (``localmax``, ``localmin``, ``peak_pick``: the beat tracker calls them),
and keeps what it compiled in a cache beside its code. Two processes compiling them at the same
moment can leave a cache whose two halves disagree (numba issue #10128, open in numba 0.68; the fix
proposed in numba pull request #10545), after which every process that loads it dies of a
segmentation fault until the cache is deleted. A parallel dataset build, a test suite on several
workers or two commands started together do exactly that: it happened here to a benchmark and a
test run started side by side. So the first import in each process, and the first call of those
functions, happen under a file lock (:mod:`filelock`): the first process compiles and writes the
cache, the others wait and then load it whole.

If your librosa already crashes with ``Segmentation fault`` in ``librosa/util/utils.py``, its cache is
damaged: delete the ``*.nbi`` and ``*.nbc`` files under ``librosa/util/__pycache__`` (or under
``NUMBA_CACHE_DIR`` when it is set) and they are compiled again.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from types import ModuleType

from kinectdata.core.errors import KinectDataError

LOCK_TIMEOUT_S = 300.0
"""How long a process waits for another to finish compiling before it goes on without the lock."""

_compiled = False
"""Whether this process has imported librosa and compiled (or loaded) its cached functions."""


def lock_path() -> Path:
    """The lock file the processes of one user share: in the temporary folder, named by the user
    (a lock file another user owns could not be opened)."""
    user = os.getuid() if hasattr(os, "getuid") else os.environ.get("USERNAME", "user")
    return Path(tempfile.gettempdir()) / f"kinectdata-librosa-{user}.lock"


def import_librosa(needed_for: str) -> ModuleType:
    """The librosa module, its cached numba functions compiled or loaded under :func:`lock_path`'s
    lock the first time in this process.

    Args:
        needed_for: what needs it, for the message when it is missing ("music beat tracking").

    Raises:
        KinectDataError: librosa is not installed (one line with the command that installs it).
    """
    global _compiled
    from filelock import FileLock, Timeout

    try:
        if _compiled:
            import librosa
        else:
            try:
                with FileLock(str(lock_path()), timeout=LOCK_TIMEOUT_S):
                    librosa = _import_and_compile()
            except (Timeout, OSError):  # a lock that cannot be had: go on as librosa alone would
                librosa = _import_and_compile()
            _compiled = True
    except ImportError:
        raise KinectDataError(f"{needed_for} needs librosa: pip install 'kinectdata[music]'") from None
    return librosa


def _import_and_compile() -> ModuleType:
    import librosa
    import numpy as np

    signal = np.zeros(8)
    for dtype in (np.float32, np.float64):  # the types kinectdata gives it; each has its own entry
        librosa.util.localmax(signal.astype(dtype))
        librosa.util.localmin(signal.astype(dtype))
        librosa.util.peak_pick(signal.astype(dtype), pre_max=1, post_max=1, pre_avg=1, post_avg=1, delta=0.1, wait=1)
    return librosa
