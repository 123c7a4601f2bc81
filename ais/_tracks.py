"""Rules 7 (repeated keys) and 8 (speed jumps) of a first load, in one streaming pass.

Both rules look at each MMSI's fixes in (time, line) order. AIS files are written in time
order, so each track's fixes usually already come in that order in the file. Rather than
sorting ~5 M fixes by track (the numpy version: factorize, sort, five gathers, ~0.45 s, plus
~0.4 s to fetch the fixes from DuckDB), :func:`first_load_rules` reads the fixes in file order
where they lie (the scanner's arrays) and keeps a few values per track:

* the time of the track's last fix: a fix with the same time repeats its key (rule 7, the
  first fix of the run is the reference); an earlier one means the track went back in time:
  such a track (rare) is set aside and handled by the sorting path (:func:`sorted_fixes`, then
  :func:`ais.clean.speed_jump_mask`);
* the state of step 1 of the jump rule, the walk of :mod:`ais._jumps` (last kept fix, the
  one before it, pending outliers): the very code :func:`ais.clean.speed_jump_mask` runs
  track after track, here fed with the tracks interleaved. Its outliers are quarantined at
  once; its cuts give the segments.

Only the tracks with a cut go through step 2, the greedy choice among segments
(:func:`ais.clean.rejected_segments`), which needs each segment's length and end fixes. So
the result is by construction that of sorting every track and calling
:func:`ais.clean.speed_jump_mask` (a test compares both on shuffled and jumpy tracks).

The fixes come from two sources merged by line number on the fly: the scanner's canonical rows
(``ok`` marks those that passed rules 1-6) and the few lines typed from their text.
"""

from __future__ import annotations

import numba
import numpy as np

from ais._jumps import (_F_A, _S_A_FIXED, _S_NPEND, _S_STARTED, FEED_ROOM, MAX_OUTLIER_RUN, _append, broken, feed,
                          flush, walk_outputs, walk_state)
from ais.clean import SENTINEL_TOL, rejected_from_walk, speed_jump_mask

_EMPTY = np.int64(-(1 << 62))
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


# Bookkeeping per track besides the walk (ais._jumps): a fix seen?, the time of the last
# fix and the first line of its key (rule 7), the track went back in time, is left out, or
# starts with a stored fix.
_SEEN, _LAST_T, _LAST_LINE, _BACK, _SKIP, _CTX = range(6)


@numba.njit(nogil=True, cache=True)
def _stream_run(line_a, mmsi_a, t_a, lat_a, lon_a, ok_a, line_b, mmsi_b, t_b, lat_b, lon_b, lon_tol, vmax_kn,
                max_run, pos, keys, vals, st, si, sf, dup, spikes, cuts, cutf, cnt, rq_f, rq_i):
    """The pass of :func:`_stream` from ``pos`` = [ia, ib, tracks, dups] until the end or
    until a table is full (then ``pos`` tells where it stopped; the caller grows the tables and
    calls again). No array is reassigned in here: that kept the loop ~2 x faster."""
    ia, ib, n_tracks, n_dup = pos[0], pos[1], pos[2], pos[3]
    na, nb = len(ok_a), len(line_b)
    while True:
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
            if 2 * (n_tracks + 1) > len(keys) or n_tracks == len(st):
                break
            keys[slot] = mm
            vals[slot] = n_tracks
            n_tracks += 1
        c = vals[slot]
        if n_dup == len(dup) or cnt[0] + FEED_ROOM > len(spikes) or cnt[1] + FEED_ROOM > len(cuts):
            break
        if from_b:
            ib += 1
        else:
            ia += 1
        if st[c, _BACK] or st[c, _SKIP]:
            continue
        if abs(lo - 180.0) <= lon_tol:
            lo = -180.0
        if st[c, _SEEN]:
            if tt < st[c, _LAST_T]:
                st[c, _BACK] = 1
                continue
            if tt == st[c, _LAST_T]:
                dup[n_dup, 0], dup[n_dup, 1], dup[n_dup, 2] = li, st[c, _LAST_LINE], c
                n_dup += 1
                continue
        st[c, _SEEN], st[c, _LAST_T], st[c, _LAST_LINE] = 1, tt, li
        ts = _seconds(tt)
        if si[c, _S_STARTED] and si[c, _S_NPEND] == 0 and si[c, _S_A_FIXED] == 0 and \
                not broken(sf[c, _F_A], sf[c, _F_A + 1], sf[c, _F_A + 2], ts, la, lo, vmax_kn):
            _append(si, sf, c, ts, la, lo, li, 0, cuts, cutf, cnt)  # the common case
        else:
            feed(si, sf, c, ts, la, lo, li, 0, vmax_kn, max_run, spikes, cuts, cutf, cnt, rq_f, rq_i)
    pos[0], pos[1], pos[2], pos[3] = ia, ib, n_tracks, n_dup
    return ia >= na and ib >= nb


