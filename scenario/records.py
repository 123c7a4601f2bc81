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


def _voyage_context(records: pd.DataFrame, voyages: pd.DataFrame, spec: ScenarioSpec) -> pd.DataFrame:
    """Destination, ETA and draught as the crew would have typed them at each record's time."""
    records["destination"] = ""
    records["eta_s"] = np.int64(-1)
    records["draught_m"] = np.nan
    if voyages.empty:
        return records
    for mmsi, idx in records.groupby("mmsi").groups.items():
        vv = voyages[voyages.mmsi == mmsi].sort_values("depart_s")
        if vv.empty:
            continue
        t = records.loc[idx, "time_s"].to_numpy()
        # the voyage in progress or the next one: first voyage whose arrival is after t
        j = np.searchsorted(vv["arrive_s"].to_numpy(), t, side="right")
        j = np.clip(j, 0, len(vv) - 1)
        names = np.array([spec.ports[p].ais_destination for p in vv["dest"]], dtype=object)
        records.loc[idx, "destination"] = names[j]
        records.loc[idx, "eta_s"] = np.round(vv["arrive_s"].to_numpy()[j] / 60.0).astype(np.int64) * 60
        records.loc[idx, "draught_m"] = vv["draught_m"].to_numpy()[j]
    return records


def _static_records(rng, st: ScenarioSettings, fixes: pd.DataFrame, vessels: pd.DataFrame) -> pd.DataFrame:
    """NMEA message 5 (static and voyage data) every ``static_interval_s`` while received."""
    out = []
    for vi, v in vessels.iterrows():
        if v["ais_format"] != "nmea":
            continue
        fx = fixes[(fixes.mmsi == v["mmsi"]) & fixes.received]
        if fx.empty:
            continue
        t = _sample_times(rng, st.start_s, st.end_s, st.static_interval_s, 30)
        # keep only times when the transponder was heard (a received fix within 10 min)
        ft = fx["time_s"].to_numpy()
        j = np.clip(np.searchsorted(ft, t), 1, len(ft) - 1)
        near = np.minimum(np.abs(ft[j] - t), np.abs(ft[j - 1] - t)) <= 600
        t = t[near]
        if len(t) == 0:
            continue
        t = t[~np.isin(t, ft)]  # never share a second with a position report of the same ship
        out.append(pd.DataFrame({"mmsi": np.int64(v["mmsi"]), "time_s": t, "msg_type": 5, "vessel_index": vi}))
    if not out:
        return pd.DataFrame(columns=["mmsi", "time_s", "msg_type", "vessel_index"])
    return pd.concat(out, ignore_index=True)


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


