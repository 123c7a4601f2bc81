"""Nightly stage 3, screen: lanes x departures x weather in DuckDB, thresholds at every centroid."""

from __future__ import annotations

import numpy as np
import pandas as pd

from pipelines.nightly.night import Night

def _headings(points: pd.DataFrame) -> np.ndarray:
    """Course at each point: towards the next point of its path (the last: from the previous)."""
    from thresholds.geodesy import initial_bearing_deg

    p = points
    same_next = p["path_id"].shift(-1) == p["path_id"]
    same_prev = p["path_id"].shift(1) == p["path_id"]
    lat, lon = p["lat_deg"].to_numpy(float), p["lon_deg"].to_numpy(float)
    nlat, nlon = np.roll(lat, -1), np.roll(lon, -1)
    plat, plon = np.roll(lat, 1), np.roll(lon, 1)
    fwd = np.asarray(initial_bearing_deg(lat, lon, nlat, nlon), dtype=float)
    back = np.asarray(initial_bearing_deg(plat, plon, lat, lon), dtype=float)
    return np.where(same_next.to_numpy(), fwd, np.where(same_prev.to_numpy(), back, np.nan))


def _fmt_rule(name: str, value: float, limit: float, unit: str) -> str:
    labels = {"hs": ("Hs", "m"), "wind": ("wind", "m/s"), "period": ("wave period", "s"), "beam_seas": ("encounter", "deg"),
              "surf_riding": ("speed", "kn"), "high_waves": ("Hs", "m"), "synchronous_roll": ("T_E", "s"),
              "parametric_roll": ("T_E", "s")}
    what, u = labels.get(name, (name, unit))
    v = f"{value:.1f}" if np.isfinite(value) else "?"
    lim = f" (limit {limit:.1f} {u})" if np.isfinite(limit) else ""
    return f"{what} {v} {u}{lim}"


