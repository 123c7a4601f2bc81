"""Involuntary speed loss in waves and wind: Bowditch/Mannarini, Aertssen, Khokhlov, Kwon, or none.

Every model takes the calm-water speed, the sea state (the significant wave height, or for Kwon
the 10 m wind speed) and the project's one encounter angle ``encounter_deg`` (0 = head seas /
wind from dead ahead, 180 = following, IMO MSC.1/Circ.1228 convention; see
:func:`encounter_angle_deg`) and returns the **speed loss** in knots (positive = slower). Each
formula converts to its own convention at its boundary:

* Bowditch/Mannarini and Aertssen are tabulated with theta = 0 for *following* seas:
  ``theta = (encounter_deg + 180) mod 360``.
* Khokhlov uses theta in radians with 0 = head seas, folded to [0, pi].
* Kwon tabulates head (0-30 deg), bow (30-60), beam (60-150) and following (150-180) weather,
  0 = head, folded to [0, 180].

Validity. Khokhlov's formula is published for 4 000-20 000 dwt and 9-20 kn: the ship enters
it through D·v0 only, at most 4.0e5 t·kn there; beyond D·v0 = 7.4e5 t·kn its last factor turns
negative and head seas would *speed the ship up*. The router refuses D·v0 above 4.0e5 and says
so when dwt or speed alone lies outside (:func:`khokhlov_check`). Kwon's table holds
for block coefficients 0.55-0.85 and where its speed-reduction coefficient C_U is positive
(:func:`routing.speed_loss_kwon.kwon_check`).

:func:`speed_loss` dispatches on the model name and applies the speed floor;
:func:`attained_speed_kn` returns the speed through the water after the loss;
:func:`max_attainable_speed_kn` bounds it from above (Khokhlov *raises* the speed in following
seas), which keeps the A* heuristic admissible.

All functions are vectorised: they accept scalars, ndarrays, pandas Series or xarray
DataArrays and return the type of ``hs_m``. NaN wave heights (land) give NaN.

References
----------
.. [1] M. Grifoll, C. Borén and M. Castells-Sanabra, "A comprehensive ship weather routing
       system using CMEMS products and A* algorithm," Ocean Eng., vol. 255, p. 111427, 2022,
       doi:10.1016/j.oceaneng.2022.111427 (Appendix I, Eqs. A1.1-A1.3, Tables A1.1-A1.2).
.. [2] G. Mannarini, N. Pinardi, G. Coppini, P. Oddo and A. Iafrati, "VISIR-I: small vessels -
       least-time nautical routes using wave forecasts," Geosci. Model Dev., vol. 9,
       pp. 1597-1625, 2016, doi:10.5194/gmd-9-1597-2016 (after N. Bowditch, *The American
       Practical Navigator*, Pub. No. 9, NIMA, 2002, Table 3705).
.. [3] W. Aertssen, "Service performance and seakeeping trials on a large container ship,"
       Trans. RINA, vol. 117, pp. 305-326, 1975; coefficients as tabulated by
       A. Maisiuk and I. Gribkovskaia, "Fleet sizing for offshore supply vessels with
       stochastic sailing and service times," Procedia Comput. Sci., vol. 31, pp. 939-948,
       2014, doi:10.1016/j.procs.2014.05.346.
.. [4] V. I. Lubkovsky (Khokhlov's formula), cited by Maisiuk and Gribkovskaia [3].
.. [5] WMO, *Manual on Marine Meteorological Services*, WMO-No. 558, 2012, Annex I
       (Beaufort scale: probable maximum wave heights 1.5, 2.5, 4, 5.5, 7.5 m for Beaufort 4-8).
.. [6] SIMROUTE Technical Manual, Universitat Politècnica de Catalunya, section 2 (Table 2:
       Aertssen sector edges).
.. [7] Y. J. Kwon, "Speed loss due to added resistance in wind and waves," The Naval Architect,
       RINA, pp. 14-16, Mar. 2008 (Tables 1-3: direction reduction coefficient, speed reduction
       coefficient, ship form coefficient); the tables as reproduced by R. Lu, O. Turan,
       E. Boulougouris, C. Banks and A. Incecik, "A semi-empirical ship operational performance
       prediction model for voyage optimization towards energy efficient shipping," Ocean Eng.,
       vol. 110, pp. 18-28, 2015, doi:10.1016/j.oceaneng.2015.07.042.
.. [8] WMO, *Manual on Marine Meteorological Services*, WMO-No. 558, Annex (Beaufort scale of
       wind force: equivalent 10 m wind speeds, lower limits 0.3, 1.6, 3.4, 5.5, 8.0, 10.8,
       13.9, 17.2, 20.8, 24.5, 28.5, 32.7 m/s for forces 1-12).
.. [9] stormlane ``/work/shared/ANCHORS.md`` (SIMROUTE's code as run on R6): Aertssen's Hs bands
       as SIMROUTE codes them, < 2.5 / 2.5-4 / 4-5.5 / 5.5-7.5 / >= 7.5 m.
"""

