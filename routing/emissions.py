"""STEAM2 fuel consumption and exhaust emissions along a route, with the wave power increase.

The model follows the SIMROUTE paper's Appendix III and the SIMROUTE technical manual §4, which
implement STEAM2 [1]_ [2]_ with the power increase needed in waves [3]_. It is written here from
the published formulas; the SIMROUTE emission script has four defects that this module avoids
(observed on its R6 case, see ``ANCHORS.md``):

1. **Engine load counted twice.** SIMROUTE sums ``P_new · EL_new · EF · Δt`` (paper Eq. A3.2);
   the power ``P_new`` already *is* the engine output, so multiplying it by the load again scales
   every emission by EL (≈ 0.2–0.5 on short-sea routes) and by a different factor on each route.
   Here every pollutant is ``P_new · EF · Δt`` (STEAM2 [2]_, Eq. 1 of [1]_).
2. **0.445 instead of 0.455** in the relative SFOC parabola (paper Eq. A3.4; STEAM2 and the
   paper's own Table A3.2 and manual §4 give 0.455). At EL = 0.8 the typo lowers SFOC by 0.6 %.
3. **Baseline at design power.** SIMROUTE adds the wave increase to ``EL · P_installed`` (the
   power at *design* speed) instead of to the power at the speed actually sailed,
   ``P(v) = EL · P_installed · (v / v_design)³`` [1]_. At 16.1 kn against a 25 kn design speed
   that overstates the baseline 3.7-fold.
4. **The weather charged twice.** SIMROUTE adds the increase that would restore the calm-water
   speed, ``ΔP = k·(v0³ − v³)``, to that fixed baseline *and* sums over the longer time of the
   slowed ship, so a storm costs both extra power and extra hours. Here the power on a leg is the
   power that makes the leg's own speed in the leg's waves (see :func:`leg_power_kw`), over the
   leg's own duration: the engine setting of the calm-water speed, over the slowed time. CO2 and SO2 are proportional to the fuel
   burnt (``CO2 = FC · CC · M(CO2)/M(C)``), as they must be by mass balance; in SIMROUTE they are
   not (its R6 CO2 saving, 16.14 %, differs from its fuel saving, 13.98 %).

References
----------
.. [1] J.-P. Jalkanen, A. Brink, J. Kalli, H. Pettersson, J. Kukkonen and T. Stipa, "A modelling
       system for the exhaust emissions of marine traffic and its application in the Baltic Sea
       area," Atmos. Chem. Phys., vol. 9, pp. 9209-9223, 2009, doi:10.5194/acp-9-9209-2009.
.. [2] J.-P. Jalkanen, L. Johansson, J. Kukkonen, A. Brink, J. Kalli and T. Stipa, "Extension of an
       assessment model of ship traffic exhaust emissions for particulate matter and carbon
       monoxide," Atmos. Chem. Phys., vol. 12, pp. 2641-2659, 2012, doi:10.5194/acp-12-2641-2012.
.. [3] M. Grifoll, C. Borén and M. Castells-Sanabra, "A comprehensive ship weather routing system
       using CMEMS products and A* algorithm," Ocean Eng., vol. 255, 111427, 2022,
       doi:10.1016/j.oceaneng.2022.111427 (Eq. 2-3 and Appendix III); SIMROUTE technical manual §4.
.. [4] IMO MARPOL Annex VI, Regulation 13 (Tier I NOx limit curve, 17 / 45·n^-0.2 / 9.8 g/kWh).
.. [5] IUPAC Commission on Isotopic Abundances and Atomic Weights, "Standard atomic weights," 2021
       (C 12.011, O 15.999, S 32.06 g/mol).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

#: Molar masses [5]. [g/mol]
M_C_G_MOL = 12.011
M_O_G_MOL = 15.999
M_S_G_MOL = 32.06
M_CO2_G_MOL = M_C_G_MOL + 2.0 * M_O_G_MOL
M_SO2_G_MOL = M_S_G_MOL + 2.0 * M_O_G_MOL

#: Relative SFOC parabola coefficients, STEAM2 [2], Eq. 6 (0.455; SIMROUTE's script uses 0.445).
SFOC_REL_A = 0.455
SFOC_REL_B = -0.71
SFOC_REL_C = 1.28

#: NOx limit curve of IMO Tier I [4] as used by STEAM2 [1]: 17 g/kWh below 130 rpm,
#: 45·n^-0.2 from 130 to 2000 rpm, 9.8 g/kWh above 2000 rpm.
NOX_LOW_RPM = 130.0
NOX_HIGH_RPM = 2000.0

#: PM components of [2], Eq. 13a-13d: sulphate and bound water per percent fuel sulphur
#: [g/kWh per % S], organic carbon, elemental carbon and ash [g/kWh], and the engine-load
#: dependence of organic carbon (a, b, c of Eq. 13c; 3.333 below 15 % load).
PM_SO4_PER_PCT_S = 0.312
PM_H2O_PER_PCT_S = 0.244
PM_OC_G_KWH = 0.2
PM_EC_G_KWH = 0.08
PM_ASH_G_KWH = 0.06
PM_OC_LOAD_A = 1.024
PM_OC_LOAD_B = -47.660
PM_OC_LOAD_C = 32.547
PM_OC_LOW_LOAD = 0.15
PM_OC_LOW_LOAD_FACTOR = 3.333


def steam2_power_kw(speed_kn, installed_power_kw, design_speed_kn, engine_load_frac=0.8):
    """Propulsion power at a calm-water speed, STEAM2's cubic law.

    ``P(v) = EL · P_installed · (v / v_design)³`` [1]_ (Eq. 4-5 of the SIMROUTE manual §4).

    Parameters
    ----------
    speed_kn : numeric
        Speed through the water. [kn]
    installed_power_kw : float
        Total installed main-engine power (MCR). [kW]
    design_speed_kn : float
        Design (service) speed, reached at engine load ``engine_load_frac``. [kn]
    engine_load_frac : float, default 0.8
        Engine load at design speed, as a fraction of MCR. [-]

    Returns
    -------
    numeric
        Power. [kW]

    Notes
    -----
    Negative speeds are treated as zero power; the result is not capped (see
    :func:`leg_power_kw` for the cap at the installed power).

    References
    ----------
    .. [1] J.-P. Jalkanen et al., Atmos. Chem. Phys., vol. 9, pp. 9209-9223, 2009,
           doi:10.5194/acp-9-9209-2009.

    Examples
    --------
    >>> round(steam2_power_kw(12.5, 14400.0, 25.0, 0.8), 6)
    1440.0
    """
    v = np.clip(np.asarray(speed_kn, dtype=float), 0.0, None)
    p = engine_load_frac * installed_power_kw * (v / design_speed_kn) ** 3  # [1], Eq. 4-5
    return p if np.ndim(p) else float(p)


def wave_power_increase_frac(speed_loss_frac):
    """Relative power increase that restores the speed lost in waves.

    ``ΔP / P = 1 / (1 − Δv/v)³ − 1`` (SIMROUTE paper Eq. 2, after Molland et al. 2017 [1]_).

    Parameters
    ----------
    speed_loss_frac : numeric
        ``Δv / v``: speed loss in waves as a fraction of the calm-water speed of the engine
        setting. Negative values (a speed *gain*, e.g. Khokhlov in following seas) give a power
        decrease. Values ≥ 1 (the ship is stopped by the waves) give ``inf``. [-]

    Returns
    -------
    numeric
        ``ΔP / P``. [-]

    References
    ----------
    .. [1] M. Grifoll et al., Ocean Eng., vol. 255, 111427, 2022, Eq. 2,
           doi:10.1016/j.oceaneng.2022.111427.

    Examples
    --------
    >>> round(wave_power_increase_frac(0.2), 6)
    0.953125
    """
    r = np.asarray(speed_loss_frac, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(r < 1.0, 1.0 / (1.0 - np.minimum(r, 1.0 - 1e-300)) ** 3 - 1.0, np.inf)  # [1], Eq. 2
    out = np.where(np.isnan(r), np.nan, out)
    return out if np.ndim(out) else float(out)


def sfoc_relative(engine_load_frac):
    """Relative specific fuel oil consumption as a function of engine load, STEAM2's parabola.

    ``SFOC_rel = 0.455 · EL² − 0.71 · EL + 1.28`` [1]_ (≈ 1.0 at 80 % load).

    Parameters
    ----------
    engine_load_frac : numeric
        Engine load as a fraction of MCR. [-]

    Returns
    -------
    numeric
        Multiplier of the engine's base SFOC. [-]

    References
    ----------
    .. [1] J.-P. Jalkanen et al., Atmos. Chem. Phys., vol. 12, pp. 2641-2659, 2012,
           doi:10.5194/acp-12-2641-2012.

    Examples
    --------
    >>> round(sfoc_relative(0.8), 6)
    1.0032
    """
    el = np.asarray(engine_load_frac, dtype=float)
    out = SFOC_REL_A * el**2 + SFOC_REL_B * el + SFOC_REL_C  # [1], Eq. 6
    return out if np.ndim(out) else float(out)


def ef_co2_g_kwh(sfoc_g_kwh, carbon_frac):
    """CO2 emission factor: all fuel carbon oxidised, ``SFOC · CC · M(CO2)/M(C)``. [g/kWh]

    SIMROUTE manual §4, Table A3.2 of the SIMROUTE paper; molar masses from IUPAC.

    Examples
    --------
    >>> round(ef_co2_g_kwh(200.0, 0.85), 4)
    622.8899
    """
    out = np.asarray(sfoc_g_kwh, dtype=float) * carbon_frac * M_CO2_G_MOL / M_C_G_MOL
    return out if np.ndim(out) else float(out)


def ef_so2_g_kwh(sfoc_g_kwh, sulphur_frac):
    """SO2 emission factor: all fuel sulphur to SO2, ``SFOC · SC · M(SO2)/M(S)``. [g/kWh]

    SIMROUTE manual §4 (n(S) = n(SO2)); Table A3.2 of the SIMROUTE paper.

    Examples
    --------
    >>> round(ef_so2_g_kwh(200.0, 0.027), 4)
    10.7896
    """
    out = np.asarray(sfoc_g_kwh, dtype=float) * sulphur_frac * M_SO2_G_MOL / M_S_G_MOL
    return out if np.ndim(out) else float(out)


def ef_nox_g_kwh(engine_rpm):
    """NOx emission factor by engine speed, the IMO Tier I curve used by STEAM2. [g/kWh]

    17 g/kWh for n < 130 rpm, ``45 · n^-0.2`` for 130 ≤ n ≤ 2000 rpm, 9.8 g/kWh for n > 2000 rpm
    (MARPOL Annex VI Reg. 13; SIMROUTE manual §4). The curve is continuous to 0.01 g/kWh at both
    band edges.

    Examples
    --------
    >>> round(ef_nox_g_kwh(500.0), 4)
    12.9843
    """
    n = np.asarray(engine_rpm, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        mid = 45.0 * n ** (-0.2)
    out = np.where(n < NOX_LOW_RPM, 17.0, np.where(n > NOX_HIGH_RPM, 9.8, mid))
    out = np.where(np.isnan(n), np.nan, out)
    return out if np.ndim(out) else float(out)


def pm_oc_load_factor(engine_load_frac):
    """Engine-load multiplier of the organic-carbon PM factor, [2]_ Eq. 13c. [-]

    ``3.333`` below 15 % load, ``a / (1 + b · exp(−c · EL))`` above, with a = 1.024, b = −47.660,
    c = 32.547 (→ 1.024 at high load; organic carbon grows at low load).

    References
    ----------
    .. [2] J.-P. Jalkanen et al., Atmos. Chem. Phys., vol. 12, pp. 2641-2659, 2012,
           doi:10.5194/acp-12-2641-2012.
    """
    el = np.asarray(engine_load_frac, dtype=float)
    with np.errstate(over="ignore"):
        high = PM_OC_LOAD_A / (1.0 + PM_OC_LOAD_B * np.exp(-PM_OC_LOAD_C * np.maximum(el, PM_OC_LOW_LOAD)))
    out = np.where(el < PM_OC_LOW_LOAD, PM_OC_LOW_LOAD_FACTOR, high)
    return out if np.ndim(out) else float(out)


def ef_pm_g_kwh(engine_load_frac, sulphur_frac):
    """Total PM emission factor of STEAM2, [2]_ Eq. 13-14. [g/kWh]

    ``EF_PM = SFOC_rel(EL) · (EF_SO4 + EF_H2O + EF_OC · OC_EL + EF_EC + EF_ash)`` with
    ``EF_SO4 = 0.312 · S``, ``EF_H2O = 0.244 · S`` (S = fuel sulphur in percent), ``EF_OC = 0.2``,
    ``EF_EC = 0.08``, ``EF_ash = 0.06`` g/kWh and ``OC_EL`` from :func:`pm_oc_load_factor`.

    References
    ----------
    .. [2] J.-P. Jalkanen et al., Atmos. Chem. Phys., vol. 12, pp. 2641-2659, 2012,
           doi:10.5194/acp-12-2641-2012.
    """
    el = np.asarray(engine_load_frac, dtype=float)
    s_pct = 100.0 * float(sulphur_frac)
    ef = sfoc_relative(el) * (
        PM_SO4_PER_PCT_S * s_pct  # [2], Eq. 13a
        + PM_H2O_PER_PCT_S * s_pct  # [2], Eq. 13b
        + PM_OC_G_KWH * pm_oc_load_factor(el)  # [2], Eq. 13c-d
        + PM_EC_G_KWH
        + PM_ASH_G_KWH
    )
    return ef if np.ndim(ef) else float(ef)


@dataclass(frozen=True)
class Engine:
    """The engine and fuel particulars STEAM2 needs (SIMROUTE manual §4 defaults)."""

    installed_power_kw: float = 14400.0
    design_speed_kn: float = 25.0
    engine_load_frac: float = 0.8
    sfoc_g_kwh: float = 200.0
    sulphur_frac: float = 0.027
    carbon_frac: float = 0.85
    engine_rpm: float = 500.0

    @classmethod
    def from_vessel(cls, vessel) -> "Engine":
        """Take the fields from a :class:`thresholds.vessel.Vessel`."""
        return cls(
            installed_power_kw=float(vessel.installed_power_kw),
            design_speed_kn=float(vessel.design_speed_kn),
            engine_load_frac=float(vessel.engine_load_frac),
            sfoc_g_kwh=float(vessel.sfoc_g_kwh),
            sulphur_frac=float(vessel.sulphur_frac),
            carbon_frac=float(vessel.carbon_frac),
            engine_rpm=float(vessel.engine_rpm),
        )

    def __post_init__(self):
        for name in ("installed_power_kw", "design_speed_kn", "engine_load_frac", "sfoc_g_kwh", "engine_rpm"):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise ValueError(f"Engine.{name} must be a positive number, got {value!r}")
        for name in ("sulphur_frac", "carbon_frac"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"Engine.{name} is a mass fraction in [0, 1], got {value!r}")


def leg_power_kw(speed_kn, speed_loss_kn, engine: Engine):
    """Power that makes ``speed_kn`` through waves that cost ``speed_loss_kn``, and its parts.

    The speed-loss models give the loss ``Δv`` of an engine setting in waves. A ship that made
    ``v`` over a leg therefore ran the engine setting of calm-water speed ``v + Δv``; the wave
    increase of [3]_ Eq. 2 with ``Δv/(v + Δv)`` on top of the calm-water power at the speed made,
    ``P(v)``, gives ``P_new = P(v) · (1 + ΔP/P) = P(v + Δv)``. For a route timed with the
    involuntary speed loss (``v = v0 − Δv``) this is the engine setting ``P(v0)`` over the slowed
    time: the weather is charged once, through the longer time, never twice (SIMROUTE defect 4).

    Parameters
    ----------
    speed_kn : numeric
        Speed made on the leg. [kn]
    speed_loss_kn : numeric
        Speed loss of the engine setting in the leg's waves (model output, may be negative for a
        speed gain; NaN = no weather, treated as 0). [kn]
    engine : Engine

    Returns
    -------
    dict of ndarray
        ``power_calm_kw`` (``P(v)``), ``wave_increase_frac`` (ΔP/P), ``power_kw`` (``P_new``, capped
        at the installed power), ``engine_load_frac`` (``P_new / P_installed``) and
        ``power_limited`` (True where the required power exceeded the installed power: the leg's
        speed could not have been made in those waves by this engine).
    """
    v = np.clip(np.asarray(speed_kn, dtype=float), 0.0, None)
    dv = np.nan_to_num(np.asarray(speed_loss_kn, dtype=float), nan=0.0)
    dv = np.broadcast_to(dv, v.shape)
    p_calm = steam2_power_kw(v, engine.installed_power_kw, engine.design_speed_kn, engine.engine_load_frac)
    p_calm = np.asarray(p_calm, dtype=float)
    setting = v + dv
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(setting > 0.0, dv / setting, 0.0)
    increase = np.asarray(wave_power_increase_frac(r), dtype=float)
    increase = np.where(v > 0.0, increase, 0.0)
    with np.errstate(invalid="ignore"):
        p_new = np.where(v > 0.0, p_calm * (1.0 + increase), 0.0)  # [3], Eq. 3
    limited = p_new > engine.installed_power_kw * (1.0 + 1e-12)
    p_new = np.minimum(p_new, engine.installed_power_kw)
    return {
        "power_calm_kw": p_calm,
        "wave_increase_frac": increase,
        "power_kw": p_new,
        "engine_load_frac": p_new / engine.installed_power_kw,  # [3], Eq. A3.3
        "power_limited": limited,
    }


def steam2_legs(leg_time_h, speed_kn, speed_loss_kn, engine: Engine) -> pd.DataFrame:
    """Fuel and emissions per leg: STEAM2 with the wave power increase.

    For each leg i: ``P_new,i`` from :func:`leg_power_kw`, ``EL_i = P_new,i / P_installed``,
    ``SFOC_i = SFOC_rel(EL_i) · SFOC_base``, fuel ``FC_i = P_new,i · SFOC_i · Δt_i`` (paper Eq.
    A3.6), ``CO2_i = FC_i · CC · M(CO2)/M(C)``, ``SO2_i = FC_i · SC · M(SO2)/M(S)``,
    ``NOx_i = P_new,i · EF_NOx(rpm) · Δt_i``, ``PM_i = P_new,i · EF_PM(EL_i, S) · Δt_i`` — each
    pollutant once per unit of engine output (no second engine-load factor, SIMROUTE defect 1).

    Parameters
    ----------
    leg_time_h : array_like, shape (n,)
        Duration of each leg. [h]
    speed_kn : array_like, shape (n,)
        Speed made on each leg. [kn]
    speed_loss_kn : array_like, shape (n,) or scalar
        Speed loss of the engine setting in each leg's waves (0 = calm). [kn]
    engine : Engine

    Returns
    -------
    DataFrame
        One row per leg: ``time_h``, ``speed_kn``, ``speed_loss_kn``, ``power_calm_kw``,
        ``wave_increase_frac``, ``power_kw``, ``engine_load_frac``, ``sfoc_g_kwh``, ``energy_kwh``,
        ``fuel_t``, ``co2_t``, ``so2_t``, ``nox_t``, ``pm_t``, ``power_limited``.
    """
    dt = np.asarray(leg_time_h, dtype=float)
    v = np.asarray(speed_kn, dtype=float)
    if dt.shape != v.shape:
        raise ValueError(f"leg_time_h {dt.shape} and speed_kn {v.shape} must have the same shape")
    if np.any(dt < 0) or not np.all(np.isfinite(dt)):
        raise ValueError("leg durations must be finite and non-negative")
    dv = np.broadcast_to(np.asarray(speed_loss_kn, dtype=float), v.shape)
    parts = leg_power_kw(v, dv, engine)
    p = parts["power_kw"]
    el = parts["engine_load_frac"]
    sfoc = sfoc_relative(el) * engine.sfoc_g_kwh  # [2], Eq. 6; paper Eq. A3.5
    energy = p * dt
    fuel_g = energy * sfoc  # paper Eq. A3.6
    return pd.DataFrame(
        {
            "time_h": dt,
            "speed_kn": v,
            "speed_loss_kn": np.nan_to_num(dv, nan=0.0),
            "power_calm_kw": parts["power_calm_kw"],
            "wave_increase_frac": parts["wave_increase_frac"],
            "power_kw": p,
            "engine_load_frac": el,
            "sfoc_g_kwh": sfoc,
            "energy_kwh": energy,
            "fuel_t": fuel_g / 1e6,
            "co2_t": fuel_g * engine.carbon_frac * M_CO2_G_MOL / M_C_G_MOL / 1e6,
            "so2_t": fuel_g * engine.sulphur_frac * M_SO2_G_MOL / M_S_G_MOL / 1e6,
            "nox_t": energy * ef_nox_g_kwh(engine.engine_rpm) / 1e6,
            "pm_t": energy * ef_pm_g_kwh(el, engine.sulphur_frac) / 1e6,
            "power_limited": parts["power_limited"],
        }
    )


def steam2_totals(legs: pd.DataFrame) -> dict:
    """Route totals of :func:`steam2_legs`: fuel and pollutants [t], energy [kWh], power-limited hours."""
    return {
        "fuel_t": float(legs["fuel_t"].sum()),
        "co2_t": float(legs["co2_t"].sum()),
        "so2_t": float(legs["so2_t"].sum()),
        "nox_t": float(legs["nox_t"].sum()),
        "pm_t": float(legs["pm_t"].sum()),
        "energy_kwh": float(legs["energy_kwh"].sum()),
        "mean_power_kw": float(legs["energy_kwh"].sum() / legs["time_h"].sum()) if legs["time_h"].sum() > 0 else 0.0,
        "power_limited_h": float(legs.loc[legs["power_limited"], "time_h"].sum()),
    }


def simroute_legacy_emissions(leg_time_h, leg_speed_kn, calm_speed_kn, engine: Engine, *, sfoc_quadratic: float = 0.445,
                              engine_load_twice: bool = True, design_baseline: bool = True) -> dict:
    """SIMROUTE's emission computation, defects included (switchable), for comparison only.

    Written from the description of SIMROUTE's script (``ANCHORS.md``) and the paper's Eq. 2-3
    and A3.1-A3.6, not from its code. Per leg i sailed at speed ``v_i`` (made good) for
    ``Δt_i`` hours, with ``k = EL · P_installed / v_design³`` and calm-water speed ``v0``:

    * wave increase ``ΔP_i = P_transient,i · (1/(1 − Δv_i/v0)³ − 1)`` with
      ``P_transient,i = k · v_i³`` and ``Δv_i = v0 − v_i``, i.e. ``ΔP_i = k · (v0³ − v_i³)``;
    * ``P_new,i = EL · P_installed + ΔP_i`` (``design_baseline``; else ``k · v_i³ + ΔP_i =
      P(v0)``, the power of the engine setting, which is what :func:`steam2_legs` uses);
    * ``SFOC_i = (q · EL_i² − 0.71 · EL_i + 1.28) · SFOC`` with ``EL_i = P_new,i / P_installed``
      and ``q = sfoc_quadratic`` (0.445 in SIMROUTE, 0.455 in STEAM2);
    * fuel ``Σ P_new,i · SFOC_i · Δt_i`` over the slowed leg times;
    * each pollutant ``Σ P_new,i · EL_i · EF_i · Δt_i`` (``engine_load_twice``; else without
      ``EL_i``, so CO2 stays proportional to fuel).

    On R6 this reproduces SIMROUTE's published split (CO2 saving 16.14 %, fuel 13.98 %) to
    within about half a point (see docs/methods.md); :func:`steam2_legs` is the model stormlane reports.

    Returns
    -------
    dict
        ``fuel_t``, ``co2_t``, ``so2_t``, ``nox_t``.
    """
    dt = np.asarray(leg_time_h, dtype=float)
    v = np.asarray(leg_speed_kn, dtype=float)
    v0 = float(calm_speed_kn)
    k = engine.engine_load_frac * engine.installed_power_kw / engine.design_speed_kn**3
    delta_p = k * (v0**3 - v**3)  # = k v^3 (1/(1 - (v0 - v)/v0)^3 - 1), paper Eq. 2
    base = engine.engine_load_frac * engine.installed_power_kw if design_baseline else k * v**3
    p_new = base + delta_p  # paper Eq. 3
    el_new = p_new / engine.installed_power_kw  # paper Eq. A3.3
    sfoc = (sfoc_quadratic * el_new**2 - 0.71 * el_new + 1.28) * engine.sfoc_g_kwh  # paper Eq. A3.4-A3.5
    fuel_g = p_new * sfoc * dt  # paper Eq. A3.6
    load = el_new if engine_load_twice else 1.0  # paper Eq. A3.2
    return {
        "fuel_t": float(fuel_g.sum() / 1e6),
        "co2_t": float((p_new * load * ef_co2_g_kwh(sfoc, engine.carbon_frac) * dt).sum() / 1e6),
        "so2_t": float((p_new * load * ef_so2_g_kwh(sfoc, engine.sulphur_frac) * dt).sum() / 1e6),
        "nox_t": float((p_new * load * ef_nox_g_kwh(engine.engine_rpm) * dt).sum() / 1e6),
    }
