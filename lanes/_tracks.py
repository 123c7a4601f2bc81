"""Rules 7 (repeated keys) and 8 (speed jumps) of a first load, in one streaming pass.

Both rules look at each MMSI's fixes in (time, line) order. AIS files are written in time
order, so each track's fixes usually already come in that order in the file. Rather than
sorting ~5 M fixes by track (the numpy version: factorize, sort, five gathers, ~0.45 s, plus
~0.4 s to fetch the fixes from DuckDB), :func:`first_load_rules` reads the fixes in file order
where they lie (the scanner's arrays) and keeps a few values per track:

* the track's last kept fix: a fix with the same time repeats its key (rule 7, the first fix of
  the run is the reference); a later one is tested for a link with it, the test of
  :func:`lanes.clean.speed_jump_mask` (the same compiled haversine, :mod:`lanes._jumps`), and a
  failed link cuts the track into a new segment;
* whether the track went back in time: such a track (rare) is set aside and handled by the
  sorting path (:func:`sorted_fixes`, then :func:`lanes.clean.speed_jump_mask`).

Only the tracks with a cut go through the greedy segment step
(:func:`lanes.clean.rejected_segments`), which needs each segment's length and end fixes. So
the result is by construction that of sorting every track and calling
:func:`lanes.clean.speed_jump_mask` (a test compares both on shuffled and jumpy tracks).

The haversine is skipped for the pairs that are linked for sure: with ``sin x <= x``,
``cos <= 1`` and ``asin s <= 1.002 s`` for ``s <= 0.1``, the distance is at most
``1.002 R sqrt(dlat^2 + dlon^2)`` (radians); when that bound, with a 1e-6 margin for rounding,
is within the allowed distance, the exact formula cannot find a break.

The fixes come from two sources merged by line number on the fly: the scanner's canonical rows
(``ok`` marks those that passed rules 1-6) and the few lines typed from their text.
"""

from __future__ import annotations

import numba
import numpy as np

from lanes._jumps import _dist_nmi, linked
from lanes.clean import SENTINEL_TOL, rejected_segments, speed_jump_mask
from thresholds.units import EARTH_RADIUS_NMI

_EMPTY = np.int64(-(1 << 62))
_RAD = np.pi / 180.0
_KEYS = (("line", np.int64), ("mmsi", np.int64), ("t_us", np.int64), ("lat", np.float64), ("lon", np.float64))


