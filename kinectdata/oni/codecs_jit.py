"""The 16z and 8z frame decoders as compiled byte loops (numba), used by :mod:`.codecs`.

The codecs (see :mod:`.codecs` and OpenNI's ``XnStreamCompression.cpp``) are byte codes read in
order, so the natural decoder is one pass over the bytes carrying the current value. In Python
that loop is hopeless; compiled by numba it takes one or two nanoseconds a byte, several times the
vectorised numpy decoders' speed and faster than OpenNI's own player. numba is optional
(``pip install kinectdata[fast]``): :mod:`.codecs` imports this module only when it is asked to
decode, numba is importable and ``KINECTDATA_JIT`` is not ``0``.

What makes the loops fast (each measured on ``python -m benchmarks bench_oni``'s recordings):

- indices are unsigned (``np.uint64`` throughout, constants included): numba adds a negative-index
  wraparound to every access through a signed index, which here cost a third of the time;
- each code byte's two nibble differences and output count come from one [256, 4] table;
- the output has :data:`SLACK` spare slots, so each byte writes its values, and the first values of
  a run of repeats, unconditionally (a run's length then rarely needs a branch), and a value that
  lands past the frame's end does no harm;
- Im8z images are mostly absolute-value codes one after the other (RGB bytes differ by more than
  the nibbles hold): a tight inner loop takes those.

The kernels return a status instead of raising: :data:`OK`, or what may be wrong with the payload
(cut inside a code, too few values, an index past the 16zT table). Every payload the numpy
decoders refuse gets a status other than OK; :mod:`.codecs` then runs the numpy decoder, which
raises :class:`~kinectdata.oni.codecs.CodecError` with its precise message (or, for an index past
the table that lies beyond the frame's end, decodes the frame). The size checks made before any
decoding (a payload shorter than its header or longer than any encoding of the frame) stay in
:mod:`.codecs`.

The compiled code is cached on disk (``cache=True``): in ``__pycache__`` beside this file, or under
``NUMBA_CACHE_DIR`` when that is set (numba falls back to a per-user cache folder where the package
folder is not writable). A process's first decode of each kind (16zT, 16zP, Im8z) loads it from
there in a fraction of a second; without a cache it compiles (about a second each).
"""

from __future__ import annotations

import numba
import numpy as np

OK, CUT, TOO_FEW, PAST_TABLE = 0, 1, 2, 3
"""Kernel statuses: decoded; a code runs past the payload's end; fewer values than the frame has;
(16zT) a value decoded, perhaps past the frame's end, indexes past the table."""

SLACK = 80
"""Spare output slots after the frame's ``count`` values. A code starts below ``count`` and writes
at most 67 slots from there (a 16z run of 60 values filled 8 at a time), so no write checks the
frame's end."""

_U = np.uint64
_0, _1, _2, _3, _4, _8 = _U(0), _U(1), _U(2), _U(3), _U(4), _U(8)
_M16, _M8, _F, _D, _6, _192 = _U(0xFFFF), _U(0xFF), _U(0x0F), _U(0x0D), _U(6), _U(192)


def _pair_table(runs_below: int, escapes: bool) -> np.ndarray:
    """[256, 4] uint64 per code byte: the difference to the first value, the difference to the
    value after the byte, the values it outputs, and (16z) whether an escape follows.

    Differences are stored modulo 2**64 (``v - d`` then wraps like the codec's arithmetic). A pair
    byte (< 0xE0) outputs ``v - (hi - 6)`` and ``v - (hi - 6) - (lo - 6)``; low nibble D: only the
    first; F: only the first, then an escape (16z) or an absolute byte (8z, flagged by the caller's
    own test). A run byte 0xE0 + m (below ``runs_below``) outputs the value 2m times. Other bytes
    (16z: 0xFF, an escape alone; 8z: 0xF0..0xFF) output nothing here.
    """
    t = np.zeros((256, 4), np.int64)
    for c in range(256):
        if c < 0xE0:
            hi, lo = c >> 4, c & 0x0F
            t[c, 0] = t[c, 1] = hi - 6
            t[c, 2] = 1
            if lo == 0x0F:
                t[c, 3] = escapes
            elif lo != 0x0D:
                t[c, 1] += lo - 6
                t[c, 2] = 2
        elif c < runs_below:
            t[c, 2] = 2 * (c - 0xE0)
        else:
            t[c, 3] = escapes
    return t.astype(np.uint64)  # negative differences wrap modulo 2**64


