"""Involuntary speed loss in wind and the waves it raises, after Kwon (2008).

Kwon's method gives the speed loss in percent of the calm-water speed as a product of three
tabulated coefficients ([1] Tables 1-3, as reproduced in [2])::

    dV / V1 [%] = C_beta(BN, weather direction) * C_U(Cb, loading, Fn) * C_Form(BN, displacement)

* **BN**, the Beaufort number of the true 10 m wind (:func:`beaufort_number`, WMO scale [3]);
* **C_beta**, the direction reduction coefficient ([1] Table 1), with the weather direction
  relative to the bow, 0 = head: head 0-30 deg ``2 C_beta = 2``; bow 30-60 deg
  ``2 C_beta = 1.7 - 0.03 (BN - 4)^2``; beam 60-150 deg ``2 C_beta = 0.9 - 0.06 (BN - 6)^2``;
  following 150-180 deg ``2 C_beta = 0.4 - 0.03 (BN - 8)^2``;
* **C_U**, the speed reduction coefficient ([1] Table 2): a quadratic in the Froude number
  ``Fn = V / sqrt(g L)`` per block coefficient Cb 0.55-0.85 and loading (normal/loaded rows for
  every Cb, ballast rows for Cb 0.75-0.85); between two tabulated Cb the coefficient is
  interpolated linearly (the table lists Cb in steps of 0.05);
* **C_Form**, the ship form coefficient ([1] Table 3), with the displacement volume V [m^3]:
  ``0.5 BN + BN^6.5 / (2.7 V^(2/3))`` for loaded ships (all but container ships),
  ``0.7 BN + BN^6.5 / (2.7 V^(2/3))`` in ballast, ``0.7 BN + BN^6.5 / (22 V^(2/3))`` for
  container ships (normal loading).

The weather direction is the wind's ("wind and waves from the same direction" in [1]); the
waves are not read: the Beaufort number stands for the wind and the sea it raises, so Kwon is
used alone, never added to a wave model. Negative table values (the fitted parabolas of C_beta
outside the Beaufort numbers they were fitted for, e.g. following seas below BN 5) are taken as
zero: the method describes losses, never gains, so the speed after Kwon's loss never exceeds v0.
A negative C_U (a Froude number beyond the table's fit for that Cb) is refused by
:func:`kwon_check`.

References
----------
.. [1] Y. J. Kwon, "Speed loss due to added resistance in wind and waves," The Naval Architect,
       RINA, pp. 14-16, Mar. 2008.
.. [2] R. Lu, O. Turan, E. Boulougouris, C. Banks and A. Incecik, "A semi-empirical ship
       operational performance prediction model for voyage optimization towards energy efficient
       shipping," Ocean Eng., vol. 110, pp. 18-28, 2015, doi:10.1016/j.oceaneng.2015.07.042
       (Kwon's Tables 1-3 reproduced; the Fn^2 terms are negative except for Cb = 0.85, as
       printed there; some public implementations print them all positive).
.. [3] WMO, *Manual on Marine Meteorological Services*, WMO-No. 558, Annex (Beaufort scale of
       wind force, equivalent 10 m wind speeds).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from routing.speed_loss import SpeedLossRangeError, SpeedLossValidityWarning, _as_float, _fold_deg, _wrap
from thresholds.units import GRAVITY_MS2, MS_PER_KN

#: Lower limits of Beaufort forces 1..12 (10 m wind) [3]. [m/s]
BEAUFORT_LOWER_MS = (0.3, 1.6, 3.4, 5.5, 8.0, 10.8, 13.9, 17.2, 20.8, 24.5, 28.5, 32.7)
#: Upper edges of Kwon's head, bow and beam sectors (following beyond) [1] Table 1. [deg, 0 = head]
KWON_SECTOR_EDGES_DEG = (30.0, 60.0, 150.0)
#: 2 C_beta = a - b (BN - c)^2 per sector (head, bow, beam, following) [1] Table 1.
KWON_DIRECTION = ((2.0, 0.0, 0.0), (1.7, 0.03, 4.0), (0.9, 0.06, 6.0), (0.4, 0.03, 8.0))
#: C_U = a + b Fn + c Fn^2 per block coefficient, normal (or loaded) condition [1] Table 2 / [2].
KWON_CU_NORMAL = {
    0.55: (1.7, -1.4, -7.4),
    0.60: (2.2, -2.5, -9.7),
    0.65: (2.6, -3.7, -11.6),
    0.70: (3.1, -5.3, -12.4),
    0.75: (2.4, -10.6, -9.5),
    0.80: (2.6, -13.1, -15.1),
    0.85: (3.1, -18.7, 28.0),
}
#: Ballast rows of the same table (Cb 0.75-0.85; below 0.75 the table has only the normal rows).
KWON_CU_BALLAST = {
    0.75: (2.6, -12.5, -13.5),
    0.80: (3.0, -16.3, -21.6),
    0.85: (3.4, -20.9, 31.8),
}
#: C_Form = a BN + BN^6.5 / (k V^(2/3)): (a, k) per hull form and loading [1] Table 3.
KWON_FORM = {"container": (0.7, 22.0), "loaded": (0.5, 2.7), "ballast": (0.7, 2.7)}
#: Block coefficients covered by the table.
KWON_CB_RANGE = (0.55, 0.85)
#: Loading conditions of the vessel profiles.
LOADINGS = ("loaded", "ballast")


def beaufort_number(wind_ms):
    """Beaufort force of a 10 m wind speed (WMO scale [3]): the number of lower limits it reaches.

    NaN gives 0.

    Examples
    --------
    >>> beaufort_number(np.array([0.0, 5.5, 7.9, 8.0, 17.1, 40.0])).tolist()
    [0, 4, 4, 5, 7, 12]
    """
    w = _as_float(wind_ms)
    return np.searchsorted(np.asarray(BEAUFORT_LOWER_MS), np.where(np.isnan(w), 0.0, w), side="right").astype(int)


def kwon_direction_coefficient(bn, encounter_deg):
    """C_beta of [1] Table 1 for Beaufort ``bn`` and the weather's encounter angle (0 = head),
    negative values taken as zero (see the module docstring).

    Examples
    --------
    >>> kwon_direction_coefficient(np.array([6, 6, 6, 6]), np.array([0.0, 45.0, 90.0, 180.0])).round(3).tolist()
    [1.0, 0.79, 0.45, 0.14]
    """
    a = _fold_deg(encounter_deg)
    sec = np.searchsorted(np.asarray(KWON_SECTOR_EDGES_DEG), a, side="left")  # edges belong to the sector below
    coef = np.asarray(KWON_DIRECTION)
    b = _as_float(bn)
    two_c = coef[sec, 0] - coef[sec, 1] * (b - coef[sec, 2]) ** 2  # [1] Table 1
    return np.maximum(two_c, 0.0) / 2.0


def kwon_speed_coefficient(cb: float, froude: float, loading: str = "loaded") -> float:
    """C_U of [1] Table 2, linear in Cb between the tabulated rows.

    Examples
    --------
    >>> round(kwon_speed_coefficient(0.60, 0.2), 4)   # 2.2 - 2.5 * 0.2 - 9.7 * 0.04
    1.312
    """
    if loading not in LOADINGS:
        raise ValueError(f"loading must be one of {', '.join(LOADINGS)}, got {loading!r}")
    rows = dict(KWON_CU_NORMAL)
    if loading == "ballast":
        rows.update(KWON_CU_BALLAST)
    lo, hi = KWON_CB_RANGE
    cb = float(cb)
    if not lo - 1e-12 <= cb <= hi + 1e-12:
        raise SpeedLossRangeError(f"Kwon's table covers block coefficients {lo:g}-{hi:g}, got Cb = {cb:g}")
    keys = sorted(rows)
    values = [rows[k][0] + rows[k][1] * froude + rows[k][2] * froude**2 for k in keys]  # [1] Table 2
    return float(np.interp(cb, keys, values))


def kwon_form_coefficient(bn, displacement_m3: float, form: str):
    """C_Form of [1] Table 3 for Beaufort ``bn`` and the displacement volume [m^3].

    Examples
    --------
    >>> round(float(kwon_form_coefficient(6, 20000.0, "container")), 2)  # 4.2 + 6^6.5 / (22 * 20000^(2/3))
    11.25
    """
    if form not in KWON_FORM:
        raise ValueError(f"Kwon hull form must be one of {', '.join(KWON_FORM)}, got {form!r}")
    a, k = KWON_FORM[form]
    b = _as_float(bn)
    return a * b + b**6.5 / (k * float(displacement_m3) ** (2.0 / 3.0))  # [1] Table 3


@dataclass(frozen=True)
class KwonHull:
    """What Kwon's method needs of a ship: block coefficient, length, displacement, hull form, loading."""

    cb: float
    lpp_m: float
    displacement_m3: float
    form: str  # "container", "loaded" or "ballast" (C_Form row)
    loading: str = "loaded"  # C_U rows

    def __post_init__(self):
        if self.form not in KWON_FORM:
            raise ValueError(f"Kwon hull form must be one of {', '.join(KWON_FORM)}, got {self.form!r}")
        if self.loading not in LOADINGS:
            raise ValueError(f"loading must be one of {', '.join(LOADINGS)}, got {self.loading!r}")
        if not (self.lpp_m > 0 and self.displacement_m3 > 0 and self.cb > 0):
            raise ValueError("Kwon's hull needs positive cb, lpp_m and displacement_m3")

    @classmethod
    def from_vessel(cls, vessel) -> "KwonHull":
        """From a :class:`thresholds.vessel.Vessel`: its ``block_coefficient``, ``lpp_m``,
        ``displacement_m3`` (default Cb·Lpp·B·T, the moulded volume) and ``loading``; container
        ships take the container row of C_Form."""
        cb = getattr(vessel, "block_coefficient", None)
        if cb is None:
            raise SpeedLossRangeError(
                f"the Kwon speed-loss model needs the block coefficient of vessel {vessel.name}: add block_coefficient to its profile"
            )
        loading = getattr(vessel, "loading", "loaded") or "loaded"
        disp = getattr(vessel, "displacement_m3", None) or cb * vessel.lpp_m * vessel.beam_m * vessel.draught_m
        form = "container" if vessel.vessel_class == "container" else loading
        return cls(float(cb), float(vessel.lpp_m), float(disp), form, loading)

    def froude(self, speed_kn: float) -> float:
        """Froude number V / sqrt(g Lpp)."""
        return float(speed_kn) * MS_PER_KN / math.sqrt(GRAVITY_MS2 * self.lpp_m)

    def speed_coefficient(self, speed_kn: float) -> float:
        return kwon_speed_coefficient(self.cb, self.froude(speed_kn), self.loading)

    def form_terms(self) -> tuple[float, float]:
        """(a, b) of C_Form = a BN + b BN^6.5."""
        a, k = KWON_FORM[self.form]
        return a, 1.0 / (k * self.displacement_m3 ** (2.0 / 3.0))


