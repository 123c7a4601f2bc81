"""Whole-vessel safety evaluation and the "safe cell" mask used by deviations and A*.

:func:`assess` applies a profile's operator limits (:mod:`thresholds.operator`) and the IMO
MSC.1/Circ.1228 rules (:mod:`thresholds.imo_msc1228`) for one :class:`~thresholds.vessel.Vessel`
to weather arrays of any shape; :func:`safe_cell_mask` does it for a set of candidate headings at
once and returns a boolean mask plus the reason codes (:data:`thresholds.assessment.REASON_BITS`).

Which period feeds which rule (documented choice): the encounter period T_E of the roll rules
uses the peak period ``tp_s`` (the period SIMROUTE uses; the dominant wave train sets the
encounter rhythm), falling back to ``tm_s``; the successive high-wave rule uses the mean period
``tm_s`` (falling back to ``tp_s``) for both its "average wave length" and its T_E / T_W band.
"""

from __future__ import annotations

import numpy as np

from thresholds import imo_msc1228 as imo
from thresholds.assessment import Assessment
from thresholds.operator import OperatorLimits, OperatorProfile, evaluate_operator


def roll_period_of(vessel) -> float | None:
    """The vessel's natural roll period: given, or from GM by the IS Code (None if neither). [s]"""
    if getattr(vessel, "roll_period_s", None):
        return float(vessel.roll_period_s)
    if getattr(vessel, "gm_m", None):
        return float(imo.natural_roll_period_s(vessel.beam_m, vessel.gm_m, vessel.draught_m, vessel.lpp_m))
    return None


def _limits_for(vessel, limits):
    if limits is None:
        return None
    if isinstance(limits, OperatorProfile):
        return limits.limits_for(vessel.vessel_class, vessel.lpp_m)
    if isinstance(limits, OperatorLimits):
        return limits.for_lpp(vessel.lpp_m)
    raise TypeError(f"limits must be OperatorProfile, OperatorLimits or None, not {type(limits).__name__}")


def assess(
    vessel,
    limits=None,
    *,
    hs_m,
    wave_from_deg=None,
    tp_s=None,
    tm_s=None,
    wind_u_ms=None,
    wind_v_ms=None,
    wind_ms=None,
    heading_deg=None,
    speed_kn=None,
    imo_settings: imo.ImoSettings | None = None,
    missing: str = "raise",
) -> Assessment:
    """Evaluate operator limits and IMO MSC.1/Circ.1228 rules for one vessel.

    Parameters
    ----------
    vessel : Vessel
        Uses ``lpp_m`` (L of the IMO rules), ``speed_kn`` (when ``speed_kn`` is not given),
        ``vessel_class``, and ``roll_period_s`` or ``gm_m`` + ``beam_m`` + ``draught_m``.
    limits : OperatorProfile, OperatorLimits or None
        Operator limits; a profile picks the variant for the vessel's class and Lpp. The profile's
        IMO settings are used unless ``imo_settings`` is given.
    hs_m, wave_from_deg, tp_s, tm_s, wind_u_ms, wind_v_ms, wind_ms : numeric
        Weather in canonical names, broadcastable to one shape.
    heading_deg : numeric, optional
        Course. Without it only heading-free rules run (Hs, wind, period) and the others
        (beam seas, surf-riding, successive high waves, roll) are listed in ``Assessment.skipped``.
    speed_kn : numeric, optional
        Speed through the water (default: the vessel's service speed). [kn]
    imo_settings : ImoSettings, optional
        Overrides the profile's IMO settings.
    missing : {"raise", "skip"}
        An operator rule whose variable is absent raises, or is skipped and listed (see
        :func:`~thresholds.operator.evaluate_operator`). IMO rules without their inputs are
        always skipped and listed in ``Assessment.skipped``.

    Returns
    -------
    Assessment

    Examples
    --------
    >>> from thresholds.vessel import Vessel
    >>> v = Vessel("demo", "container", 18.0, 180.0, 30.0, 10.0, 20000, 14400, 20.0, 500, 200, roll_period_s=20.0)
    >>> a = assess(v, hs_m=8.0, tp_s=12.0, tm_s=10.0, wave_from_deg=180.0, heading_deg=0.0)  # following seas
    >>> sorted(k for k, r in a.rules.items() if r.fired)
    ['high_waves']
    >>> sorted(k for k, r in assess(v, hs_m=8.0, tp_s=12.0, tm_s=10.0, wave_from_deg=0.0, heading_deg=0.0).rules.items() if r.fired)
    []
    """
    lim = _limits_for(vessel, limits)
    if imo_settings is None:
        imo_settings = limits.imo if isinstance(limits, OperatorProfile) else imo.ImoSettings()
    if lim is not None:
        result = evaluate_operator(lim, hs_m=hs_m, wave_from_deg=wave_from_deg, tp_s=tp_s, tm_s=tm_s,
                                   wind_u_ms=wind_u_ms, wind_v_ms=wind_v_ms, wind_ms=wind_ms, heading_deg=heading_deg,
                                   missing=missing)
    else:
        result = Assessment()
    if lim is not None and lim.beam_sectors_deg and heading_deg is None:
        result = result.merge(Assessment(skipped=("beam_seas: no heading given",)))
    if not imo_settings.enabled:
        return result

    return result.merge(_imo_rules(vessel, imo_settings, hs_m=hs_m, wave_from_deg=wave_from_deg, tp_s=tp_s, tm_s=tm_s,
                                   heading_deg=heading_deg, speed_kn=speed_kn))


