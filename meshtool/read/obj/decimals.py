"""Plain decimal numbers read exactly with numpy's integer parser (the fast path of OBJ vertex data).

:func:`decimal_numbers` gives bit for bit the values of a correctly rounded parser (Python's ``float``,
``np.loadtxt``) or ``None``; :mod:`meshtool.read.obj.lines` falls back to those parsers on ``None``.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

#: Bytes of a block that :func:`decimal_numbers` reads besides its keywords' letters.
_DECIMAL_BYTES = b"0123456789.+-eE \n"
#: Exact powers of ten (every 10**k up to 10**22 is a float64 without rounding).
_POW10 = 10.0 ** np.arange(23)
#: Largest integer mantissa below which every integer is exact in a float64.
_EXACT = 2**53
_LETTER_TABLES: dict[bytes, bytes] = {}
#: Most tokens of a block read one by one with ``float`` (past the fast path's digits or powers of ten).
_MAX_SLOW = 10_000


def _digit(c: npt.NDArray[np.uint8]) -> BoolArray:
    result: BoolArray = (c >= 48) & (c <= 57)
    return result


def decimal_numbers(block: bytes, letters: dict[int, int]) -> tuple[FloatArray, IntArray] | None:
    r"""Every number of a block of plain decimals and the count per line, or ``None``.

    Plain decimals: ``[+-]digits[.digits][(e|E)[+-]digits]`` (at least one digit before the exponent).

    The fast path of OBJ vertex data: the keywords and exponent marks are blanked and the dots deleted in one
    ``translate``, the block read as integers (numpy's integer parser, several times its float parser), and
    each mantissa ``m`` scaled by ``10**(exponent - decimals)``: ``m`` and the power are exact floats when
    ``|m| <= 2**53`` and the power is at most 22, and one IEEE multiplication or division is correctly
    rounded, so the result is bit for bit what a correctly rounded parser (``float``, ``np.loadtxt``) reads
    (Clinger's fast path); ``-0`` keeps its sign. Up to :data:`_MAX_SLOW` tokens beyond that (17 digits,
    ``1e-30``) are read by Python's ``float`` from their text. Anything else (``nan``, a tab,
    a token that is not one number) means ``None``: the caller reads the block with numpy's float parser or
    line by line.

    Args:
        block: Lines that each start with their keyword (``v``, ``vt``, ``vn``) and end with ``\n``.
        letters: Each keyword letter (a byte value, all of them past ``e``) and how many times it starts a
            keyword in the block: a letter found more often occurs in the numbers (not plain decimals).

    Returns:
        The numbers in order (float64, shape (n,)) and how many each line holds, or ``None``.
    """
    key = bytes(sorted(letters))
    if not block or min(key) < 102:
        return None
    # one pass: what is left without the plain decimals' bytes must be the keywords' letters, each as often
    # as it starts a keyword (a letter found more often occurs in the numbers)
    rest = block.translate(None, _DECIMAL_BYTES)
    if len(rest) != sum(letters.values()) or rest.translate(None, key):
        return None
    if any(rest.count(c) != n for c, n in letters.items()):
        return None
    a = np.frombuffer(block, dtype=np.uint8)
    ws = (a <= 32) | (a >= 102)  # the keywords' letters (counted above; e and E are below 102): blanks
    edges = np.flatnonzero(ws[1:] != ws[:-1]) + 1  # the block starts and ends blank: start, end, start, ...
    tstart, tend = edges[0::2], edges[1::2]
    n = tstart.size
    if n == 0:
        return None
    ends = tend  # where each token's mantissa ends (its exponent mark, if any)
    marks = np.flatnonzero((a == 101) | (a == 69)) if b"e" in block or b"E" in block else edges[:0]
    if marks.size:
        marked = np.searchsorted(tend, marks, side="right")  # token of each exponent mark
        if marks.size > 1 and not bool((np.diff(marked) > 0).all()):
            return None  # two marks in one token
        before, after = a[marks - 1], a[marks + 1]  # a mark is never first or last: keyword before, newline after
        after2 = a[np.minimum(marks + 2, a.size - 1)]
        ok_before = _digit(before) | ((before == 46) & _digit(a[np.maximum(marks - 2, 0)]))
        ok_after = _digit(after) | (((after == 43) | (after == 45)) & _digit(after2))
        if not bool((ok_before & ok_after).all()):
            return None
        ends = tend.copy()
        ends[marked] = marks
    dots = np.flatnonzero(a == 46)
    if dots.size == n and bool((dots >= tstart).all() and (dots < tend).all()):
        decimals = ends - dots - 1  # the i-th dot in the i-th token: one in every token (the usual %f text)
    else:
        decimals = np.zeros(n, dtype=np.int64)
        if dots.size:
            dotted = np.searchsorted(tend, dots, side="right")  # token of each dot
            if dots.size > 1 and not bool((np.diff(dotted) > 0).all()):
                return None  # two dots in one token
            decimals[dotted] = ends[dotted] - dots - 1
    if int(decimals.min()) < 0:
        return None  # a dot in the exponent
    signs = np.flatnonzero((a == 45) | (a == 43))
    if signs.size:
        prior = a[signs - 1]
        if not bool((ws[signs - 1] | (prior == 101) | (prior == 69)).all()):
            return None  # a sign inside a token ("5-3", "--1", "1.-2")
    short = np.flatnonzero(tend - tstart <= 2)
    if short.size:  # a token of a sign and/or a dot only holds no digit: "-", ".", "+."
        first, second = a[tstart[short]], a[np.minimum(tstart[short] + 1, a.size - 1)]
        one = (tend - tstart)[short] == 1
        if not bool((_digit(first) | (~one & _digit(second))).all()):
            return None
    table = _LETTER_TABLES.get(key)
    if table is None:
        blanks = key + b"eE"
        table = _LETTER_TABLES[key] = bytes.maketrans(blanks, b" " * len(blanks))
    try:
        ints = np.fromstring(block.translate(table, b"."), dtype=np.int64, sep=" ")
    except ValueError:
        return None
    if ints.size != n + marks.size:
        return None
    if marks.size:
        has_mark = np.zeros(n, dtype=np.int64)
        has_mark[marked] = 1
        at = np.arange(n) + np.cumsum(has_mark) - has_mark  # each mantissa's place among the integers
        mantissa = ints[at]
        power = -decimals
        power[marked] += ints[at[marked] + 1]
    else:
        mantissa, power = ints, -decimals
    # beyond the fast path: more digits than a float64 holds exactly (numpy saturates beyond int64) or a
    # power of ten past 22 ("2.710505e-20"): those few tokens are read by Python's float from their text
    inexact = (mantissa > _EXACT) | (mantissa < -_EXACT) | (power < -22) | (power > 22)
    slow = np.flatnonzero(inexact) if bool(inexact.any()) else None
    if slow is not None:
        if slow.size > _MAX_SLOW:
            return None
        power = np.where(inexact, 0, power)
    exact = mantissa.astype(np.float64)
    values: FloatArray
    if int(power.max()) <= 0:
        values = exact / _POW10[-power]
    else:
        values = np.where(power >= 0, exact * _POW10[np.maximum(power, 0)], exact / _POW10[np.maximum(-power, 0)])
    zero = np.flatnonzero(mantissa == 0)
    if zero.size and signs.size:
        values[zero[a[tstart[zero]] == 45]] = -0.0
    if slow is not None:
        values[slow] = [float(block[s:e]) for s, e in zip(tstart[slow].tolist(), tend[slow].tolist(), strict=True)]
    counts = tokens_per_line(a, tstart, tend)
    if not bool(counts.all()):
        return None  # a keyword alone: an error, reported by the caller's path as before
    return values, counts


def tokens_per_line(a: npt.NDArray[np.uint8], tstart: IntArray, tend: IntArray) -> IntArray:
    """Tokens on each line of a block (``a``, newline-terminated lines) from the tokens' start and end offsets.

    When the tokens divide evenly, the lines are checked to hold ``k`` each (every ``k``-th token starts
    after the previous line's newline and the token ``k - 1`` later ends before this line's): no search.
    """
    newlines = np.flatnonzero(a == 10)
    lines = newlines.size
    if lines and tstart.size % lines == 0 and tstart.size:
        k = tstart.size // lines
        if bool((tend[k - 1 :: k] <= newlines).all() and (tstart[k::k] > newlines[:-1]).all()):
            return np.full(lines, k, dtype=np.int64)
    line_starts = np.empty_like(newlines)
    if lines:
        line_starts[0] = 0
        line_starts[1:] = newlines[:-1] + 1
    counts: IntArray = np.diff(np.searchsorted(tstart, line_starts), append=tstart.size)
    return counts