def screen_departures(night: Night) -> pd.DataFrame:
    """The adverse-weather screen of every lane-departure (pure step; DuckDB in memory).

    Returns
    -------
    DataFrame
        One row per (``path_id``, ``depart_utc``): ``n_points``, ``n_points_no_weather``
        (beyond the forecast, on the weather's land cells, or off the grid), of them
        ``n_points_beyond_weather`` (timed outside the weather's time span: no rule can fire there,
        so a departure screened ``ok`` with such points was screened on its part with weather
        only; the night says so), ``adverse``,
        ``rules`` (rule names, sorted), ``reasons`` (per rule: the worst centroid, its value
        against the limit, time and place), ``max_hs_m`` and the worst point, ``error`` (a path
        that could not be screened at all).
    """
    from pipelines.storage import open_workspace
    from pipelines.storage.weather import join_points_weather, load_weather
    from thresholds.safety import assess

    rows = []
    frames, deps = [], []
    for p in night.paths:
        if p.error or len(p.centroids) < 2:
            err = p.error or f"lane {p.lane_id} has {len(p.centroids)} centroid(s); at least 2 are needed"
            rows += [{"path_id": p.path_id, "depart_utc": t, "n_points": len(p.centroids), "n_points_no_weather": len(p.centroids),
                      "n_points_beyond_weather": 0, "adverse": False, "rules": [], "reasons": [], "max_hs_m": np.nan, "worst_time_utc": None,
                      "worst_lat_deg": np.nan, "worst_lon_deg": np.nan, "error": err} for t in night.path_departures(p)]
            continue
        c = p.centroids.assign(path_id=p.path_id)
        speed = c["speed_kn"].astype(float)
        v0 = night.vessels[p.vessel_profile].speed_kn
        c["speed_kn"] = speed.where(np.isfinite(speed) & (speed > 0), v0)
        frames.append(c[["path_id", "seq", "lat_deg", "lon_deg", "speed_kn"]])
        deps += [{"path_id": p.path_id, "departure_utc": t} for t in night.path_departures(p)]
    if frames:
        points = pd.concat(frames, ignore_index=True).sort_values(["path_id", "seq"], kind="stable").reset_index(drop=True)
        points["heading_deg"] = _headings(points)
        with open_workspace(":memory:") as mem:
            load_weather(mem, night.weather_ds, name="nightly")
            joined = join_points_weather(mem, points.drop(columns="heading_deg"), pd.DataFrame(deps), grid="nightly", on_missing="flag")
        joined = joined.merge(points[["path_id", "seq", "heading_deg"]], on=["path_id", "seq"], how="left")
        fired_cols = {}
        joined["fired_any"] = False
        vessel_of = {p.path_id: p.vessel_profile for p in night.paths}
        joined["vessel"] = joined["path_id"].map(vessel_of)
        detail = {}
        for prof, idx in joined.groupby("vessel").groups.items():
            g = joined.loc[idx]
            w = {k: g[k].to_numpy(dtype=float) for k in ("hs_m", "wave_from_deg", "tp_s", "tm_s", "wind_u_ms", "wind_v_ms") if k in g}
            a = assess(night.vessels[prof], night.limits, heading_deg=g["heading_deg"].to_numpy(float),
                       speed_kn=g["speed_kn"].to_numpy(float), missing="skip", **w)
            for name, r in a.rules.items():
                f = np.broadcast_to(np.asarray(r.fired, dtype=bool), (len(g),))
                fired_cols.setdefault(name, pd.Series(False, index=joined.index))
                fired_cols[name].loc[idx] = f
                detail[name] = detail.get(name, []) + [pd.DataFrame({
                    "margin": np.broadcast_to(np.asarray(r.margin, float), (len(g),)),
                    "value": np.broadcast_to(np.asarray(r.value, float), (len(g),)),
                    "limit": np.broadcast_to(np.asarray(r.limit, float), (len(g),)),
                    "unit": r.margin_unit}, index=idx)]
        for name, s in fired_cols.items():
            joined[f"fired_{name}"] = s.to_numpy()
            joined["fired_any"] |= s.to_numpy()
        details = {name: pd.concat(parts).sort_index() for name, parts in detail.items()}
        for (pid, dep), g in joined.groupby(["path_id", "departure_utc"], sort=True):
            ok = (g["status"] == "ok").to_numpy()
            hs = g["hs_m"].to_numpy(dtype=float)
            row = {"path_id": pid, "depart_utc": pd.Timestamp(dep), "n_points": len(g), "n_points_no_weather": int((~ok).sum()),
                   "n_points_beyond_weather": int((g["status"] == "outside_time").sum()), "adverse": bool(g["fired_any"].any()), "rules": [], "reasons": [], "max_hs_m": np.nan, "worst_time_utc": None,
                   "worst_lat_deg": np.nan, "worst_lon_deg": np.nan, "error": None}
            if np.isfinite(hs).any():
                k = int(np.nanargmax(hs))
                row.update(max_hs_m=float(hs[k]), worst_time_utc=pd.Timestamp(g["eta_utc"].iloc[k]),
                           worst_lat_deg=float(g["lat_deg"].iloc[k]), worst_lon_deg=float(g["lon_deg"].iloc[k]))
            else:
                row["error"] = (f"no weather at any of the {len(g)} centroids of this departure "
                                f"({', '.join(sorted(set(g['status'])))}); the lane lies outside the weather grid or time span")
            for name in sorted(fired_cols):
                f = g[f"fired_{name}"].to_numpy()
                if not f.any():
                    continue
                d = details[name].loc[g.index[f]]
                j = int(np.nanargmax(d["margin"].to_numpy())) if np.isfinite(d["margin"].to_numpy()).any() else 0
                at = g.loc[d.index[j]]
                row["rules"].append(name)
                row["reasons"].append({
                    "rule": name, "text": f"{name}: {_fmt_rule(name, d['value'].iloc[j], d['limit'].iloc[j], d['unit'].iloc[j])} at "
                                          f"{pd.Timestamp(at['eta_utc']):%Y-%m-%dT%H:%MZ}, {at['lat_deg']:.2f}N {at['lon_deg']:.2f}E",
                    "n_points": int(f.sum()), "seq": int(at["seq"]), "time_utc": pd.Timestamp(at["eta_utc"]).isoformat(),
                    "value": float(d["value"].iloc[j]), "limit": float(d["limit"].iloc[j]),
                })
            rows.append(row)
    out = pd.DataFrame(rows, columns=["path_id", "depart_utc", "n_points", "n_points_no_weather", "n_points_beyond_weather", "adverse",
                                      "rules", "reasons", "max_hs_m", "worst_time_utc", "worst_lat_deg", "worst_lon_deg", "error"])
    out["depart_utc"] = pd.to_datetime(out["depart_utc"], utc=True)
    return out.sort_values(["path_id", "depart_utc"], kind="stable").reset_index(drop=True)
