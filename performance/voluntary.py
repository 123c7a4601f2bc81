"""The sea states in which masters of each ship class actually slow down, read from AIS.

No published formula holds the voluntary part of the speed loss: masters take speed off to limit
slamming, green water, propeller racing and accelerations (A. R. J. M. Lloyd, *Seakeeping: Ship
Behaviour in Rough Weather*, 1989, ch. 14), each by their own judgement. In AIS it shows as a
**step**: the involuntary loss grows smoothly with Hs (by 1-5 % of the speed per metre at
moderate Hs: Aertssen's table, Grifoll et al. 2022, Table A1.2), and where masters intervene the
speed falls several times faster, over a few tenths of a metre of Hs.

For each class and heading sector (head to bow 0-60 deg, beam 60-120, following 120-180; the
encounter angle folded), :func:`step` bins the fixes by Hs (:data:`BIN_M` bins holding at least
:data:`MIN_BIN_FIXES` fixes), takes the median speed ratio and the median Hs of each bin, and the
rate at which the median falls between neighbouring bins. The steepest fall is a voluntary
slow-down when

* it falls at least :data:`MIN_RATE_FRAC_PER_M` of the speed per metre of Hs, and at least
  :data:`TREND_FACTOR` times the median rate between the other bins (the smooth trend);
* it takes at least :data:`MIN_DROP_FRAC` of the speed; and
* it lasts: at least one bin lies above it and every bin above keeps at least half of that fall;
* the fixes above it come from at least :data:`MIN_VOYAGES_ABOVE` voyages (one voyage's
  master is an anecdote, not the class).

The threshold is the middle of the step (between the two bins' median Hs), reported with the
two ends, which bound it: where the data thin out (few ships cross heavy seas) the interval says
how well AIS pins it down. A sector without such a step says why (too few heavy-sea fixes, or no
step). These are evidence for the operator beside the configured limits, not a replacement of them.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

#: Heading sectors (folded encounter angle, degrees, [lo, hi)); the first is the class's threshold.
SECTORS = {"head-bow": (0.0, 60.0), "beam": (60.0, 120.0), "following": (120.0, 180.01)}
BIN_M = 0.25
MIN_BIN_FIXES = 20
MIN_RATE_FRAC_PER_M = 0.15
TREND_FACTOR = 3.0
MIN_DROP_FRAC = 0.03
MIN_VOYAGES_ABOVE = 2


def _bins(hs: np.ndarray, y: np.ndarray) -> pd.DataFrame:
    b = np.floor(hs / BIN_M).astype(int)
    g = pd.DataFrame({"b": b, "h": hs, "y": y}).groupby("b").agg(h=("h", "median"), y=("y", "median"), n=("y", "size"))
    return g[g["n"] >= MIN_BIN_FIXES].reset_index(drop=True)


def step(hs_m, ratio, voyage=None) -> dict:
    """The voluntary step of one class and sector (module notes).

    Returns
    -------
    dict
        ``threshold_hs_m`` (None when no step), ``from_hs_m`` / ``to_hs_m`` (the step's ends),
        ``drop_frac`` (speed the step takes off), ``rate_frac_per_m``, ``trend_frac_per_m``,
        ``fixes``, ``fixes_above``, ``max_hs_m``, ``bins`` and ``why`` when no step is reported.
    """
    hs = np.asarray(hs_m, dtype=float)
    y = np.asarray(ratio, dtype=float)
    ok = np.isfinite(hs) & np.isfinite(y)
    hs, y = hs[ok], y[ok]
    voy = np.arange(hs.size) if voyage is None else np.asarray(voyage, dtype=object)[ok]
    out = {"threshold_hs_m": None, "from_hs_m": None, "to_hs_m": None, "drop_frac": None, "rate_frac_per_m": None,
           "trend_frac_per_m": None, "fixes": int(hs.size), "fixes_above": 0,
           "max_hs_m": float(hs.max()) if hs.size else None}
    g = _bins(hs, y)
    out["bins"] = int(len(g))
    if len(g) < 4:
        top = float(g["h"].max()) if len(g) else 0.0
        out["why"] = f"too few fixes in heavy seas (bins of {MIN_BIN_FIXES}+ fixes reach Hs {top:.1f} m)"
        return out
    h, med = g["h"].to_numpy(), g["y"].to_numpy()
    rate = (med[:-1] - med[1:]) / np.maximum(h[1:] - h[:-1], 1e-6)
    k = int(np.argmax(rate))
    trend = float(np.median(np.delete(rate, k)))
    drop = float(med[k] - med[k + 1])
    lasts = k + 2 < len(g) and bool(np.all(med[k + 1:] <= med[k] - 0.5 * drop))
    voyages_above = len(set(voy[hs >= h[k + 1]]))
    out.update({"from_hs_m": float(round(h[k], 2)), "to_hs_m": float(round(h[k + 1], 2)), "drop_frac": drop,
                "rate_frac_per_m": float(rate[k]), "trend_frac_per_m": trend})
    out["voyages_above"] = int(voyages_above)
    if (rate[k] >= MIN_RATE_FRAC_PER_M and rate[k] >= TREND_FACTOR * max(trend, 0.0) and drop >= MIN_DROP_FRAC and lasts
            and voyages_above >= MIN_VOYAGES_ABOVE):
        mid = 0.5 * (h[k] + h[k + 1])
        out["threshold_hs_m"] = float(round(mid, 2))
        out["fixes_above"] = int((hs >= mid).sum())
    else:
        out["why"] = (f"no voluntary step (steepest fall {100 * rate[k]:.1f} %/m between Hs {h[k]:.1f} and {h[k + 1]:.1f} m, "
                      f"trend {100 * trend:.1f} %/m, {100 * drop:.1f} % of the speed{'' if lasts else ', not lasting'}, "
                      f"{voyages_above} voyage(s) above)")
    return out


def voluntary_thresholds(df: pd.DataFrame) -> list[dict]:
    """Per class and heading sector, the Hs above which AIS shows voluntary speed reduction.

    ``df`` holds ``mmsi``, ``voyage_id``, ``ship_class``, ``encounter_deg`` (folded), ``hs_m`` and
    ``speed_ratio`` per fix.
    """
    rows = []
    for cls in sorted(df["ship_class"].unique()):
        sub = df[df["ship_class"] == cls]
        enc = sub["encounter_deg"].to_numpy(dtype=float)
        for sector, (lo, hi) in SECTORS.items():
            m = (enc >= lo) & (enc < hi)
            got = step(sub["hs_m"].to_numpy(float)[m], sub["speed_ratio"].to_numpy(float)[m],
                       sub["voyage_id"].to_numpy(dtype=object)[m] if "voyage_id" in sub else None)
            rows.append({"ship_class": str(cls), "sector": sector, "encounter_deg": [lo, min(hi, 180.0)],
                         "vessels": int(sub.loc[m, "mmsi"].nunique()), **got})
    return rows