from __future__ import annotations

import warnings

import numpy as np

from thresholds.errors import StormlaneError
from thresholds.units import METRES_PER_FOOT

#: Names accepted by :func:`speed_loss`.
MODELS = ("bowditch", "aertssen", "khokhlov", "kwon", "none")
#: Models driven by the waves (``hs_m``) and by the wind (``wind_u_ms``/``wind_v_ms``).
WAVE_MODELS = ("bowditch", "aertssen", "khokhlov")
WIND_MODELS = ("kwon",)


class SpeedLossRangeError(StormlaneError, ValueError):
    """A speed-loss formula is asked outside the range it was published for (the router refuses)."""

# --- Bowditch / Mannarini: [1] Table A1.1, [2] -------------------------------------------------
#: f(theta) coefficients [kn/ft^2] for following, beam and head seas ([1], Table A1.1).
BOWDITCH_F_FOLLOWING_KN_FT2 = 0.0083
BOWDITCH_F_BEAM_KN_FT2 = 0.0165
BOWDITCH_F_HEAD_KN_FT2 = 0.0248

# --- Aertssen: [1] Table A1.2, [3], sector edges of [6] -----------------------------------------
#: Upper Hs bound of each Beaufort class 4..8 [m]: the WMO probable maximum wave heights [5],
#: which are the Hs column of [1] Table A1.2 for Beaufort 5..8. Hs <= 1.5 m (Beaufort <= 4) is
#: below the table: no loss. (Convention ``"wmo"``, ours.)
AERTSSEN_HS_UPPER_M = (1.5, 2.5, 4.0, 5.5, 7.5)
#: SIMROUTE's coded convention ``"simroute"`` [9]: the tabulated Hs of Beaufort 5..8 is the
#: *lower* edge of the class, Hs < 2.5 m gives no loss, Hs >= 7.5 m Beaufort 8. [m]
AERTSSEN_SIMROUTE_HS_LOWER_M = (2.5, 4.0, 5.5, 7.5)
#: Hs -> Beaufort conventions offered by :func:`aertssen_beaufort`.
AERTSSEN_BANDS = ("wmo", "simroute")
#: Encounter sector lower edges [deg, 0 = head seas]: head [0, 30), bow [30, 60), beam
#: [60, 150), following [150, 180] ([6] Table 2 converted with encounter = 180 - theta).
AERTSSEN_SECTOR_EDGES_DEG = (30.0, 60.0, 150.0)
#: m coefficients, rows head/bow/beam/following, columns Beaufort 5, 6, 7, 8 ([1] Table A1.2).
AERTSSEN_M = np.array(
    [
        [900.0, 1300.0, 2100.0, 3600.0],  # head      ([1]: theta 150-210)
        [700.0, 1000.0, 1400.0, 2300.0],  # bow
        [350.0, 500.0, 700.0, 1000.0],  # beam
        [100.0, 200.0, 400.0, 700.0],  # following ([1]: theta 0-30 / 330-360)
    ]
)
#: n coefficients [%], same layout as :data:`AERTSSEN_M`.
AERTSSEN_N = np.array(
    [
        [2.0, 6.0, 11.0, 18.0],
        [2.0, 5.0, 8.0, 12.0],
        [1.0, 3.0, 5.0, 7.0],
        [0.0, 1.0, 2.0, 3.0],
    ]
)

# --- Khokhlov: [1] Eq. A1.3, [4] ----------------------------------------------------------------
KHOKHLOV_A = 0.745  # [kn/m]
KHOKHLOV_B = 0.245  # [kn/(m rad)]
KHOKHLOV_C = 1.35e-6  # [1/(t kn)]
#: Validity of Khokhlov's formula ([1] Appendix I, SIMROUTE manual section 2): deadweight [t] and
#: calm-water (design) speed [kn].
KHOKHLOV_DWT_RANGE_T = (4000.0, 20000.0)
KHOKHLOV_SPEED_RANGE_KN = (9.0, 20.0)
#: Largest D·v0 inside that range (20 000 t x 20 kn): the factor 1 - 1.35e-6 D v0 stays >= 0.46.
#: It reaches 0 at D·v0 = 1 / 1.35e-6 = 7.41e5 t·kn and is negative beyond (head seas would speed
#: the ship up). [t·kn]
KHOKHLOV_DV_MAX = KHOKHLOV_DWT_RANGE_T[1] * KHOKHLOV_SPEED_RANGE_KN[1]

