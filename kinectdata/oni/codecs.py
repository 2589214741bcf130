"""Decoders of the frame codecs OpenNI writes into ``.oni`` files.

=========  ==============================================================================
FourCC     payload
=========  ==============================================================================
``NONE``   raw pixels (little-endian)
``16zP``   16-bit values, "16z" delta coded
``16zT``   u16 table size N, N u16 table entries, then a 16z stream of indices into the table
``Im8z``   8-bit values (an RGB888 image's bytes, interleaved), "8z" delta coded
``JPEG``   a JPEG image (decoded by Pillow: ``pip install kinectdata[jpeg]``)
=========  ==============================================================================

The 16z and 8z streams are byte codes read in order: nibble pairs of small differences, runs of
repeats and escapes carrying larger differences or absolute values (OpenNI's
``XnStreamCompression.cpp``). Where a code starts depends on the codes before it, so a plain
decoder is a loop over every byte, far too slow in Python for 640x480 at 30 fps. These decoders
are vectorised instead: every byte that may open a multi-byte code (an escape) is a candidate;
which candidates really open a code is settled by iterating the rule "a candidate is a code
unless a real code just before it covers it" over the candidates only (a handful of iterations,
with an exact sequential pass for pathological chains); after that each code's outputs are laid
out with cumulative sums and the values follow from one more cumulative sum, restarted at every
absolute value.

Where numba is installed (``pip install kinectdata[fast]``), :func:`decode_16z` and
:func:`decode_8z` run that plain byte loop compiled instead (:mod:`.codecs_jit`, 10 to over 100
times faster than these numpy decoders); ``KINECTDATA_JIT=0`` switches it off. Both give identical
values and refuse the same payloads with the same :class:`CodecError` (a payload the compiled loop
refuses is handed to the numpy decoder for its message). ``_decode_16z_numpy`` and
``_decode_8z_numpy`` are the numpy decoders themselves.
"""

from __future__ import annotations

import os

import numpy as np

from kinectdata.core.errors import KinectDataError

CODECS = ("NONE", "16zP", "16zT", "Im8z", "JPEG")


class CodecError(KinectDataError):
    """A frame's payload is not valid for its codec (the caller adds file, stream and frame)."""


def fourcc(code: int) -> str:
    """The four characters of a FourCC code (``c1 | c2<<8 | c3<<16 | c4<<24``)."""
    return int(code).to_bytes(4, "little").decode("latin-1")


# -- the compiled decoders ----------------------------------------------------------------------

_JIT: dict[str, object] = {}
"""The imported :mod:`.codecs_jit` (key ``module``), or why it is not usable (key ``missing``)."""


def _jit_module():
    """:mod:`.codecs_jit` when it is usable and not switched off (``KINECTDATA_JIT=0``), else None.
    Imported on first use: numba takes a few tenths of a second to import."""
    if os.environ.get("KINECTDATA_JIT", "1").strip() == "0":
        return None
    if not _JIT:
        try:
            from kinectdata.oni import codecs_jit
        except Exception as exc:  # noqa: BLE001 (numba or llvmlite missing, broken, or no cache folder: numpy decodes)
            _JIT["missing"] = f"numba is not importable ({exc}): pip install 'kinectdata[fast]'"
        else:
            _JIT["module"] = codecs_jit
    return _JIT.get("module")


def jit_missing() -> str | None:
    """Why the compiled decoders are not used (None: they are): numba missing, or ``KINECTDATA_JIT=0``."""
    if _jit_module() is not None:
        return None
    return _JIT.get("missing") or "switched off by KINECTDATA_JIT=0"


def jit_available() -> bool:
    """True when :func:`decode_16z` and :func:`decode_8z` use the compiled byte loops of
    :mod:`.codecs_jit` (numba installed, ``KINECTDATA_JIT`` not ``0``), False when they use numpy."""
    return _jit_module() is not None


# -- code starts --------------------------------------------------------------------------------

_JACOBI_ROUNDS = 48


