"""librosa's numba cache is compiled by one process at a time (kinectdata.core.librosa_import): a
process that needs librosa while another holds the lock waits for it, and a missing librosa is one
line naming what needed it."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

from kinectdata.core import librosa_import
from kinectdata.core.errors import KinectDataError

HOLD = """
import sys, time
from filelock import FileLock
from kinectdata.core.librosa_import import lock_path
with FileLock(str(lock_path())):
    print("held", flush=True)
    time.sleep(float(sys.argv[1]))
    print(repr(time.time()), flush=True)
"""

NEED = """
import time
from kinectdata.core.librosa_import import import_librosa
librosa = import_librosa("a test")
print(repr(time.time()), librosa.util.localmax.__name__, flush=True)
"""


@pytest.mark.slow
def test_a_process_that_needs_librosa_waits_for_the_one_compiling_it(tmp_path):
    pytest.importorskip("librosa")
    env = dict(os.environ, TMPDIR=str(tmp_path))  # a lock of this test's own
    holder = subprocess.Popen([sys.executable, "-c", HOLD, "6"], stdout=subprocess.PIPE, text=True, env=env)
    assert holder.stdout.readline().strip() == "held"
    started = time.time()
    needer = subprocess.run([sys.executable, "-c", NEED], capture_output=True, text=True, env=env, timeout=120)
    released = float(holder.stdout.readline())
    holder.wait(timeout=30)
    assert needer.returncode == 0, needer.stderr
    got, name = needer.stdout.split()
    assert name == "localmax"
    assert float(got) >= released > started  # it went on only once the holder let go
    assert (tmp_path / librosa_import.lock_path().name).exists()


@pytest.mark.parametrize("compiled", [False, True])
def test_missing_librosa_is_one_line_naming_what_needed_it(monkeypatch, compiled):
    monkeypatch.setattr(librosa_import, "_compiled", compiled)
    monkeypatch.setitem(sys.modules, "librosa", None)  # import librosa raises ImportError
    said = r"^music beat tracking needs librosa: pip install 'kinectdata\[music\]'$"
    with pytest.raises(KinectDataError, match=said):
        librosa_import.import_librosa("music beat tracking")
