"""One-pass scanner of large DMA/NOAA CSV files: line offsets and the *canonical* rows typed.

The bulk CSV ingest needs, for every physical line, where it starts and ends, and for every
record its typed position fields. This module does both in one compiled pass over a memory map
(numba, no GIL: the file is cut into one range per core). It types a row only when every used
field is written in a *canonical* form, for which the typing is provably the one of the SQL and
pandas rules of :mod:`ais.io.csv_formats`; every other line is reported as *special* and the
caller types it from its text with the exact rules. Canonical forms:

* the line holds no double quote, no ``\\r`` (one trailing ``\\r`` is removed) and exactly the
  header's number of fields (split on commas);
* MMSI: ASCII digits only (nine digits: the number; any other count, or empty: missing);
* time: the spec's format with every field zero-padded (DMA ``dd/mm/yyyy HH:MM:SS``, NOAA
  ``yyyy-mm-ddTHH:MM:SS`` or with a space), a valid calendar date, hour < 24, minute < 60,
  second < 60 and a year in 1700-2200 (inside pandas' nanosecond range);
* numbers (lat, lon, SOG, COG, heading, numeric status): empty (missing), or ``-?D+(.D+)?``
  with at most 15 digits and not a negative zero. Such a decimal ``M / 10^k`` has ``M < 2^53``
  and ``k <= 15``: both are exact doubles and one IEEE division is correctly rounded, which is
  what DuckDB's ``CAST(x AS DOUBLE)`` and Python's ``float`` return (Clinger's fast path [1]);
* navigational status: a number as above, or ASCII text equal, once lower-cased, to one of
  :data:`ais.io.csv_formats.NAV_STATUS_WORDS`.

Static fields are not typed here: a 64-bit hash of their bytes groups the rows by static tuple
(the texts are re-split from the line when the vessels table is merged).

References
----------
.. [1] W. D. Clinger, "How to read floating point numbers accurately," in Proc. ACM SIGPLAN
       PLDI, 1990, pp. 92-101, doi: 10.1145/93542.93557.
.. [2] H. Hinnant, "chrono-Compatible Low-Level Date Algorithms," 2013,
       https://howardhinnant.github.io/date_algorithms.html (``days_from_civil``: the proleptic
       Gregorian day count used for the epoch).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

#: Roles of a column in the scan.
ROLE_NONE, ROLE_MMSI, ROLE_TIME, ROLE_NUM, ROLE_NAV, ROLE_STATIC = 0, 1, 2, 3, 4, 5
#: Line kinds reported by the scan.
KIND_ROW, KIND_SPECIAL, KIND_BLANK = 0, 1, 2
#: Time layouts understood canonically (strptime formats tried in order -> code).
TIME_LAYOUTS = {("%d/%m/%Y %H:%M:%S",): 1, ("%Y-%m-%dT%H:%M:%S",): 2, ("%Y-%m-%d %H:%M:%S",): 3,
                ("%Y-%m-%dT%H:%M:%S", "%Y-%m-%d %H:%M:%S"): 4, ("%Y-%m-%d %H:%M:%S", "%Y-%m-%dT%H:%M:%S"): 4}
NULL_TIME = np.iinfo(np.int64).min

#: Exact powers of ten (10**k is a double exactly for k <= 22).
_POW10 = np.array([10.0 ** k for k in range(23)])


@numba.njit(nogil=True, cache=True, inline="always")
def parse_num(buf, a, b):
    """(state, value): state 0 = number, 1 = empty, 2 = not canonical."""
    if a == b:
        return 1, np.nan
    i = a
    neg = False
    if buf[i] == 45:
        neg = True
        i += 1
    m = 0
    nd = 0
    k = 0
    dot = False
    before = 0
    while i < b:
        c = buf[i]
        if 48 <= c <= 57:
            nd += 1
            if nd > 15:
                return 2, np.nan
            m = m * 10 + (c - 48)
            if dot:
                k += 1
            else:
                before += 1
        elif c == 46 and not dot:
            dot = True
        else:
            return 2, np.nan
        i += 1
    if before == 0 or (dot and k == 0) or (neg and m == 0):
        return 2, np.nan
    v = m / _POW10[k]
    return 0, (-v if neg else v)

@numba.njit(nogil=True, cache=True, inline="always")
def two(buf, i):
    c0 = buf[i]
    c1 = buf[i + 1]
    if c0 < 48 or c0 > 57 or c1 < 48 or c1 > 57:
        return -1
    return (c0 - 48) * 10 + (c1 - 48)

@numba.njit(nogil=True, cache=True, inline="always")
def parse_time(buf, a, b, layout):
    """Microseconds since the epoch, or NULL_TIME when not canonical."""
    if b - a != 19:
        return NULL_TIME
    if layout == 1:  # dd/mm/yyyy HH:MM:SS
        if buf[a + 2] != 47 or buf[a + 5] != 47 or buf[a + 10] != 32:
            return NULL_TIME
        d = two(buf, a)
        mo = two(buf, a + 3)
        y1 = two(buf, a + 6)
        y2 = two(buf, a + 8)
        h0 = a + 11
    else:  # yyyy-mm-ddTHH:MM:SS (or a space)
        if buf[a + 4] != 45 or buf[a + 7] != 45:
            return NULL_TIME
        sep = buf[a + 10]
        if not ((layout != 3 and sep == 84) or (layout != 2 and sep == 32)):
            return NULL_TIME
        y1 = two(buf, a)
        y2 = two(buf, a + 2)
        mo = two(buf, a + 5)
        d = two(buf, a + 8)
        h0 = a + 11
    if buf[h0 + 2] != 58 or buf[h0 + 5] != 58:
        return NULL_TIME
    hh = two(buf, h0)
    mi = two(buf, h0 + 3)
    ss = two(buf, h0 + 6)
    if d < 0 or mo < 0 or y1 < 0 or y2 < 0 or hh < 0 or mi < 0 or ss < 0:
        return NULL_TIME
    y = y1 * 100 + y2
    if y < 1700 or y > 2200 or mo < 1 or mo > 12 or d < 1 or hh > 23 or mi > 59 or ss > 59:
        return NULL_TIME
    leap = (y % 4 == 0 and y % 100 != 0) or y % 400 == 0
    dim = 31
    if mo == 2:
        dim = 29 if leap else 28
    elif mo == 4 or mo == 6 or mo == 9 or mo == 11:
        dim = 30
    if d > dim:
        return NULL_TIME
    # days from civil (proleptic Gregorian), Hinnant's algorithm
    yy = y - 1 if mo <= 2 else y
    era = yy // 400
    yoe = yy - era * 400
    mp = mo - 3 if mo > 2 else mo + 9
    doy = (153 * mp + 2) // 5 + d - 1
    doe = yoe * 365 + yoe // 4 - yoe // 100 + doy
    days = era * 146097 + doe - 719468
    return ((days * 24 + hh) * 60 + mi) * 60000000 + ss * 1000000

@numba.njit(nogil=True, cache=True, inline="always")
def nav_word(buf, a, b, words, woff, wcode):
    n = b - a
    for w in range(len(wcode)):
        if woff[w + 1] - woff[w] != n:
            continue
        ok = True
        for j in range(n):
            c = buf[a + j]
            if 65 <= c <= 90:
                c += 32
            if c != words[woff[w] + j]:
                ok = False
                break
        if ok:
            return wcode[w]
    return -1.0

_CLS = np.zeros(256, dtype=np.uint8)
_CLS[44], _CLS[10], _CLS[34], _CLS[13] = 1, 2, 3, 4  # comma, newline, quote, carriage return


@numba.njit(nogil=True, cache=True)
def scan(buf, pos, end, n_fields, roles, slots, layout, words, woff, wcode,
         starts, ends, kind, line, mmsi, t_us, vals, shash):
    """Scan lines from ``pos`` (a line start) until ``end`` or until the outputs are full, in
    one pass over the bytes. Per line: ``starts``, ``ends``, ``kind``; per row (a line of kind
    :data:`KIND_ROW`, packed): ``line`` (0-based line index of this call), ``mmsi``, ``t_us``,
    ``vals``, ``shash``. Each row's values are written to the next free row slot while its line
    is parsed; a line found special leaves the slot to the next one. Returns (lines written,
    rows written, position reached)."""
    # Long by design: the per-range driver of the compiled scan (ranges, threads, packing the
    # outputs in place); its steps share the preallocated output arrays.
    cap = len(starts)
    nvals = vals.shape[0]
    prime = np.uint64(1099511628211)
    n = 0
    nr = 0
    while pos < end and n < cap:
        mm = np.int64(-1)
        tt = NULL_TIME
        h = np.uint64(14695981039346656037)
        special = False
        for v in range(nvals):
            vals[v, nr] = np.nan
        f = 0
        fs = pos
        last_cr = -2
        n_cr = 0
        i = pos
        while True:
            while i < end and _CLS[buf[i]] == 0:
                i += 1
            k = _CLS[buf[i]] if i < end else 2
            if k == 3:
                special = True
                i += 1
                continue
            if k == 4:
                n_cr += 1
                last_cr = i
                i += 1
                continue
            # a comma or the end of the line: field f is fs:fe
            fe = i
            if k == 2 and n_cr > 0:
                if last_cr == i - 1:  # the line's one trailing \r is not part of it
                    fe = i - 1
                if n_cr > 1 or last_cr != i - 1:
                    special = True
            if f >= n_fields:
                special = True
            elif not special:
                r = roles[f]
                if r == 5:
                    for j in range(fs, fe):
                        h = (h ^ np.uint64(buf[j])) * prime
                    h = (h ^ np.uint64(256 + f)) * prime
                elif r == 3 or r == 4:
                    state, x = parse_num(buf, fs, fe)
                    if state == 2:
                        if r == 4:
                            x = nav_word(buf, fs, fe, words, woff, wcode)
                            if x < 0:
                                special = True
                        else:
                            special = True
                    vals[slots[f], nr] = x
                elif r == 2:
                    tt = parse_time(buf, fs, fe, layout)
                    if tt == NULL_TIME:
                        special = True
                elif r == 1:
                    if fe - fs == 9:
                        m = np.int64(0)
                        for j in range(fs, fe):
                            c = buf[j]
                            if c < 48 or c > 57:
                                special = True
                            m = m * 10 + (c - 48)
                        mm = m
                    else:
                        for j in range(fs, fe):
                            if buf[j] < 48 or buf[j] > 57:
                                special = True
            f += 1
            fs = i + 1
            if k == 2:
                break
            i += 1
        le = fe
        starts[n] = pos
        ends[n] = le
        if le == pos:
            kind[n] = 2
        elif special or f != n_fields:
            kind[n] = 1
        else:
            kind[n] = 0
            line[nr] = n
            mmsi[nr] = mm
            t_us[nr] = tt
            shash[nr] = h
            nr += 1
        n += 1
        pos = i + 1
    return n, nr, pos


@numba.njit(nogil=True, cache=True)
def _move(a, src, dst, n):
    """``a[dst:dst + n] = a[src:src + n]``, front to back (``dst <= src``: no temporary)."""
    for i in range(n):
        a[dst + i] = a[src + i]



def _compile():
    return scan


class ScanResult:
    """What :func:`scan_csv` found: per physical line ``starts``, ``ends``, ``kind``; per line
    of kind :data:`KIND_ROW` (a *row*, in file order) its 1-based ``line`` number and typed
    values (``mmsi`` -1 = missing, ``t_us`` NULL_TIME = missing, ``vals`` NaN = missing, one
    row per name in ``fields``, ``shash``)."""

    def __init__(self, starts, ends, kind, line, mmsi, t_us, vals, shash, fields, stray_cr, quote_lines):
        self.starts, self.ends, self.kind = starts, ends, kind
        self.line, self.mmsi, self.t_us, self.vals, self.shash = line, mmsi, t_us, vals, shash
        self.fields, self.stray_cr, self.quote_lines = fields, stray_cr, quote_lines

    @property
    def n_lines(self) -> int:
        return len(self.starts)


def _anonymous(shape, dtype) -> np.ndarray:
    """An uninitialised array in its own anonymous memory map, without numpy's transparent huge
    page advice. Measured on the 5 M-row DMA file, whole ingests in fresh processes: 3.25-3.28 s
    against 3.66-3.81 s with ``np.empty`` (its ``MADV_HUGEPAGE`` makes the kernel compact
    memory for 2 MiB pages on first touch while the scan waits); a process's later ingests are
    ~0.25 s slower (4 KiB page faults), still well within the target."""
    import mmap

    count = int(np.prod(shape))
    if not hasattr(mmap, "MAP_ANONYMOUS"):  # not a POSIX system: numpy's own allocation
        return np.empty(shape, dtype=dtype)
    mem = mmap.mmap(-1, max(count * np.dtype(dtype).itemsize, 1), flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)
    return np.frombuffer(mem, dtype=dtype, count=count).reshape(shape)


def _outputs(cap: int, nv: int) -> tuple:
    """Empty outputs of :func:`scan` for ``cap`` lines (and rows)."""
    e = _anonymous
    return (e(cap, np.int64), e(cap, np.int64), e(cap, np.uint8), e(cap, np.int64),
            e(cap, np.int64), e(cap, np.int64), e((nv, cap), np.float64), e(cap, np.uint64))


_PER_LINE = 3  # the first three outputs are per line, the others per row


def scan_csv(buf: np.ndarray, index: dict[str, int], n_fields: int, time_formats: tuple, nav_words: dict,
             static_fields=(), n_threads: int = 2, chunk_lines: int = 1 << 26) -> ScanResult | None:
    """Scan ``buf`` (the bytes of a whole file, e.g. a memory map; line 1 is the header and is
    scanned like any line, callers ignore it). ``index``: stage field -> 0-based column;
    ``static_fields`` are hashed; ``time_formats`` the spec's strptime formats, tried in order
    (a string matches at most one of the known layouts, so the order does not matter). None
    when the time formats have no canonical layout. ``chunk_lines``: the most lines per region
    (tests make it small).

    Memory: every range writes into its own region of one allocation sized from the lines per
    byte of the file's first 64 KiB; the regions are then moved together in place. (Fresh
    memory is expensive on this class of machine: the former per-range arrays joined by a
    concatenation, and the rows picked out of every line by a gather, touched ~3 x the bytes.)
    A range with more lines than its region continues in arrays of its own, joined at the end.
    """
    # Long by design: a numba kernel, one pass over the bytes of a range as a state machine
    # (field, number, time states); split into functions, every byte would cross a call.
    layout = TIME_LAYOUTS.get(tuple(time_formats))
    if layout is None:
        return None
    scan = _compile()
    num_fields = [f for f in ("lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "nav_status") if f in index]
    roles = np.zeros(max(n_fields, 1), dtype=np.int64)
    slots = np.zeros(max(n_fields, 1), dtype=np.int64)
    for name, col in index.items():
        if col >= n_fields:
            continue
        if name == "mmsi":
            roles[col] = ROLE_MMSI
        elif name == "time_utc":
            roles[col] = ROLE_TIME
        elif name in num_fields:
            roles[col] = ROLE_NAV if name == "nav_status" else ROLE_NUM
            slots[col] = num_fields.index(name)
        elif name in static_fields:
            roles[col] = ROLE_STATIC
    wb = [w.encode("ascii") for w in nav_words if w.isascii()]
    words = np.frombuffer(b"".join(wb) or b"\0", dtype=np.uint8)
    woff = np.zeros(len(wb) + 1, dtype=np.int64)
    woff[1:] = np.cumsum([len(w) for w in wb])
    wcode = np.array([float(nav_words[w.decode()]) for w in wb], dtype=np.float64)
    size = len(buf)
    # Cut points at line starts, one range per thread.
    cuts = [0]
    for k in range(1, n_threads):
        p = size * k // n_threads
        q = int(np.argmax(buf[p:p + (1 << 20)] == 10)) if p < size else 0
        if p >= size or buf[p + q] != 10:
            continue  # no newline near: fewer ranges
        if p + q + 1 > cuts[-1]:
            cuts.append(p + q + 1)
    cuts.append(size)
    nv = max(len(num_fields), 1)

    sample = buf[:1 << 16]
    per_line = max(1.0, len(sample) / max(1, int(np.count_nonzero(sample == 10))))

    def room(a, b):
        # room for the lines expected in a..b (one region for most files)
        return int(min(max((b - a) / per_line * 1.02 + 1024, 1024), b - a + 1, chunk_lines))

    ranges = [(cuts[i], cuts[i + 1]) for i in range(len(cuts) - 1) if cuts[i + 1] > cuts[i]]
    caps = [room(a, b) for a, b in ranges]
    offs = np.r_[0, np.cumsum(caps)].astype(np.int64)
    big = _outputs(int(offs[-1]), nv)

    def region(k):
        a, b = int(offs[k]), int(offs[k + 1])
        return tuple(x[..., a:b] for x in big)

    def run(k):
        """[(outputs, lines, rows), ...] of range k: its region, then arrays of its own."""
        a, b = ranges[k]
        parts = []
        pos = a
        out = region(k)
        while pos < b:
            n, r, pos = scan(buf, pos, b, n_fields, roles, slots, layout, words, woff, wcode, *out)
            parts.append((out, n, r))
            out = _outputs(room(pos, b), nv)
        return parts

    if len(ranges) > 1:
        with ThreadPoolExecutor(max_workers=len(ranges)) as pool:
            results = list(pool.map(run, range(len(ranges))))
    else:
        results = [run(k) for k in range(len(ranges))]
    parts = [p for res in results for p in res]
    # 1-based line numbers of the rows (each call numbered its lines from 0)
    before = 0
    for out, n, r in parts:
        out[_PER_LINE][:r] += before + 1
        before += n
    if all(len(res) <= 1 for res in results):
        # move the regions together: views of the one allocation
        n_at, r_at = 0, 0
        for k, res in enumerate(results):
            for out, n, r in res:
                src = int(offs[k])
                if src != n_at or src != r_at:
                    for j, x in enumerate(big):
                        d = n_at if j < _PER_LINE else r_at
                        m = n if j < _PER_LINE else r
                        for row in (x if x.ndim == 2 else (x,)):
                            _move(row, src, d, m)
                n_at, r_at = n_at + n, r_at + r
        cat = [x[..., :(n_at if j < _PER_LINE else r_at)] for j, x in enumerate(big)]
    else:
        cat = [np.concatenate([out[j][..., :(n if j < _PER_LINE else r)] for out, n, r in parts], axis=-1)
               for j in range(len(big))]
    del big
    starts, ends, kind = cat[0], cat[1], cat[2]
    # Lines with a quote or a \r were marked special; which of them hold a quote / a stray \r
    # (the line index's flags) is found on those few lines only.
    spec = np.flatnonzero(kind == KIND_SPECIAL)
    mv = memoryview(buf) if not isinstance(buf, np.ndarray) else buf
    quote, stray = [], False
    for k in spec.tolist():
        b = bytes(mv[starts[k]:ends[k]])
        if b'"' in b:
            quote.append(k + 1)
        if b"\r" in b:
            stray = True
    if size and buf[size - 1] == 13:
        stray = True
    return ScanResult(starts, ends, kind, cat[3], cat[4], cat[5], cat[6], cat[7], num_fields, stray,
                      np.asarray(quote, dtype=np.int64))