@numba.njit(nogil=True, cache=True)
def _slot(keys, key):
    """Slot of ``key`` in the open-addressing table ``keys`` (its own or the empty one)."""
    mask = len(keys) - 1
    h = (np.uint64(key) * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(40)
    i = np.int64(h) & mask
    while keys[i] != key and keys[i] != _EMPTY:
        i = (i + 1) & mask
    return i


@numba.njit(nogil=True, cache=True)
def _grow(keys, vals):
    new_keys = np.full(len(keys) * 2, _EMPTY, dtype=np.int64)
    new_vals = np.empty(len(keys) * 2, dtype=np.int32)
    for i in range(len(keys)):
        if keys[i] != _EMPTY:
            j = _slot(new_keys, keys[i])
            new_keys[j] = keys[i]
            new_vals[j] = vals[i]
    return new_keys, new_vals


@numba.njit(nogil=True, cache=True)
def _code(keys, vals, n_tracks, mm):
    """(keys, vals, n_tracks, code): the track code of MMSI ``mm``, numbered by first appearance
    in an open-addressing table grown at half load."""
    s = _slot(keys, mm)
    if keys[s] == _EMPTY:
        if 2 * (n_tracks + 1) > len(keys):
            keys, vals = _grow(keys, vals)
            s = _slot(keys, mm)
        keys[s] = mm
        vals[s] = n_tracks
        n_tracks += 1
    return keys, vals, n_tracks, vals[s]


@numba.njit(nogil=True, cache=True, inline="always")
def _seconds(t_us):
    # Seconds as the pure path computes them (nanoseconds / 1e9), so float ties agree.
    return np.float64(t_us * 1000) / 1e9


@numba.njit(nogil=True, cache=True, inline="always")
def _broken(t1, lat1, lon1, t2, lat2, lon2, vmax_kn):
    """The break test of :func:`lanes._jumps._breaks` for one pair, the bound first."""
    allowed = vmax_kn * (t2 - t1) / 3600.0
    dphi = (lat2 - lat1) * _RAD
    dlam = (lon2 - lon1) * _RAD
    q = dphi * dphi + dlam * dlam
    if q <= 0.04 and 1.002 * EARTH_RADIUS_NMI * np.sqrt(q) * (1.0 + 1e-6) <= allowed:
        return False
    return _dist_nmi(lat1, lon1, lat2, lon2) > allowed


# Per-track state of the stream: integer and float columns.
_KEPT, _LAST_T, _LAST_LINE, _FIRST_LINE, _BACK, _SKIP, _CTX = range(7)
_LTS, _LLAT, _LLON, _FTS, _FLAT, _FLON = range(6)


@numba.njit(nogil=True, cache=True)
def _stream_run(line_a, mmsi_a, t_a, lat_a, lon_a, ok_a, line_b, mmsi_b, t_b, lat_b, lon_b, lon_tol, vmax_kn,
                pos, keys, vals, st_i, st_f, dup, cut, cut_fix):
    """The pass of :func:`_stream` from ``pos`` = [ia, ib, tracks, dups, cuts] until the end or
    until a table is full (then ``pos`` tells where it stopped; the caller grows the tables and
    calls again). No array is reassigned in here: that kept the loop ~2 x faster."""
    ia, ib, n_tracks, n_dup, n_cut = pos[0], pos[1], pos[2], pos[3], pos[4]
    na, nb = len(ok_a), len(line_b)
    full = False
    while not full:
        while ia < na and not ok_a[ia]:
            ia += 1
        from_b = ib < nb and (ia >= na or line_b[ib] < line_a[ia])
        if from_b:
            li, mm, tt, la, lo = line_b[ib], mmsi_b[ib], t_b[ib], lat_b[ib], lon_b[ib]
        elif ia < na:
            li, mm, tt, la, lo = line_a[ia], mmsi_a[ia], t_a[ia], lat_a[ia], lon_a[ia]
        else:
            break
        slot = _slot(keys, mm)
        if keys[slot] == _EMPTY:
            if 2 * (n_tracks + 1) > len(keys) or n_tracks == len(st_i):
                break
            keys[slot] = mm
            vals[slot] = n_tracks
            n_tracks += 1
        c = vals[slot]
        if n_dup == len(dup) or n_cut == len(cut):
            break
        if from_b:
            ib += 1
        else:
            ia += 1
        if st_i[c, _BACK] or st_i[c, _SKIP]:
            continue
        if abs(lo - 180.0) <= lon_tol:
            lo = -180.0
        k = st_i[c, _KEPT]
        ts = _seconds(tt)
        if k > 0:
            if tt < st_i[c, _LAST_T]:
                st_i[c, _BACK] = 1
                continue
            if tt == st_i[c, _LAST_T]:
                dup[n_dup, 0], dup[n_dup, 1], dup[n_dup, 2] = li, st_i[c, _LAST_LINE], c
                n_dup += 1
                continue
            if _broken(st_f[c, _LTS], st_f[c, _LLAT], st_f[c, _LLON], ts, la, lo, vmax_kn):
                cut[n_cut, 0], cut[n_cut, 1], cut[n_cut, 2], cut[n_cut, 3] = c, k, st_i[c, _LAST_LINE], li
                cut_fix[n_cut, 0], cut_fix[n_cut, 1], cut_fix[n_cut, 2] = st_f[c, _LTS], st_f[c, _LLAT], st_f[c, _LLON]
                cut_fix[n_cut, 3], cut_fix[n_cut, 4], cut_fix[n_cut, 5] = ts, la, lo
                n_cut += 1
        else:
            st_i[c, _FIRST_LINE] = li
            st_f[c, _FTS], st_f[c, _FLAT], st_f[c, _FLON] = ts, la, lo
        st_i[c, _KEPT] = k + 1
        st_i[c, _LAST_T] = tt
        st_i[c, _LAST_LINE] = li
        st_f[c, _LTS], st_f[c, _LLAT], st_f[c, _LLON] = ts, la, lo
    pos[0], pos[1], pos[2], pos[3], pos[4] = ia, ib, n_tracks, n_dup, n_cut
    return ia >= na and ib >= nb


@numba.njit(nogil=True, cache=True)
def _seed(keys, vals, st_i, st_f, mmsi, t_us, lat, lon, skip):
    """Tracks known before the stream (codes 0..k-1): skipped ones, or ones whose first fix is
    a stored fix (context, line -1: its segment is pinned, it is never flagged)."""
    for c in range(len(mmsi)):
        s = _slot(keys, mmsi[c])
        keys[s] = mmsi[c]
        vals[s] = c
        if skip[c]:
            st_i[c, _SKIP] = 1
            continue
        ts = _seconds(t_us[c])
        st_i[c, _KEPT], st_i[c, _LAST_T], st_i[c, _LAST_LINE], st_i[c, _FIRST_LINE], st_i[c, _CTX] = \
            1, t_us[c], -1, -1, 1
        st_f[c, _LTS], st_f[c, _LLAT], st_f[c, _LLON] = ts, lat[c], lon[c]
        st_f[c, _FTS], st_f[c, _FLAT], st_f[c, _FLON] = ts, lat[c], lon[c]


def _stream(*data, context: dict | None = None):
    """One pass over the fixes (the ``ok`` rows of a and every row of b, merged by line):
    per track its state (``st_i``, ``st_f``), the repeated keys and the cuts. ``context``:
    :func:`first_load_rules`'s."""
    k = 0 if context is None else len(context["mmsi"])
    size = 4096
    while size < 2 * (k + 1):
        size *= 2
    keys = np.full(size, _EMPTY, dtype=np.int64)
    vals = np.empty(size, dtype=np.int32)
    st_i, st_f = np.zeros((max(2048, k + 1), 7), dtype=np.int64), np.zeros((max(2048, k + 1), 6))
    pos = np.zeros(5, dtype=np.int64)
    if k:
        _seed(keys, vals, st_i, st_f, *(np.ascontiguousarray(context[n], dtype=dt) for n, dt in
                                        (("mmsi", np.int64), ("t_us", np.int64), ("lat", np.float64),
                                         ("lon", np.float64), ("skip", np.bool_))))
        pos[2] = k
    dup, cut, cut_fix = np.empty((4096, 3), dtype=np.int64), np.empty((4096, 4), dtype=np.int64), np.empty((4096, 6))
    while not _stream_run(*data, pos, keys, vals, st_i, st_f, dup, cut, cut_fix):
        n_tracks, n_dup, n_cut = pos[2], pos[3], pos[4]
        if 2 * (n_tracks + 1) > len(keys):
            keys, vals = _grow(keys, vals)
        if n_tracks == len(st_i):
            st_i = np.concatenate((st_i, np.zeros_like(st_i)))
            st_f = np.concatenate((st_f, np.zeros_like(st_f)))
        if n_dup == len(dup):
            dup = np.concatenate((dup, np.empty_like(dup)))
        if n_cut == len(cut):
            cut, cut_fix = np.concatenate((cut, np.empty_like(cut))), np.concatenate((cut_fix, np.empty_like(cut_fix)))
    n_tracks, n_dup, n_cut = pos[2], pos[3], pos[4]
    return keys, vals, st_i[:n_tracks], st_f[:n_tracks], dup[:n_dup], cut[:n_cut], cut_fix[:n_cut]


@numba.njit(nogil=True, cache=True)
def _pass_two(keys, vals, back, skip, kept0, rej_ptr, rej_lo, rej_hi, line_a, mmsi_a, t_a, lat_a, lon_a, ok_a, line_b,
              mmsi_b, t_b, lat_b, lon_b, lon_tol):
    """The stream again, for the rare cases the first pass cannot settle alone: the lines of
    the fixes in rejected segments of more than two fixes (``rej_*``: per track, ordinal
    ranges), and the fixes of the tracks set aside (``back``; ``skip``: tracks left out).
    ``kept0``: fixes before the stream (1 for a track with a stored context fix)."""
    n_tracks = len(back)
    kept = kept0.copy()
    last_t = np.zeros(n_tracks, dtype=np.int64)
    jump = np.empty(1024, dtype=np.int64)
    n_jump = 0
    b_fix = np.empty((1024, 5), dtype=np.int64)  # line, track, t_us, lat and lon bits
    n_back = 0
    ia, ib = 0, 0
    na, nb = len(ok_a), len(line_b)
    while True:
        while ia < na and not ok_a[ia]:
            ia += 1
        if ib < nb and (ia >= na or line_b[ib] < line_a[ia]):
            li, mm, tt, la, lo = line_b[ib], mmsi_b[ib], t_b[ib], lat_b[ib], lon_b[ib]
            ib += 1
        elif ia < na:
            li, mm, tt, la, lo = line_a[ia], mmsi_a[ia], t_a[ia], lat_a[ia], lon_a[ia]
            ia += 1
        else:
            break
        c = vals[_slot(keys, mm)]
        if skip[c]:
            continue
        if back[c]:
            if abs(lo - 180.0) <= lon_tol:
                lo = -180.0
            if n_back == len(b_fix):
                b_fix = np.concatenate((b_fix, np.empty_like(b_fix)))
            b_fix[n_back, 0], b_fix[n_back, 1], b_fix[n_back, 2] = li, c, tt
            b_fix[n_back, 3] = np.array([la]).view(np.int64)[0]
            b_fix[n_back, 4] = np.array([lo]).view(np.int64)[0]
            n_back += 1
            continue
        if rej_ptr[c + 1] == rej_ptr[c]:
            continue
        k = kept[c]
        if k > 0 and tt == last_t[c]:
            continue  # a repeated key (already reported)
        for r in range(rej_ptr[c], rej_ptr[c + 1]):
            if rej_lo[r] <= k < rej_hi[r]:
                if n_jump == len(jump):
                    jump = np.concatenate((jump, np.empty_like(jump)))
                jump[n_jump] = li
                n_jump += 1
                break
        kept[c] = k + 1
        last_t[c] = tt
    return jump[:n_jump], b_fix[:n_back]


def first_load_rules(scan: dict, exact: dict, max_speed_kn: float, context: dict | None = None) -> dict:
    """Rules 7 and 8 on a file's accepted fixes: ``dup`` (lines repeating the (MMSI, time) of
    an earlier fix), ``ref`` (the first line of each one's run) and ``jump`` (lines of
    :func:`lanes.clean.speed_jump_mask`'s quarantined fixes), all as int64 arrays.

    ``scan``: ``line``, ``mmsi``, ``t_us``, ``lat``, ``lon`` and ``ok`` (passed rules 1-6) of
    the scanner's rows; ``exact``: the same keys but ``ok`` for the fixes typed from their text
    that passed rules 1-6. Each source in ascending line order.

    ``context`` (a workspace that already holds positions): per MMSI (``mmsi``, ``skip``,
    ``t_us``, ``lat``, ``lon``) either ``skip`` (its fixes are left out: the caller judges
    them) or the stored fix just before the MMSI's first fix in the file, when no stored fix is
    at or after that time: it opens the track as a fixed fix (its segment pinned, never
    flagged), as :func:`lanes.clean.speed_jump_mask` treats stored context. A track with context
    that goes back in time in the file is left out too. ``fallback``: the MMSIs left out."""
    a = [np.ascontiguousarray(scan[k], dtype=dt) for k, dt in _KEYS]
    b = [np.ascontiguousarray(exact[k], dtype=dt) for k, dt in _KEYS]
    ok = np.ascontiguousarray(scan["ok"], dtype=np.bool_)
    data = (*a, ok, *b, float(SENTINEL_TOL))
    vmax = float(max_speed_kn)
    keys, vals, st_i, st_f, dup, cut, cut_fix = _stream(*data, vmax, context=context)
    ctx = st_i[:, _CTX].astype(bool)
    back = st_i[:, _BACK].astype(bool)
    drop = st_i[:, _SKIP].astype(bool) | (back & ctx)
    aside = back & ~ctx
    done = ~(drop | aside)  # tracks settled by the stream
    dup = dup[done[dup[:, 2]]]
    keep = done[cut[:, 0]]
    cut, cut_fix = cut[keep], cut_fix[keep]
    # The greedy segment step on each track with a cut (cuts come in stream order, so in
    # ordinal order within a track). A rejected segment of one or two fixes is known by the
    # lines at its ends; longer ones need the second pass.
    jumps = []
    long_rej: dict[int, list] = {}
    order = np.argsort(cut[:, 0], kind="stable")
    cut, cut_fix = cut[order], cut_fix[order]
    bounds = np.flatnonzero(np.r_[True, cut[1:, 0] != cut[:-1, 0], True]) if len(cut) else []
    for s, e in zip(bounds[:-1], bounds[1:]):
        c = int(cut[s, 0])
        opens = [0] + cut[s:e, 1].tolist() + [int(st_i[c, _KEPT])]
        heads = [st_f[c, _FTS:]] + [cut_fix[i, 3:] for i in range(s, e)]  # first fix of each segment
        tails = [cut_fix[i, :3] for i in range(s, e)] + [st_f[c, _LTS:_FTS]]  # last fix of each segment
        head_line = [int(st_i[c, _FIRST_LINE])] + cut[s:e, 3].tolist()
        tail_line = cut[s:e, 2].tolist() + [int(st_i[c, _LAST_LINE])]
        lengths = [opens[q + 1] - opens[q] for q in range(len(opens) - 1)]
        pinned = [bool(ctx[c])] + [False] * (len(lengths) - 1)  # the stored fix opens segment 0
        for q in rejected_segments(lengths, pinned,
                                   lambda p, q, tails=tails, heads=heads: bool(linked(*tails[p], *heads[q], vmax))):
            if lengths[q] <= 2:
                jumps += {head_line[q], tail_line[q]}
            else:
                long_rej.setdefault(c, []).append((opens[q], opens[q + 1]))
    ref_out, dup_out = [dup[:, 1]], [dup[:, 0]]
    if long_rej or aside.any():
        rej_ptr = np.zeros(len(back) + 1, dtype=np.int64)
        for c, ranges in long_rej.items():
            rej_ptr[c + 1] = len(ranges)
        rej_ptr = np.cumsum(rej_ptr)
        flat = np.array([r for c in sorted(long_rej) for r in long_rej[c]], dtype=np.int64).reshape(-1, 2)
        more, b_fix = _pass_two(keys, vals, aside, drop, ctx.astype(np.int64), rej_ptr,
                                np.ascontiguousarray(flat[:, 0]), np.ascontiguousarray(flat[:, 1]), *data)
        jumps += more.tolist()
        if len(b_fix):
            s = sorted_fixes({"line": b_fix[:, 0], "mmsi": b_fix[:, 1], "t_us": b_fix[:, 2],
                              "lat": b_fix[:, 3].view(np.float64), "lon": b_fix[:, 4].view(np.float64),
                              "ok": np.ones(len(b_fix), dtype=bool)},
                             {k: np.empty(0, dtype=dt) for k, dt in _KEYS})
            mask = speed_jump_mask(s["track"], (s["t_us"] * 1000) / 1e9, s["lat"], s["lon"], vmax)
            jumps += s["line"][mask].tolist()
            dup_out.append(s["dup"])
            ref_out.append(s["ref"])
    mmsi_of = np.empty(len(back), dtype=np.int64)
    used = keys != _EMPTY
    mmsi_of[vals[used]] = keys[used]
    return {"dup": np.concatenate(dup_out), "ref": np.concatenate(ref_out), "jump": np.array(jumps, dtype=np.int64),
            "fallback": mmsi_of[drop]}


@numba.njit(nogil=True, cache=True)
def _sorted_fixes(line_a, mmsi_a, t_a, lat_a, lon_a, ok_a, line_b, mmsi_b, t_b, lat_b, lon_b, lon_tol):
    na, nb = len(ok_a), len(line_b)
    n = nb
    for i in range(na):
        if ok_a[i]:
            n += 1
    keys = np.full(1024, _EMPTY, dtype=np.int64)
    vals = np.empty(1024, dtype=np.int32)
    n_tracks = 0
    code = np.empty(n, dtype=np.int32)
    m_line = np.empty(n, dtype=np.int64)
    m_t = np.empty(n, dtype=np.int64)
    m_lat = np.empty(n)
    m_lon = np.empty(n)
    ia, ib = 0, 0
    for m in range(n):
        while ia < na and not ok_a[ia]:
            ia += 1
        if ib < nb and (ia >= na or line_b[ib] < line_a[ia]):
            li, mm, tt, la, lo = line_b[ib], mmsi_b[ib], t_b[ib], lat_b[ib], lon_b[ib]
            ib += 1
        else:
            li, mm, tt, la, lo = line_a[ia], mmsi_a[ia], t_a[ia], lat_a[ia], lon_a[ia]
            ia += 1
        if abs(lo - 180.0) <= lon_tol:
            lo = -180.0
        keys, vals, n_tracks, code[m] = _code(keys, vals, n_tracks, mm)
        m_line[m], m_t[m], m_lat[m], m_lon[m] = li, tt, la, lo
    start = np.zeros(n_tracks + 1, dtype=np.int64)
    for m in range(n):
        start[code[m] + 1] += 1
    for c in range(n_tracks):
        start[c + 1] += start[c]
    # a counting sort by track: stable, so each track keeps file (line) order
    pos = start[:n_tracks].copy()
    line = np.empty(n, dtype=np.int64)
    t_us = np.empty(n, dtype=np.int64)
    lat = np.empty(n, dtype=np.float64)
    lon = np.empty(n, dtype=np.float64)
    for m in range(n):
        d = pos[code[m]]
        pos[code[m]] = d + 1
        line[d], t_us[d], lat[d], lon[d] = m_line[m], m_t[m], m_lat[m], m_lon[m]
    # per track: time order (a stable sort when needed: then by line), repeated keys, packing
    track = np.empty(n, dtype=np.int32)
    dup_line = np.empty(n, dtype=np.int64)
    ref_line = np.empty(n, dtype=np.int64)
    n_dup = 0
    k = 0
    for c in range(n_tracks):
        a, b = start[c], start[c + 1]
        ordered = True
        for i in range(a + 1, b):
            if t_us[i] < t_us[i - 1]:
                ordered = False
                break
        if not ordered:
            o = np.argsort(t_us[a:b], kind="mergesort") + a
            line[a:b] = line[o]
            t_us[a:b] = t_us[o]
            lat[a:b] = lat[o]
            lon[a:b] = lon[o]
        first_line = -1
        for i in range(a, b):
            # (packing writes only at k <= i: t_us[i - 1] is still the sorted value)
            if i > a and t_us[i] == t_us[i - 1]:
                dup_line[n_dup] = line[i]
                ref_line[n_dup] = first_line
                n_dup += 1
                continue
            first_line = line[i]
            line[k], t_us[k], lat[k], lon[k] = line[i], t_us[i], lat[i], lon[i]
            track[k] = c
            k += 1
    return line[:k], track[:k], t_us[:k], lat[:k], lon[:k], dup_line[:n_dup], ref_line[:n_dup]


def sorted_fixes(scan: dict, exact: dict) -> dict:
    """The accepted fixes sorted by (track, time, line), repeated keys taken out (the sorting
    path, for tracks that go back in time; also the reference the streaming path is tested
    against). Same inputs as :func:`first_load_rules`. Returns ``line``, ``track`` (codes by
    first appearance), ``t_us``, ``lat``, ``lon`` of the kept fixes, and ``dup`` / ``ref``."""
    out = _sorted_fixes(*(np.ascontiguousarray(scan[k], dtype=dt) for k, dt in _KEYS),
                        np.ascontiguousarray(scan["ok"], dtype=np.bool_),
                        *(np.ascontiguousarray(exact[k], dtype=dt) for k, dt in _KEYS), float(SENTINEL_TOL))
    return dict(zip(("line", "track", "t_us", "lat", "lon", "dup", "ref"), out))


@numba.njit(nogil=True, cache=True)
def _latest_run(mmsi, shash, t_us, line, lo, hi, keys_m, keys_h, used, best_t, best_line, t_max, pos):
    """:func:`latest_by_static` from row ``pos[0]`` until the end or until the table is half
    full (then the caller grows it and calls again)."""
    mask = len(keys_m) - 1
    n_groups = pos[1]
    i = pos[0]
    while i < len(mmsi):
        m = mmsi[i]
        if m < lo or m > hi:
            i += 1
            continue
        h = shash[i]
        s = np.int64(((np.uint64(m) * np.uint64(0x9E3779B97F4A7C15)) ^ h) >> np.uint64(33)) & mask
        while used[s] and (keys_m[s] != m or keys_h[s] != h):
            s = (s + 1) & mask
        if not used[s]:
            if 2 * (n_groups + 1) > len(keys_m):
                break
            used[s] = True
            keys_m[s], keys_h[s] = m, h
            best_t[s], best_line[s], t_max[s] = t_us[i], line[i], t_us[i]
            n_groups += 1
        else:
            t = t_us[i]
            if t > best_t[s] or (t == best_t[s] and line[i] > best_line[s]):
                best_t[s], best_line[s] = t, line[i]
            if t > t_max[s]:
                t_max[s] = t
        i += 1
    pos[0], pos[1] = i, n_groups
    return i >= len(mmsi)


def latest_by_static(mmsi, shash, t_us, line, mmsi_min: int, mmsi_max: int) -> dict:
    """Per (MMSI, static hash) group of rows with an MMSI in ``[mmsi_min, mmsi_max]``: the
    latest row by (time, line) (``t_us``, ``line``) and the latest time (``t_max``), as arrays
    with ``mmsi`` and ``shash``: what the vessels merge needs from a file's rows (the
    ``GROUP BY mmsi, s_hash`` of :func:`pipelines.storage.ais._upsert_vessels`, ~5 x cheaper
    on a 5 M row scan). Every row must have a time."""
    args = [np.ascontiguousarray(x, dtype=dt) for x, dt in
            ((mmsi, np.int64), (shash, np.uint64), (t_us, np.int64), (line, np.int64))]
    cap = 1 << 14
    pos = np.zeros(2, dtype=np.int64)
    while True:
        table = (np.zeros(cap, np.int64), np.zeros(cap, np.uint64), np.zeros(cap, np.bool_), np.zeros(cap, np.int64),
                 np.zeros(cap, np.int64), np.zeros(cap, np.int64))
        pos[:] = 0  # a full table starts over at twice the size (rare: > cap / 2 groups)
        if _latest_run(*args, int(mmsi_min), int(mmsi_max), *table, pos):
            break
        cap *= 4
    used = table[2]
    return {"mmsi": table[0][used], "shash": table[1][used], "t_us": table[3][used], "line": table[4][used],
            "t_max": table[5][used]}
