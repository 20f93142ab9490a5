"""Compiled CSV text: floats in Python's shortest round-trip form (``repr``), fast.

A solution CSV of a long run is millions of floats, and CPython's ``repr(float)`` (David
Gay's correctly rounded dtoa, shortest mode) costs about 0.4-1.3 us per value: 5-15 s for
a 10,000-period run, more than its solve. This module writes the same text from compiled
code:

- **Digits**: Grisu3 (F. Loitsch, "Printing floating-point numbers quickly and accurately
  with integers", PLDI 2010; the algorithm of Google's double-conversion ``FastDtoa``,
  shortest mode). With 64-bit integer arithmetic and a table of cached powers of ten it
  finds the shortest digit string that reads back as the same double and, among those,
  the one closest to it; for about 0.5% of doubles it cannot prove that its answer is
  both, and says so. Those values (and NaN, infinities) are formatted by Python's own
  ``repr`` instead. So every field is exactly ``repr(value)``: same digits, same text.
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
from fractions import Fraction

import numba
import numpy as np

jit = numba.njit(cache=True, nogil=True)  # formats beside the figures (io.Background)

FLOAT_WIDTH = 24  # longest repr of a double: '-2.2250738585072014e-308'
INT_WIDTH = 20  # longest int64: '-9223372036854775808'
_U64 = np.uint64
_MASK32 = np.uint64(0xFFFFFFFF)
_HIDDEN = np.uint64(1 << 52)
_SIGNIFICAND_MASK = np.uint64((1 << 52) - 1)
_MIN_TARGET_EXPONENT = -60
_MAX_TARGET_EXPONENT = -32
_FIRST_CACHED_EXPONENT = -348
_CACHED_STEP = 8


def _cached_powers() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """10^k for k = -348, -340, ..., 340 as 64-bit significands f (2^63 <= f < 2^64,
    rounded to nearest) and binary exponents e: 10^k ~ f 2^e (exact rational arithmetic;
    the table of double-conversion's cached-powers.cc)."""
    fs, es, ks = [], [], []
    for k in range(_FIRST_CACHED_EXPONENT, 341, _CACHED_STEP):
        value = Fraction(10) ** k
        e = math.floor(math.log2(value.numerator) - math.log2(value.denominator)) - 63
        while value / Fraction(2) ** e >= 2**64:
            e += 1
        while value / Fraction(2) ** e < 2**63:
            e -= 1
        f = math.floor(value / Fraction(2) ** e + Fraction(1, 2))
        if f == 2**64:
            f, e = f // 2, e + 1
        fs.append(f)
        es.append(e)
        ks.append(k)
    return np.array(fs, dtype=np.uint64), np.array(es, dtype=np.int64), np.array(ks, np.int64)


CACHED_F, CACHED_E, CACHED_K = _cached_powers()


@jit
def _multiply(a, b):
    """High 64 bits of the 128-bit product a b, rounded (DiyFp::Multiply)."""
    a_hi = a >> _U64(32)
    a_lo = a & _MASK32
    b_hi = b >> _U64(32)
    b_lo = b & _MASK32
    ac = a_hi * b_hi
    bc = a_lo * b_hi
    ad = a_hi * b_lo
    bd = a_lo * b_lo
    tmp = (bd >> _U64(32)) + (ad & _MASK32) + (bc & _MASK32) + _U64(1 << 31)
    return ac + (ad >> _U64(32)) + (bc >> _U64(32)) + (tmp >> _U64(32))


@jit
def _normalize(f, e):
    while (f & _U64(0xFFC0000000000000)) == _U64(0):
        f = f << _U64(10)
        e -= 10
    while (f & _U64(0x8000000000000000)) == _U64(0):
        f = f << _U64(1)
        e -= 1
    return f, e


@jit
def _round_weed(digits, length, distance_too_high_w, unsafe_interval, rest, ten_kappa, unit):
    small_distance = distance_too_high_w - unit
    big_distance = distance_too_high_w + unit
    while (
        rest < small_distance
        and unsafe_interval - rest >= ten_kappa
        and (
            rest + ten_kappa < small_distance
            or small_distance - rest >= rest + ten_kappa - small_distance
        )
    ):
        digits[length - 1] -= 1
        rest += ten_kappa
    if (
        rest < big_distance
        and unsafe_interval - rest >= ten_kappa
        and (
            rest + ten_kappa < big_distance or big_distance - rest > rest + ten_kappa - big_distance
        )
    ):
        return False
    return _U64(2) * unit <= rest and rest <= unsafe_interval - _U64(4) * unit


@jit
def grisu3(bits, digits):
    """Shortest digits of a finite double > 0, given by its IEEE bits (uint64), into
    ``digits`` (uint8 array, ASCII).

    Returns ``(length, decimal_exponent)`` with value ~ digits x 10^decimal_exponent, or
    ``(0, 0)`` when Grisu3 cannot guarantee the shortest, closest answer (then use repr).
    """
    biased = np.int64((bits >> _U64(52)) & _U64(0x7FF))
    significand = bits & _SIGNIFICAND_MASK
    if biased == 0:
        f = significand
        e = np.int64(-1074)
    else:
        f = significand + _HIDDEN
        e = biased - 1075
    # boundaries m- and m+ (Double::NormalizedBoundaries)
    plus_f, plus_e = _normalize((f << _U64(1)) + _U64(1), e - 1)
    if significand == _U64(0) and biased > 1:
        minus_f, minus_e = (f << _U64(2)) - _U64(1), e - 2
    else:
        minus_f, minus_e = (f << _U64(1)) - _U64(1), e - 1
    minus_f = minus_f << _U64(minus_e - plus_e)
    w_f, w_e = _normalize(f, e)
    # the cached power 10^mk that brings w's exponent into [-60, -32]
    min_exponent = _MIN_TARGET_EXPONENT - (w_e + 64)
    k = np.int64(math.ceil((min_exponent + 63) * 0.30102999566398114))
    index = (-_FIRST_CACHED_EXPONENT + k - 1) // _CACHED_STEP + 1
    c_f, c_e, mk = CACHED_F[index], CACHED_E[index], CACHED_K[index]
    w_f = _multiply(w_f, c_f)
    low_f = _multiply(minus_f, c_f)
    high_f = _multiply(plus_f, c_f)
    one_e = w_e + c_e + 64  # the common exponent of the scaled w, low, high
    # DigitGen
    unit = _U64(1)
    too_low = low_f - unit
    too_high = high_f + unit
    unsafe_interval = too_high - too_low
    shift = _U64(-one_e)
    one_f = _U64(1) << shift
    integrals = too_high >> shift
    fractionals = too_high & (one_f - _U64(1))
    divisor = _U64(1)
    kappa = 1
    while divisor * _U64(10) <= integrals:
        divisor *= _U64(10)
        kappa += 1
    length = 0
    while kappa > 0:
        digits[length] = np.uint8(integrals // divisor + _U64(48))
        length += 1
        integrals = integrals % divisor
        kappa -= 1
        rest = (integrals << shift) + fractionals
        if rest < unsafe_interval:
            ok = _round_weed(digits, length, too_high - w_f, unsafe_interval, rest,
                             divisor << shift, unit)  # fmt: skip
            return (length, kappa - mk) if ok else (0, 0)
        divisor = divisor // _U64(10)
    while True:
        fractionals *= _U64(10)
        unit *= _U64(10)
        unsafe_interval *= _U64(10)
        digits[length] = np.uint8((fractionals >> shift) + _U64(48))
        length += 1
        fractionals &= one_f - _U64(1)
        kappa -= 1
        if fractionals < unsafe_interval:
            ok = _round_weed(digits, length, (too_high - w_f) * unit, unsafe_interval,
                             fractionals, one_f, unit)  # fmt: skip
            return (length, kappa - mk) if ok else (0, 0)


@jit
def format_float(value, bits, out, pos, digits):
    """``repr(value)`` as ASCII into ``out[pos:]`` (``bits``: its IEEE bits as uint64);
    returns the new position, or -1 if the value needs Python's repr (non-finite, or
    Grisu3 gave up)."""
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
    negative = value < 0.0
    length, exponent = grisu3(bits & _U64(0x7FFFFFFFFFFFFFFF), digits)
    if length == 0:
        return -1
    if negative:
        out[pos] = 45
        pos += 1
    decpt = length + exponent  # value = 0.d1 d2 ... x 10^decpt
    if decpt <= -4 or decpt > 16:
        out[pos] = digits[0]
        pos += 1
        if length > 1:
            out[pos] = 46  # '.'
            pos += 1
            for i in range(1, length):
                out[pos] = digits[i]
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
    if decpt <= 0:
        out[pos] = 48
        out[pos + 1] = 46
        pos += 2
        for _ in range(-decpt):
            out[pos] = 48
            pos += 1
        for i in range(length):
            out[pos] = digits[i]
            pos += 1
        return pos
    if decpt >= length:
        for i in range(length):
            out[pos] = digits[i]
            pos += 1
        for _ in range(decpt - length):
            out[pos] = 48
            pos += 1
        out[pos] = 46
        out[pos + 1] = 48
        return pos + 2
    for i in range(decpt):
        out[pos] = digits[i]
        pos += 1
    out[pos] = 46
    pos += 1
    for i in range(decpt, length):
        out[pos] = digits[i]
        pos += 1
    return pos


@jit
def format_int(value, out, pos):
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
    digits = np.empty(32, dtype=np.uint8)
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
                end = format_float(floats[index[c], r], float_bits[index[c], r], out, pos,
                                   digits)  # fmt: skip
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
    An object column is TEXT only if its values are all ``str`` (``format_block`` checks)."""
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


def format_block(columns, text_field, nonfinite: str | None = None) -> bytes | None:
    """The CSV rows of a block of columns (numpy arrays of equal length) as UTF-8 bytes,
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
        return out[:size].tobytes()
    # The few fields Grisu3 left (and NaN/inf): Python's repr, spliced in at their places.
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
