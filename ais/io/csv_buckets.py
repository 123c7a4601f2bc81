"""Split a large DMA/NOAA CSV file into files of whole vessels: MMSI ranges of about equal rows.

The ingest applies its cross-row rules (repeated (MMSI, time) keys, speed jumps, the latest
static fields) within one vessel's rows only, so a file cut into groups of whole vessels and
committed group after group gives exactly the rules' result on the whole file, with the memory
of one group (issue 23: the ingest's peak grew with the rows of the largest file, about 0.69 KB
per row). Each group is an ordinary CSV file: the input's header line, then the lines of the
group in their input order; beside it the input's line number of each of its lines (line 1 is
the header), so that quarantine lines and ``source_line`` name the input's lines.

A line's group is decided by the MMSI the ingest would read from it (:mod:`ais.io.csv_formats`:
the MMSI field, split on commas, or by an RFC 4180 parse when the line holds a double quote up
to that field, matching ``MMSI_RE``: nine ASCII digits between white space; a quote in a later
field cannot move it, and a line whose quotes make it a bad line has no cross-row rule). Lines without such an MMSI (bad
lines, blank lines, repeated headers) have no cross-row rule and go to the first group. The
groups are MMSI ranges, so a day's positions of the groups, one after the other, are in the
(MMSI, time) order of the whole file (the positions dataset's parts are written that way).

Lines are split on ``\\n`` as in :class:`ais.io.lineindex.LineIndex`; a last line without a
newline gets one in its group's file (the same line).
"""

from __future__ import annotations

import mmap
import re
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np

from ais.io.csv_formats import MMSI_RE, split_csv_line

#: Key of a line without an MMSI, and of a line with a double quote up to its MMSI field (decided
#: in Python by the ingest's own splitter).
NO_KEY, QUOTED = -1, -2
#: Bytes of the input per step of the split (bounded temporary memory).
_STEP_BYTES = 64 << 20
#: The ranges are chosen from every k-th step of the input: the balance of the groups needs the
#: share of rows per vessel, not every row (the split itself reads every line).
_SAMPLE_STRIDE = 3


@numba.njit(nogil=True, cache=True)
def _is_ws(c):
    return c == 32 or c == 9 or c == 10 or c == 13 or c == 11 or c == 12


@numba.njit(nogil=True, cache=True)
def _line_keys(buf, pos, end, col, starts, stops, keys):
    """From ``pos`` (a line start) to ``end``: each line's start, stop (one past its newline, or
    ``end``) and MMSI key (the nine-digit number of field ``col``, :data:`NO_KEY`, or
    :data:`QUOTED` when a double quote stands before the field's end: only then can the
    quoted-field parse read another field there), at most ``len(keys)`` lines. Returns (lines,
    next position)."""
    n = 0
    cap = len(keys)
    while pos < end and n < cap:
        starts[n] = pos
        field = 0
        a = -1
        b = -1
        quoted = False
        i = pos
        while i < end and buf[i] != 10:
            c = buf[i]
            if c == 34 and b < 0:  # a quote after the MMSI field cannot move it
                quoted = True
            elif c == 44:
                if field == col:
                    b = i
                field += 1
                if field == col:
                    a = i + 1
            i += 1
        if field == col and b < 0:
            b = i
        if col == 0:
            a = pos
        stops[n] = i + 1 if i < end else end
        key = NO_KEY
        if quoted:
            key = QUOTED
        elif a >= 0 and b >= a:
            while a < b and _is_ws(buf[a]):
                a += 1
            while b > a and _is_ws(buf[b - 1]):
                b -= 1
            if b - a == 9:
                v = 0
                for j in range(a, b):
                    d = buf[j] - 48
                    if d < 0 or d > 9:
                        v = -1
                        break
                    v = v * 10 + d
                key = v if v >= 0 else NO_KEY
        keys[n] = key
        n += 1
        pos = stops[n - 1]
    return n, pos


@numba.njit(nogil=True, cache=True)
def _scatter(buf, starts, stops, group, n_groups, first_line, out, lines_out):
    """The lines of one step sorted by group (stable): their bytes into ``out`` (each ending in
    a newline) and their input line numbers (``first_line`` + index) into ``lines_out``.
    Returns each group's (bytes, lines) end offsets."""
    n = len(starts)
    nbytes = np.zeros(n_groups + 1, np.int64)
    nlines = np.zeros(n_groups + 1, np.int64)
    for r in range(n):
        a, b = starts[r], stops[r]
        size = b - a
        if size == 0 or buf[b - 1] != 10:
            size += 1
        nbytes[group[r] + 1] += size
        nlines[group[r] + 1] += 1
    for g in range(n_groups):
        nbytes[g + 1] += nbytes[g]
        nlines[g + 1] += nlines[g]
    at_b = nbytes[:-1].copy()
    at_l = nlines[:-1].copy()
    for r in range(n):
        g = group[r]
        a, b = starts[r], stops[r]
        k = at_b[g]
        out[k:k + b - a] = buf[a:b]
        k += b - a
        if b == a or buf[b - 1] != 10:
            out[k] = 10
            k += 1
        at_b[g] = k
        lines_out[at_l[g]] = first_line + r
        at_l[g] += 1
    return nbytes, nlines


