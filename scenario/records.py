"""What the demo scenario writes, one row per line or message: the received fixes, NMEA static
messages and the dirty rows of every kind the ingest must quarantine. See :mod:`scenario.generator`."""

from __future__ import annotations

import numpy as np
import pandas as pd

from scenario.sailing import _sample_times
from scenario.spec import AIS_FORMATS, FORMAT_KINDS, ScenarioSettings, ScenarioSpec
from thresholds.geodesy import destination_point
from thresholds.units import METRES_PER_NMI


# --------------------------------------------------------------------------------------------
# Records: what gets written, dirty rows included
# --------------------------------------------------------------------------------------------

_RECORD_COLUMNS = [
    "mmsi", "time_s", "lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "nav_status", "msg_type",
    "channel", "fmt", "vessel_index", "voyage_id", "destination", "eta_s", "draught_m", "dirty_kind",
    "dirty_detail", "time_text", "sort_s", "sort_sub",
]


def _quantise(df: pd.DataFrame) -> pd.DataFrame:
    """Round to what AIS carries: 1/10 000 min positions, 0.1 kn, 0.1 deg, whole-degree heading."""
    df["lat_deg"] = np.round(df["lat_deg"].to_numpy() * 600000.0) / 600000.0
    df["lon_deg"] = np.round(df["lon_deg"].to_numpy() * 600000.0) / 600000.0
    df["sog_kn"] = np.round(np.minimum(df["sog_kn"].to_numpy(), 102.2), 1)
    df["cog_deg"] = np.round(df["cog_deg"].to_numpy(), 1) % 360.0
    df["heading_deg"] = np.round(df["heading_deg"].to_numpy()) % 360.0
    return df


def _voyage_context(cols: dict, voyages: pd.DataFrame, spec: ScenarioSpec) -> None:
    """Destination, ETA and draught as the crew would have typed them at each record's time
    (columns ``destination``, ``eta_s``, ``draught_m`` of ``cols``, set in place)."""
    n = len(cols["time_s"])
    cols["destination"] = np.full(n, "", dtype=object)
    cols["eta_s"] = np.full(n, -1, dtype=np.int64)
    cols["draught_m"] = np.full(n, np.nan)
    if voyages.empty:
        return
    m, t_all = cols["mmsi"], cols["time_s"]
    for mmsi in np.unique(voyages["mmsi"].to_numpy()):
        idx = np.flatnonzero(m == mmsi)
        if not len(idx):
            continue
        vv = voyages[voyages.mmsi == mmsi].sort_values("depart_s")
        # the voyage in progress or the next one: first voyage whose arrival is after t
        j = np.searchsorted(vv["arrive_s"].to_numpy(), t_all[idx], side="right")
        j = np.clip(j, 0, len(vv) - 1)
        names = np.array([spec.ports[p].ais_destination for p in vv["dest"]], dtype=object)
        cols["destination"][idx] = names[j]
        cols["eta_s"][idx] = np.round(vv["arrive_s"].to_numpy()[j] / 60.0).astype(np.int64) * 60
        cols["draught_m"][idx] = vv["draught_m"].to_numpy()[j]


def _static_records(rng, st: ScenarioSettings, fixes: pd.DataFrame, vessels: pd.DataFrame) -> dict | None:
    """NMEA message 5 (static and voyage data) every ``static_interval_s`` while received:
    columns ``mmsi``, ``time_s``, ``msg_type``, ``vessel_index`` (None when there is none)."""
    out = []
    fmt, fleet_mmsi = vessels["ais_format"].to_numpy(), vessels["mmsi"].to_numpy()
    fx_mmsi, fx_received, fx_time = (fixes[c].to_numpy() for c in ("mmsi", "received", "time_s"))
    for vi in np.flatnonzero(fmt == "nmea"):
        ft = fx_time[(fx_mmsi == fleet_mmsi[vi]) & fx_received]
        if not len(ft):
            continue
        t = _sample_times(rng, st.start_s, st.end_s, st.static_interval_s, 30)
        # keep only times when the transponder was heard (a received fix within 10 min)
        j = np.clip(np.searchsorted(ft, t), 1, len(ft) - 1)
        near = np.minimum(np.abs(ft[j] - t), np.abs(ft[j - 1] - t)) <= 600
        t = t[near]
        if len(t) == 0:
            continue
        t = t[~np.isin(t, ft)]  # never share a second with a position report of the same ship
        out.append((np.full(len(t), fleet_mmsi[vi], dtype=np.int64), t, np.full(len(t), int(vessels.index[vi]))))
    if not out:
        return None
    mmsi, t, vi = (np.concatenate(c) for c in zip(*out))
    return {"mmsi": mmsi, "time_s": t, "msg_type": np.full(len(t), 5, dtype=np.int64), "vessel_index": vi}


