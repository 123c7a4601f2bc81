"""The streaming rules 7-8 kernel (ais._tracks) against a plain sort-then-scan reference."""

from __future__ import annotations

import numpy as np
import pytest

from ais._tracks import first_load_rules, sorted_fixes
from ais.clean import SENTINEL_TOL, speed_jump_mask

VMAX_KN = 60.0


def reference(scan: dict, exact: dict, vmax_kn: float = VMAX_KN) -> dict:
    """Merge by line, sort each MMSI's fixes by (time, line) with numpy, take repeated keys
    out and call speed_jump_mask: the rules as written in ais.clean."""
    no_ctx = {"mmsi": np.empty(0, np.int64), "skip": np.empty(0, bool), "t_us": np.empty(0, np.int64),
              "lat": np.empty(0), "lon": np.empty(0)}
    return reference_with_context(scan, exact, no_ctx, (), vmax_kn)


def as_pairs(d: dict) -> tuple:
    return sorted(zip(d["dup"].tolist(), d["ref"].tolist())), sorted(d["jump"].tolist())


def fleet(seed: int, n_vessels: int, n_steps: int, jumps: int = 0, long_jumps: int = 0, dups: int = 0,
          shuffle_tracks: int = 0, near_180: bool = False):
    """Time-ordered fixes of ``n_vessels`` ships (10 s cadence, 6-20 kn), with injected
    one-fix outliers, runs of 5 fixes from a second transmitter far away, repeated keys and
    tracks written out of time order."""
    rng = np.random.default_rng(seed)
    n = n_vessels * n_steps
    i = np.arange(n)
    v = i % n_vessels
    step = i // n_vessels
    mmsi = (201_000_000 + rng.choice(574_000_000, n_vessels, replace=False))[v]
    t_us = step * 10_000_000 + 1_735_689_600_000_000 + (v % 10) * 1_000_000
    lat0 = rng.uniform(-60, 60, n_vessels)
    lon0 = np.full(n_vessels, 179.995) if near_180 else rng.uniform(-170, 170, n_vessels)
    sog = rng.uniform(6, 20, n_vessels)
    cog = rng.uniform(0, 360, n_vessels)
    d = sog[v] * step * 10 / 3600 / 60
    lat = lat0[v] + d * np.cos(np.radians(cog[v])) + rng.normal(0, 2e-5, n)
    lon = lon0[v] + d * np.sin(np.radians(cog[v])) / np.cos(np.radians(lat0[v])) + rng.normal(0, 2e-5, n)
    lon = (lon + 180.0) % 360.0 - 180.0
    if near_180:
        lon[::7] = 180.0  # written as +180, stored as -180
    lat[rng.choice(n, jumps, replace=False)] += 2.0
    for s in rng.choice(n - 6 * n_vessels, long_jumps, replace=False):
        lat[s + n_vessels * np.arange(5)] += 1.5  # five consecutive fixes of one ship
    dd = rng.choice(np.arange(n_vessels, n), dups, replace=False)
    t_us[dd] = t_us[dd - n_vessels]  # same key as the ship's fix before
    same_vals = dd[: dups // 2]
    lat[same_vals], lon[same_vals] = lat[same_vals - n_vessels], lon[same_vals - n_vessels]
    for ship in rng.choice(n_vessels, shuffle_tracks, replace=False):
        rows = np.flatnonzero(v == ship)
        t_us[rows] = rng.permutation(t_us[rows])
    line = i + 2
    return {"line": line, "mmsi": mmsi, "t_us": t_us.astype(np.int64), "lat": lat, "lon": lon}


def split(fixes: dict, seed: int, frac_exact: float = 0.01, frac_bad: float = 0.01):
    """Some rows go to the 'typed from text' source, some fail rules 1-6 (ok False)."""
    rng = np.random.default_rng(seed)
    n = len(fixes["line"])
    to_exact = rng.random(n) < frac_exact
    exact = {k: v[to_exact] for k, v in fixes.items()}
    scan = {k: v[~to_exact] for k, v in fixes.items()}
    scan["ok"] = rng.random(len(scan["line"])) >= frac_bad
    return scan, exact


@pytest.mark.parametrize("seed", range(6))
def test_stream_equals_sort_then_scan(seed):
    f = fleet(seed, n_vessels=37 + 20 * seed, n_steps=60, jumps=25, long_jumps=4, dups=30, shuffle_tracks=seed % 3)
    scan, exact = split(f, seed)
    got = first_load_rules(scan, exact, VMAX_KN)
    want = reference(scan, exact)
    assert as_pairs(got) == as_pairs(want)
    assert len(want["jump"]) >= 25 and len(want["dup"]) >= 20  # the injected faults are really there


def test_many_tracks_grow_every_table():
    # More tracks, repeated keys and cuts than the first sizes of the stream's tables.
    f = fleet(7, n_vessels=5000, n_steps=6, jumps=5000, dups=5000)
    scan, exact = split(f, 7)
    assert as_pairs(first_load_rules(scan, exact, VMAX_KN)) == as_pairs(reference(scan, exact))


def test_antimeridian_and_lon_180():
    f = fleet(3, n_vessels=20, n_steps=80, jumps=5, near_180=True)
    scan, exact = split(f, 3)
    assert as_pairs(first_load_rules(scan, exact, VMAX_KN)) == as_pairs(reference(scan, exact))


def test_hand_computed_track():
    # One ship at 0 N, moving 0.01 deg (0.6 nmi) east per minute (36 kn): the third fix is 1 deg
    # off (a jump), the fifth repeats the fourth's time (a duplicate). A second ship has a run
    # of three fixes from another transmitter between runs of two and four of its own: the
    # four are accepted first (largest), the three are not linked to them (rejected as one
    # segment, so the second pass finds their lines), the two are (36 kn over 4 minutes).
    minute = 60_000_000
    line = np.arange(2, 17)
    mmsi = np.array([1] * 6 + [2] * 9) + 219_000_000
    t_us = np.r_[[0, 1, 2, 3, 3, 4], np.arange(9)] * minute
    lat = np.r_[[0, 0, 1, 0, 0, 0], [10, 10, 11, 11, 11, 10, 10, 10, 10.0]]
    lon = np.r_[[0, 0.01, 0.02, 0.03, 0.03, 0.04], 0.01 * np.arange(9)]
    scan = {"line": line, "mmsi": mmsi, "t_us": t_us, "lat": lat, "lon": lon, "ok": np.ones(15, bool)}
    empty = {k: v[:0] for k, v in scan.items() if k != "ok"}
    got = first_load_rules(scan, empty, VMAX_KN)
    assert sorted(got["jump"].tolist()) == [4, 10, 11, 12]
    assert got["dup"].tolist() == [6] and got["ref"].tolist() == [5]
    assert as_pairs(got) == as_pairs(reference(scan, empty))


def test_sorted_fixes_orders_by_track_time_line():
    scan = {"line": np.array([2, 3, 4, 5, 6]), "mmsi": np.array([9, 8, 9, 9, 8]),
            "t_us": np.array([30, 5, 10, 10, 1]), "lat": np.zeros(5), "lon": np.array([0, 0, 180.0, 0, 0]),
            "ok": np.array([True, True, True, True, False])}
    empty = {k: v[:0] for k, v in scan.items() if k != "ok"}
    s = sorted_fixes(scan, empty)
    assert s["line"].tolist() == [4, 2, 3] and s["track"].tolist() == [0, 0, 1]
    assert s["dup"].tolist() == [5] and s["ref"].tolist() == [4]
    assert s["lon"].tolist() == [-180.0, 0.0, 0.0]


def reference_with_context(scan: dict, exact: dict, ctx: dict, leave_out, vmax_kn: float = VMAX_KN) -> dict:
    """The rules as the SQL path applies them: each MMSI's stored fix before the file is a fixed
    fix ahead of its track (speed_jump_mask's ``fixed``); MMSIs in ``leave_out`` are ignored."""
    ok = scan["ok"]
    cols = {k: np.r_[scan[k][ok], exact[k]] for k in ("line", "mmsi", "t_us", "lat", "lon")}
    keep = ~np.isin(cols["mmsi"], list(leave_out))
    cols = {k: v[keep] for k, v in cols.items()}
    use = ~ctx["skip"] & ~np.isin(ctx["mmsi"], list(leave_out))
    n_ctx = int(use.sum())
    line = np.r_[-1 - np.arange(n_ctx), cols["line"]]
    mmsi = np.r_[ctx["mmsi"][use], cols["mmsi"]]
    t_us = np.r_[ctx["t_us"][use], cols["t_us"]]
    lat = np.r_[ctx["lat"][use], cols["lat"]]
    lon = np.r_[ctx["lon"][use], cols["lon"]]
    lon = np.where(np.abs(lon - 180.0) <= SENTINEL_TOL, -180.0, lon)
    order = np.lexsort((line, t_us, mmsi))
    line, mmsi, t_us, lat, lon = line[order], mmsi[order], t_us[order], lat[order], lon[order]
    same = np.r_[False, (mmsi[1:] == mmsi[:-1]) & (t_us[1:] == t_us[:-1])]
    first = np.maximum.accumulate(np.where(~same, np.arange(len(line)), 0))
    dup, ref = line[same], line[first[same]]
    k = ~same
    mask = speed_jump_mask(mmsi[k], (t_us[k] * 1000) / 1e9, lat[k], lon[k], vmax_kn, fixed=line[k] < 0)
    return {"dup": dup, "ref": ref, "jump": line[k][mask]}


@pytest.mark.parametrize("seed", range(4))
def test_stream_with_stored_context_equals_fixed_fixes(seed):
    # A second file: most ships have a stored fix before their first fix in the file (some
    # linked to it, some 1 degree away: the new track's first segment is then judged against
    # a pinned fix), some ships are left to the caller (skip), one ship with context goes back
    # in time in the file (left out too), the others are new.
    f = fleet(seed, n_vessels=40, n_steps=50, jumps=15, long_jumps=2, dups=10, shuffle_tracks=2)
    scan, exact = split(f, seed)
    rng = np.random.default_rng(seed)
    ships, first_at = np.unique(f["mmsi"], return_index=True)
    n = len(ships)
    skip = rng.random(n) < 0.15
    has_ctx = ~skip & (rng.random(n) < 0.7)
    t0 = f["t_us"][first_at]
    far = rng.random(n) < 0.3
    ctx = {"mmsi": ships[skip | has_ctx], "skip": skip[skip | has_ctx],
           "t_us": (t0 - 60_000_000)[skip | has_ctx],
           "lat": (f["lat"][first_at] + np.where(far, 1.0, 0.0))[skip | has_ctx],
           "lon": f["lon"][first_at][skip | has_ctx]}
    got = first_load_rules(scan, exact, VMAX_KN, ctx)
    leave_out = set(got["fallback"].tolist())
    assert set(ships[skip].tolist()) <= leave_out
    assert leave_out - set(ships[skip].tolist()) <= set(ships[has_ctx].tolist())  # back in time, with context
    want = reference_with_context(scan, exact, ctx, leave_out)
    assert as_pairs(got) == as_pairs(want)
    assert len(want["jump"]) >= 10