#: Default speed floor when neither ``floor_kn`` nor a vessel is given. [kn]
DEFAULT_FLOOR_KN = 2.0


class SpeedLossValidityWarning(UserWarning):
    """An input lies outside the range in which a speed-loss formula was fitted."""


def _wrap(result, like):
    """Return ``result`` in the container type of ``like`` (scalar, ndarray, Series, DataArray)."""
    if np.ndim(like) == 0 and np.ndim(result) == 0:
        return float(result)
    if hasattr(like, "dims") and hasattr(like, "copy"):  # xarray.DataArray, duck-typed
        return like.copy(data=np.broadcast_to(result, like.shape).copy())
    if hasattr(like, "index") and hasattr(like, "to_numpy"):  # pandas.Series
        return type(like)(np.broadcast_to(result, like.shape), index=like.index, name=getattr(like, "name", None))
    return np.asarray(result, dtype=float)


def _as_float(x):
    return np.asarray(getattr(x, "values", x), dtype=float)


def encounter_angle_deg(heading_deg, wave_from_deg):
    """Encounter angle between a ship's heading and the direction waves come from.

    Parameters
    ----------
    heading_deg : numeric
        Ship's heading (course through the water), clockwise from north. [deg]
    wave_from_deg : numeric
        Direction the waves come FROM, clockwise from north. [deg]

    Returns
    -------
    numeric
        ``(wave_from_deg - heading_deg) mod 360`` in [0, 360): 0 = head seas, 90 = waves
        from starboard, 180 = following seas. [deg]

    Examples
    --------
    >>> encounter_angle_deg(0.0, 0.0), encounter_angle_deg(90.0, 270.0)
    (0.0, 180.0)
    """
    alpha = np.mod(_as_float(wave_from_deg) - _as_float(heading_deg), 360.0)
    return _wrap(alpha, wave_from_deg if np.ndim(wave_from_deg) else heading_deg)


def _fold_deg(encounter_deg):
    """Encounter angle folded to [0, 180] (port and starboard are symmetric)."""
    a = np.mod(_as_float(encounter_deg), 360.0)
    return np.where(a > 180.0, 360.0 - a, a)


def _hs_valid(hs):
    """NaN for negative (invalid) wave heights; NaN stays NaN."""
    return np.where(hs >= 0.0, hs, np.nan)


def speed_loss_bowditch(speed_kn, hs_m, encounter_deg, sectors: str = "symmetric"):
    """Speed loss in waves after Bowditch as used by Mannarini et al. (VISIR) and SIMROUTE.

    ``v = v0 - f(theta) * H**2`` with H the significant wave height in feet and f in kn/ft^2
    ([1] Eq. A1.1, Table A1.1; the SIMROUTE manual's "H^5" is an OCR error).

    Parameters
    ----------
    speed_kn : numeric
        Calm-water speed v0 (unused by the formula; kept for a uniform signature). [kn]
    hs_m : numeric
        Significant wave height. [m]
    encounter_deg : numeric
        Encounter angle, 0 = head seas (see :func:`encounter_angle_deg`). [deg]
    sectors : {"symmetric", "printed"}
        The table of [1] is tabulated with theta = (encounter + 180) mod 360 (0 = following):
        f = 0.0083 for theta in [0, 45] and [270, 360], 0.0165 for (45, 135) and (225, 270),
        0.0248 for [135, 225]. ``"printed"`` uses these edges literally; ``"symmetric"``
        (default) mirrors the port-side edges (following [315, 360], beam (225, 315)), reading
        the printed 270 as a misprint since port and starboard seas load the hull alike.

    Returns
    -------
    numeric
        Speed loss f * H^2. [kn]

    Notes
    -----
    No validity range is published; the loss exceeds v0 in heavy head seas (16.1 kn at
    Hs = 7.8 m), which is what :func:`speed_loss`'s floor is for.

    Examples
    --------
    >>> round(speed_loss_bowditch(16.1, 3.048, 0.0), 4)  # 10 ft head seas
    2.48
    """
    hs = _hs_valid(_as_float(hs_m))
    theta = np.mod(_as_float(encounter_deg) + 180.0, 360.0)  # [1]: theta = 0 following seas
    if sectors == "symmetric":
        following = (theta <= 45.0) | (theta >= 315.0)
    elif sectors == "printed":
        following = (theta <= 45.0) | (theta >= 270.0)
    else:
        raise ValueError(f"unknown Bowditch sector table {sectors!r}; use 'symmetric' or 'printed'")
    head = (theta >= 135.0) & (theta <= 225.0)
    f = np.where(following, BOWDITCH_F_FOLLOWING_KN_FT2, np.where(head, BOWDITCH_F_HEAD_KN_FT2, BOWDITCH_F_BEAM_KN_FT2))
    h_ft = hs / METRES_PER_FOOT
    loss = f * h_ft**2  # [1], Eq. A1.1
    return _wrap(loss + 0.0 * _as_float(speed_kn), hs_m)