def _pick_bases(rng, eligible: np.ndarray, n: int) -> np.ndarray:
    """``n`` distinct indices drawn from the True entries of ``eligible`` (sorted)."""
    pool = np.flatnonzero(eligible)
    n = min(n, len(pool))
    if n == 0:
        return np.empty(0, dtype=np.int64)
    return np.sort(rng.choice(pool, size=n, replace=False))


def _bad_mmsi(rng, mmsi: int) -> int:
    variant = rng.integers(0, 4)
    if variant == 0:  # a digit lost: 8 digits
        return mmsi // 10
    if variant == 1:  # MID 111: SAR aircraft, not a ship
        return 111_000_000 + mmsi % 1_000_000
    if variant == 2:  # MID 970: AIS-SART, not a ship
        return 970_000_000 + mmsi % 1_000_000
    return mmsi % 10_000_000  # leading digits lost: 7 digits


_BAD_TIMES = ("32/01/2025 10:00:00", "{d}/13/2025 07:15:00", "{d}/01/2025 25:61:00", "", "not-a-time",
              "2025-01-{d}T??:00:00", "00/00/0000 00:00:00")


def _take(cols: dict, idx: np.ndarray) -> dict:
    """The rows ``idx`` of every column (copies)."""
    return {c: x[idx] for c, x in cols.items()}


def _concat(parts: list[dict]) -> dict:
    """The rows of the column dicts ``parts`` one after the other (the columns of the first)."""
    return {c: np.concatenate([p[c] for p in parts]) for c in parts[0]}


