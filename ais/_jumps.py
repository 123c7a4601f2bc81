"""Compiled link test of the speed-jump rule (:func:`ais.clean.speed_jump_mask`).

Two consecutive fixes of one track are *linked* when the great-circle distance between them
(haversine [1], the formula of :func:`thresholds.geodesy.haversine_nmi`) is at most the highest
plausible speed times the time between them. On a 5 M-fix file the numpy version spent ~0.3 s
in temporaries of the haversine alone; this kernel fuses it per pair, releases the GIL and
runs one range of pairs per core. The link tests of single pairs use the same compiled
formula, so a pair is judged the same way wherever it is tested.

References
----------
.. [1] R. W. Sinnott, "Virtues of the Haversine," Sky and Telescope, vol. 68, no. 2, p. 159,
       1984.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from thresholds.units import EARTH_RADIUS_NMI

_RAD = np.pi / 180.0
#: Below this many pairs one thread is cheaper than starting two.
_MIN_PAIRS_PER_THREAD = 200_000


@numba.njit(nogil=True, cache=True, inline="always")
def _dist_nmi(lat1, lon1, lat2, lon2):
    p1, p2 = lat1 * _RAD, lat2 * _RAD
    a = np.sin((p2 - p1) / 2.0) ** 2 + np.cos(p1) * np.cos(p2) * np.sin((lon2 * _RAD - lon1 * _RAD) / 2.0) ** 2
    a = min(max(a, 0.0), 1.0)
    return 2.0 * EARTH_RADIUS_NMI * np.arcsin(np.sqrt(a))


@numba.njit(nogil=True, cache=True)
def _breaks(same, t_s, lat, lon, vmax_kn, a, b, out):
    """``out[i]`` for pairs ``a <= i < b``: fix i and i + 1 are of one track and not linked."""
    for i in range(a, b):
        out[i] = same[i] and (
            _dist_nmi(lat[i], lon[i], lat[i + 1], lon[i + 1]) > vmax_kn * (t_s[i + 1] - t_s[i]) / 3600.0)


@numba.njit(nogil=True, cache=True)
def linked(t1_s, lat1, lon1, t2_s, lat2, lon2, vmax_kn):
    """Whether two fixes are linked (distance <= ``vmax_kn`` x the time between them)."""
    return _dist_nmi(lat1, lon1, lat2, lon2) <= vmax_kn * abs(t2_s - t1_s) / 3600.0


def link_breaks(same_track, t_s, lat_deg, lon_deg, max_speed_kn: float, n_threads: int = 2) -> np.ndarray:
    """Bool array of the ``n - 1`` consecutive pairs of fixes sorted by (track, time): True
    where fix i and fix i + 1 are of the same track (``same_track[i]``) but not linked."""
    same = np.ascontiguousarray(same_track, dtype=np.bool_)
    t, lat, lon = (np.ascontiguousarray(x, dtype=np.float64) for x in (t_s, lat_deg, lon_deg))
    n_pairs = len(same)
    out = np.zeros(n_pairs, dtype=np.bool_)
    k = max(1, min(n_threads, n_pairs // _MIN_PAIRS_PER_THREAD))
    cuts = [n_pairs * j // k for j in range(k + 1)]
    if k == 1:
        _breaks(same, t, lat, lon, float(max_speed_kn), 0, n_pairs, out)
    else:
        with ThreadPoolExecutor(max_workers=k) as pool:
            list(pool.map(lambda j: _breaks(same, t, lat, lon, float(max_speed_kn), cuts[j], cuts[j + 1], out),
                          range(k)))
    return out


# ---------------------------------------------------------------------------------------------
# Step 1 of the speed-jump rule: one walk along a track that removes outliers and cuts the rest
# into segments (step 2, the greedy choice among segments, is ais.clean.rejected_segments).
# One compiled state machine, fed one fix at a time, so that the sorted path
# (ais.clean.speed_jump_mask: one track after the other) and the streaming path
# (ais._tracks.first_load_rules: the tracks interleaved in file order) run the same code.
# ---------------------------------------------------------------------------------------------
#: The longest run of consecutive fixes taken as one outlier burst when the fix after it is
#: linked to the fix before it.
MAX_OUTLIER_RUN = 3

# Integer state per track: walk started, kept fixes so far (ordinal of the next kept fix), the
# last kept fix ``a`` (line, stored?), the fix before it in its segment ``pa`` (known?, line),
# pending fixes, the track's first fix (line, stored?); then the pending fixes' lines.
_S_STARTED, _S_K, _S_A_LINE, _S_A_FIXED, _S_PA_OK, _S_PA_LINE, _S_NPEND, _S_FIRST_LINE, _S_FIRST_FIXED = range(9)
_S_PEND = 9
# Float state per track: (t, lat, lon) of ``a``, ``pa``, the first fix, then of each pending fix.
_F_A, _F_PA, _F_FIRST, _F_PEND = 0, 3, 6, 9
#: Free room the outputs need before one feed or flush (bounds the events of one call for
#: runs of up to MAX_OUTLIER_RUN fixes).
FEED_ROOM = 64


def walk_state(n_tracks: int, max_run: int = MAX_OUTLIER_RUN) -> tuple[np.ndarray, np.ndarray]:
    """Empty per-track state arrays of :func:`feed` for ``n_tracks`` tracks."""
    return (np.zeros((n_tracks, _S_PEND + max_run), dtype=np.int64),
            np.zeros((n_tracks, _F_PEND + 3 * max_run), dtype=np.float64))


def walk_outputs(cap: int = 4096) -> tuple:
    """Empty outputs of :func:`feed`: spikes (line, track), cuts (track, ordinal of the cut,
    tail line, head line, head stored?), the cuts' tail and head fixes (t, lat, lon each), the
    counters (spikes, cuts) and two scratch arrays."""
    return (np.empty((cap, 2), dtype=np.int64), np.empty((cap, 5), dtype=np.int64), np.empty((cap, 6)),
            np.zeros(2, dtype=np.int64), np.empty((64, 3)), np.empty((64, 2), dtype=np.int64))


@numba.njit(nogil=True, cache=True, inline="always")
def broken(t1_s, lat1, lon1, t2_s, lat2, lon2, vmax_kn):
    """Not linked (``t2_s >= t1_s``). The haversine is skipped when a bound already shows the
    pair linked: with ``sin x <= x``, ``cos <= 1`` and ``asin s <= 1.002 s`` for ``s <= 0.1``
    the distance is at most ``1.002 R sqrt(dlat^2 + dlon^2)`` (radians); with a 1e-6 margin for
    rounding, the exact formula cannot find a break when that bound is within reach."""
    allowed = vmax_kn * (t2_s - t1_s) / 3600.0
    dphi = (lat2 - lat1) * _RAD
    dlam = (lon2 - lon1) * _RAD
    q = dphi * dphi + dlam * dlam
    if q <= 0.04 and 1.002 * EARTH_RADIUS_NMI * np.sqrt(q) * (1.0 + 1e-6) <= allowed:
        return False
    return _dist_nmi(lat1, lon1, lat2, lon2) > allowed


@numba.njit(nogil=True, cache=True, inline="always")
def _set_a(si, sf, c, t, la, lo, li, fx):
    sf[c, _F_A], sf[c, _F_A + 1], sf[c, _F_A + 2] = t, la, lo
    si[c, _S_A_LINE], si[c, _S_A_FIXED] = li, fx


@numba.njit(nogil=True, cache=True)
def _cut(si, sf, c, t, la, lo, li, fx, cuts, cutf, cnt):
    """Fix (t, la, lo, li, fx) opens a new segment after the last kept fix."""
    n = cnt[1]
    cuts[n, 0], cuts[n, 1], cuts[n, 2], cuts[n, 3], cuts[n, 4] = c, si[c, _S_K], si[c, _S_A_LINE], li, fx
    cutf[n, 0], cutf[n, 1], cutf[n, 2] = sf[c, _F_A], sf[c, _F_A + 1], sf[c, _F_A + 2]
    cutf[n, 3], cutf[n, 4], cutf[n, 5] = t, la, lo
    cnt[1] = n + 1
    _set_a(si, sf, c, t, la, lo, li, fx)
    si[c, _S_PA_OK] = 0
    si[c, _S_K] += 1


@numba.njit(nogil=True, cache=True)
def _append(si, sf, c, t, la, lo, li, fx, cuts, cutf, cnt):
    """A fix linked to the last kept one: it continues the segment, unless it is stored and the
    segment new or the other way round (a segment never mixes the two)."""
    if fx != si[c, _S_A_FIXED]:
        _cut(si, sf, c, t, la, lo, li, fx, cuts, cutf, cnt)
        return
    sf[c, _F_PA], sf[c, _F_PA + 1], sf[c, _F_PA + 2] = sf[c, _F_A], sf[c, _F_A + 1], sf[c, _F_A + 2]
    si[c, _S_PA_LINE], si[c, _S_PA_OK] = si[c, _S_A_LINE], 1
    _set_a(si, sf, c, t, la, lo, li, fx)
    si[c, _S_K] += 1


@numba.njit(nogil=True, cache=True)
def _cut_at_pending(si, sf, c, cuts, cutf, cnt, rq_f, rq_i):
    """The pending fixes never came back within reach of the last kept fix: the first opens a
    new segment, the others go to ``rq_*`` (rows 0..m-1) to be fed again; returns m."""
    m = 0
    for j in range(1, si[c, _S_NPEND]):
        p = _F_PEND + 3 * j
        rq_f[m, 0], rq_f[m, 1], rq_f[m, 2] = sf[c, p], sf[c, p + 1], sf[c, p + 2]
        rq_i[m, 0], rq_i[m, 1] = si[c, _S_PEND + j], 0
        m += 1
    si[c, _S_NPEND] = 0
    _cut(si, sf, c, sf[c, _F_PEND], sf[c, _F_PEND + 1], sf[c, _F_PEND + 2], si[c, _S_PEND], 0, cuts, cutf, cnt)
    return m


@numba.njit(nogil=True, cache=True)
def _step(si, sf, c, t, la, lo, li, fx, vmax_kn, max_run, spikes, cuts, cutf, cnt, rq_f, rq_i):
    """One fix of track ``c`` through the walk. Returns how many fixes it put in ``rq_*`` to be
    fed again, in order, before any other fix of the track (0 nearly always)."""
    if si[c, _S_STARTED] == 0:
        si[c, _S_STARTED], si[c, _S_FIRST_LINE], si[c, _S_FIRST_FIXED] = 1, li, fx
        sf[c, _F_FIRST], sf[c, _F_FIRST + 1], sf[c, _F_FIRST + 2] = t, la, lo
        _set_a(si, sf, c, t, la, lo, li, fx)
        si[c, _S_PA_OK] = 0
        si[c, _S_K] = 1
        return 0
    at, ala, alo = sf[c, _F_A], sf[c, _F_A + 1], sf[c, _F_A + 2]
    n_pend = si[c, _S_NPEND]
    if n_pend > 0:
        if not broken(at, ala, alo, t, la, lo, vmax_kn):
            # back within reach of the last kept fix: the pending run was an outlier burst
            for j in range(n_pend):
                spikes[cnt[0], 0], spikes[cnt[0], 1] = si[c, _S_PEND + j], c
                cnt[0] += 1
            si[c, _S_NPEND] = 0
            _append(si, sf, c, t, la, lo, li, fx, cuts, cutf, cnt)
            return 0
        if fx == 0 and n_pend < max_run:
            si[c, _S_PEND + n_pend] = li
            p = _F_PEND + 3 * n_pend
            sf[c, p], sf[c, p + 1], sf[c, p + 2] = t, la, lo
            si[c, _S_NPEND] = n_pend + 1
            return 0
        # never back within reach: a real cut before the first pending fix; the others and
        # this one are fed again after it
        m = _cut_at_pending(si, sf, c, cuts, cutf, cnt, rq_f, rq_i)
        rq_f[m, 0], rq_f[m, 1], rq_f[m, 2] = t, la, lo
        rq_i[m, 0], rq_i[m, 1] = li, fx
        return m + 1
    if not broken(at, ala, alo, t, la, lo, vmax_kn):
        _append(si, sf, c, t, la, lo, li, fx, cuts, cutf, cnt)
        return 0
    if si[c, _S_A_FIXED] == 0 and si[c, _S_PA_OK] == 1 and \
            not broken(sf[c, _F_PA], sf[c, _F_PA + 1], sf[c, _F_PA + 2], t, la, lo, vmax_kn):
        # the last kept fix was a lone outlier: the one before it reaches this one
        spikes[cnt[0], 0], spikes[cnt[0], 1] = si[c, _S_A_LINE], c
        cnt[0] += 1
        si[c, _S_K] -= 1
        _set_a(si, sf, c, sf[c, _F_PA], sf[c, _F_PA + 1], sf[c, _F_PA + 2], si[c, _S_PA_LINE], 0)
        si[c, _S_PA_OK] = 0
        _append(si, sf, c, t, la, lo, li, fx, cuts, cutf, cnt)
        return 0
    if fx == 0 and max_run > 0:
        si[c, _S_PEND] = li
        sf[c, _F_PEND], sf[c, _F_PEND + 1], sf[c, _F_PEND + 2] = t, la, lo
        si[c, _S_NPEND] = 1
        return 0
    _cut(si, sf, c, t, la, lo, li, fx, cuts, cutf, cnt)
    return 0


@numba.njit(nogil=True, cache=True)
def _drain(si, sf, c, m, vmax_kn, max_run, spikes, cuts, cutf, cnt, rq_f, rq_i):
    """Feed the ``m`` fixes of ``rq_*`` (rows 0..m-1) in order; fixes a step gives back go in
    front of the rest. ``rq_*`` rows from 32 on are the work list."""
    w = 32
    for j in range(m):
        rq_f[w + j, 0], rq_f[w + j, 1], rq_f[w + j, 2] = rq_f[j, 0], rq_f[j, 1], rq_f[j, 2]
        rq_i[w + j, 0], rq_i[w + j, 1] = rq_i[j, 0], rq_i[j, 1]
    h, n = w, w + m
    while h < n:
        t, la, lo, li, fx = rq_f[h, 0], rq_f[h, 1], rq_f[h, 2], rq_i[h, 0], rq_i[h, 1]
        h += 1
        back = _step(si, sf, c, t, la, lo, li, fx, vmax_kn, max_run, spikes, cuts, cutf, cnt, rq_f, rq_i)
        if back:
            # new work list: the given-back fixes, then what was left
            rest = n - h
            for j in range(rest - 1, -1, -1):
                rq_f[w + back + j, 0], rq_f[w + back + j, 1], rq_f[w + back + j, 2] = \
                    rq_f[h + j, 0], rq_f[h + j, 1], rq_f[h + j, 2]
                rq_i[w + back + j, 0], rq_i[w + back + j, 1] = rq_i[h + j, 0], rq_i[h + j, 1]
            for j in range(back):
                rq_f[w + j, 0], rq_f[w + j, 1], rq_f[w + j, 2] = rq_f[j, 0], rq_f[j, 1], rq_f[j, 2]
                rq_i[w + j, 0], rq_i[w + j, 1] = rq_i[j, 0], rq_i[j, 1]
            h, n = w, w + back + rest


@numba.njit(nogil=True, cache=True)
def feed(si, sf, c, t, la, lo, li, fx, vmax_kn, max_run, spikes, cuts, cutf, cnt, rq_f, rq_i):
    """Feed one fix (time ``t`` [s], position, line ``li``, stored ``fx`` 0/1) of track ``c``
    to the walk; the outputs need :data:`FEED_ROOM` free rows."""
    m = _step(si, sf, c, t, la, lo, li, fx, vmax_kn, max_run, spikes, cuts, cutf, cnt, rq_f, rq_i)
    if m:
        _drain(si, sf, c, m, vmax_kn, max_run, spikes, cuts, cutf, cnt, rq_f, rq_i)


@numba.njit(nogil=True, cache=True)
def flush(si, sf, c, vmax_kn, max_run, spikes, cuts, cutf, cnt, rq_f, rq_i):
    """End of track ``c``: pending fixes that never came back within reach of the last kept
    fix open a segment (and are walked again after its first fix); repeated until none is
    pending. The outputs need :data:`FEED_ROOM` free rows."""
    while si[c, _S_NPEND] > 0:
        m = _cut_at_pending(si, sf, c, cuts, cutf, cnt, rq_f, rq_i)
        if m:
            _drain(si, sf, c, m, vmax_kn, max_run, spikes, cuts, cutf, cnt, rq_f, rq_i)


@numba.njit(nogil=True, cache=True)
def _walk_sorted(starts, ends, t, lat, lon, fixed, vmax_kn, max_run, si, sf, spikes, cuts, cutf, cnt, rq_f, rq_i):
    """Walk tracks ``k`` = fixes ``starts[k]:ends[k]`` (sorted by time) with line = fix index.
    Returns False when an output is nearly full (``cnt`` and the state tell where it stopped:
    the caller grows the outputs and calls again from the track it stopped in, afresh)."""
    for k in range(len(starts)):
        if si[k, _S_STARTED] == 2:
            continue  # done in an earlier call
        si[k, :] = 0
        c0 = cnt.copy()
        for i in range(starts[k], ends[k]):
            if cnt[0] + FEED_ROOM > len(spikes) or cnt[1] + FEED_ROOM > len(cuts):
                cnt[0], cnt[1] = c0[0], c0[1]  # this track again, after the caller grew the outputs
                return False
            feed(si, sf, k, t[i], lat[i], lon[i], i, 1 if fixed[i] else 0, vmax_kn, max_run, spikes, cuts, cutf,
                 cnt, rq_f, rq_i)
        if cnt[0] + FEED_ROOM > len(spikes) or cnt[1] + FEED_ROOM > len(cuts):
            cnt[0], cnt[1] = c0[0], c0[1]
            return False
        flush(si, sf, k, vmax_kn, max_run, spikes, cuts, cutf, cnt, rq_f, rq_i)
        si[k, _S_STARTED] = 2
    return True


def walk_sorted(starts, ends, t_s, lat_deg, lon_deg, fixed, max_speed_kn: float, max_run: int = MAX_OUTLIER_RUN):
    """Step 1 of the speed-jump rule on tracks given as index ranges of fixes sorted by time.
    Returns ``(si, sf, spikes, cuts, cutf)``: the final state per track (the track's first fix,
    last kept fix and number of kept fixes), the indices of the outliers, and one row per cut
    (track, kept fixes before it, index of the segment's last fix, index of the next
    segment's first fix, whether that fix is stored) with the two fixes' (t, lat, lon)."""
    if not 0 <= max_run <= 8:  # the scratch rows of _drain hold the runs of up to 8 fixes
        raise ValueError(f"max_run must be in 0..8, not {max_run}")
    starts = np.ascontiguousarray(starts, dtype=np.int64)
    ends = np.ascontiguousarray(ends, dtype=np.int64)
    args = [np.ascontiguousarray(x, dtype=np.float64) for x in (t_s, lat_deg, lon_deg)]
    fx = np.ascontiguousarray(fixed, dtype=np.bool_)
    si, sf = walk_state(len(starts), max_run)
    spikes, cuts, cutf, cnt, rq_f, rq_i = walk_outputs(256)
    while not _walk_sorted(starts, ends, *args, fx, float(max_speed_kn), int(max_run), si, sf, spikes, cuts, cutf,
                           cnt, rq_f, rq_i):
        spikes = np.concatenate((spikes, np.empty_like(spikes)))
        cuts, cutf = np.concatenate((cuts, np.empty_like(cuts))), np.concatenate((cutf, np.empty_like(cutf)))
    si[:, _S_STARTED] = 1
    return si, sf, spikes[:cnt[0], 0], cuts[:cnt[1]], cutf[:cnt[1]]
