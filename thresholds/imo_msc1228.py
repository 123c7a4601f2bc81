"""IMO MSC.1/Circ.1228 dangerous-situation criteria, vectorised over any array shape.

The circular ("Revised guidance to the master for avoiding dangerous situations in adverse
weather and sea conditions", IMO, 11 January 2007) gives four situations a master should avoid
(Annex, section 4.2): surf-riding and broaching-to (4.2.1), successive high-wave attack (4.2.2.1
and 4.2.2.2), synchronous rolling (4.2.3.1) and parametric rolling (4.2.3.2). SIMROUTE
implements the first and the last (paper Appendix II); stormlane implements all four, as
written:

* successive high-wave attack needs, besides an average wave length over 0.8 L and a
  significant wave height over 0.04 L (4.2.2.1), the ship in the dangerous zone of the
  circular's figure 3: an encounter period about 1.8 to 3.0 times the wave period (4.2.2.2) --
  following and quartering seas; it never fires in head seas, where T_E < T_W;
* synchronous rolling is T_E close to the natural roll period T_R (4.2.3.1); parametric rolling
  is listed for T_E close to T_R or to T_R / 2 (4.2.3.2): the first condition is the synchronous
  one, reported once, as synchronous; parametric is the T_E close to T_R / 2 band, so a cell is
  never counted twice;
* "close to" has no number in the circular: each resonance band is ``|k T_E - T_R| <= eps T_R``
  with eps = 0.10, the tolerance of SIMROUTE's safety script (``/work/shared/ANCHORS.md``; the
  paper's Eq. A2.3-A2.4 leave eps open), configurable per profile (``roll_tolerance_frac``).

Conventions (DESIGN.md): ``encounter_deg`` α is the direction the waves come from relative to
the bow, 0 = head seas, 180 = following seas, in [0, 360). Speeds in knots, lengths in metres,
periods in seconds. Every criterion returns a :class:`~thresholds.assessment.RuleResult`
(``fired`` mask, signed ``margin`` – positive when the rule fires, in the unit named by
``margin_unit`` –, plus the ``value`` compared with the ``limit``) so reports can say why a cell
is unsafe and by how much.

References
----------
.. [1] IMO, "Revised guidance to the master for avoiding dangerous situations in adverse weather
       and sea conditions," MSC.1/Circ.1228, 11 Jan. 2007.
.. [2] IMO, "International Code on Intact Stability, 2008 (2008 IS Code)," Res. MSC.267(85),
       Part A, para. 2.3.4 (rolling period).
.. [3] M. Grifoll et al., "A comprehensive ship weather routing system using CMEMS products and
       A* algorithm," Ocean Eng., vol. 255, 111427, 2022, doi:10.1016/j.oceaneng.2022.111427,
       Appendix II (seed ``simroute_paper_grifoll_2022``).
.. [4] SIMROUTE's safety script as run on R6 (``/work/shared/ANCHORS.md``): parametric roll within
       +-10 % of the resonance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from thresholds.assessment import RuleResult
from thresholds.units import GRAVITY_MS2, wrap_deg

#: Surf-riding speed coefficient of [1] (surf-riding): V > 1.8·√L / cos(180° − α). [kn / √m]
SURF_RIDING_COEFF = 1.8
#: Sector of following/quartering seas where surf-riding can occur, [1] (surf-riding; open). [deg]
SURF_RIDING_SECTOR_DEG = (135.0, 225.0)
#: Successive high-wave attack, [1] 4.2.2.1: average wave length > 0.8·L ...
HIGH_WAVE_LENGTH_FRAC = 0.8
#: ... and significant wave height > 0.04·L.
HIGH_WAVE_HEIGHT_FRAC = 0.04
#: ... with the ship in the dangerous zone: T_E "nearly equal to double (i.e. about 1.8-3.0 times)"
#: the wave period T_W, [1] 4.2.2.2 and figure 3 (closed band).
HIGH_WAVE_TE_RANGE = (1.8, 3.0)
#: Default relative tolerance ε of the resonance bands |k·T_E − T_R| ≤ ε·T_R ([1] 4.2.3.1-4.2.3.2
#: say "close to" with no number; [3] Eq. A2.3–A2.4 leave ε open): SIMROUTE's ±10 % [4].
ROLL_TOLERANCE_FRAC = 0.10


def _arr(x):
    return np.asarray(x, dtype=float)


def encounter_angle_deg(heading_deg, wave_from_deg):
    """Encounter angle α of waves on a ship, 0 = head seas, 180 = following seas, in [0, 360).

    Parameters
    ----------
    heading_deg : numeric
        Ship's course, clockwise from true north. [deg]
    wave_from_deg : numeric
        Direction the waves come FROM, clockwise from true north (CMEMS ``VMDR``). [deg]

    Returns
    -------
    numeric
        α = (wave_from − heading) mod 360: waves from dead ahead give 0, waves from astern 180,
        waves from starboard 90. [deg]

    Notes
    -----
    [1], Annex, definitions and the T_E diagram (α measured from the bow, 0° in head waves, 180° in following waves).

    Examples
    --------
    >>> float(encounter_angle_deg(90.0, 270.0))
    180.0
    """
    return wrap_deg(_arr(wave_from_deg) - _arr(heading_deg))


def wave_length_m(period_s):
    """Deep-water wave length λ = g·T² / (2π) for a wave period T. [m]

    Notes
    -----
    Linear (Airy) dispersion in deep water, the relation behind [1] Fig. 2 (λ ≈ 1.56·T²).

    Examples
    --------
    >>> round(float(wave_length_m(10.0)), 2)
    156.08
    """
    return GRAVITY_MS2 * _arr(period_s) ** 2 / (2.0 * np.pi)


def encounter_period_s(period_s, speed_kn, encounter_deg):
    """Wave encounter period T_E = 3·T² / (3·T + V·cos α) of [1] (Fig. 2) and [3] Appendix II.

    Parameters
    ----------
    period_s : numeric
        Wave period T. [s]
    speed_kn : numeric
        Ship speed V. [kn]
    encounter_deg : numeric
        Encounter angle α, 0 = head seas. [deg]

    Returns
    -------
    numeric
        Encounter period. [s] The formula is the deep-water relation T_E = λ / (c + V·cos α) with
        λ = 1.56·T², c = 1.56·T (m/s) and V in knots (0.514/1.56 ≈ 1/3). When the ship overtakes
        following waves the denominator turns negative: the period is then the time between
        overtaking two crests, so the absolute value is returned; a ship riding at wave speed
        (denominator 0) has an infinite encounter period.

    Examples
    --------
    >>> float(encounter_period_s(10.0, 0.0, 0.0))
    10.0
    >>> float(encounter_period_s(10.0, 15.0, 0.0))
    6.666666666666667
    """
    t = _arr(period_s)
    denom = 3.0 * t + _arr(speed_kn) * np.cos(np.deg2rad(_arr(encounter_deg)))  # [1] Fig. 2
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(denom == 0.0, np.inf, 3.0 * t**2 / np.abs(denom))


def natural_roll_period_s(beam_m, gm_m, draught_m, lwl_m):
    """Natural roll period T_R = 2·C·B / √GM of the 2008 IS Code [2], Part A, para. 2.3.4.

    Parameters
    ----------
    beam_m : numeric
        Moulded breadth B. [m]
    gm_m : numeric
        Metacentric height corrected for free surface, GM. [m]
    draught_m : numeric
        Mean moulded draught d. [m]
    lwl_m : numeric
        Length of the ship at the waterline L_WL (Lpp is a fair stand-in). [m]

    Returns
    -------
    numeric
        T_R = 2·C·B/√GM with C = 0.373 + 0.023·(B/d) − 0.043·(L_WL/100) ([2], 2.3.4). [s]
        NaN where GM ≤ 0 (no positive initial stability, no roll period).

    Examples
    --------
    >>> round(float(natural_roll_period_s(32.2, 1.0, 12.0, 200.0)), 3)
    22.457
    """
    b = _arr(beam_m)
    gm = _arr(gm_m)
    c = 0.373 + 0.023 * (b / _arr(draught_m)) - 0.043 * (_arr(lwl_m) / 100.0)  # [2] 2.3.4
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(gm > 0.0, 2.0 * c * b / np.sqrt(np.where(gm > 0.0, gm, np.nan)), np.nan)


def surf_riding(speed_kn, encounter_deg, length_m) -> RuleResult:
    """Surf-riding and broaching-to, [1] (surf-riding and broaching-to) and [3] Eq. A2.1–A2.2.

    The rule fires when 135° < α < 225° (open interval) and V > 1.8·√L / cos(180° − α).

    Parameters
    ----------
    speed_kn : numeric
        Ship speed V. [kn]
    encounter_deg : numeric
        Encounter angle α, 0 = head seas. [deg]
    length_m : numeric
        Ship length L. [m]

    Returns
    -------
    RuleResult
        ``value`` = V, ``limit`` = critical speed 1.8·√L/cos(180° − α) (NaN outside the sector),
        ``margin`` = V − limit in knots (−inf outside the sector). NaN inputs never fire.

    Examples
    --------
    >>> r = surf_riding(20.0, 180.0, 100.0)   # limit 18 kn in following seas
    >>> bool(r.fired), float(r.margin)
    (True, 2.0)
    """
    v = _arr(speed_kn)
    alpha = wrap_deg(_arr(encounter_deg))
    lo, hi = SURF_RIDING_SECTOR_DEG
    in_sector = (alpha > lo) & (alpha < hi)  # [1] surf-riding; [3] Eq. A2.1
    with np.errstate(invalid="ignore", divide="ignore"):
        crit = SURF_RIDING_COEFF * np.sqrt(_arr(length_m)) / np.cos(np.deg2rad(180.0 - alpha))  # Eq. A2.2
    limit = np.where(in_sector, crit, np.nan)
    margin = np.where(in_sector, v - crit, -np.inf)
    margin = np.where(np.isnan(v), np.nan, margin)
    fired = in_sector & (v > crit)
    return RuleResult("surf_riding", fired, margin, "kn", v + 0.0 * alpha, limit)


def successive_high_waves(hs_m, period_s, length_m, speed_kn=None, encounter_deg=None) -> RuleResult:
    """Successive high-wave attack, [1] 4.2.2.1-4.2.2.2: λ > 0.8·L, Hs > 0.04·L and 1.8 T_W ≤ T_E ≤ 3.0 T_W.

    Parameters
    ----------
    hs_m : numeric
        Significant wave height. [m]
    period_s : numeric
        Average (mean) wave period T_W, turned into the average wave length by
        :func:`wave_length_m` and into the encounter period by :func:`encounter_period_s`. [s]
    length_m : numeric
        Ship length L. [m]
    speed_kn, encounter_deg : numeric, optional
        Speed through the water [kn] and encounter angle (0 = head seas) [deg]: the dangerous
        zone of the circular's figure 3, T_E / T_W in [1.8, 3.0] (following and quartering
        seas). Without them only the wave conditions of 4.2.2.1 are judged (the circular's
        preconditions; callers that have a heading must give it).

    Returns
    -------
    RuleResult
        ``value`` = Hs, ``limit`` = 0.04·L (NaN where λ ≤ 0.8·L). ``margin`` (fraction) = the
        smallest relative excess over the conditions: (λ − 0.8L)/0.8L, (Hs − 0.04L)/0.04L and,
        with a heading, the depth of T_E/T_W inside [1.8, 3.0] relative to 1.8; positive only
        when all hold.

    Examples
    --------
    >>> r = successive_high_waves(5.0, 9.0, 100.0)   # λ = 126.5 m > 80 m, Hs 5 m > 4 m
    >>> bool(r.fired), round(float(r.margin), 3)
    (True, 0.25)
    >>> bool(successive_high_waves(5.0, 9.0, 100.0, 10.0, 0.0).fired)  # head seas: T_E < T_W
    False
    >>> bool(successive_high_waves(5.0, 9.0, 100.0, 15.0, 180.0).fired)  # T_E / T_W = 27 / 12 = 2.25
    True
    """
    hs = _arr(hs_m)
    length = _arr(length_m)
    lam = wave_length_m(period_s)
    lam_lim = HIGH_WAVE_LENGTH_FRAC * length
    hs_lim = HIGH_WAVE_HEIGHT_FRAC * length
    long_waves = lam > lam_lim
    fired = long_waves & (hs > hs_lim)
    margin = np.minimum((lam - lam_lim) / lam_lim, (hs - hs_lim) / hs_lim)
    if speed_kn is not None and encounter_deg is not None:
        lo, hi = HIGH_WAVE_TE_RANGE
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = encounter_period_s(period_s, speed_kn, encounter_deg) / _arr(period_s)  # [1] 4.2.2.2
            zone = (ratio >= lo) & (ratio <= hi)
            fired = fired & zone
            margin = np.minimum(margin, np.minimum(ratio - lo, hi - ratio) / lo)
    return RuleResult("high_waves", fired, margin, "frac", hs + 0.0 * lam, np.where(long_waves, hs_lim, np.nan))


def _resonance(name, te_multiple, te_s, tr_s, tolerance_frac):
    """|k·T_E − T_R| ≤ ε·T_R, with margin ε − |k·T_E − T_R|/T_R (fraction of T_R)."""
    te = _arr(te_s)
    tr = _arr(tr_s)
    with np.errstate(invalid="ignore"):
        mismatch = np.abs(te_multiple * te - tr) / tr
        margin = tolerance_frac - mismatch
        fired = margin >= 0.0
    return RuleResult(name, fired, margin, "frac", te, tr / te_multiple)


def synchronous_roll(te_s, tr_s, tolerance_frac=ROLL_TOLERANCE_FRAC) -> RuleResult:
    """Synchronous rolling, [1] 4.2.3.1: encounter period close to the natural roll period.

    Fires when |T_E − T_R| ≤ ε·T_R ([3] Eq. A2.3; ε of [4], see :data:`ROLL_TOLERANCE_FRAC`).

    Parameters
    ----------
    te_s : numeric
        Encounter period, see :func:`encounter_period_s`. [s]
    tr_s : numeric
        Natural roll period, see :func:`natural_roll_period_s`. [s]
    tolerance_frac : float
        ε, relative tolerance of "approximately equal" (default 0.10, SIMROUTE's value).

    Returns
    -------
    RuleResult
        ``value`` = T_E, ``limit`` = T_R, ``margin`` = ε − |T_E − T_R|/T_R (positive inside the band).

    Examples
    --------
    >>> bool(synchronous_roll(19.0, 20.0).fired), bool(synchronous_roll(17.9, 20.0).fired)
    (True, False)
    """
    return _resonance("synchronous_roll", 1.0, te_s, tr_s, tolerance_frac)


def parametric_roll(te_s, tr_s, tolerance_frac=ROLL_TOLERANCE_FRAC) -> RuleResult:
    """Parametric rolling, [1] 4.2.3.2 and [3] Eq. A2.4: encounter period close to half the roll period.

    Fires when |2·T_E − T_R| ≤ ε·T_R (T_E ≈ T_R / 2). The circular lists T_E ≈ T_R for
    parametric rolling too; that band is :func:`synchronous_roll`'s (4.2.3.1), reported there
    only, so no cell counts twice.

    Returns
    -------
    RuleResult
        ``value`` = T_E, ``limit`` = T_R / 2, ``margin`` = ε − |2·T_E − T_R|/T_R (fraction of T_R).

    Examples
    --------
    >>> bool(parametric_roll(10.0, 20.0).fired), bool(parametric_roll(20.0, 20.0).fired)
    (True, False)
    """
    return _resonance("parametric_roll", 2.0, te_s, tr_s, tolerance_frac)


@dataclass(frozen=True)
class ImoSettings:
    """Which MSC.1/Circ.1228 rules a safety evaluation applies, and how.

    Attributes
    ----------
    enabled : bool
        Apply the IMO rules at all.
    roll_tolerance_frac : float
        ε of the resonance tests (default 0.10, see :data:`ROLL_TOLERANCE_FRAC`).
    gate_hs_m : float
        Surf-riding and the roll-resonance rules fire only where Hs ≥ this. The circular gives no
        height (it addresses "adverse weather"); 0 applies them literally, a positive value keeps a
        0.3 m swell at the roll period from marking a cell unsafe. Project choice, configurable.
    """

    enabled: bool = True
    roll_tolerance_frac: float = ROLL_TOLERANCE_FRAC
    gate_hs_m: float = 0.0

    @classmethod
    def from_dict(cls, data: dict | None, where: str = "") -> "ImoSettings":
        from thresholds.errors import StormlaneError

        data = dict(data or {})
        unknown = sorted(set(data) - set(cls.__dataclass_fields__))
        if unknown:
            raise StormlaneError(f"{where}: unknown IMO setting(s) {', '.join(unknown)}; known: {', '.join(cls.__dataclass_fields__)}")
        try:
            out = cls(
                enabled=bool(data.get("enabled", True)),
                roll_tolerance_frac=float(data.get("roll_tolerance_frac", ROLL_TOLERANCE_FRAC)),
                gate_hs_m=float(data.get("gate_hs_m", 0.0)),
            )
        except (TypeError, ValueError) as err:
            raise StormlaneError(f"{where}: {err}") from None
        if not 0.0 < out.roll_tolerance_frac < 1.0 or out.gate_hs_m < 0.0:
            raise StormlaneError(f"{where}: roll_tolerance_frac must be in (0, 1) and gate_hs_m >= 0")
        return out