def _inject_dirty(rng, st: ScenarioSettings, recs: dict) -> dict:
    """Add dirty rows to the clean position records (see :data:`DIRTY_KINDS`); ``recs`` is a
    dict of columns, sorted by mmsi and time. Returns the records with the dirty rows appended
    (``sentinel_fields`` edits clean rows in place)."""
    # Long by design: one branch per kind, each drawing from the one stream in a fixed order.
    # a record can seed a dirty row when it is an under-way position report at sea with its
    # neighbours (same ship) 50-70 s away, so an injected row between them is unambiguous
    t, m = recs["time_s"], recs["mmsi"]
    same_prev = np.r_[False, m[1:] == m[:-1]]
    same_next = np.r_[same_prev[1:], False]
    gap_prev = np.r_[0, np.diff(t)]
    gap_next = np.r_[np.diff(t), 0]
    position = recs["msg_type"] != 5
    base_ok = (
        same_prev & same_next & (gap_prev >= 50) & (gap_prev <= 70) & (gap_next >= 50) & (gap_next <= 70)
        & (recs["phase"] == "sea") & position
    )
    used = np.zeros(len(t), bool)
    extra = []
    for fmt in AIS_FORMATS:
        in_fmt = (recs["fmt"] == fmt) & position
        n_fmt = int(in_fmt.sum())
        if n_fmt == 0:
            continue
        for kind in FORMAT_KINDS[fmt]:
            rate = float(st.dirty_rates.get(kind, 0.0))
            if rate <= 0:
                continue
            n = max(st.dirty_min_per_kind, int(round(rate * n_fmt)))
            bases = _pick_bases(rng, base_ok & in_fmt & ~used, n)
            used[bases] = True
            k = len(bases)
            if k == 0:
                continue
            if kind == "sentinel_fields":
                which = rng.integers(1, 8, k)  # bit mask over SOG / COG / heading
                sog, cog, hdg = (which & 1) > 0, (which & 2) > 0, (which & 4) > 0
                recs["sog_kn"][bases[sog]] = 102.3
                recs["cog_deg"][bases[cog]] = 360.0
                recs["heading_deg"][bases[hdg]] = 511.0
                recs["dirty_kind"][bases] = kind
                recs["dirty_detail"][bases] = [
                    ",".join(n for n, f in (("sog_kn", a), ("cog_deg", b), ("heading_deg", c)) if f)
                    for a, b, c in zip(sog, cog, hdg)
                ]
                continue
            sub = _take(recs, bases)
            sub["dirty_kind"][:] = kind
            sub["sort_sub"][:] = 1
            delta = rng.integers(15, 36, k)
            lat, lon = sub["lat_deg"].copy(), sub["lon_deg"].copy()
            detail = sub["dirty_detail"]
            if kind == "sentinel_position":
                sub["lat_deg"][:], sub["lon_deg"][:] = 91.0, 181.0
                sub["time_s"] += delta
                detail[:] = "lat=91,lon=181"
            elif kind == "out_of_range":
                on_lat = rng.random(k) < 0.5
                sign = rng.choice([-1.0, 1.0], k)
                bad_lat = np.round(rng.uniform(92.0, 99.0, k), 4) * sign
                bad_lon = np.round(rng.uniform(182.0, 199.0, k), 4) * sign
                sub["lat_deg"] = np.where(on_lat, bad_lat, lat)
                sub["lon_deg"] = np.where(on_lat, lon, bad_lon)
                sub["time_s"] += delta
                detail[:] = [f"lat={a}" if f else f"lon={b}" for f, a, b in zip(on_lat, bad_lat, bad_lon)]
            elif kind == "invalid_mmsi":
                bad = [_bad_mmsi(rng, int(x)) for x in sub["mmsi"]]
                sub["mmsi"] = np.asarray(bad, dtype=np.int64)
                sub["vessel_index"][:] = -1
                detail[:] = [f"mmsi={x}" for x in bad]
            elif kind == "bad_timestamp":
                texts = [_BAD_TIMES[i].format(d=f"{d:02d}") for i, d in
                         zip(rng.integers(0, len(_BAD_TIMES), k), rng.integers(1, 29, k))]
                sub["time_text"][:] = texts
                detail[:] = [f"timestamp={x!r}" for x in texts]
            elif kind == "speed_jump":
                dist = rng.uniform(20.0, 45.0, k)
                sub["lat_deg"], sub["lon_deg"] = destination_point(lat, lon, rng.uniform(0, 360, k), dist)
                sub["time_s"] += delta
                detail[:] = [f"jump {d:.1f} nmi in {s} s" for d, s in zip(dist, delta)]
            elif kind == "duplicate_exact":
                detail[:] = "copy of the previous report"
            elif kind == "duplicate_timestamp":
                dist = rng.uniform(0.03, 0.15, k)
                sub["lat_deg"], sub["lon_deg"] = destination_point(lat, lon, rng.uniform(0, 360, k), dist)
                sub["sog_kn"] = np.maximum(0.0, sub["sog_kn"] + rng.choice([-0.4, 0.3], k))
                detail[:] = [f"same second, {d * METRES_PER_NMI:.0f} m apart" for d in dist]
            elif kind == "malformed_row":
                detail[:] = "line cut short"
            elif kind == "bad_checksum":
                sub["time_s"] += delta
                detail[:] = "payload corrupted, checksum mismatch"
            extra.append(sub)
    return _concat([recs, *extra]) if extra else recs