@numba.njit(nogil=True, cache=True)
def _seed(keys, vals, st, si, sf, mmsi, t_us, lat, lon, skip, vmax_kn, max_run, spikes, cuts, cutf, cnt, rq_f, rq_i):
    """Tracks known before the stream (codes 0..k-1): skipped ones, or ones whose first fix is
    a stored fix (context, line -1: stored, never flagged)."""
    for c in range(len(mmsi)):
        s = _slot(keys, mmsi[c])
        keys[s] = mmsi[c]
        vals[s] = c
        if skip[c]:
            st[c, _SKIP] = 1
            continue
        st[c, _SEEN], st[c, _LAST_T], st[c, _LAST_LINE], st[c, _CTX] = 1, t_us[c], -1, 1
        feed(si, sf, c, _seconds(t_us[c]), lat[c], lon[c], -1, 1, vmax_kn, max_run, spikes, cuts, cutf, cnt, rq_f,
             rq_i)


@numba.njit(nogil=True, cache=True)
def _flush_all(si, st, sf, c0, vmax_kn, max_run, spikes, cuts, cutf, cnt, rq_f, rq_i):
    """End of the stream: :func:`ais._jumps.flush` on every track from ``c0``; returns the
    track it stopped at when an output is nearly full (else the number of tracks)."""
    for c in range(c0, len(si)):
        if cnt[0] + FEED_ROOM > len(spikes) or cnt[1] + FEED_ROOM > len(cuts):
            return c
        if not (st[c, _BACK] or st[c, _SKIP]):
            flush(si, sf, c, vmax_kn, max_run, spikes, cuts, cutf, cnt, rq_f, rq_i)
    return len(si)


def _stream(*data, vmax_kn: float, context: dict | None = None):
    """One pass over the fixes (the ``ok`` rows of a and every row of b, merged by line): rule
    7 and step 1 of the jump rule (the walk of :mod:`ais._jumps`) per track. ``context``:
    :func:`first_load_rules`'s. Returns the track table, the bookkeeping and walk states, the
    repeated keys (line, first line of the key, track), the outliers (line, track), the cuts."""
    k = 0 if context is None else len(context["mmsi"])
    size = 4096
    while size < 2 * (k + 1):
        size *= 2
    keys = np.full(size, _EMPTY, dtype=np.int64)
    vals = np.empty(size, dtype=np.int32)
    n0 = max(2048, k + 1)
    st = np.zeros((n0, 6), dtype=np.int64)
    si, sf = walk_state(n0)
    spikes, cuts, cutf, cnt, rq_f, rq_i = walk_outputs(4096)
    pos = np.zeros(4, dtype=np.int64)
    walk = (float(vmax_kn), MAX_OUTLIER_RUN)
    if k:
        _seed(keys, vals, st, si, sf, *(np.ascontiguousarray(context[n], dtype=dt) for n, dt in
                                        (("mmsi", np.int64), ("t_us", np.int64), ("lat", np.float64),
                                         ("lon", np.float64), ("skip", np.bool_))), *walk,
              spikes, cuts, cutf, cnt, rq_f, rq_i)
        pos[2] = k
    dup = np.empty((4096, 3), dtype=np.int64)

    def grow(spikes, cuts, cutf):
        if cnt[0] + FEED_ROOM > len(spikes):
            spikes = np.concatenate((spikes, np.empty_like(spikes)))
        if cnt[1] + FEED_ROOM > len(cuts):
            cuts, cutf = np.concatenate((cuts, np.empty_like(cuts))), np.concatenate((cutf, np.empty_like(cutf)))
        return spikes, cuts, cutf

    while not _stream_run(*data, *walk, pos, keys, vals, st, si, sf, dup, spikes, cuts, cutf, cnt, rq_f, rq_i):
        n_tracks, n_dup = pos[2], pos[3]
        if 2 * (n_tracks + 1) > len(keys):
            keys, vals = _grow(keys, vals)
        if n_tracks == len(st):
            st = np.concatenate((st, np.zeros_like(st)))
            si, sf = np.concatenate((si, np.zeros_like(si))), np.concatenate((sf, np.zeros_like(sf)))
        if n_dup == len(dup):
            dup = np.concatenate((dup, np.empty_like(dup)))
        spikes, cuts, cutf = grow(spikes, cuts, cutf)
    n_tracks, n_dup = pos[2], pos[3]
    st, si, sf = st[:n_tracks], si[:n_tracks], sf[:n_tracks]
    c = 0
    while c < n_tracks:
        c = _flush_all(si, st, sf, c, *walk, spikes, cuts, cutf, cnt, rq_f, rq_i)
        spikes, cuts, cutf = grow(spikes, cuts, cutf)
    return keys, vals, st, si, sf, dup[:n_dup], spikes[:cnt[0]], cuts[:cnt[1]], cutf[:cnt[1]]