def kwon_check(hull: KwonHull, speed_kn: float, vessel_name: str = "") -> float:
    """C_U of the ship at ``speed_kn``; refuses a Cb outside 0.55-0.85 or a non-positive C_U.

    Raises
    ------
    SpeedLossRangeError
        Naming the vessel, Cb, Froude number and C_U.
    """
    who = f"vessel {vessel_name}" if vessel_name else "the vessel"
    try:
        cu = hull.speed_coefficient(speed_kn)
    except SpeedLossRangeError as err:
        raise SpeedLossRangeError(f"{who}: {err}") from None
    if not cu > 0.0:
        raise SpeedLossRangeError(
            f"Kwon's speed reduction coefficient C_U is {cu:.3f} <= 0 for {who} (Cb {hull.cb:g}, {hull.loading}, "
            f"Fn {hull.froude(speed_kn):.3f} at {speed_kn:g} kn): the table's fit does not reach that Froude number"
        )
    return cu


def speed_loss_kwon(speed_kn, wind_ms, encounter_deg, hull: KwonHull):
    """Speed loss after Kwon [1]: ``v0 * C_beta * C_U * C_Form / 100``. [kn]

    Parameters
    ----------
    speed_kn : numeric
        Calm-water speed v0 (also sets the Froude number). [kn]
    wind_ms : numeric
        True 10 m wind speed. [m/s]
    encounter_deg : numeric
        Direction the wind comes from relative to the bow, 0 = head wind. [deg]
    hull : KwonHull

    Returns
    -------
    numeric
        Speed loss, >= 0 (NaN where the wind is NaN). [kn]

    Examples
    --------
    >>> hull = KwonHull(0.60, 225.0, 30000.0, "container")
    >>> round(speed_loss_kwon(16.1, 14.0, 0.0, hull), 3)   # Beaufort 7, head wind: 16.1 * 1.458 * 19.55 %
    4.589
    """
    v0 = _as_float(speed_kn)
    w = _as_float(wind_ms)
    bn = beaufort_number(w)
    cu = np.vectorize(lambda v: kwon_speed_coefficient(hull.cb, hull.froude(v), hull.loading))(v0) if np.ndim(v0) else hull.speed_coefficient(float(v0))
    if np.any(np.asarray(cu) <= 0.0):
        warnings.warn("Kwon: C_U <= 0 beyond the table's Froude numbers; taken as 0 (no loss)", SpeedLossValidityWarning, stacklevel=2)
    pct = kwon_direction_coefficient(bn, encounter_deg) * np.maximum(cu, 0.0) * kwon_form_coefficient(bn, hull.displacement_m3, hull.form)
    loss = np.where(np.isnan(w), np.nan, v0 * pct / 100.0)  # [1]: dV/V1 in percent
    return _wrap(loss, wind_ms)