_T16 = _pair_table(0xFF, True)
_T8 = _pair_table(0xF0, False)

_jit = numba.njit(cache=True, nogil=True)


@numba.njit(inline="always")
def _looked_up(v, lut, top):
    """The output for value ``v``: ``v`` itself (16zP, ``lut`` None) or its table entry (16zT; an
    index past the table reads the last entry, and the kernel reports it)."""
    if lut is None:
        return v
    return lut[min(v, top)]


@_jit
def _kernel_16z(body, first, count, lut, out):
    """Decode a 16z stream.

    Args:
        body: [n] uint8, the stream's bytes after its u16 first value (read-only array).
        first: the first value (0..65535), uint64.
        count: values the frame has (>= 1), uint64.
        lut: [N] uint16, 16zT's table (each value is an index into it), or None (16zP).
        out: [count + SLACK] uint16; ``out[:count]`` receives the frame's values.

    Returns:
        OK, CUT, TOO_FEW or PAST_TABLE. Decoding stops at the frame's end, but the codes after
        it are still walked: a payload whose last code is cut is refused wherever the cut lies.
    """
    n = _U(body.size)
    top = _M16
    if lut is not None:
        if lut.size == 0:
            return PAST_TABLE
        top = _U(lut.size) - _1
    v = first
    most = v  # (16zT) the largest index used
    out[0] = _looked_up(v, lut, top)
    k, p = _1, _0
    while p < n and k < count:
        c = body[p]
        p += _1
        v1 = (v - _T16[c, 0]) & _M16
        v = (v - _T16[c, 1]) & _M16
        if lut is not None:
            most = max(most, max(v1, v))
        out[k] = _looked_up(v1, lut, top)
        x = _looked_up(v, lut, top)
        for i in range(1, 8):  # the second value, or a run's first ones
            out[k + _U(i)] = x
        m = _T16[c, 2]
        if m > _8:  # a run longer than that
            for j in range(k + _8, k + m, _8):
                for i in range(8):
                    out[j + _U(i)] = x
        k += m
        if _T16[c, 3]:  # an escape: a difference in one byte (top bit set) or an absolute value in two
            if p >= n:
                return CUT
            e = body[p]
            if e >= 0x80:
                v = (v + _192 - e) & _M16
                p += _1
            else:
                if p + _1 >= n:
                    return CUT
                v = (_U(e) << _8) | body[p + _1]
                p += _2
            if lut is not None:
                most = max(most, v)
            out[k] = _looked_up(v, lut, top)
            k += _1
    if k < count:
        return TOO_FEW
    status = _rest_16z(body, p)
    if status == OK and most > top:
        return PAST_TABLE
    return status


@_jit
def _rest_16z(body, p):
    """Walk the 16z codes from byte ``p`` (uint64) to the end of ``body`` without decoding them
    (what a payload holds past its frame): CUT if the last code runs past the end, else OK."""
    n = _U(body.size)
    while p < n:
        c = body[p]
        p += _1
        if _T16[c, 3]:
            if p >= n:
                return CUT
            p += _1 if body[p] >= 0x80 else _2
            if p > n:
                return CUT
    return OK