def _imo_rules(vessel, imo_settings, *, hs_m, wave_from_deg, tp_s, tm_s, heading_deg, speed_kn) -> Assessment:
    """IMO MSC.1/Circ.1228's rules (successive high waves, surf-riding, synchronous and parametric
    roll) for one vessel; rules lacking their inputs (heading, wave direction, period, roll period)
    are listed in ``Assessment.skipped``."""
    hs = np.asarray(hs_m, dtype=float)
    length = float(vessel.lpp_m)
    rules = {}
    skipped = []
    missing = [np.isnan(hs)]
    mean_period = tm_s if tm_s is not None else tp_s
    enc_period = tp_s if tp_s is not None else tm_s
    if heading_deg is None or wave_from_deg is None:
        why = "no heading given" if heading_deg is None else "no wave direction"
        skipped += [f"high_waves: {why}", f"surf_riding: {why}", f"synchronous_roll: {why}", f"parametric_roll: {why}"]
    else:
        alpha = imo.encounter_angle_deg(heading_deg, wave_from_deg)
        missing.append(np.isnan(alpha))
        v = vessel.speed_kn if speed_kn is None else speed_kn
        if mean_period is None:
            skipped.append("high_waves: no wave period")
        else:  # 4.2.2: the wave conditions and the dangerous zone of T_E / T_W, at this heading and speed
            rules["high_waves"] = imo.successive_high_waves(hs, mean_period, length, v, alpha)
            missing.append(np.isnan(np.asarray(mean_period, dtype=float)))
        with np.errstate(invalid="ignore"):
            gate = hs >= imo_settings.gate_hs_m
        surf = imo.surf_riding(v, alpha, length)
        rules["surf_riding"] = _gated(surf, gate, imo_settings.gate_hs_m)
        tr = roll_period_of(vessel)
        if tr is None or enc_period is None:
            why = "no GM or roll period for the vessel" if tr is None else "no wave period"
            skipped += [f"synchronous_roll: {why}", f"parametric_roll: {why}"]
        else:
            te = imo.encounter_period_s(enc_period, v, alpha)
            rules["synchronous_roll"] = _gated(imo.synchronous_roll(te, tr, imo_settings.roll_tolerance_frac), gate, imo_settings.gate_hs_m)
            rules["parametric_roll"] = _gated(imo.parametric_roll(te, tr, imo_settings.roll_tolerance_frac), gate, imo_settings.gate_hs_m)
            missing.append(np.isnan(np.asarray(enc_period, dtype=float)))
    no_data = np.logical_or.reduce(np.broadcast_arrays(*missing))
    return Assessment(rules, no_data, tuple(skipped))


