"""The DMA CSV lines of many records at once, as Arrow string arrays (issue 23: the year-scale
generator's writer).

Formatting each line with Python f-strings cost about 10 us per row, the largest part of
writing a year of a fleet. Here every column is turned into text by Arrow's compute kernels and
the lines are joined column by column; the text is the same, byte for byte, as Python's
formatting (``f"{x:.6f}"``, ``f"{x:.1f}"``, ``int(x)``) that :func:`scenario.writers.write_dma_csv`
used before (tested against it on every kind of row):

* a fixed-point number ``f"{x:.{d}f}"`` is the integer ``rint(|x| 10^d)`` split at the decimal
  point, with ``-`` when ``x``'s sign bit is set (Python prints ``-0.000000`` for ``-0.0`` and
  for tiny negatives too). This is Python's correctly rounded result whenever ``|x| 10^d`` is
  more than 0.001 from a rounding tie and below ``2^40`` (the float product is then within
  ``2^-12`` of the exact one, so the nearest integer is unambiguous). Quantised AIS values
  (1/600 000 degree, 0.1 kn, 0.1 degree) are never near a tie; the few values that are, and
  NaN, are formatted by Python itself.
* times are a ``dd/mm/YYYY `` prefix per UTC day joined with a table of the 86 400
  ``HH:MM:SS`` texts of a day.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

#: Beyond this, ``|x| 10^d`` in float64 may be more than 2^-12 from the exact product.
_EXACT_LIMIT = float(2 ** 40)

_HMS: pa.Array | None = None


def hms_texts() -> pa.Array:
    """``HH:MM:SS`` for every second of a day (index = seconds since midnight)."""
    global _HMS
    if _HMS is None:
        s = np.arange(86400)
        two = pc.utf8_lpad(pc.cast(pa.array(np.arange(60)), pa.string()), width=2, padding="0")
        _HMS = pc.binary_join_element_wise(two.take(pa.array(s // 3600)), two.take(pa.array(s // 60 % 60)),
                                           two.take(pa.array(s % 60)), ":")
    return _HMS


def fixed_text(x, decimals: int) -> pa.Array:
    """``f"{v:.{decimals}f}"`` of every value of ``x`` (``decimals`` >= 1), see the module docstring."""
    x = np.asarray(x, dtype=np.float64)
    scale = 10 ** int(decimals)
    with np.errstate(invalid="ignore"):
        s = np.abs(x) * scale
        r = np.rint(s)
        exact = np.isfinite(s) & (s < _EXACT_LIMIT) & (np.abs(s - r) < 0.499)
    ri = np.where(exact, r, 0.0).astype(np.int64)
    whole = pc.cast(pa.array(ri // scale), pa.string())
    frac = pc.utf8_lpad(pc.cast(pa.array(ri % scale), pa.string()), width=int(decimals), padding="0")
    text = pc.binary_join_element_wise(whole, frac, ".")
    negative = np.signbit(x) & exact
    if negative.any():
        text = pc.if_else(pa.array(negative), pc.binary_join_element_wise("-", text, ""), text)
    if not exact.all():
        slow = np.flatnonzero(~exact)
        text = pc.replace_with_mask(text, pa.array(~exact),
                                    pa.array([f"{v:.{decimals}f}" for v in x[slow].tolist()], pa.string()))
    return text


def int_text(x) -> pa.Array:
    """``str(int(v))`` of every value (truncation toward zero, as ``int()``)."""
    return pc.cast(pa.array(np.trunc(np.asarray(x, dtype=np.float64)).astype(np.int64)), pa.string())


def dma_time_text(time_s) -> pa.Array:
    """Unix seconds (>= 0) to ``dd/mm/YYYY HH:MM:SS`` (day first, as the DMA export)."""
    time_s = np.asarray(time_s, dtype=np.int64)
    days, where = np.unique(time_s // 86400, return_inverse=True)
    prefix = pa.array([pd.Timestamp(int(d) * 86400, unit="s").strftime("%d/%m/%Y ") for d in days], pa.string())
    return pc.binary_join_element_wise(prefix.take(pa.array(where.reshape(-1))),
                                       hms_texts().take(pa.array(time_s % 86400)), "")


def lookup_text(table: list[str], index) -> pa.Array:
    """``table[i]`` for every ``i`` of ``index``."""
    return pa.array(table, pa.string()).take(pa.array(np.asarray(index, dtype=np.int64)))


def _text_column(x) -> pa.Array:
    """A string column as an Arrow array (numpy or pandas object columns are converted)."""
    if isinstance(x, (pa.Array, pa.ChunkedArray)):
        return x
    return pa.array(np.asarray(x, dtype=object), pa.string())


def dma_lines(cols: dict, statics: list[tuple[str, str]], unknown_static: tuple[str, str],
              nav_words: list[str]) -> pa.Array:
    """The DMA CSV line of every record, each ending with a newline.

    ``cols``: ``time_s``, ``mmsi``, ``lat_deg``, ``lon_deg``, ``nav_status``, ``sog_kn``,
    ``cog_deg``, ``heading_deg``, ``vessel_index``, ``draught_m``, ``eta_s`` (numpy arrays or
    pandas columns) and ``destination``, ``dirty_kind``, ``time_text`` (those or Arrow string
    arrays); ``statics[i]``: the identity and dimension fields of vessel ``i``
    (``unknown_static`` for ``vessel_index`` < 0); ``nav_words``: the status word of codes
    0..15 (others: the last entry's).
    """
    kind = _text_column(cols["dirty_kind"])
    ts = dma_time_text(cols["time_s"])
    bad_ts = pc.equal(kind, "bad_timestamp")
    if pc.any(bad_ts).as_py():
        ts = pc.if_else(bad_ts, _text_column(cols["time_text"]), ts)
    nav = np.asarray(cols["nav_status"], dtype=np.int64)
    nav_txt = lookup_text(nav_words, np.where((nav >= 0) & (nav < len(nav_words)), nav, len(nav_words) - 1))
    head = pc.binary_join_element_wise(ts, "Class A", int_text(cols["mmsi"]), fixed_text(cols["lat_deg"], 6),
                                       fixed_text(cols["lon_deg"], 6), nav_txt, ",")
    vi = np.asarray(cols["vessel_index"], dtype=np.int64)
    known = pa.array(vi >= 0)
    which = np.where(vi >= 0, vi, len(statics))
    ident = lookup_text([s for s, _ in statics] + [unknown_static[0]], which)
    dims = lookup_text([d for _, d in statics] + [unknown_static[1]], which)
    eta_s = np.asarray(cols["eta_s"], dtype=np.int64)
    eta = pc.if_else(pa.array((vi >= 0) & (eta_s >= 0)), dma_time_text(np.maximum(eta_s, 0)), "")
    draught = pc.if_else(known, fixed_text(cols["draught_m"], 1), "")
    dest = pc.if_else(known, _text_column(cols["destination"]), "")
    full = pc.binary_join_element_wise(head, "", fixed_text(cols["sog_kn"], 1), fixed_text(cols["cog_deg"], 1),
                                       int_text(cols["heading_deg"]), ident, draught, dest, eta, "AIS", dims, ",")
    cut = pc.equal(kind, "malformed_row")  # a line cut off after the navigational status
    line = pc.if_else(cut, head, full) if pc.any(cut).as_py() else full
    return pc.binary_join_element_wise(line, "", "\n")


def concatenated_bytes(lines: pa.Array) -> memoryview:
    """The values of a string array laid end to end (no copy)."""
    if isinstance(lines, pa.ChunkedArray):
        lines = lines.combine_chunks()
    if len(lines) == 0:
        return memoryview(b"")
    offsets = np.frombuffer(lines.buffers()[1], dtype=np.int32, count=lines.offset + len(lines) + 1)
    start, stop = int(offsets[lines.offset]), int(offsets[lines.offset + len(lines)])
    return memoryview(lines.buffers()[2])[start:stop]