@_jit
def _kernel_8z(body, first, count, out):
    """Decode an 8z stream.

    Args:
        body: [n] uint8, the stream's bytes after its first value (read-only array).
        first: the first value (0..255), uint64.
        count: values the frame has (>= 1), uint64.
        out: [count + SLACK] uint8; ``out[:count]`` receives the frame's values.

    Returns:
        OK, CUT or TOO_FEW (the codes after the frame's end are walked for a cut one too).
    """
    n = _U(body.size)
    v = first
    out[0] = v
    k, p = _1, _0
    while p < n and k < count:
        # the common case on RGB: absolute codes 0xF? ?F byte (two values), one after the other
        while p + _2 < n and k < count and body[p] >= 0xF0 and (body[p + _1] & 0x0F) == 0x0F:
            c2 = _U(body[p + _1])
            out[k] = ((_U(body[p]) & _F) << _4) | (c2 >> _4)
            v = _U(body[p + _2])
            out[k + _1] = v
            k += _2
            p += _3
        if p >= n or k >= count:
            break
        c = _U(body[p])
        p += _1
        if c >= 0xF0:  # absolute: c's low nibble and the next byte's high nibble; then by its low nibble
            if p >= n:
                return CUT
            c2 = _U(body[p])
            p += _1
            v = ((c & _F) << _4) | (c2 >> _4)
            out[k] = v
            k += _1
            lo = c2 & _F
            if lo == _D:
                continue
            if lo != _F:
                v = (v + _6 - lo) & _M8
                out[k] = v
                k += _1
                continue
        else:  # a pair byte or a run
            v1 = (v - _T8[c, 0]) & _M8
            v = (v - _T8[c, 1]) & _M8
            out[k] = v1
            for i in range(1, 8):
                out[k + _U(i)] = v
            m = _T8[c, 2]
            if m > _8:
                for j in range(k + _8, k + m, _8):
                    for i in range(8):
                        out[j + _U(i)] = v
            k += m
            if c >= 0xE0 or (c & _F) != _F:
                continue
        if p >= n:  # low nibble F: an absolute byte follows
            return CUT
        v = _U(body[p])
        p += _1
        out[k] = v
        k += _1
    if k < count:
        return TOO_FEW
    return _rest_8z(body, p)


@_jit
def _rest_8z(body, p):
    """Walk the 8z codes from byte ``p`` (uint64) to the end of ``body``: CUT if the last runs past it."""
    n = _U(body.size)
    while p < n:
        c = body[p]
        p += _1
        if c >= 0xF0:
            if p >= n:
                return CUT
            p += _2 if (body[p] & 0x0F) == 0x0F else _1
            if p > n:
                return CUT
        elif c < 0xE0 and (c & 0x0F) == 0x0F:
            p += _1
            if p > n:
                return CUT
    return OK


def _read_only(a: np.ndarray) -> np.ndarray:
    """``a`` as a read-only view, so that bytes and bytearray payloads share one compiled kernel."""
    if a.flags.writeable:
        a = a.view()
        a.flags.writeable = False
    return a


def decode_16z(buf: np.ndarray, pos: int, count: int, lut: np.ndarray | None) -> tuple[int, np.ndarray]:
    """Decode the 16z stream at byte ``pos`` of ``buf`` into ``count`` uint16 values.

    Args:
        buf: [B] uint8, the payload; the stream's u16 first value is at ``pos`` (``pos + 2 <= B``).
        count: values the frame has (>= 1).
        lut: [N] uint16, 16zT's table, or None for 16zP.

    Returns:
        (status, values [count] uint16); the values are the frame's only when status is OK.
    """
    first = _U(int(buf[pos]) | int(buf[pos + 1]) << 8)
    out = np.empty(count + SLACK, np.uint16)
    status = _kernel_16z(_read_only(buf[pos + 2 :]), first, _U(count), lut, out)
    return int(status), out[:count]


def decode_8z(buf: np.ndarray, count: int) -> tuple[int, np.ndarray]:
    """Decode an 8z payload (``buf`` [B] uint8, B >= 1: the first value, then the stream) into
    ``count`` (>= 1) uint8 values.

    Returns:
        (status, values [count] uint8); the values are the frame's only when status is OK.
    """
    out = np.empty(count + SLACK, np.uint8)
    status = _kernel_8z(_read_only(buf[1:]), _U(buf[0]), _U(count), out)
    return int(status), out[:count]