def aertssen_beaufort(hs_m, bands: str = "wmo"):
    """Beaufort class used to pick Aertssen's coefficients from the significant wave height.

    [1] Table A1.2 lists one Hs per Beaufort class (5: 2.5 m, 6: 4.0, 7: 5.5, 8: 7.5); which
    heights fall in a class is a convention:

    * ``"wmo"`` (ours): b is the smallest class whose WMO probable maximum wave height [5] is at
      least Hs: Hs <= 1.5 m -> 4 (below the table, no loss), (1.5, 2.5] -> 5, (2.5, 4.0] -> 6,
      (4.0, 5.5] -> 7, (5.5, 7.5] -> 8, above 7.5 m -> 9 (outside the table, Beaufort 8 used).
    * ``"simroute"`` (SIMROUTE's code [9]): the tabulated Hs is the class's lower edge:
      Hs < 2.5 m -> 4 (no loss), [2.5, 4) -> 5, [4, 5.5) -> 6, [5.5, 7.5) -> 7, >= 7.5 -> 8.

    The two agree on no band: SIMROUTE's code gives one class less for every Hs in (1.5, 7.5)
    outside the tabulated values. NaN -> 0.

    Examples
    --------
    >>> aertssen_beaufort(np.array([1.5, 2.5, 2.6, 7.5, 8.0])).tolist()
    [4, 5, 6, 8, 9]
    >>> aertssen_beaufort(np.array([1.5, 2.5, 2.6, 7.5, 8.0]), "simroute").tolist()
    [4, 5, 5, 8, 8]
    """
    hs = _as_float(hs_m)
    h = np.where(np.isnan(hs), 0.0, hs)
    if bands == "wmo":
        bn = 4 + np.searchsorted(np.asarray(AERTSSEN_HS_UPPER_M), h, side="left")
    elif bands == "simroute":
        bn = 4 + np.searchsorted(np.asarray(AERTSSEN_SIMROUTE_HS_LOWER_M), h, side="right")
    else:
        raise ValueError(f"unknown Aertssen Hs -> Beaufort convention {bands!r}; use one of {', '.join(AERTSSEN_BANDS)}")
    return np.where(np.isnan(hs), 0, bn).astype(int)


def aertssen_sector(encounter_deg):
    """Aertssen heading sector: 0 head [0, 30), 1 bow [30, 60), 2 beam [60, 150), 3 following [150, 180].

    The encounter angle is folded to [0, 180] first. Edges from the SIMROUTE manual [6]
    (Table 2, theta = 180 - encounter); [1] Table A1.2 prints other edges (bow 30-120,
    beam 120-150 from the bow), which would rank beam seas below bow seas over 90 degrees
    of heading: we keep Aertssen's own head/bow/beam/following split.
    """
    a = _fold_deg(encounter_deg)
    return np.searchsorted(np.asarray(AERTSSEN_SECTOR_EDGES_DEG), a, side="right").astype(int)