def _record_columns(rng, st: ScenarioSettings, fixes: pd.DataFrame, vessels: pd.DataFrame) -> dict:
    """The received fixes and the static messages as columns (the fixes' columns, ``msg_type``,
    ``fmt``, ``vessel_index``, ``channel``, the dirty-row columns, the sort keys), sorted by
    mmsi and time (stable)."""
    received = fixes["received"].to_numpy(dtype=bool)
    cols = {c: fixes[c].to_numpy()[received] for c in fixes.columns if c != "received"}
    n = len(cols["time_s"])
    cols["msg_type"] = np.where(rng.random(n) < 0.15, 3, 1)  # some "special" position reports
    static = _static_records(rng, st, fixes, vessels)
    if static is not None:  # message 5 rows: no position, status or voyage
        k = len(static["time_s"])
        for c, x in cols.items():
            if c in static:
                add = static[c]
            elif c in ("phase", "voyage_id"):
                add = np.full(k, "", dtype=object)
            else:
                add, x = np.full(k, np.nan), x.astype(float)
            cols[c] = np.concatenate([x, add])
        n += k
    mmsi = cols["mmsi"].astype(np.int64)
    cols["mmsi"] = mmsi
    row_of = {mm: i for i, mm in enumerate(vessels["mmsi"].to_numpy())}
    codes, inverse = np.unique(mmsi, return_inverse=True)
    where = np.array([row_of[c] for c in codes], dtype=np.int64)[inverse]
    cols["fmt"] = vessels["ais_format"].to_numpy(dtype=object)[where]
    cols["vessel_index"] = where
    cols["channel"] = np.where(rng.random(n) < 0.5, "A", "B").astype(object)
    for c in ("dirty_kind", "dirty_detail", "time_text"):  # time_text: only read for bad_timestamp
        cols[c] = np.full(n, "", dtype=object)
    cols["sort_s"] = cols["time_s"].copy()
    cols["sort_sub"] = np.zeros(n, dtype=np.int64)
    order = np.lexsort((cols["time_s"], mmsi))
    return _take(cols, order) if np.any(order != np.arange(n)) else cols


def record_columns(rng, st: ScenarioSettings, spec: ScenarioSpec, fixes: pd.DataFrame, vessels: pd.DataFrame,
                   voyages: pd.DataFrame) -> dict:
    """The columns of :func:`build_records` (numpy arrays, strings as objects), without the
    DataFrame: what the year-scale fleet spills (:mod:`pipelines.scenario_fleet`)."""
    recs = _inject_dirty(rng, st, _record_columns(rng, st, fixes, vessels))
    _voyage_context(recs, voyages, spec)
    # output order: by time; an injected copy follows its original (stable)
    order = np.lexsort((recs["sort_sub"], recs["mmsi"], recs["sort_s"]))
    nav = recs["nav_status"]
    if nav.dtype.kind == "f":  # the static messages' rows carry no status
        recs["nav_status"] = np.where(np.isnan(nav), -1, nav)
    out = {c: recs[c][order] for c in _RECORD_COLUMNS + ["phase"]}
    for col in ("sog_kn", "cog_deg", "heading_deg"):
        out[col] = out[col].astype(float)
    for col in ("time_s", "sort_s", "nav_status"):
        out[col] = out[col].astype(np.int64)
    return out


def build_records(rng, st: ScenarioSettings, spec: ScenarioSpec, fixes: pd.DataFrame, vessels: pd.DataFrame,
                  voyages: pd.DataFrame) -> pd.DataFrame:
    """What the writers write, from the quantised fixes: the received fixes (some as message 3),
    NMEA static messages, the dirty rows, the voyage context typed by the crew; in output order
    (by time; an injected copy follows its original).

    ``vessels`` is the whole fleet table (``vessel_index`` is a row of it); ``fixes`` and
    ``voyages`` may be the whole fleet's (the demo) or one ship's (the year-scale fleet of
    :mod:`scenario.fleet`, one random stream per ship). Built as numpy columns
    (:func:`record_columns`) and made a DataFrame once at the end: pandas' row-wise ``.loc``
    passes cost about 55 ms per ship.
    """
    return pd.DataFrame(record_columns(rng, st, spec, fixes, vessels, voyages))
