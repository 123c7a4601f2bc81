"""The compiled CSV scan types a field only when its text is canonical, and then exactly as
Python / DuckDB would; everything else is reported as a special line."""

from __future__ import annotations

import calendar

import numpy as np
import pytest

from ais.io.csv_formats import NAV_STATUS_WORDS
from ais.io.csv_scan import KIND_BLANK, KIND_ROW, KIND_SPECIAL, scan_csv

# columns: time, mmsi, lat, status, name
INDEX = {"time_utc": 0, "mmsi": 1, "lat_deg": 2, "nav_status": 3, "name": 4}
DMA_T = ("%d/%m/%Y %H:%M:%S",)


def _scan(lines, n_threads=1, time_formats=DMA_T, newline=b"\n"):
    data = newline.join(x.encode("utf-8") if isinstance(x, str) else x for x in lines) + newline
    return scan_csv(np.frombuffer(data, dtype=np.uint8), INDEX, 5, time_formats, NAV_STATUS_WORDS, ("name",),
                    n_threads=n_threads), data


def one_hash(text: str, field: int = 4) -> int:
    """The scan's 64-bit FNV-1a hash of one static field (its bytes, then 256 + its column)."""
    h = 14695981039346656037
    for b in [*text.encode(), 256 + field]:
        h = ((h ^ b) * 1099511628211) % 2**64
    return h


def _epoch_us(y, mo, d, h, mi, s):
    return calendar.timegm((y, mo, d, h, mi, s)) * 1_000_000


@pytest.mark.parametrize("text, value", [
    ("55.123456", 55.123456), ("-0.5", -0.5), ("007", 7.0), ("123456789012345", 123456789012345.0),
    ("0.00000000000001", 1e-14), ("-179.999999", -179.999999), ("", None), ("90", 90.0),
    ("1.7976931348", 1.7976931348), ("0.1", 0.1), ("102.3", 102.3),
])
def test_canonical_numbers_are_exactly_pythons_float(text, value):
    r, _ = _scan([f"01/01/2025 00:00:00,219000001,{text},,N"])
    assert r.kind.tolist() == [KIND_ROW]
    got = r.vals[r.fields.index("lat_deg"), 0]
    if value is None:
        assert np.isnan(got)
    else:
        assert got == value and np.signbit(got) == np.signbit(value)


@pytest.mark.parametrize("text", ["1e5", "+1", "-0", "-0.000", "1.", ".5", "1.2.3", " 1", "1 ", "nan", "inf",
                                  "1234567890123456", "0.000000000000001", "0x10", "1_0", "١"])
def test_other_numbers_are_special(text):
    r, _ = _scan([f"01/01/2025 00:00:00,219000001,{text},,N"])
    assert r.kind.tolist() == [KIND_SPECIAL]


def test_random_decimals_round_like_float():
    rng = np.random.default_rng(7)
    lines, want = [], []
    for _ in range(3000):
        ndig = int(rng.integers(1, 16))
        digits = "".join(str(int(d)) for d in rng.integers(0, 10, ndig))
        cut = int(rng.integers(1, ndig + 1))
        text = digits[:cut] + ("." + digits[cut:] if cut < ndig else "")
        if rng.random() < 0.5 and int(digits) != 0:
            text = "-" + text
        lines.append(f"01/01/2025 00:00:00,219000001,{text},,N")
        want.append(float(text))
    r, _ = _scan(lines, n_threads=2)
    assert (r.kind == KIND_ROW).all()
    assert r.vals[r.fields.index("lat_deg")].tolist() == want


@pytest.mark.parametrize("text, expect", [
    ("29/02/2024 23:59:59", _epoch_us(2024, 2, 29, 23, 59, 59)),
    ("01/01/1970 00:00:00", 0),
    ("31/12/1899 12:00:00", _epoch_us(1899, 12, 31, 12, 0, 0)),  # before the epoch
    ("15/06/2025 08:30:05", _epoch_us(2025, 6, 15, 8, 30, 5)),
])
def test_canonical_times(text, expect):
    r, _ = _scan([f"{text},219000001,55.0,,N"])
    assert r.kind.tolist() == [KIND_ROW]
    assert r.t_us[0] == expect


@pytest.mark.parametrize("text", ["29/02/2025 00:00:00", "31/04/2025 00:00:00", "01/13/2025 00:00:00",
                                  "01/01/2025 24:00:00", "01/01/2025 00:60:00", "01/01/2025 00:00:60",
                                  "1/1/2025 00:00:00", "01/01/2025T00:00:00", "01/01/2025 00:00:00.5",
                                  " 01/01/2025 00:00:00", "", "01/01/1600 00:00:00", "2025-01-01T00:00:00"])
def test_other_times_are_special(text):
    r, _ = _scan([f"{text},219000001,55.0,,N"])
    assert r.kind.tolist() == [KIND_SPECIAL]