def speed_loss_aertssen(speed_kn, hs_m, encounter_deg, lpp_m, bands: str = "wmo"):
    """Speed loss in waves after Aertssen (1975).

    ``v = v0 - (m / Lpp + n) * v0 / 100`` ([1] Eq. A1.2) with m, n from [1] Table A1.2 by
    Beaufort class (:func:`aertssen_beaufort`, convention ``bands``) and heading sector
    (:func:`aertssen_sector`).

    Parameters
    ----------
    speed_kn : numeric
        Calm-water speed v0. [kn]
    hs_m : numeric
        Significant wave height. [m]
    encounter_deg : numeric
        Encounter angle, 0 = head seas. [deg]
    lpp_m : float
        Length between perpendiculars. [m]
    bands : {"wmo", "simroute"}
        Hs -> Beaufort convention, see :func:`aertssen_beaufort`.

    Returns
    -------
    numeric
        Speed loss. [kn]

    Notes
    -----
    Below Beaufort 5 (Hs <= 1.5 m; ``"simroute"``: Hs < 2.5 m) the table gives no loss. Above Hs = 7.5 m (Beaufort 9+)
    the Beaufort 8 coefficients are used and a :class:`SpeedLossValidityWarning` is issued.

    Examples
    --------
    >>> round(speed_loss_aertssen(16.1, 3.0, 0.0, 225.0), 4)  # Beaufort 6, head seas
    1.8962
    """
    lpp = float(lpp_m)
    if not lpp > 0:
        raise ValueError(f"Aertssen needs a positive length between perpendiculars, got lpp_m={lpp_m!r}")
    hs = _hs_valid(_as_float(hs_m))
    v0 = _as_float(speed_kn)
    bn = aertssen_beaufort(hs, bands)
    if np.any(bn > 8):
        warnings.warn(
            f"Aertssen: Hs above 7.5 m (max {np.nanmax(hs):.2f} m) is beyond Beaufort 8, the end of the "
            "table; using the Beaufort 8 coefficients",
            SpeedLossValidityWarning,
            stacklevel=2,
        )
    col = np.clip(bn - 5, 0, 3)
    sec = aertssen_sector(encounter_deg)
    sec, col = np.broadcast_arrays(sec, col)
    m = AERTSSEN_M[sec, col]
    n = AERTSSEN_N[sec, col]
    loss = np.where(bn >= 5, (m / lpp + n) * v0 / 100.0, 0.0)  # [1], Eq. A1.2
    loss = np.where(np.isnan(hs), np.nan, loss)
    return _wrap(loss, hs_m)


def _warn_khokhlov_range(v0, dwt):
    lo_d, hi_d = KHOKHLOV_DWT_RANGE_T
    lo_v, hi_v = KHOKHLOV_SPEED_RANGE_KN
    if not lo_d <= dwt <= hi_d:
        warnings.warn(
            f"Khokhlov: deadweight {dwt:g} t is outside the formula's range {lo_d:g}-{hi_d:g} t",
            SpeedLossValidityWarning,
            stacklevel=3,
        )
    v = v0[np.isfinite(v0)]
    if v.size and (v.min() < lo_v or v.max() > hi_v):
        warnings.warn(
            f"Khokhlov: speed {v.min():g}-{v.max():g} kn is outside the formula's range {lo_v:g}-{hi_v:g} kn",
            SpeedLossValidityWarning,
            stacklevel=3,
        )


