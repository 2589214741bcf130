"""Pickles of numpy arrays read without running code from the file.

Corpora (AIST++'s ``keypoints3d/*.pkl``, Bailando's ``.npy`` dicts) save arrays as pickles, and
loading a pickle normally runs whatever the file asks for. :func:`load_arrays_pickle` accepts only
what arrays in plain containers need (numpy arrays, dtypes and scalars; dicts, lists, tuples,
strings, numbers) and refuses any other class or function with one line naming it.
"""

from __future__ import annotations

import io
import pickle
import pickletools
from typing import IO, Any

PICKLE_SUFFIXES = (".pkl", ".pickle")
"""File name endings of pickles."""

_ARRAY_GLOBALS = frozenset(
    {
        ("numpy.core.multiarray", "_reconstruct"),
        ("numpy._core.multiarray", "_reconstruct"),
        ("numpy.core.multiarray", "scalar"),
        ("numpy._core.multiarray", "scalar"),
        ("numpy.core.numeric", "_frombuffer"),  # numpy >= 1.x with pickle protocol 5
        ("numpy._core.numeric", "_frombuffer"),
        ("numpy", "ndarray"),
        ("numpy", "dtype"),
        ("collections", "OrderedDict"),
        ("_codecs", "encode"),  # how protocols 0-2 write bytes: text to bytes, nothing else
    }
)


class _ArraysOnlyUnpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str):
        if (module, name) in _ARRAY_GLOBALS:
            return super().find_class(module, name)
        raise pickle.UnpicklingError(f"refused: the pickle asks for {module}.{name}, not a numpy array")


def load_arrays_pickle(file: IO[bytes]) -> Any:
    """The object pickled in the open binary ``file``, if it is made of arrays and plain containers.

    The opcodes are checked first, without running any (:func:`pickletools.genops`): a memo index
    far beyond the pickle's length (which makes the unpickler allocate gigabytes of memo, from a
    15-byte file) is refused as damage.

    Raises:
        pickle.UnpicklingError: the pickle names another class or function (the message names it),
            or is damaged; EOFError when it ends early.
    """
    data = file.read()
    _check_opcodes(data)
    return _ArraysOnlyUnpickler(io.BytesIO(data)).load()


_MEMO_WRITES = frozenset({"PUT", "BINPUT", "LONG_BINPUT"})


def _check_opcodes(data: bytes) -> None:
    try:
        for count, (opcode, arg, position) in enumerate(pickletools.genops(data), start=1):
            if opcode.name in _MEMO_WRITES and int(arg) > count:
                raise pickle.UnpicklingError(f"memo index {arg} at byte {position}: beyond any pickle's (damaged)")
    except ValueError as exc:  # an unknown opcode, an argument cut short
        raise pickle.UnpicklingError(str(exc)) from None