_MMSI = re.compile(MMSI_RE)


def quoted_key(text: bytes, col: int) -> int:
    """The MMSI key of a line with a double quote up to its MMSI field: its fields by the
    ingest's own splitter."""
    line = text.decode("utf-8", "replace").rstrip("\n")
    if line.endswith("\r"):
        line = line[:-1]
    fields = split_csv_line(line)
    if col < len(fields) and _MMSI.fullmatch(fields[col]):
        return int(fields[col])
    return NO_KEY


@numba.njit(nogil=True, cache=True)
def _step_end(buf, pos, want):
    """One past the last newline before ``want`` (a line boundary after ``pos``), else the end of
    the line holding ``want`` (a line longer than a step), else the end of the buffer."""
    size = len(buf)
    if want >= size:
        return size
    i = want
    while i > pos:
        if buf[i - 1] == 10:
            return i
        i -= 1
    i = want
    while i < size:
        if buf[i] == 10:
            return i + 1
        i += 1
    return size


def _step(buf: np.ndarray, pos: int, col: int) -> tuple:
    """(starts, stops, keys, next position) of the lines of one step from ``pos``."""
    end = _step_end(buf, pos, pos + _STEP_BYTES)
    cap = max(1024, int((end - pos) // 32))  # lines of at least 32 bytes; more: a second call
    starts, stops, keys = (np.empty(cap, np.int64) for _ in range(3))
    n, at = _line_keys(buf, pos, end, col, starts, stops, keys)
    if at < end:
        s2, e2, k2, at = _step(buf, at, col)  # pragma: no cover - only lines shorter than 32 bytes
        return np.r_[starts[:n], s2], np.r_[stops[:n], e2], np.r_[keys[:n], k2], at
    return starts[:n], stops[:n], keys[:n], at


def _steps(buf: np.ndarray, start: int, col: int, stride: int = 1, mm: mmap.mmap | None = None):
    """(starts, stops, keys) of the lines from ``start`` on, about :data:`_STEP_BYTES` at a time;
    with ``stride`` k, only every k-th step. The next step is scanned in a thread (the kernel
    releases the GIL) while the caller uses this one. ``mm`` (the map under ``buf``): the pages
    of each step are let go once it is used, so that the process's resident memory does not
    grow with the file (they stay in the page cache)."""
    from concurrent.futures import ThreadPoolExecutor

    size = len(buf)
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="stormlane-split") as pool:
        ahead = pool.submit(_step, buf, start, col) if start < size else None
        first = start
        while ahead is not None:
            starts, stops, k, pos = ahead.result()
            after = _step_end(buf, pos, pos + (stride - 1) * _STEP_BYTES) if stride > 1 and pos < size else pos
            ahead = pool.submit(_step, buf, after, col) if after < size else None
            for i in np.flatnonzero(k == QUOTED):
                k[i] = quoted_key(bytes(buf[starts[i]:stops[i]]), col)
            yield starts, stops, k
            if mm is not None and hasattr(mmap, "MADV_DONTNEED"):
                a, b = first - first % mmap.PAGESIZE, pos - pos % mmap.PAGESIZE
                if b > a:
                    mm.madvise(mmap.MADV_DONTNEED, a, b - a)
            first = after


def _header_stop(buf: np.ndarray) -> int:
    nl = np.flatnonzero(buf[:1 << 20] == 10)
    if len(nl):
        return int(nl[0]) + 1
    tail = np.flatnonzero(buf == 10)
    return int(tail[0]) + 1 if len(tail) else len(buf)


def mmsi_bounds(mmsi: np.ndarray, rows: np.ndarray, n_groups: int, no_key_rows: int = 0) -> np.ndarray:
    """Upper MMSI bounds (exclusive) of at most ``n_groups`` ranges with about equal rows, from
    the distinct MMSIs ``mmsi`` (sorted) and their ``rows``; the lines without a key (all in
    the first group) count towards it. A vessel is never split: fewer groups when one vessel
    holds more than a group's share."""
    total = int(rows.sum()) + int(no_key_rows)
    cum = np.cumsum(rows) + int(no_key_rows)
    bounds = []
    for g in range(1, n_groups):
        i = int(np.searchsorted(cum, total * g / n_groups, side="left")) + 1  # first vessel of group g
        if i < len(mmsi) and (not bounds or mmsi[i] > bounds[-1]):
            bounds.append(int(mmsi[i]))
    return np.asarray(bounds, dtype=np.int64)


def group_of(keys: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """The group of each key: its MMSI range of :func:`mmsi_bounds`, the first for no key (< 0)."""
    return np.where(keys < 0, 0, np.searchsorted(bounds, keys, side="right")).astype(np.int64)


def by_group(keys: np.ndarray, bounds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(order, cuts): the rows of ``keys`` ordered by group (:func:`group_of`), each group's in
    their input order, group ``g`` being ``order[cuts[g]:cuts[g + 1]]``."""
    group = group_of(keys, bounds)
    order = np.argsort(group, kind="stable")
    return order, np.searchsorted(group[order], np.arange(len(bounds) + 2))


def _add_counts(mmsi: np.ndarray, rows: np.ndarray, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct-MMSI row counts with ``keys`` added (memory grows with vessels, not rows)."""
    u, c = np.unique(keys, return_counts=True)
    both = np.concatenate([mmsi, u])
    m, inv = np.unique(both, return_inverse=True)
    n = np.zeros(len(m), dtype=np.int64)
    np.add.at(n, inv, np.concatenate([rows, c]))
    return m, n


@dataclass(frozen=True)
class Group:
    """One group's file (CSV, or Parquet: :mod:`ais.io.parquet_buckets`), the input's line
    numbers of its lines (``.npy``; a Parquet row's line is its 1-based row number) and its lines."""

    path: Path
    lines: Path
    n_lines: int

    def line_numbers(self) -> np.ndarray:
        return np.load(self.lines)


def split_by_mmsi(path, mmsi_col: int, n_groups: int, folder) -> list[Group]:
    """Split the CSV file ``path`` (header on line 1; ``mmsi_col`` the 0-based MMSI column) into
    at most ``n_groups`` files of whole vessels in ``folder`` (module docstring), in MMSI order.
    Two passes over a memory map: the rows of each MMSI, then the split."""
    folder = Path(folder)
    with open(path, "rb") as fh:
        size = fh.seek(0, 2)
        if size == 0:
            raise ValueError(f"{path}: empty file")
        mm = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
    try:
        buf = np.frombuffer(mm, dtype=np.uint8)
        head = _header_stop(buf)
        mmsi, rows = np.empty(0, np.int64), np.empty(0, np.int64)
        no_key = 0
        for _, _, k in _steps(buf, head, mmsi_col, stride=_SAMPLE_STRIDE, mm=mm):
            ok = k >= 0
            mmsi, rows = _add_counts(mmsi, rows, k[ok])
            no_key += int(len(k) - ok.sum())
        bounds = mmsi_bounds(mmsi, rows, max(1, int(n_groups)), no_key)
        return _write_groups(buf, mm, head, mmsi_col, bounds, folder)
    finally:
        del buf
        try:
            mm.close()
        except BufferError:  # a finished step generator not yet collected still views it
            pass  # closed when collected


def _write_groups(buf: np.ndarray, mm: mmap.mmap, head: int, col: int, bounds: np.ndarray, folder: Path) -> list[Group]:
    header = bytes(buf[:head]) if buf[head - 1] == 10 else bytes(buf[:head]) + b"\n"
    n = len(bounds) + 1
    names = [folder / f"group-{g:04d}.csv" for g in range(n)]
    line_files = [folder / f"group-{g:04d}.lines.i64" for g in range(n)]
    counts = np.ones(n, dtype=np.int64)  # the header
    outs = [open(p, "wb") for p in names]
    louts = [open(p, "wb") for p in line_files]
    try:
        for o, lo in zip(outs, louts):
            o.write(header)
            np.asarray([1], dtype=np.int64).tofile(lo)
        line = 2
        for starts, stops, keys in _steps(buf, head, col, mm=mm):
            group = group_of(keys, bounds)
            out = np.empty(int(stops[-1] - starts[0]) + len(starts), dtype=np.uint8)
            lines = np.empty(len(starts), dtype=np.int64)
            nbytes, nlines = _scatter(buf, starts, stops, group, n, line, out, lines)
            for g in range(n):
                if nlines[g + 1] > nlines[g]:
                    outs[g].write(memoryview(out[nbytes[g]:nbytes[g + 1]]))
                    lines[nlines[g]:nlines[g + 1]].tofile(louts[g])
                    counts[g] += nlines[g + 1] - nlines[g]
            line += len(starts)
    finally:
        for f in (*outs, *louts):
            f.close()
    groups = []
    for g in range(n):
        npy = line_files[g].with_suffix(".npy")
        np.save(npy, np.fromfile(line_files[g], dtype=np.int64))
        line_files[g].unlink()
        groups.append(Group(names[g], npy, int(counts[g])))
    return groups
