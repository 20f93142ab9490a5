"""Compiled CSV text: floats in Python's shortest round-trip form (``repr``), fast.

A solution CSV of a long run is millions of floats, and CPython's ``repr(float)`` (David
Gay's correctly rounded dtoa, shortest mode) costs about 0.4-1.3 us per value: 5-15 s for
a 10,000-period run, more than its solve. This module writes the same text from compiled
code:

- **Digits**: Schubfach (R. Giulietti, "The Schubfach way to render doubles", 2020; the
  algorithm of Java's ``Double.toString`` since JDK 19, here after A. Bolz's C++
  transcription in Drachennest). Three 64 x 128-bit products with a table of 617
  powers of ten (computed below in exact integer arithmetic) give the decimal in the
  double's rounding interval with the fewest digits and, among those, the one closest to
  it (ties to an even digit): the digits of ``repr`` (Gay's shortest mode), for every
  finite double, with no fallback. NaN and infinities are formatted by Python's own
  ``repr``. So every field is exactly ``repr(value)``: same digits, same text.
- **Layout**: the rules of CPython's ``float_repr`` (``PyOS_double_to_string`` with
  ``'r'`` and ``Py_DTSF_ADD_DOT_0``): positional for decimal-point positions
  ``-4 < decpt <= 16`` (``0.001``, ``12.5``, ``1000000.0``), else ``d.ddde+XX``
  (``1e-05``, ``1.5e+16``), ``0.0`` and ``-0.0`` for zeros.

``format_block`` turns a block of columns (floats, integers, short texts) into the bytes of
the CSV rows; ``rubcli.io.write_csv`` uses it for every block whose columns are numpy
arrays, and tests/test_io.py checks it field by field against ``repr`` and ``str``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from llvmlite import ir
from numba.core import types
from numba.cpython.unsafe.numbers import leading_zeros
from numba.extending import intrinsic

from rubcli.cached_jit import njit

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence

    from numba.core.base import BaseContext
    from numba.core.typing.templates import Signature

    from rubcli.labels import Labels

jit = njit(nogil=True)  # formats beside the figures (io.Background)

FLOAT_WIDTH = 24  # longest repr of a double: '-2.2250738585072014e-308'
INT_WIDTH = 20  # longest int64: '-9223372036854775808'
_U64 = np.uint64
_U32 = np.uint32
_K_MIN, _K_MAX = -292, 324


def _pow10_table():
    """g(k) = ceil(10^k 2^(127 - floor(log2 10^k))) for k in [-292, 324]: 2^127 <= g < 2^128
    (the table of the Schubfach paper, exact integer arithmetic), as (hi, lo) words."""
    hi, lo = [], []
    for k in range(_K_MIN, _K_MAX + 1):
        if k >= 0:
            num, den = 10**k, 1
        else:
            num, den = 1, 10**-k
        e2 = num.bit_length() - den.bit_length()  # floor(log2 num/den) is e2 or e2 - 1
        if (num << max(0, -e2)) < (den << max(0, e2)):
            e2 -= 1
        shift = 127 - e2
        if shift >= 0:
            num <<= shift
        else:
            den <<= -shift
        g = -(-num // den)
        assert 2**127 <= g < 2**128, k
        hi.append(g >> 64)
        lo.append(g & (2**64 - 1))
    return np.array(hi, dtype=np.uint64), np.array(lo, dtype=np.uint64)


G_HI, G_LO = _pow10_table()
DIGIT_PAIRS = np.frombuffer("".join(f"{i:02d}" for i in range(100)).encode(), dtype=np.uint8).copy()


@intrinsic
def _umul128(typingctx, a, b):
    """The 128-bit product of two uint64 as (high, low) words."""
    sig = types.UniTuple(types.uint64, 2)(types.uint64, types.uint64)

    def codegen(
        context: BaseContext,
        builder: ir.IRBuilder,
        signature: Signature,
        args: tuple[ir.Value, ...],
    ) -> ir.Value:
        wide = ir.IntType(128)
        product = builder.mul(builder.zext(args[0], wide), builder.zext(args[1], wide))
        low = builder.trunc(product, ir.IntType(64))
        high = builder.trunc(builder.lshr(product, ir.Constant(wide, 64)), ir.IntType(64))
        return context.make_tuple(builder, signature.return_type, [high, low])

    return sig, codegen


@jit
def _round_to_odd(g_hi, g_lo, cp):
    """Bits 63..126 of the 192-bit product (g_hi 2^64 + g_lo) cp, with the bits below made
    sticky in the last place (Schubfach's round-to-odd product)."""
    x_hi, _ = _umul128(g_lo, cp)
    y_hi, y_lo = _umul128(g_hi, cp)
    y_lo2 = y_lo + x_hi
    if y_lo2 < x_hi:
        y_hi += _U64(1)
    return ((y_hi << _U64(1)) | (y_lo2 >> _U64(63))) | _U64(y_lo2 != _U64(0))


@jit
def to_decimal(bits: np.uint64) -> tuple[np.uint64, int]:
    """(D, k) with the finite double > 0 of IEEE bits ``bits`` ~ D 10^k, D the shortest
    correctly rounded decimal significand (trailing zeros removed): Schubfach (Giulietti,
    figures 4 and 6 of the paper; the variables are the paper's). Integers below 2^53
    are exact: their own digits."""
    mantissa = bits & _U64((1 << 52) - 1)
    biased = np.int64(bits >> _U64(52))
    if biased != 0:
        c = mantissa | _U64(1 << 52)
        q = biased - 1075
        if 0 <= -q < 53:
            f = c >> _U64(-q)
            if (f << _U64(-q)) == c:
                k = 0
                while f % _U64(10) == _U64(0):
                    f //= _U64(10)
                    k += 1
                return f, k
    else:
        c = mantissa
        q = np.int64(-1074)
    even = (c & _U64(1)) == _U64(0)
    closer = mantissa == _U64(0) and biased > 1
    cbl = _U64(4) * c - _U64(2) + _U64(closer)
    cb = _U64(4) * c
    cbr = _U64(4) * c + _U64(2)
    k = (q * 1262611 - (524031 if closer else 0)) >> 22
    h = q + ((-k * 1741647) >> 19)
    index = -k - _K_MIN
    g_hi, g_lo = G_HI[index], G_LO[index]
    vbl = _round_to_odd(g_hi, g_lo, cbl << _U64(h))
    vb = _round_to_odd(g_hi, g_lo, cb << _U64(h))
    vbr = _round_to_odd(g_hi, g_lo, cbr << _U64(h))
    lower = vbl if even else vbl + _U64(1)
    upper = vbr if even else vbr - _U64(1)
    s = vb // _U64(4)
    result = _U64(0)
    found = False
    if s >= _U64(10):
        sp = s // _U64(10)
        up_inside = lower <= _U64(40) * sp
        wp_inside = _U64(40) * sp + _U64(40) <= upper
        if up_inside != wp_inside:
            result = sp + _U64(wp_inside)
            k += 1
            found = True
    if not found:
        u_inside = lower <= _U64(4) * s
        w_inside = _U64(4) * s + _U64(4) <= upper
        if u_inside != w_inside:
            result = s + _U64(w_inside)
        else:
            mid = _U64(4) * s + _U64(2)
            up = vb > mid or (vb == mid and (s & _U64(1)) != _U64(0))
            result = s + _U64(up)
    while result % _U64(10) == _U64(0):
        result //= _U64(10)
        k += 1
    return result, k


POW10 = np.array([10**k for k in range(20)], dtype=np.uint64)


@jit
def _pair(out, i, r):
    """The two digits of r < 100 into out[i:i + 2]."""
    out[i] = DIGIT_PAIRS[2 * r]
    out[i + 1] = DIGIT_PAIRS[2 * r + 1]


@jit
def _eight(out, i, v):
    """The 8 digits of v < 10^8 (uint32) into out[i:i + 8]."""
    a = v // _U32(10000)
    b = v % _U32(10000)
    _pair(out, i, a // _U32(100))
    _pair(out, i + 2, a % _U32(100))
    _pair(out, i + 4, b // _U32(100))
    _pair(out, i + 6, b % _U32(100))


@jit
def decimal_length(d: np.uint64) -> int:
    """The number of decimal digits of 0 < d < 10^19: floor(log10 d) + 1, from the bit
    length (1233 / 4096 ~ log10 2), corrected once."""
    bit_length = 64 - np.int64(leading_zeros(d))
    length = (bit_length * 1233) >> 12
    if d >= POW10[length]:
        length += 1
    return length


@jit
def write_digits(out: np.ndarray, start: int, d: np.uint64, length: int) -> None:
    """The ``length`` decimal digits of d (< 10^17) as ASCII into ``out[start:]``, right to
    left, two at a time (8 at a time in 32-bit arithmetic while d >= 10^8)."""
    end = start + length
    if d >= _U64(100000000):
        _eight(out, end - 8, _U32(d % _U64(100000000)))
        d //= _U64(100000000)
        end -= 8
    v = _U32(d)
    while v >= _U32(100):
        end -= 2
        _pair(out, end, v % _U32(100))
        v //= _U32(100)
    if v >= _U32(10):
        _pair(out, start, v)
    else:
        out[start] = np.uint8(48 + v)


@jit
def format_float(value: float, bits: np.uint64, out: np.ndarray, pos: int) -> int:
    """``repr(value)`` as ASCII into ``out[pos:]`` (``bits``: its IEEE bits as uint64);
    returns the new position, or -1 for NaN and infinities (Python's repr writes those).

    The layout of CPython's ``float_repr``: the digits are written where they end up and
    only the ones before the decimal point (positional) or the first one (exponential)
    are moved one place to make room for the point."""
    if not math.isfinite(value):
        return -1
    if value == 0.0:
        if math.copysign(1.0, value) < 0.0:
            out[pos] = 45  # '-'
            pos += 1
        out[pos] = 48
        out[pos + 1] = 46
        out[pos + 2] = 48
        return pos + 3
    if value < 0.0:
        out[pos] = 45
        pos += 1
    d, exponent = to_decimal(bits & _U64(0x7FFFFFFFFFFFFFFF))
    length = decimal_length(d)
    decpt = length + exponent  # value = 0.d1 d2 ... x 10^decpt
    if decpt <= -4 or decpt > 16:  # d.ddde+XX
        write_digits(out, pos + 1, d, length)
        out[pos] = out[pos + 1]
        if length > 1:
            out[pos + 1] = 46  # '.'
            pos += length + 1
        else:
            pos += 1
        out[pos] = 101  # 'e'
        exp10 = decpt - 1
        out[pos + 1] = 45 if exp10 < 0 else 43
        pos += 2
        exp10 = abs(exp10)
        if exp10 >= 100:
            out[pos] = 48 + exp10 // 100
            pos += 1
        out[pos] = 48 + (exp10 // 10) % 10
        out[pos + 1] = 48 + exp10 % 10
        return pos + 2
    if decpt <= 0:  # 0.000ddd
        out[pos] = 48
        out[pos + 1] = 46
        pos += 2
        for _ in range(-decpt):
            out[pos] = 48
            pos += 1
        write_digits(out, pos, d, length)
        return pos + length
    if decpt >= length:  # ddd000.0
        write_digits(out, pos, d, length)
        pos += length
        for _ in range(decpt - length):
            out[pos] = 48
            pos += 1
        out[pos] = 46
        out[pos + 1] = 48
        return pos + 2
    write_digits(out, pos + 1, d, length)  # dd.ddd
    for i in range(decpt):
        out[pos + i] = out[pos + 1 + i]
    out[pos + decpt] = 46
    return pos + length + 1


@jit
def format_int(value: int, out: np.ndarray, pos: int) -> int:
    """``str(value)`` of an int64 as ASCII into ``out[pos:]``; returns the new position."""
    if value == 0:
        out[pos] = 48
        return pos + 1
    buffer = np.empty(INT_WIDTH, dtype=np.uint8)
    n = 0
    negative = value < 0
    magnitude = np.uint64(-(value + 1)) + np.uint64(1) if negative else np.uint64(value)
    while magnitude > np.uint64(0):
        buffer[n] = np.uint8(magnitude % np.uint64(10) + np.uint64(48))
        magnitude = magnitude // np.uint64(10)
        n += 1
    if negative:
        out[pos] = 45
        pos += 1
    for i in range(n):
        out[pos] = buffer[n - 1 - i]
        pos += 1
    return pos


@jit
def _format_rows(floats, float_bits, ints, texts, kinds, index, table, table_len, fallback, out):
    """The rows of a block: column c is ``floats[index[c]]`` (kind 0), ``ints[index[c]]``
    (kind 1) or ``table[texts[index[c]]]`` (kind 2). A float that needs Python's repr is
    left out, its (column, row, byte position) recorded in ``fallback``; returns the bytes
    written and the number of fallbacks."""
    n_rows = floats.shape[1] if floats.shape[0] else (ints.shape[1] if ints.shape[0]
                                                        else texts.shape[1])  # fmt: skip
    pos = 0
    n_fallback = 0
    n_cols = kinds.size
    for r in range(n_rows):
        for c in range(n_cols):
            if c > 0:
                out[pos] = 44  # ','
                pos += 1
            kind = kinds[c]
            if kind == 0:
                end = format_float(floats[index[c], r], float_bits[index[c], r], out, pos)
                if end < 0:
                    fallback[n_fallback, 0] = c
                    fallback[n_fallback, 1] = r
                    fallback[n_fallback, 2] = pos
                    n_fallback += 1
                else:
                    pos = end
            elif kind == 1:
                pos = format_int(ints[index[c], r], out, pos)
            else:
                code = texts[index[c], r]
                for i in range(table_len[code]):
                    out[pos] = table[code, i]
                    pos += 1
        out[pos] = 10  # '\n'
        pos += 1
    return pos, n_fallback


FLOAT, INT, TEXT = 0, 1, 2


def column_kind(column: object) -> int | None:
    """How ``format_block`` formats a column (FLOAT, INT, TEXT), or None if it cannot.
    An object column is TEXT only if its values are all ``str`` (``format_block`` checks);
    so is a coded one (``io.Labels``: integer ``codes`` and the text ``names[code]``)."""
    if hasattr(column, "codes") and hasattr(column, "names"):
        return TEXT
    if not isinstance(column, np.ndarray) or column.ndim != 1:
        return None
    if column.dtype.kind == "f":
        return FLOAT
    if column.dtype.kind in "iu" and column.dtype.itemsize <= 8:
        if column.dtype.kind == "u" and column.dtype.itemsize == 8:
            return None if column.size and int(column.max()) >= 2**63 else INT
        return INT
    if column.dtype.kind in "OU":
        return TEXT
    return None


def _coded_rows(codes: np.ndarray, names, encoded: dict[object, int]) -> np.ndarray:
    """The table row of each code's text (``names[code]``), adding the texts to
    ``encoded``; ValueError for a code without a name."""
    keys = np.array(sorted(names), dtype=np.int64)
    codes = np.asarray(codes, dtype=np.int64)
    position = np.clip(np.searchsorted(keys, codes), 0, max(0, keys.size - 1))
    if codes.size and (keys.size == 0 or not np.array_equal(keys[position], codes)):
        raise ValueError("a coded text column has a code without a name")
    rows = np.array([encoded.setdefault(names[k], len(encoded)) for k in keys.tolist()])
    return rows[position] if codes.size else np.zeros(0, dtype=np.int64)


def format_block(
    columns: Sequence[np.ndarray | Labels],
    text_field: Callable[[object], str],
    nonfinite: str | None = None,
) -> bytes | memoryview | None:
    """The CSV rows of a block of columns (numpy arrays of equal length) as UTF-8 bytes
    (a bytes-like object: ``bytes`` or a ``memoryview`` of the formatted buffer),
    each float field exactly ``repr(value)`` (``nonfinite`` for NaN/inf if given), each
    integer ``str(value)``, each text ``text_field(value)`` (the caller's quoting rule).
    None when a column is of another kind (the caller formats the block itself)."""
    kinds = [column_kind(c) for c in columns]
    if not columns or any(k is None for k in kinds):
        return None
    n = len(columns[0])
    float_cols = [c for c, k in zip(columns, kinds, strict=True) if k == FLOAT]
    int_cols = [c for c, k in zip(columns, kinds, strict=True) if k == INT]
    text_cols = [c for c, k in zip(columns, kinds, strict=True) if k == TEXT]
    floats = np.empty((len(float_cols), n))
    for i, c in enumerate(float_cols):
        floats[i] = c
    ints = np.empty((len(int_cols), n), dtype=np.int64)
    for i, c in enumerate(int_cols):
        ints[i] = c
    texts = np.empty((len(text_cols), n), dtype=np.int64)
    encoded: dict[object, int] = {}
    for i, c in enumerate(text_cols):
        if hasattr(c, "names"):  # coded: no Python string per row
            texts[i] = _coded_rows(c.codes, c.names, encoded)
            continue
        values = c.tolist()
        try:
            distinct = set(values)
        except TypeError:  # unhashable objects: the caller's general path
            return None
        if not all(type(v) is str for v in distinct):  # e.g. floats in an object array
            return None
        for v in distinct:
            if v not in encoded:
                encoded[v] = len(encoded)
        texts[i] = [encoded[v] for v in values]
    fields = [text_field(v).encode("utf-8") for v in encoded]
    width = max((len(f) for f in fields), default=0)
    table = np.zeros((max(1, len(fields)), max(1, width)), dtype=np.uint8)
    table_len = np.zeros(max(1, len(fields)), dtype=np.int64)
    for i, f in enumerate(fields):
        table[i, : len(f)] = np.frombuffer(f, dtype=np.uint8)
        table_len[i] = len(f)
    counters = {FLOAT: 0, INT: 0, TEXT: 0}
    index = np.empty(len(kinds), dtype=np.int64)
    for c, k in enumerate(kinds):
        index[c] = counters[k]
        counters[k] += 1
    row_width = (len(float_cols) * FLOAT_WIDTH + len(int_cols) * INT_WIDTH
                 + len(text_cols) * width + len(kinds))  # fmt: skip
    out = np.empty(n * row_width, dtype=np.uint8)
    fallback = np.empty((n * len(float_cols), 3), dtype=np.int64)
    codes = np.asarray(kinds, dtype=np.int64)
    bits = floats.view(np.uint64)
    size, n_fallback = _format_rows(
        floats, bits, ints, texts, codes, index, table, table_len, fallback, out
    )
    if n_fallback == 0:
        return memoryview(out)[:size]  # written as it is: no copy of the text
    # NaN and infinities: Python's repr (or ``nonfinite``), spliced in at their places.
    view = memoryview(out)
    filled = []
    start = 0
    for c, r, at in fallback[:n_fallback].tolist():
        value = float(floats[index[c], r])
        nan_or_inf = not math.isfinite(value)
        text = nonfinite if nonfinite is not None and nan_or_inf else repr(value)
        filled.append(view[start:at])
        filled.append(text.encode("utf-8"))
        start = at
    filled.append(view[start:size])
    return b"".join(filled)