def _code_starts(n: int, candidates: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Which of the bytes 0..n-1 start a code.

    Every byte starts a one-byte code unless it is covered by a real multi-byte code before it.
    ``candidates`` [M] (ascending) are the bytes that would open a code of ``lengths`` [M] (2 or
    3) bytes if they start one; a candidate is real unless a real candidate 1 or 2 bytes before
    covers it.

    Returns:
        [n] bool, True where a code starts.
    """
    m = candidates.size
    real = np.ones(m, bool)
    if m:
        # the candidate just before (1 or 2 bytes) that could cover each one
        k = np.arange(m)
        gap1 = np.zeros(m, bool)
        gap1[1:] = candidates[1:] - candidates[:-1] == 1
        prev1 = np.where(gap1, k - 1, -1)
        # two bytes before: either the previous candidate (gap 2) or the one before that (gaps 1+1)
        gap2a = np.zeros(m, bool)
        gap2a[1:] = candidates[1:] - candidates[:-1] == 2
        gap2b = np.zeros(m, bool)
        gap2b[2:] = candidates[2:] - candidates[:-2] == 2
        prev2 = np.where(gap2a, k - 1, np.where(gap2b, k - 2, -1))
        long2 = np.zeros(m, bool)
        ok2 = prev2 >= 0
        long2[ok2] = lengths[prev2[ok2]] == 3
        has1, has2 = prev1 >= 0, ok2 & long2
        p1, p2 = np.maximum(prev1, 0), np.maximum(prev2, 0)
        for _ in range(_JACOBI_ROUNDS):  # causal recurrence: converges in (longest chain + 1) rounds
            new = ~((has1 & real[p1]) | (has2 & real[p2]))
            if np.array_equal(new, real):
                break
            real = new
        else:  # a chain longer than the rounds (only adversarial data): settle it in order
            real = np.zeros(m, bool)
            covered = -1
            for i, (c, length) in enumerate(zip(candidates.tolist(), lengths.tolist())):
                if c > covered:
                    real[i] = True
                    covered = c + length - 1
    starts = np.ones(n, bool)
    rc, rl = candidates[real], lengths[real]
    starts[rc + 1] = False
    starts[rc[rl == 3] + 2] = False
    return starts


def _expand(
    first: int,
    deltas: np.ndarray,
    reps: np.ndarray,
    reset_at: np.ndarray,
    reset_to: np.ndarray,
    count: int,
    bits: int,
    what: str,
    table: np.ndarray | None = None,
) -> np.ndarray:
    """The ``count`` output values from per-code slots.

    Each code has two slots ([C, 2] arrays, flattened in order): slot value = previous value -
    ``deltas``, except at the flat slot indices ``reset_at`` where it is ``reset_to``; a slot is
    output ``reps`` times (0: unused, 2n: a run). The first output is ``first``. Values wrap to
    ``bits`` bits and, with a ``table``, are indices into it.
    """
    flat = deltas.ravel()
    mask = (1 << bits) - 1  # everything only matters modulo 2**bits
    if reset_at.size:  # fold each reset into the differences: the correction landing on its value
        flat[reset_at] = 0
        before = np.cumsum(np.add.reduceat(flat, np.concatenate([[0], reset_at]), dtype=np.int64)[:-1])
        needed = first - before - reset_to  # the total correction the values need from each reset on
        flat[reset_at] = np.diff(needed, prepend=0) & mask
    values = first - np.cumsum(flat)  # int32 may wrap: the low bits stay right
    values &= mask
    reps = np.concatenate([[1], reps.ravel()])
    total = int(reps.sum(dtype=np.int64))
    if total < count:
        raise CodecError(f"{what}: {total} values decoded, {count} expected")
    used = _slots_needed(reps, total - count)
    out = np.empty(used, np.uint16 if bits == 16 else np.uint8)
    out[0], out[1:] = first, values[: used - 1]
    reps = reps[:used]
    if table is not None:
        # an unused slot (repeat count 0) repeats the value before it, so the largest retained
        # value is the largest output
        if int(out.max()) >= table.size:
            raise CodecError(f"{what}: an index points past the {table.size}-entry value table")
        out = table[out]
    return np.repeat(out, reps)[:count]


def _slots_needed(reps: np.ndarray, excess: int) -> int:
    """How many leading slots make the first ``sum(reps) - excess`` outputs (usually all but a
    few trailing ones; a damaged payload's long tail is cut here, before anything is expanded)."""
    if excess == 0:
        return reps.size
    tail = np.cumsum(reps[::-1][:64], dtype=np.int64)
    if tail[-1] > excess:  # the cut is in the last 64 slots
        return reps.size - int(np.searchsorted(tail, excess, side="right"))
    ends = np.cumsum(reps, dtype=np.int64)
    return int(np.searchsorted(ends, ends[-1] - excess)) + 1


def _slots(table: np.ndarray, codes: np.ndarray) -> np.ndarray:
    """Rows of a [256, 2] int32 table for each code byte, as a new [C, 2] array. (Gathering
    the rows as single int64 values is several times faster than numpy's row gather.)"""
    return table.view(np.int64).ravel()[codes].view(np.int32).reshape(-1, 2)


def _need(what: str, have: int, need: int) -> None:
    if have < need:
        raise CodecError(f"{what}: the payload ends early ({have} bytes, {need} needed)")


def _not_too_long(what: str, have: int, most: int) -> None:
    """Refuse a payload longer than any encoding of the frame (a damaged size field), before the
    per-byte arrays are made."""
    if have > most:
        raise CodecError(f"{what}: the payload is {have} bytes, more than any encoding of the frame ({most})")


def _padded(body: np.ndarray) -> np.ndarray:
    """The bytes with two zeros appended, so a code cut off by the end can be looked at."""
    pad = np.zeros(body.size + 2, np.uint8)
    pad[: body.size] = body
    return pad


# -- 16z ----------------------------------------------------------------------------------------
# Per code byte: the two slots' differences and repeat counts. A pair byte (< 0xE0) holds two
# nibbles, each "value -= nibble - 6"; a low nibble D means no second value, F an escape in the
# following byte(s) (it fills slot 1). 0xE0 + n repeats the value 2n times; 0xFF is an escape
# alone (slot 0).


def _pair_tables() -> tuple[np.ndarray, np.ndarray]:
    """[256, 2] differences and repeat counts with the rows of the pair bytes (< 0xE0) filled,
    which 16z and 8z share: "value -= nibble - 6" per nibble, low nibble D no second value, F an
    escape (difference 0; the escape's value is a reset)."""
    d, r = np.zeros((256, 2), np.int32), np.zeros((256, 2), np.int32)
    for b in range(0xE0):
        hi, lo = b >> 4, b & 0x0F
        d[b, 0], r[b, 0] = hi - 6, 1
        if lo != 0x0D:
            r[b, 1] = 1
            d[b, 1] = lo - 6 if lo != 0x0F else 0
    return d, r


_D16, _R16 = _pair_tables()
for _b in range(0xE0, 0xFF):
    _R16[_b, 0] = 2 * (_b - 0xE0)
_R16[0xFF, 0] = 1


def decode_16z(payload: bytes, count: int, *, table: bool, what: str = "16z frame") -> np.ndarray:
    """Decode a ``16zP`` (``table=False``) or ``16zT`` payload into ``count`` uint16 values [count].

    Outputs beyond ``count`` (some writers leave a trailing byte) are dropped; fewer is an error.
    Decoded by the compiled byte loop of :mod:`.codecs_jit` where :func:`jit_available`, else by
    the numpy decoder; both give the same values and refuse the same payloads.

    Raises:
        CodecError: the payload is cut short, makes too few values, or (16zT) indexes past its table.
    """
    jit = _jit_module()
    if jit is None or count < 1:
        return _decode_16z_numpy(payload, count, table=table, what=what)
    buf = np.frombuffer(payload, np.uint8)
    pos, lut = _16z_header(buf, count, table, what)
    status, values = jit.decode_16z(buf, pos, count, lut)
    if status != jit.OK:  # the numpy decoder says precisely what is wrong
        return _decode_16z_numpy(payload, count, table=table, what=what)
    return values


def _16z_header(buf: np.ndarray, count: int, table: bool, what: str) -> tuple[int, np.ndarray | None]:
    """Where a 16z payload's stream starts (its u16 first value) and its 16zT table ([N] uint16,
    None for 16zP), after checking the payload is long enough and not too long for the frame."""
    pos, lut = 0, None
    if table:
        _need(what, buf.size, 2)
        size = int(buf[0]) | int(buf[1]) << 8
        _need(what, buf.size, 2 + 2 * size)
        lut = buf[2 : 2 + 2 * size].view("<u2").astype(np.uint16)
        pos = 2 + 2 * size
    _need(what, buf.size, pos + 2)
    _not_too_long(what, buf.size - pos, 3 * count + 16)  # an escape per value is 3 bytes
    return pos, lut


def _decode_16z_numpy(payload: bytes, count: int, *, table: bool, what: str = "16z frame") -> np.ndarray:
    """:func:`decode_16z` by whole-array operations (numpy only)."""
    buf = np.frombuffer(payload, np.uint8)
    pos, lut = _16z_header(buf, count, table, what)
    first = int(buf[pos]) | int(buf[pos + 1]) << 8
    body = buf[pos + 2 :]
    n, pad = body.size, _padded(body)
    opens = np.flatnonzero(((body < 0xE0) & ((body & 0x0F) == 0x0F)) | (body == 0xFF))
    esc = pad[opens + 1]
    lengths = 2 + (esc < 0x80).astype(np.int64)
    starts = _code_starts(n + 2, opens, lengths)[:n]
    real = starts[opens]
    rc, rlen, resc = opens[real], lengths[real], esc[real]
    if rlen.size and rc[-1] + rlen[-1] > n:
        raise CodecError(f"{what}: the payload ends inside an escape (byte {rc[-1]} of {n})")
    codes = np.flatnonzero(starts)
    b = body[codes]
    deltas, reps = _slots(_D16, b), _slots(_R16, b)
    slot = 2 * np.searchsorted(codes, rc) + (body[rc] != 0xFF)  # flat slot of each escape
    small = resc >= 0x80
    deltas.ravel()[slot[small]] = resc[small].astype(np.int32) - 192
    big = ~small
    reset_to = (resc[big].astype(np.int64) << 8) | pad[rc[big] + 2]
    return _expand(first, deltas, reps, slot[big], reset_to, count, 16, what, lut)


# -- 8z -----------------------------------------------------------------------------------------
# A pair byte (< 0xE0): two nibble differences; low nibble D: none second; F: the next byte is an
# absolute value (slot 1). 0xE0..0xEF: runs. 0xF0..0xFF: an absolute value made of its low nibble
# and the next byte's high nibble (slot 0), then by the next byte's low nibble a difference, an
# absolute third byte (F) or nothing (D) (slot 1).

_D8, _R8 = _pair_tables()
for _b in range(0xE0, 0xF0):
    _R8[_b, 0] = 2 * (_b - 0xE0)
_R8[0xF0:, 0] = 1


def decode_8z(payload: bytes, count: int, *, what: str = "Im8z frame") -> np.ndarray:
    """Decode an ``Im8z`` payload into ``count`` uint8 values [count] (extra outputs dropped), by
    :mod:`.codecs_jit` where :func:`jit_available`, else by numpy (same values, same refusals).

    Raises:
        CodecError: the payload is cut short or makes too few values.
    """
    jit = _jit_module()
    if jit is None or count < 1:
        return _decode_8z_numpy(payload, count, what=what)
    buf = np.frombuffer(payload, np.uint8)
    _8z_sizes(buf, count, what)
    status, values = jit.decode_8z(buf, count)
    if status != jit.OK:  # the numpy decoder says precisely what is wrong
        return _decode_8z_numpy(payload, count, what=what)
    return values


def _8z_sizes(buf: np.ndarray, count: int, what: str) -> None:
    """Check an Im8z payload ([B] uint8) holds its first value and is not too long for the frame."""
    _need(what, buf.size, 1)
    _not_too_long(what, buf.size, 2 * count + 16)  # the encoder's worst is 3 bytes per 2 values


def _decode_8z_numpy(payload: bytes, count: int, *, what: str = "Im8z frame") -> np.ndarray:
    """:func:`decode_8z` by whole-array operations (numpy only)."""
    buf = np.frombuffer(payload, np.uint8)
    _8z_sizes(buf, count, what)
    body = buf[1:]
    n, pad = body.size, _padded(body)
    nxt = pad[1 : n + 1]
    opens = np.flatnonzero(((body < 0xE0) & ((body & 0x0F) == 0x0F)) | (body >= 0xF0))
    high = body[opens] >= 0xF0
    lengths = np.where(high & ((nxt[opens] & 0x0F) == 0x0F), 3, 2)
    starts = _code_starts(n + 2, opens, lengths)[:n]
    real = starts[opens]
    rc, rlen = opens[real], lengths[real]
    if rlen.size and rc[-1] + rlen[-1] > n:
        raise CodecError(f"{what}: the payload ends inside a code (byte {rc[-1]} of {n})")
    codes = np.flatnonzero(starts)
    b = body[codes]
    deltas, reps = _slots(_D8, b), _slots(_R8, b)
    # pair with low nibble F: slot 1 is the next byte, absolute
    pf = np.flatnonzero((b < 0xE0) & ((b & 0x0F) == 0x0F))
    at = [2 * pf + 1]
    to = [pad[codes[pf] + 1]]
    # 0xF?: slot 0 absolute; slot 1 by the next byte's low nibble
    hi = np.flatnonzero(b >= 0xF0)
    second = pad[codes[hi] + 1]
    at.append(2 * hi)
    to.append(((b[hi] & 0x0F) << 4) | (second >> 4))
    lo2 = second & 0x0F
    d2 = (lo2 != 0x0D) & (lo2 != 0x0F)
    deltas[hi[d2], 1] = lo2[d2].astype(np.int32) - 6
    reps[hi[lo2 != 0x0D], 1] = 1
    a2 = lo2 == 0x0F
    at.append(2 * hi[a2] + 1)
    to.append(pad[codes[hi[a2]] + 2])
    reset_at = np.concatenate(at)
    order = np.argsort(reset_at, kind="stable")
    reset_to = np.concatenate(to).astype(np.int64)[order]
    return _expand(int(buf[0]), deltas, reps, reset_at[order], reset_to, count, 8, what)


# -- JPEG and raw -------------------------------------------------------------------------------


def decode_raw(payload: bytes, dtype: np.dtype, count: int, *, what: str = "raw frame") -> np.ndarray:
    """``count`` values of ``dtype`` (little-endian) from a ``NONE`` payload (extra bytes dropped)."""
    dtype = np.dtype(dtype).newbyteorder("<")
    _need(what, len(payload), count * dtype.itemsize)
    return np.frombuffer(payload, dtype, count).astype(dtype.newbyteorder("="))