@numba.njit(nogil=True, cache=True)
def _pass_two(keys, vals, back, skip, kept0, spike_lines, rej_ptr, rej_lo, rej_hi, line_a, mmsi_a, t_a, lat_a, lon_a,
              ok_a, line_b, mmsi_b, t_b, lat_b, lon_b, lon_tol):
    """The stream again, for the rare cases the first pass cannot settle alone: the lines of
    the fixes in rejected segments of more than two fixes (``rej_*``: per track, ranges of
    ordinals, which count the kept fixes - repeated keys and the outliers ``spike_lines``,
    sorted, left out), and the fixes of the tracks set aside (``back``; ``skip``: tracks left
    out). ``kept0``: fixes before the stream (1 for a track with a stored context fix)."""
    n_tracks = len(back)
    kept = kept0.copy()
    seen = kept0.copy()
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
        if seen[c] and tt == last_t[c]:
            continue  # a repeated key (already reported)
        seen[c] = 1
        last_t[c] = tt
        s = np.searchsorted(spike_lines, li)
        if s < len(spike_lines) and spike_lines[s] == li:
            continue  # an outlier (already reported)
        k = kept[c]
        for r in range(rej_ptr[c], rej_ptr[c + 1]):
            if rej_lo[r] <= k < rej_hi[r]:
                if n_jump == len(jump):
                    jump = np.concatenate((jump, np.empty_like(jump)))
                jump[n_jump] = li
                n_jump += 1
                break
        kept[c] = k + 1
    return jump[:n_jump], b_fix[:n_back]


def first_load_rules(scan: dict, exact: dict, max_speed_kn: float, context: dict | None = None) -> dict:
    """Rules 7 and 8 on a file's accepted fixes: ``dup`` (lines repeating the (MMSI, time) of
    an earlier fix), ``ref`` (the first line of each one's run) and ``jump`` (lines of
    :func:`ais.clean.speed_jump_mask`'s quarantined fixes), all as int64 arrays.

    ``scan``: ``line``, ``mmsi``, ``t_us``, ``lat``, ``lon`` and ``ok`` (passed rules 1-6) of
    the scanner's rows; ``exact``: the same keys but ``ok`` for the fixes typed from their text
    that passed rules 1-6. Each source in ascending line order.

    ``context`` (a workspace that already holds positions): per MMSI (``mmsi``, ``skip``,
    ``t_us``, ``lat``, ``lon``) either ``skip`` (its fixes are left out: the caller judges
    them) or the stored fix just before the MMSI's first fix in the file, when no stored fix is
    at or after that time: it opens the track as a stored fix (never flagged), as
    :func:`ais.clean.speed_jump_mask` treats stored context. A track with context that goes
    back in time in the file is left out too. ``fallback``: the MMSIs left out."""
    a = [np.ascontiguousarray(scan[k], dtype=dt) for k, dt in _KEYS]
    b = [np.ascontiguousarray(exact[k], dtype=dt) for k, dt in _KEYS]
    ok = np.ascontiguousarray(scan["ok"], dtype=np.bool_)
    data = (*a, ok, *b, float(SENTINEL_TOL))
    vmax = float(max_speed_kn)
    keys, vals, st, si, sf, dup, spikes, cuts, cutf = _stream(*data, vmax_kn=vmax, context=context)
    ctx = st[:, _CTX].astype(bool)
    back = st[:, _BACK].astype(bool)
    drop = st[:, _SKIP].astype(bool) | (back & ctx)
    aside = back & ~ctx
    done = ~(drop | aside)  # tracks settled by the stream
    dup = dup[done[dup[:, 2]]]
    spike_lines = np.sort(spikes[done[spikes[:, 1]], 0])
    keep = done[cuts[:, 0]]
    cuts, cutf = cuts[keep], cutf[keep]
    # Step 2 on each track with a cut: a rejected segment of one or two fixes is known by the
    # lines at its ends; longer ones need the second pass.
    jumps = spike_lines.tolist()
    long_rej: dict[int, list] = {}
    for c, lo, hi, head, tail, _ in rejected_from_walk(si, sf, cuts, cutf, vmax):
        if hi - lo <= 2:
            jumps += {head, tail}
        else:
            long_rej.setdefault(c, []).append((lo, hi))
    ref_out, dup_out = [dup[:, 1]], [dup[:, 0]]
    if long_rej or aside.any():
        rej_ptr = np.zeros(len(back) + 1, dtype=np.int64)
        for c, ranges in long_rej.items():
            rej_ptr[c + 1] = len(ranges)
        rej_ptr = np.cumsum(rej_ptr)
        flat = np.array([r for c in sorted(long_rej) for r in long_rej[c]], dtype=np.int64).reshape(-1, 2)
        more, b_fix = _pass_two(keys, vals, aside, drop, ctx.astype(np.int64), spike_lines, rej_ptr,
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
    ``GROUP BY mmsi, s_hash`` of :func:`pipelines.storage.ais.vessels._upsert_vessels`, ~5 x cheaper
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
