"""4-byte floats read as the decimal numbers they were written from.

A Parquet file may store AIS speeds, courses and headings (or positions) as IEEE 754 binary32
("FLOAT"), as NOAA's data dictionary gives them. The writer had a decimal (an SOG of 5.9 kn);
the nearest binary32 is 5.900000095367431640625, and widening it to a double bit for bit keeps
that error. :func:`widen_float32` instead gives the double nearest to the **shortest decimal
that reads back as the same binary32** (Steele & White [1]; the value Python and numpy print):
5.9 for 5.9f, as the same row read from CSV text gives. Every binary32 has one: 9 significant
digits always read back (IEEE 754-2008 [2], 5.12.2), so the shortest has 1 to 9.

.. [1] G. L. Steele Jr., J. L. White, "How to print floating-point numbers accurately," PLDI
   1990 (shortest digits that read back; among equally short ones, the closest).
.. [2] IEEE Std 754-2008, "IEEE Standard for Floating-Point Arithmetic," 2008, 5.12.2 (decimal
   character sequences: 9 significant digits for binary32 round-trip).
"""

from __future__ import annotations

import numba
import numpy as np

#: Powers of ten up to 10**22, each exactly a double (5**22 < 2**53): a quotient or product of
#: a whole number below 2**53 by one of them is then correctly rounded, i.e. the double nearest
#: to the decimal.
_POW10 = np.array([10.0 ** i for i in range(23)])
#: Magnitudes whose candidates (1-9 digits) all use an exact power of ten (|exponent| <= 22).
_FAST_MIN, _FAST_MAX = 1e-13, 1e13


@numba.njit(nogil=True, cache=True)
def _shortest(v, out, rest) -> int:
    """For each finite, non-zero binary32 ``v[i]`` with magnitude in [_FAST_MIN, _FAST_MAX):
    ``out[i]`` = the double of the decimal with the fewest significant digits k that reads back
    as ``v[i]`` (at each k the nearest k-digit decimal, rounding half to even); others keep their
    plain widening and the finite non-zero ones are listed in ``rest`` (returns their count)."""
    n_rest = 0
    for i in range(v.shape[0]):
        f = v[i]
        x = np.float64(f)
        out[i] = x
        a = abs(x)
        if not (a >= _FAST_MIN and a < _FAST_MAX):  # zero, NaN, infinities: themselves
            if a > 0.0 and a < np.inf:
                rest[n_rest] = i
                n_rest += 1
            continue
        e = int(np.floor(np.log10(a)))
        hit = False
        for k in range(1, 10):
            p = k - 1 - e  # digits after the point
            if p >= 0:
                y = np.rint(x * _POW10[p]) / _POW10[p]
            else:
                y = np.rint(x / _POW10[-p]) * _POW10[-p]
            if np.float32(y) == f:
                out[i] = y
                hit = True
                break
        if not hit:  # not expected (9 digits read back); the exact path decides
            rest[n_rest] = i
            n_rest += 1
    return n_rest


def widen_float32(values) -> np.ndarray:
    """Binary32 ``values`` as doubles of their shortest round-trip decimals (module docstring);
    NaN, infinities and signed zeros stay themselves. About 20 ns per value; the magnitudes
    beyond 10**+-13 (none in AIS fields) go through numpy's own shortest text."""
    v = np.ascontiguousarray(values, dtype=np.float32)
    out = np.empty(v.shape[0], dtype=np.float64)
    rest = np.empty(v.shape[0], dtype=np.int64)
    n = _shortest(v, out, rest)
    if n:
        idx = rest[:n]
        out[idx] = v[idx].astype(str).astype(np.float64)
    return out