def _inject_dirty(rng, st: ScenarioSettings, recs: pd.DataFrame) -> pd.DataFrame:
    """Add dirty rows to the clean position records (see :data:`DIRTY_KINDS`).

    ``recs`` must be sorted by mmsi and time with a fresh RangeIndex.
    """
    # a record can seed a dirty row when it is an under-way position report at sea with its
    # neighbours (same ship) 50-70 s away, so an injected row between them is unambiguous
    t = recs["time_s"].to_numpy()
    m = recs["mmsi"].to_numpy()
    same_prev = np.r_[False, m[1:] == m[:-1]]
    same_next = np.r_[same_prev[1:], False]
    gap_prev = np.r_[0, np.diff(t)]
    gap_next = np.r_[np.diff(t), 0]
    base_ok = (
        same_prev & same_next & (gap_prev >= 50) & (gap_prev <= 70) & (gap_next >= 50) & (gap_next <= 70)
        & (recs["phase"].to_numpy() == "sea") & (recs["msg_type"].to_numpy() != 5)
    )
    used = np.zeros(len(recs), bool)
    extra = []
    for fmt in AIS_FORMATS:
        in_fmt = (recs["fmt"].to_numpy() == fmt) & (recs["msg_type"].to_numpy() != 5)
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
                recs.loc[bases[sog], "sog_kn"] = 102.3
                recs.loc[bases[cog], "cog_deg"] = 360.0
                recs.loc[bases[hdg], "heading_deg"] = 511.0
                recs.loc[bases, "dirty_kind"] = kind
                recs.loc[bases, "dirty_detail"] = [
                    ",".join(n for n, f in (("sog_kn", a), ("cog_deg", b), ("heading_deg", c)) if f)
                    for a, b, c in zip(sog, cog, hdg)
                ]
                continue
            sub = recs.loc[bases].copy()
            sub["dirty_kind"] = kind
            sub["sort_sub"] = 1
            delta = rng.integers(15, 36, k)
            lat, lon = sub["lat_deg"].to_numpy(), sub["lon_deg"].to_numpy()
            if kind == "sentinel_position":
                sub["lat_deg"], sub["lon_deg"] = 91.0, 181.0
                sub["time_s"] += delta
                sub["dirty_detail"] = "lat=91,lon=181"
            elif kind == "out_of_range":
                on_lat = rng.random(k) < 0.5
                sign = rng.choice([-1.0, 1.0], k)
                bad_lat = np.round(rng.uniform(92.0, 99.0, k), 4) * sign
                bad_lon = np.round(rng.uniform(182.0, 199.0, k), 4) * sign
                sub["lat_deg"] = np.where(on_lat, bad_lat, lat)
                sub["lon_deg"] = np.where(on_lat, lon, bad_lon)
                sub["time_s"] += delta
                sub["dirty_detail"] = [f"lat={a}" if f else f"lon={b}" for f, a, b in zip(on_lat, bad_lat, bad_lon)]
            elif kind == "invalid_mmsi":
                bad = [_bad_mmsi(rng, int(x)) for x in sub["mmsi"]]
                sub["mmsi"] = np.asarray(bad, dtype=np.int64)
                sub["vessel_index"] = -1
                sub["dirty_detail"] = [f"mmsi={x}" for x in bad]
            elif kind == "bad_timestamp":
                texts = [_BAD_TIMES[i].format(d=f"{d:02d}") for i, d in
                         zip(rng.integers(0, len(_BAD_TIMES), k), rng.integers(1, 29, k))]
                sub["time_text"] = texts
                sub["dirty_detail"] = [f"timestamp={x!r}" for x in texts]
            elif kind == "speed_jump":
                dist = rng.uniform(20.0, 45.0, k)
                sub["lat_deg"], sub["lon_deg"] = destination_point(lat, lon, rng.uniform(0, 360, k), dist)
                sub["time_s"] += delta
                sub["dirty_detail"] = [f"jump {d:.1f} nmi in {s} s" for d, s in zip(dist, delta)]
            elif kind == "duplicate_exact":
                sub["dirty_detail"] = "copy of the previous report"
            elif kind == "duplicate_timestamp":
                dist = rng.uniform(0.03, 0.15, k)
                sub["lat_deg"], sub["lon_deg"] = destination_point(lat, lon, rng.uniform(0, 360, k), dist)
                sub["sog_kn"] = np.maximum(0.0, sub["sog_kn"].to_numpy() + rng.choice([-0.4, 0.3], k))
                sub["dirty_detail"] = [f"same second, {d * METRES_PER_NMI:.0f} m apart" for d in dist]
            elif kind == "malformed_row":
                sub["dirty_detail"] = "line cut short"
            elif kind == "bad_checksum":
                sub["time_s"] += delta
                sub["dirty_detail"] = "payload corrupted, checksum mismatch"
            extra.append(sub)
    if extra:
        recs = pd.concat([recs, *extra], ignore_index=True)
    return recs


def build_records(rng, st: ScenarioSettings, spec: ScenarioSpec, fixes: pd.DataFrame, vessels: pd.DataFrame,
                  voyages: pd.DataFrame) -> pd.DataFrame:
    """What the writers write, from the quantised fixes: the received fixes (some as message 3),
    NMEA static messages, the dirty rows, the voyage context typed by the crew; in output order
    (by time; an injected copy follows its original).

    ``vessels`` is the whole fleet table (``vessel_index`` is a row of it); ``fixes`` and
    ``voyages`` may be the whole fleet's (the demo) or one ship's (the year-scale fleet of
    :mod:`scenario.fleet`, one random stream per ship).
    """
    fmt_of = dict(zip(vessels["mmsi"], vessels["ais_format"]))
    idx_of = {m: i for i, m in enumerate(vessels["mmsi"])}
    recs = fixes[fixes.received].drop(columns=["received"]).copy()
    recs["msg_type"] = np.where(rng.random(len(recs)) < 0.15, 3, 1)  # some "special" position reports
    static = _static_records(rng, st, fixes, vessels)
    if len(static):
        static["phase"] = ""
        static["voyage_id"] = ""
        recs = pd.concat([recs, static], ignore_index=True)
    recs["fmt"] = recs["mmsi"].map(fmt_of)
    recs["vessel_index"] = recs["mmsi"].map(idx_of).astype(np.int64)
    recs["channel"] = np.where(rng.random(len(recs)) < 0.5, "A", "B")
    recs["dirty_kind"] = ""
    recs["dirty_detail"] = ""
    recs["time_text"] = ""  # only read for dirty_kind == "bad_timestamp"
    recs["sort_s"] = recs["time_s"]
    recs["sort_sub"] = 0
    recs = recs.sort_values(["mmsi", "time_s"], kind="stable").reset_index(drop=True)
    recs = _inject_dirty(rng, st, recs)
    recs = _voyage_context(recs, voyages, spec)
    recs["time_s"] = recs["time_s"].astype(np.int64)
    recs["sort_s"] = recs["sort_s"].astype(np.int64)
    # output order: by time; an injected copy follows its original
    recs = recs.sort_values(["sort_s", "mmsi", "sort_sub"], kind="stable").reset_index(drop=True)
    recs = recs[[c for c in _RECORD_COLUMNS if c in recs.columns] + ["phase"]]
    for col in ("sog_kn", "cog_deg", "heading_deg"):
        recs[col] = recs[col].astype(float)
    recs["nav_status"] = recs["nav_status"].fillna(-1).astype(np.int64)
    return recs
