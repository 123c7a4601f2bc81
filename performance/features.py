"""Features of the performance model: the sea state relative to the ship, the ship, its calm speed.

Conventions are the project's (DESIGN.md): directions clockwise from north, waves and wind
"coming from", currents "flowing to"; one encounter angle ``encounter_deg`` (0 = head seas),
here folded to [0, 180] since port and starboard seas load a hull alike.

The target
----------
``speed_ratio = stw_kn / v0_kn``: the speed through the water as a fraction of the voyage's
calm-water speed, not the loss in knots. A ratio lets one model serve 13-knot tankers and
22-knot ferries (added resistance in waves and its voluntary part are, to first order, shares of
the power and so of the speed: the published formulas of Aertssen and of the STEAM2 power law
are written that way), and it composes with the router, which knows the vessel's calm-water
speed and asks for the fraction of it the sea allows. Errors are reported in knots
(:mod:`performance.validate`).

The calm-water speed
--------------------
The voyage's median speed through the water over its fixes in a low sea state: Hs below 1 m and
wind below 7.9 m/s (the top of Beaufort 4, "moderate breeze", WMO-No. 558 Annex I), when at
least :data:`CALM_MIN_FIXES` such fixes exist; else below 1.5 m and 10.7 m/s (Beaufort 5, "fresh
breeze"); otherwise the median of the ship's other voyages' calm speeds. On the demo the first
tier finds 72 % of voyages, the second all but 3 %. It is the speed the ship was set to sail, read from AIS; a small loss even
in a low sea state is therefore part of the "calm" speed, and the model's ratio is relative to it.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from thresholds.units import MS_PER_KN

#: AIS ship-type code ranges of each class (ITU-R M.1371-5, Table 53).
SHIP_CLASSES = {"passenger": (60, 69), "cargo": (70, 79), "tanker": (80, 89)}
#: Classes in a fixed order (the model's categorical code is the index).
CLASS_NAMES = ("passenger", "cargo", "tanker", "other")

#: Low sea states for the calm-water speed, tried in order (module notes): (Hs [m], wind [m/s]).
CALM_TIERS = ((1.0, 7.9), (1.5, 10.7))
CALM_MIN_FIXES = 10

#: The model's inputs, in order, and the monotonic constraint of each (-1: the speed never rises
#: when it grows). Hs in any heading and the head-wind component only slow a ship down
#: (added resistance is positive; surf-riding is the safety rules' business, not a speed gain).
FEATURES = ("hs_m", "encounter_deg", "tp_s", "wind_head_ms", "wind_cross_ms", "v0_kn", "length_m", "beam_m",
            "draught_m", "class_code")
MONOTONIC = {"hs_m": -1, "wind_head_ms": -1}
CATEGORICAL = ("class_code",)


def ship_class(ship_type) -> np.ndarray:
    """Class name per AIS ship type (:data:`SHIP_CLASSES`; anything else, or unknown, ``other``).

    Examples
    --------
    >>> ship_class([60, 71, 84, 30, None]).tolist()
    ['passenger', 'cargo', 'tanker', 'other', 'other']
    """
    st = pd.to_numeric(pd.Series(ship_type, dtype="object"), errors="coerce").to_numpy(dtype=float)
    out = np.full(st.shape, "other", dtype=object)
    for name, (lo, hi) in SHIP_CLASSES.items():
        out[(st >= lo) & (st <= hi)] = name
    return out


def class_code(names) -> np.ndarray:
    """Index of each class name in :data:`CLASS_NAMES` (the model's categorical feature)."""
    index = {n: i for i, n in enumerate(CLASS_NAMES)}
    return np.array([index.get(str(n), index["other"]) for n in np.asarray(names, dtype=object)], dtype=np.int64)


def fold_deg(angle_deg) -> np.ndarray:
    """An angle folded to [0, 180] (0 = ahead)."""
    a = np.mod(np.asarray(angle_deg, dtype=float), 360.0)
    return np.where(a > 180.0, 360.0 - a, a)


def relative_weather(course_deg, wave_from_deg, wind_u_ms, wind_v_ms, current_u_ms=None, current_v_ms=None) -> dict:
    """The sea state as the ship meets it on ``course_deg``.

    Returns
    -------
    dict of ndarray
        ``encounter_deg`` (folded, 0 = head seas), ``wind_head_ms`` (wind component from ahead,
        negative from astern), ``wind_cross_ms`` (abeam, magnitude), ``current_along_kn``
        (component along the course, flowing with the ship positive) and ``current_cross_kn``.
        Missing wind or current gives NaN.

    Examples
    --------
    >>> r = relative_weather(90.0, 90.0, -10.0, 0.0)   # heading east into an easterly
    >>> round(float(r["encounter_deg"]), 1), round(float(r["wind_head_ms"]), 1)
    (0.0, 10.0)
    """
    c = np.deg2rad(np.asarray(course_deg, dtype=float))
    out = {"encounter_deg": fold_deg(np.asarray(wave_from_deg, dtype=float) - np.asarray(course_deg, dtype=float))}
    u = np.asarray(wind_u_ms, dtype=float)
    v = np.asarray(wind_v_ms, dtype=float)
    # the wind blows TOWARDS (u, v): its component along the course is -(head wind)
    along = u * np.sin(c) + v * np.cos(c)
    out["wind_head_ms"] = -along
    out["wind_cross_ms"] = np.abs(u * np.cos(c) - v * np.sin(c))
    if current_u_ms is None or current_v_ms is None:
        nan = np.full(np.shape(c), np.nan)
        out["current_along_kn"], out["current_cross_kn"] = nan, nan.copy()
    else:
        cu = np.asarray(current_u_ms, dtype=float)
        cv = np.asarray(current_v_ms, dtype=float)
        out["current_along_kn"] = (cu * np.sin(c) + cv * np.cos(c)) / MS_PER_KN
        out["current_cross_kn"] = np.abs(cu * np.cos(c) - cv * np.sin(c)) / MS_PER_KN
    return out


def add_features(table: pd.DataFrame) -> pd.DataFrame:
    """The training table with the relative weather, speed through the water and class columns.

    Speed through the water = SOG minus the current along the course (no current: SOG). The
    course is the COG (the router's edges are courses over ground too).
    """
    df = table.copy()
    rel = relative_weather(df["cog_deg"], df["wave_from_deg"] if "wave_from_deg" in df else np.nan,
                           df["wind_u_ms"] if "wind_u_ms" in df else np.nan,
                           df["wind_v_ms"] if "wind_v_ms" in df else np.nan,
                           df["current_u_ms"] if "current_u_ms" in df else None,
                           df["current_v_ms"] if "current_v_ms" in df else None)
    for k, v in rel.items():
        df[k] = v
    if "tp_s" not in df:
        df["tp_s"] = np.nan
    if "tm_s" in df:  # a product with only a mean period: Tp ~ 1.2 Tm-10 (JONSWAP, gamma 3.3; DNV-RP-C205 3.5.5)
        df["tp_s"] = df["tp_s"].fillna(1.2 * df["tm_s"])
    df["stw_kn"] = df["sog_kn"] - np.nan_to_num(df["current_along_kn"].to_numpy(dtype=float))
    df["wind_ms"] = np.hypot(df["wind_head_ms"], df["wind_cross_ms"])
    df["ship_class"] = ship_class(df["ship_type"])
    df["class_code"] = class_code(df["ship_class"])
    return df


#: Length of the segments fixes are averaged over (module notes). [s]
SEGMENT_S = 600.0
#: Fewest fixes a segment needs (a lone fix is mostly sensor noise).
SEGMENT_MIN_FIXES = 3
#: Columns averaged over a segment (the angles are folded or signed components, so plain means).
_MEANS = ("sog_kn", "stw_kn", "hs_m", "tp_s", "encounter_deg", "wind_head_ms", "wind_cross_ms", "wind_ms",
          "current_along_kn", "current_cross_kn", "lat_deg", "lon_deg")


def segments(df: pd.DataFrame, segment_s: float = SEGMENT_S) -> pd.DataFrame:
    """Fixes of a voyage averaged over ``segment_s`` windows of UTC time (module notes).

    One row per (voyage, window) with at least :data:`SEGMENT_MIN_FIXES` fixes: the means of the
    speeds and of the sea state relative to the ship, the first fix's particulars, the middle
    time, and ``n_fixes``. ``segment_s`` = 0 keeps every fix as its own row.
    """
    if segment_s <= 0 or df.empty:
        return df.assign(n_fixes=1)
    t = (pd.to_datetime(df["time_utc"], utc=True) - pd.Timestamp(0, tz="UTC")) / pd.Timedelta(seconds=1)
    key = pd.Series(np.floor(t / segment_s).astype(np.int64), index=df.index, name="window")
    g = df.assign(_t=t).groupby([df["voyage_id"], key], sort=True)
    means = g[[c for c in _MEANS if c in df] + ["_t"]].mean()
    first = g[[c for c in ("mmsi", "ship_type", "ship_class", "class_code", "length_m", "beam_m", "draught_m", "v0_kn",
                           "v0_source") if c in df]].first()
    out = means.join(first)
    out["n_fixes"] = g.size()
    out["time_utc"] = pd.to_datetime(np.round(out.pop("_t")).astype(np.int64), unit="s", utc=True)
    out = out[out["n_fixes"] >= SEGMENT_MIN_FIXES].reset_index()
    return out.drop(columns=["window"])


def calm_water_speed(df: pd.DataFrame) -> pd.DataFrame:
    """``v0_kn`` and ``v0_source`` per fix (module notes): "voyage" (first tier), "voyage_moderate"
    (second tier), "vessel" (the ship's median voyage calm speed) or "none"."""
    out = df.copy()
    wind = out["wind_ms"].fillna(0.0)
    out["v0_kn"] = np.nan
    out["v0_source"] = "none"
    found = []
    for tier, (hs_max, wind_max) in enumerate(CALM_TIERS):
        calm = (out["hs_m"] < hs_max) & (wind < wind_max)
        g = out[calm].groupby("voyage_id")["stw_kn"].agg(["median", "size"])
        g = g[g["size"] >= CALM_MIN_FIXES]["median"]
        fill = out["voyage_id"].map(g)
        missing = out["v0_kn"].isna() & fill.notna()
        out.loc[missing, "v0_kn"] = fill[missing]
        out.loc[missing, "v0_source"] = "voyage" if tier == 0 else "voyage_moderate"
        found.append(g)
    per_voyage = out[out["v0_kn"].notna()].drop_duplicates("voyage_id")
    per_vessel = per_voyage.groupby("mmsi")["v0_kn"].median()
    fill = out["mmsi"].map(per_vessel)
    missing = out["v0_kn"].isna() & fill.notna()
    out.loc[missing, "v0_kn"] = fill[missing]
    out.loc[missing, "v0_source"] = "vessel"
    return out


def prepare(table: pd.DataFrame, particulars: pd.DataFrame | None = None,
            segment_s: float = SEGMENT_S) -> tuple[pd.DataFrame, pd.DataFrame, dict]:
    """Features, calm-water speed and target for a training table, per fix and per segment.

    Parameters
    ----------
    table : DataFrame
        From :func:`pipelines.storage.training.training_table`.
    particulars : DataFrame, optional
        Per MMSI ``length_m``, ``beam_m``, ``draught_m`` to use where AIS lacks them (the
        vessel profile's values).
    segment_s : float
        Length of the segments the model learns from (:func:`segments`).

    Returns
    -------
    (fixes, segments, dict)
        The fixes with a calm-water speed and their ``speed_ratio`` (the voluntary thresholds read
        them), the same averaged over segments (the model learns from them), and counts of what
        was left out: ``no_calm_speed`` fixes (no low-sea-state fixes on the voyage or the ship),
        ``fixes_in_short_segments``.
    """
    df = add_features(table)
    if particulars is not None and len(df):
        p = particulars.set_index("mmsi")
        for col in ("length_m", "beam_m", "draught_m"):
            if col in p:
                df[col] = df[col].where(df[col] > 0, df["mmsi"].map(p[col]))
    df = calm_water_speed(df)
    keep = df["v0_kn"].notna() & (df["v0_kn"] > 0)
    dropped = int((~keep).sum())
    fixes = df[keep].reset_index(drop=True)
    fixes["speed_ratio"] = fixes["stw_kn"] / fixes["v0_kn"]
    seg = segments(fixes, segment_s)
    short = len(fixes) - int(seg["n_fixes"].sum())
    seg["speed_ratio"] = seg["stw_kn"] / seg["v0_kn"]
    sources = fixes.drop_duplicates("voyage_id")["v0_source"].value_counts()
    return fixes, seg.reset_index(drop=True), {
        "no_calm_speed": dropped, "fixes_in_short_segments": short,
        "voyages_by_v0_source": {str(k): int(v) for k, v in sources.items()}}


def feature_matrix(df: pd.DataFrame) -> np.ndarray:
    """The model's input matrix (:data:`FEATURES`, float64; NaN where unknown)."""
    return np.column_stack([pd.to_numeric(df[c], errors="coerce").to_numpy(dtype=float) if c in df
                            else np.full(len(df), np.nan) for c in FEATURES])
