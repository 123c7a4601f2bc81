"""Where and when does the weather break the limits? Shares of unsafe sea cells per time step.

:func:`exceedance_by_time` applies a vessel's operator profile and the IMO rules
(:func:`thresholds.safety.assess`) to every sea cell of a canonical grid and counts, per time step,
the sea cells that break any rule and each rule separately. Without headings only the
heading-free rules run (Hs, wind, period; successive high waves needs the encounter period, so a
heading, MSC.1/Circ.1228 4.2.2.2) — the answer to "where is the sea too rough whatever the
course"; with headings a cell counts as unsafe when **no** heading of the set is safe there.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import xarray as xr

from thresholds.assessment import REASON_BITS
from thresholds.safety import assess, safe_cell_mask

_FIELDS = ("hs_m", "wave_from_deg", "tp_s", "tm_s", "wind_u_ms", "wind_v_ms")


def _fields(ds: xr.Dataset) -> dict:
    return {k: ds[k].values for k in _FIELDS if k in ds.data_vars}


def exceedance_by_time(ds: xr.Dataset, vessel, profile, headings_deg=None, missing: str = "skip") -> tuple[pd.DataFrame, tuple]:
    """Per time step: sea cells, unsafe cells and their share, and cells per rule.

    Parameters
    ----------
    ds : xarray.Dataset
        Canonical weather with ``hs_m`` (sea = finite ``hs_m``).
    vessel : Vessel
    profile : OperatorProfile or OperatorLimits
    headings_deg : array_like, optional
        Candidate courses; None = heading-free rules only.
    missing : {"skip", "raise"}
        Rules whose variable the data lack are skipped (and listed) or raise.

    Returns
    -------
    (DataFrame, tuple)
        Index ``time_utc`` (tz-aware UTC); columns ``n_sea``, ``n_unsafe``, ``unsafe_frac`` and
        ``n_<rule>`` per evaluated rule plus ``n_no_data`` (sea cells lacking
        an input of an evaluated rule); and the rules that were skipped, with the reason.

    Raises
    ------
    weather.errors.CoverageError
        The data lack ``hs_m``.
    """
    if "hs_m" not in ds:
        from weather.errors import CoverageError

        raise CoverageError(f"{ds.attrs.get('product', 'the weather')}: variable hs_m (significant wave height) is missing; "
                            f"exceedance needs it to tell sea from land (the data hold {', '.join(map(str, ds.data_vars)) or 'nothing'})")
    sea = np.isfinite(ds["hs_m"].values)
    f = _fields(ds)
    if headings_deg is None:
        a = assess(vessel, profile, missing=missing, **f)
        code = np.broadcast_to(a.reason_code, sea.shape)
        skipped = a.skipped
        evaluated = list(a.rules)
    else:
        _, reason = safe_cell_mask(vessel, profile, headings_deg, missing=missing, **f)
        # a cell is unsafe when every heading is; its reasons are those met on any heading
        unsafe_all = (reason != 0).all(axis=0)
        code = np.where(unsafe_all, np.bitwise_or.reduce(reason, axis=0), 0)
        probe = assess(vessel, profile, missing=missing, heading_deg=0.0, **{k: v[:1] for k, v in f.items()})
        skipped, evaluated = probe.skipped, list(probe.rules)
    code = np.where(sea, code, 0).astype(np.uint16)
    n_sea = sea.reshape(sea.shape[0], -1).sum(axis=1)
    unsafe = (code != 0) & sea
    n_unsafe = unsafe.reshape(sea.shape[0], -1).sum(axis=1)
    out = {"n_sea": n_sea, "n_unsafe": n_unsafe}
    with np.errstate(invalid="ignore", divide="ignore"):
        out["unsafe_frac"] = np.where(n_sea > 0, n_unsafe / n_sea, np.nan)
    for name, bit in REASON_BITS.items():
        if name in evaluated or name == "no_data":
            hits = ((code & bit) != 0) & sea
            out[f"n_{name}"] = hits.reshape(sea.shape[0], -1).sum(axis=1)
    index = pd.DatetimeIndex(ds.time_utc.values, name="time_utc").tz_localize("UTC")
    return pd.DataFrame(out, index=index), tuple(skipped)
