"""Compiled link test of the speed-jump rule (:func:`lanes.clean.speed_jump_mask`).

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