def khokhlov_check(dwt_t: float, speed_kn: float, vessel_name: str = "") -> str | None:
    """Khokhlov's validity for the router: refuse where D·v0 exceeds the published range's.

    The formula is published for 4 000-20 000 dwt and 9-20 kn ([1] Appendix I, the SIMROUTE
    manual §2); the ship enters it only through D·v0, in the factor (1 - 1.35e-6 D v0), which over
    that range runs from 0.95 down to 0.46 (D·v0 = 20 000 t x 20 kn = 4.0e5 t·kn,
    :data:`KHOKHLOV_DV_MAX`). Beyond it the factor falls toward 0 (at 7.4e5) and below (head seas
    speeding the ship up): refused. A ship outside the dwt or speed range whose D·v0 stays within
    it keeps a factor the formula was fitted on: allowed, and the returned note (said in every
    output that used it) names the excursion. A ship below the range's smallest D·v0 (4 000 t x
    9 kn) has a factor above 0.95, tending to 1 (at most 5 % more loss than the smallest fitted
    ship): allowed, and the note says the factor lies above the fitted range and is extrapolated.

    Returns
    -------
    str or None
        A note when dwt or speed lies outside the published range (D·v0 within it), else None.

    Raises
    ------
    SpeedLossRangeError
        D·v0 above 4.0e5 t·kn, naming the vessel, its deadweight, speed, D·v0 and the factor, e.g.
        container-large (100 000 dwt, 19 kn: D·v0 = 1.9e6 t·kn, factor -1.56: 5 m head seas would
        raise its speed from 19 to 24.8 kn).

    Examples
    --------
    >>> khokhlov_check(8000.0, 16.1) is None  # SIMROUTE R6's ship: inside
    True
    >>> print(khokhlov_check(21000.0, 17.0))  # a feeder 5 % over the dwt range, D·v0 within it
    outside the published 4,000-20,000 dwt / 9-20 kn, D·v0 <= 4.00e+05 t·kn: factor 0.52 within its 0.46-0.95
    >>> print(khokhlov_check(300.0, 10.0))  # a 30 m trawler: below the smallest D·v0
    outside the published 4,000-20,000 dwt / 9-20 kn, D·v0 <= 4.00e+05 t·kn: factor 1.00 above its 0.46-0.95 (D·v0 = 3e+03 t·kn, below the range's 3.6e+04): the loss is extrapolated beyond the ships it was fitted on
    """
    dwt, v0 = float(dwt_t), float(speed_kn)
    lo_d, hi_d = KHOKHLOV_DWT_RANGE_T
    lo_v, hi_v = KHOKHLOV_SPEED_RANGE_KN
    dv = dwt * v0
    factor = 1.0 - KHOKHLOV_C * dv
    if dv > KHOKHLOV_DV_MAX:
        who = f"vessel {vessel_name}" if vessel_name else "the vessel"
        raise SpeedLossRangeError(
            f"Khokhlov's speed loss is published for {lo_d:,.0f}-{hi_d:,.0f} dwt and {lo_v:g}-{hi_v:g} kn "
            f"(D·v0 <= {KHOKHLOV_DV_MAX:.2e} t·kn; Grifoll et al. 2022, Appendix I): {who} has {dwt:,.0f} dwt at {v0:g} kn, "
            f"D·v0 = {dv:.3g} t·kn (factor 1 - 1.35e-6·D·v0 = {factor:.2f}"
            + ("; head seas would speed it up" if factor < 0 else "")
            + "); choose another --speed-loss model (bowditch, aertssen, kwon)"
        )
    if lo_d <= dwt <= hi_d and lo_v <= v0 <= hi_v:
        return None
    f_lo = 1.0 - KHOKHLOV_C * KHOKHLOV_DV_MAX
    f_hi = 1.0 - KHOKHLOV_C * lo_d * lo_v
    note = (f"outside the published {lo_d:,.0f}-{hi_d:,.0f} dwt / {lo_v:g}-{hi_v:g} kn, D·v0 <= {KHOKHLOV_DV_MAX:.2e} t·kn: "
            f"factor {factor:.2f}")
    if factor <= f_hi:
        return f"{note} within its {f_lo:.2f}-{f_hi:.2f}"
    # a small or slow ship: the factor tends to 1, a larger loss than for any ship it was fitted on
    return (f"{note} above its {f_lo:.2f}-{f_hi:.2f} (D·v0 = {dv:.3g} t·kn, below the range's {lo_d * lo_v:.3g}): "
            "the loss is extrapolated beyond the ships it was fitted on")


def speed_loss_khokhlov(speed_kn, hs_m, encounter_deg, dwt_t):
    """Speed loss in waves after Khokhlov (Lubkovsky 2009).

    ``v = v0 - (0.745 H - 0.245 theta H) (1 - 1.35e-6 D v0)`` ([1] Eq. A1.3) with theta in
    radians, 0 = head seas, folded to [0, pi], and D the deadweight in tonnes.

    Parameters
    ----------
    speed_kn : numeric
        Calm-water speed v0. [kn]
    hs_m : numeric
        Significant wave height. [m]
    encounter_deg : numeric
        Encounter angle, 0 = head seas. [deg]
    dwt_t : float
        Deadweight. [t]

    Returns
    -------
    numeric
        Speed loss [kn]; slightly *negative* (a gain of 0.0247 H (1 - 1.35e-6 D v0) kn) in
        following seas, where 0.245 pi > 0.745.

    Notes
    -----
    Valid for 4 000-20 000 dwt and 9-20 kn ([1] Appendix I); outside it a
    :class:`SpeedLossValidityWarning` is issued, and where D·v0 >= 1/1.35e-6 = 7.41e5 t·kn (the
    last factor <= 0: head seas would speed the ship up) the loss is NaN. The router refuses the
    formula where D·v0 exceeds the published range's (:func:`khokhlov_check`). Standard error about
    0.5 kn [3].

    Examples
    --------
    >>> round(speed_loss_khokhlov(16.1, 3.0, 0.0, 8000.0), 4)
    1.8464
    """
    dwt = float(dwt_t)
    hs = _hs_valid(_as_float(hs_m))
    v0 = _as_float(speed_kn)
    _warn_khokhlov_range(np.atleast_1d(v0), dwt)
    theta = np.deg2rad(_fold_deg(encounter_deg))  # [1]: radians, 0 = head seas
    factor = 1.0 - KHOKHLOV_C * dwt * v0
    if np.any(factor <= 0.0):
        warnings.warn(
            f"Khokhlov: D·v0 = {dwt * np.nanmax(v0):.3g} t·kn makes the factor 1 - 1.35e-6 D v0 non-positive "
            "(head seas would speed the ship up): loss is NaN there",
            SpeedLossValidityWarning,
            stacklevel=2,
        )
    loss = (KHOKHLOV_A * hs - KHOKHLOV_B * theta * hs) * factor  # [1], Eq. A1.3
    loss = np.where(factor > 0.0, loss, np.nan)
    return _wrap(loss, hs_m)