def test_noaa_layouts_both_separators():
    r, _ = _scan(["2025-01-02T03:04:05,219000001,55.0,,N", "2025-01-02 03:04:05,219000001,55.0,,N",
                  "02/01/2025 03:04:05,219000001,55.0,,N"],
                 time_formats=("%Y-%m-%dT%H:%M:%S", "%Y-%m-%d %H:%M:%S"))
    assert r.kind.tolist() == [KIND_ROW, KIND_ROW, KIND_SPECIAL]
    assert r.t_us[0] == r.t_us[1] == _epoch_us(2025, 1, 2, 3, 4, 5)


def test_mmsi_status_and_line_rules():
    r, data = _scan([
        "01/01/2025 00:00:00,219000001,55.0,MOORED,N",       # status word, any case
        "01/01/2025 00:00:00,21900001,55.0,5,N",              # 8 digits: no MMSI, still canonical
        "01/01/2025 00:00:00,,55.0,,N",                       # empty MMSI
        "01/01/2025 00:00:00,2190000O1,55.0,,N",              # a letter: special
        "01/01/2025 00:00:00,219000001,55.0,moored ,N",       # word with a space: special
        "",                                                   # blank
        "01/01/2025 00:00:00,219000001,55.0,,N,extra",        # 6 fields
        "01/01/2025 00:00:00,219000001,55.0,,\"N\"",          # a quote
        b"01/01/2025 00:00:00,219000001,55.0,,A\rB",          # a carriage return inside
        b"01/01/2025 00:00:00,219000001,55.0,,N\xd8RD",       # bytes that are not UTF-8 (static field)
        "01/01/2025 00:00:00,219000001,55.0,2",               # 4 fields
    ])
    assert r.kind.tolist() == [KIND_ROW, KIND_ROW, KIND_ROW, KIND_SPECIAL, KIND_SPECIAL, KIND_BLANK, KIND_SPECIAL,
                               KIND_SPECIAL, KIND_SPECIAL, KIND_ROW, KIND_SPECIAL]
    assert r.line.tolist() == [1, 2, 3, 10]  # the rows' values are packed, with their line numbers
    assert r.mmsi[:3].tolist() == [219000001, -1, -1]
    nav = r.vals[r.fields.index("nav_status")]
    assert nav[0] == 5.0 and nav[1] == 5.0 and np.isnan(nav[2])
    assert r.quote_lines.tolist() == [8] and r.stray_cr
    # offsets: line k is data[starts:ends]
    lines = data.split(b"\n")
    for k in range(r.n_lines):
        assert data[r.starts[k]:r.ends[k]] == lines[k]


def test_crlf_lines_and_threads_agree():
    rows = [f"01/01/2025 00:{m:02d}:00,2190000{m:02d},{50 + m / 7:.6f},,SHIP {m % 3}" for m in range(60)]
    one, _ = _scan(rows, n_threads=1, newline=b"\r\n")
    two, data = _scan(rows, n_threads=2, newline=b"\r\n")
    assert (one.kind == KIND_ROW).all() and not one.stray_cr
    for name in ("starts", "ends", "kind", "line", "mmsi", "t_us", "vals", "shash"):
        assert np.array_equal(getattr(one, name), getattr(two, name), equal_nan=True), name
    assert data[one.starts[5]:one.ends[5]].decode() == rows[5]
    # rows with the same static text share a hash, others do not
    assert one.shash[0] == one.shash[3] != one.shash[1]


@pytest.mark.parametrize("n_threads,chunk_lines", [(1, 1 << 20), (2, 1 << 20), (3, 1 << 20), (2, 7), (3, 100)])
def test_ranges_fill_one_allocation_with_or_without_a_final_newline(n_threads, chunk_lines):
    # The ranges write into regions of one allocation moved together afterwards (or, small
    # chunks forced, into arrays of their own joined at the end): every line, blank ones and a
    # last line without a newline included, must come out once and in file order, and every
    # row once with its line number.
    lines = [f"01/01/2025 00:00:{i % 60:02d},2190000{i % 90 + 10:02d},{50 + i / 1000:.3f},,N{i}" for i in range(3000)]
    lines[1500] = ""
    for data in ("\n".join(lines) + "\n", "\n".join(lines)):
        buf = np.frombuffer(data.encode(), dtype=np.uint8)
        r = scan_csv(buf, INDEX, 5, DMA_T, NAV_STATUS_WORDS, ("name",), n_threads=n_threads,
                     chunk_lines=chunk_lines)
        assert r.n_lines == len(lines)
        got = [data[a:b] for a, b in zip(r.starts.tolist(), r.ends.tolist())]
        assert got == lines
        assert (r.kind == KIND_ROW).sum() == len(lines) - 1
        assert r.line.tolist() == [k + 1 for k in range(len(lines)) if k != 1500]
        lat = r.vals[r.fields.index("lat_deg")]
        assert lat.tolist() == [pytest.approx(50 + k / 1000) for k in range(len(lines)) if k != 1500]
        assert r.shash.tolist() == [one_hash(f"N{k}") for k in range(len(lines)) if k != 1500]