def _gated(rule, gate, gate_hs_m):
    """A rule that only fires where Hs ≥ the gate; margin NaN (not applicable) elsewhere."""
    if gate_hs_m <= 0.0:
        return rule
    shape = np.broadcast_shapes(np.shape(rule.fired), np.shape(gate))
    g = np.broadcast_to(gate, shape)
    return type(rule)(rule.name, np.broadcast_to(rule.fired, shape) & g, np.where(g, rule.margin, np.nan),
                      rule.margin_unit, np.broadcast_to(rule.value, shape), np.where(g, rule.limit, np.nan))


def safe_cell_mask(vessel, limits, headings_deg, *, hs_m, wave_from_deg=None, tp_s=None, tm_s=None,
                   wind_u_ms=None, wind_v_ms=None, wind_ms=None, speed_kn=None, imo_settings=None, missing="raise"):
    """Safe-cell mask of a weather field for a vessel sailing on each of a set of headings.

    Parameters
    ----------
    vessel : Vessel
    limits : OperatorProfile, OperatorLimits or None
    headings_deg : array_like, shape (H,)
        Candidate courses. [deg]
    hs_m, wave_from_deg, tp_s, tm_s, wind_u_ms, wind_v_ms, wind_ms : ndarray, shape S
        Weather fields (e.g. S = (time, lat, lon)); land and missing data are NaN.
    speed_kn : float, optional
        Speed through the water (default the vessel's service speed). [kn]
    imo_settings, missing :
        As in :func:`assess`.

    Returns
    -------
    safe : ndarray of bool, shape (H, *S)
        True where no rule fires and the data are present, for that heading.
    reason : ndarray of uint16, shape (H, *S)
        Reason codes (bits of :data:`thresholds.assessment.REASON_BITS`); 0 where safe.

    Notes
    -----
    ``safe.any(axis=0)`` is "some heading is safe here", ``safe.all(axis=0)`` "every heading is".
    Heading-free rules (Hs, wind, period, high waves) give the same answer on every heading.

    Examples
    --------
    >>> from thresholds.vessel import Vessel
    >>> from thresholds.operator import OperatorLimits
    >>> v = Vessel("demo", "container", 18.0, 180.0, 30.0, 10.0, 20000, 14400, 20.0, 500, 200)
    >>> lim = OperatorLimits(name="beam", beam_sectors_deg=[[60, 120], [240, 300]])
    >>> safe, reason = safe_cell_mask(v, lim, [0.0, 90.0], hs_m=[[2.0]], wave_from_deg=[[90.0]], tp_s=[[8.0]])
    >>> safe[:, 0, 0].tolist(), reason[:, 0, 0].tolist()
    ([False, True], [8, 0])
    """
    headings = np.asarray(headings_deg, dtype=float).ravel()
    field_shape = np.broadcast_shapes(*(np.shape(x) for x in (hs_m, wave_from_deg, tp_s, tm_s, wind_u_ms, wind_v_ms, wind_ms) if x is not None))
    heading = headings.reshape((-1,) + (1,) * len(field_shape))
    out_shape = (headings.size,) + tuple(field_shape)
    a = assess(vessel, limits, hs_m=hs_m, wave_from_deg=wave_from_deg, tp_s=tp_s, tm_s=tm_s, wind_u_ms=wind_u_ms,
               wind_v_ms=wind_v_ms, wind_ms=wind_ms, heading_deg=heading, speed_kn=speed_kn, imo_settings=imo_settings,
               missing=missing)
    reason = np.broadcast_to(a.reason_code, out_shape).copy()
    return reason == 0, reason