def speed_loss_none(speed_kn, hs_m, encounter_deg):
    """No speed loss: 0 kn wherever the wave height is known (NaN on land)."""
    hs = _as_float(hs_m)
    loss = np.where(np.isnan(hs), np.nan, 0.0) + 0.0 * _as_float(speed_kn) + 0.0 * _as_float(encounter_deg)
    return _wrap(loss, hs_m)


def is_learned(model) -> bool:
    """``model`` names a learned model (``"learned"`` or ``"learned:NAME"``): its speed comes from a
    :class:`routing.learned.LearnedSpeedTable`, not from a formula."""
    return str(model) == "learned" or str(model).startswith("learned:")


def _model_params(model, vessel, lpp_m, dwt_t, floor_kn):
    """The ship parameters a model needs (explicit values first, then the vessel's)."""
    if is_learned(model):
        floor_kn = vessel.min_speed_kn if (floor_kn is None and vessel is not None) else floor_kn
        return lpp_m, dwt_t, DEFAULT_FLOOR_KN if floor_kn is None else float(floor_kn)
    if model not in MODELS:
        raise ValueError(f"unknown speed-loss model {model!r}; choose one of {', '.join(MODELS)}")
    if vessel is not None:
        lpp_m = vessel.lpp_m if lpp_m is None else lpp_m
        dwt_t = vessel.dwt_t if dwt_t is None else dwt_t
        floor_kn = vessel.min_speed_kn if floor_kn is None else floor_kn
    if model == "aertssen" and lpp_m is None:
        raise ValueError("the Aertssen model needs lpp_m (or a vessel)")
    if model == "khokhlov" and dwt_t is None:
        raise ValueError("the Khokhlov model needs dwt_t (or a vessel)")
    return lpp_m, dwt_t, DEFAULT_FLOOR_KN if floor_kn is None else float(floor_kn)


