"""The published speed-loss formulas on the training fixes: the prior and the yardstick.

Every formula of :mod:`routing.speed_loss` that needs only waves (Bowditch, Aertssen, Khokhlov;
and any further wave model in ``routing.speed_loss.MODELS`` taking the same arguments) predicts
the speed through the water of each fix from the same inputs the learned model gets: the
voyage's calm-water speed ``v0_kn``, Hs and the encounter angle. Each ship enters with the
particulars of its vessel profile (the house rule, :mod:`pipelines.vessels`: Lpp for Aertssen,
deadweight for Khokhlov, the speed floor), as the router, the audit and the nightly run use them.

A formula outside its published range (Khokhlov: 4 000-20 000 dwt, 9-20 kn) still predicts
here, so that every model is scored on exactly the same fixes; :func:`formula_speeds` returns
the share of fixes outside each formula's range, and the validation tables print it.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from routing import speed_loss as sl

#: The wave formulas scored, in the order tables show them.
WAVE_FORMULAS = tuple(m for m in ("bowditch", "aertssen", "khokhlov") if m in sl.MODELS)


def formula_speeds(df: pd.DataFrame, ships: pd.DataFrame) -> tuple[pd.DataFrame, dict]:
    """Speed through the water by each formula at each fix. [kn]

    Parameters
    ----------
    df : DataFrame
        ``mmsi``, ``v0_kn``, ``hs_m``, ``encounter_deg`` per fix.
    ships : DataFrame
        Per ``mmsi``: ``lpp_m``, ``dwt_t``, ``min_speed_kn`` (the vessel profile's values).

    Returns
    -------
    (DataFrame, dict)
        One column ``speed_<formula>_kn`` per formula (index of ``df``), and the share of fixes
        outside each formula's validity range.
    """
    out = pd.DataFrame(index=df.index)
    outside = {}
    p = ships.set_index("mmsi")
    for name in WAVE_FORMULAS:
        col = np.full(len(df), np.nan)
        n_out = 0
        for mmsi, idx in df.groupby("mmsi").indices.items():
            sub = df.iloc[idx]
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", sl.SpeedLossValidityWarning)
                loss = sl.speed_loss(sub["v0_kn"].to_numpy(float), sub["hs_m"].to_numpy(float),
                                     sub["encounter_deg"].to_numpy(float), name,
                                     lpp_m=float(p.at[mmsi, "lpp_m"]), dwt_t=float(p.at[mmsi, "dwt_t"]),
                                     floor_kn=float(p.at[mmsi, "min_speed_kn"]))
            if any(issubclass(w.category, sl.SpeedLossValidityWarning) for w in caught):
                n_out += len(idx)
            col[idx] = sub["v0_kn"].to_numpy(float) - np.asarray(loss, float)
        out[f"speed_{name}_kn"] = col
        outside[name] = n_out / max(len(df), 1)
    return out, outside


def prior_ratio_for(name: str, df: pd.DataFrame, *, lpp_m: float, dwt_t: float, floor_kn: float) -> np.ndarray:
    """One formula's speed as a share of ``v0_kn`` at rows of ``v0_kn``, ``hs_m``, ``encounter_deg``
    for one ship (the residual model's prior on a grid: :mod:`performance.tabulate`)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sl.SpeedLossValidityWarning)  # scored on every row, as in training
        v0 = df["v0_kn"].to_numpy(float)
        loss = sl.speed_loss(v0, df["hs_m"].to_numpy(float), df["encounter_deg"].to_numpy(float), name, lpp_m=lpp_m,
                             dwt_t=dwt_t, floor_kn=floor_kn)
    return (v0 - np.asarray(loss, float)) / v0