def speed_loss(
    speed_kn,
    hs_m,
    encounter_deg,
    model: str = "bowditch",
    *,
    vessel=None,
    lpp_m: float | None = None,
    dwt_t: float | None = None,
    floor_kn: float | None = None,
    bowditch_sectors: str = "symmetric",
    aertssen_bands: str = "wmo",
    wind_ms=None,
    kwon=None,
    learned=None,
):
    """Speed loss by the named model, limited so the speed never drops below a floor.

    Parameters
    ----------
    speed_kn, hs_m, encounter_deg : numeric
        Calm-water speed [kn], significant wave height [m], encounter angle (0 = head) [deg];
        for Kwon the encounter angle of the wind.
    model : {"bowditch", "aertssen", "khokhlov", "kwon", "none"}
        Formula; unknown names raise ``ValueError``.
    vessel : thresholds.vessel.Vessel, optional
        Supplies ``lpp_m``, ``dwt_t``, the floor ``min_speed_kn`` and (Kwon) the hull form unless
        given explicitly.
    lpp_m, dwt_t : float, optional
        Length between perpendiculars [m] (Aertssen) and deadweight [t] (Khokhlov).
    aertssen_bands : {"wmo", "simroute"}
        Aertssen's Hs -> Beaufort convention (:func:`aertssen_beaufort`).
    wind_ms : numeric, optional
        10 m wind speed (Kwon; required there). [m/s]
    kwon : routing.speed_loss_kwon.KwonHull, optional
        Kwon's hull parameters; default from ``vessel``.
    floor_kn : float, optional
        Lowest speed through the water; default the vessel's ``min_speed_kn`` or 2 kn. SIMROUTE
        aborts ("Negative Ship speed") where Bowditch's loss exceeds v0; we keep steaming at
        the floor. [kn]
    bowditch_sectors : {"symmetric", "printed"}
        See :func:`speed_loss_bowditch`.
    learned : routing.learned.LearnedSpeedTable, optional
        The table of a learned model (``model`` ``"learned"`` or ``"learned:NAME"``, required
        then): loss ``v0 * (1 - ratio(Hs, encounter))``, the table's P50 ratio interpolated as the
        router does (:meth:`routing.learned.LearnedSpeedTable.ratio_at`). The ratio was tabulated at
        one calm-water speed; at another ``speed_kn`` the same ratio is applied (stated where used).

    Returns
    -------
    numeric
        Loss ``v0 - max(v, floor)``. [kn] (Negative for Khokhlov in following seas.)

    Examples
    --------
    >>> round(speed_loss(16.1, 9.0, 0.0, "bowditch", floor_kn=2.0), 6)  # 16.1 kn down to the floor
    14.1
    """
    lpp_m, dwt_t, floor = _model_params(model, vessel, lpp_m, dwt_t, floor_kn)
    if model == "bowditch":
        loss = speed_loss_bowditch(speed_kn, hs_m, encounter_deg, sectors=bowditch_sectors)
    elif model == "aertssen":
        loss = speed_loss_aertssen(speed_kn, hs_m, encounter_deg, lpp_m, bands=aertssen_bands)
    elif model == "khokhlov":
        loss = speed_loss_khokhlov(speed_kn, hs_m, encounter_deg, dwt_t)
    elif model == "kwon":
        from routing.speed_loss_kwon import KwonHull, speed_loss_kwon

        hull = kwon if kwon is not None else KwonHull.from_vessel(vessel) if vessel is not None else None
        if hull is None:
            raise ValueError("the Kwon model needs the hull (kwon=KwonHull(...) or a vessel)")
        if wind_ms is None:  # a caller without wind (e.g. a wave-only evaluation): unknown, said
            warnings.warn("Kwon: no wind speed given (wind_ms): loss NaN", SpeedLossValidityWarning, stacklevel=2)
            wind_ms = np.full(np.shape(_as_float(hs_m)), np.nan)
        loss = speed_loss_kwon(speed_kn, wind_ms, encounter_deg, hull)
    elif is_learned(model):
        if learned is None:
            raise ValueError(f"the speed-loss model {model!r} needs its table (learned=LearnedSpeedTable)")
        loss = _as_float(speed_kn) * (1.0 - learned.ratio_at(_as_float(hs_m), _as_float(encounter_deg)))
    else:
        loss = speed_loss_none(speed_kn, hs_m, encounter_deg)
    v0 = _as_float(speed_kn)
    raw = _as_float(loss)
    limited = np.where(np.isnan(raw), np.nan, np.minimum(raw, v0 - np.minimum(floor, v0)))
    return _wrap(limited, hs_m)


def attained_speed_kn(speed_kn, hs_m, encounter_deg, model: str = "bowditch", **kwargs):
    """Speed through the water after the wave loss and the floor: ``v0 - speed_loss(...)``. [kn]

    Examples
    --------
    >>> attained_speed_kn(16.1, 0.0, 0.0, "bowditch")
    16.1
    """
    loss = _as_float(speed_loss(speed_kn, hs_m, encounter_deg, model, **kwargs))
    return _wrap(_as_float(speed_kn) - loss, hs_m)


def max_attainable_speed_kn(speed_kn: float, model: str, *, hs_max_m: float, dwt_t: float | None = None) -> float:
    """Highest speed through the water any wave state up to ``hs_max_m`` can give. [kn]

    v0 for Bowditch, Aertssen, Kwon and none (they only slow the ship); for Khokhlov the loss
    ``(0.745 - 0.245 theta) H F`` with ``F = 1 - 1.35e-6 D v0`` ([1] Eq. A1.3) is most negative in
    following seas (theta = pi, a gain of ``(0.245 pi - 0.745) H F``) while F > 0, and in head
    seas (theta = 0, a gain of ``-0.745 H F``) when F < 0 (outside the formula's range, where
    the router refuses it); maximal at the largest H. Used as the A* heuristic's speed, so the
    heuristic never overestimates, for every input.

    Examples
    --------
    >>> round(max_attainable_speed_kn(16.1, "khokhlov", hs_max_m=5.0, dwt_t=8000.0), 4)
    16.202
    """
    if model not in MODELS:
        raise ValueError(f"unknown speed-loss model {model!r}; choose one of {', '.join(MODELS)}")
    v0 = float(speed_kn)
    if model != "khokhlov":
        return v0
    if dwt_t is None:
        raise ValueError("the Khokhlov model needs dwt_t")
    factor = 1.0 - KHOKHLOV_C * float(dwt_t) * v0
    per_m = max((KHOKHLOV_B * np.pi - KHOKHLOV_A) * factor, -KHOKHLOV_A * factor)  # theta = pi or 0
    return v0 + max(per_m * max(float(hs_max_m), 0.0), 0.0)
