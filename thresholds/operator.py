"""Operator weather limits (cargo-safety thresholds) as configuration, evaluated vectorised.

The limits are data, not code: ``data/operator_limits.toml`` ships the container-ship limits of
[1] Table 1 and its Lpp < 200 m variant (§3.2); users add profiles there or in their own TOML
file (loaded by ``pipelines.config.load_operator_profile``). This module holds the typed record
(:class:`OperatorLimits`, one variant for a vessel class and length range; :class:`OperatorProfile`,
a named set of variants) and the evaluation :func:`evaluate_operator`.

Reading of the tables (documented because [1] Table 1 mixes limits and forbidden ranges): [1]
Table 1's first three columns are the adverse-condition row of IMO MEPC.1/Circ.850/Rev.2 [2]
for ships over 250 m (Hs 6.0 m, peak period 7.0-15.0 s, mean wind 22.6 m/s; 4.5 m, 7.0-15.0 s,
19.0 m/s under 200 m; interpolated in Lpp between), and a row of that table is one sea state:
the period range goes with the wave height. So the default profile limits Hs where the peak
period lies in 7-15 s (``hs_period_range_s``) and interpolates Hs and wind in Lpp (tables
``[[lpp, value], ...]``), instead of forbidding any 7-15 s period on its own. The wave-direction
column is a *forbidden* range of the ship-to-wave relative direction (60–120° and 240–300°, beam
seas); the Lpp < 200 m variant's "mean wave period must not exceed 8 s" is [1] §3.2's own rule,
kept. The column-by-column reading stays available (``period_forbidden_s``, profile
``seed-literal``).

A period or direction rule on its own flags harmless swell (a 0.5 m beam swell is not a cargo
risk); a profile may therefore gate those rules with ``gate_hs_m`` (they only fire where
Hs ≥ gate). The gate is a project choice, not from [1]; the ``seed-literal`` profile has none.

References
----------
.. [1] Seed paper ``ais_weather_routing_cargo_loss`` (AIS-based weather-routing decision support
       against cargo loss in container ships, limits from Danaos Shipping), §3.2 and Table 1
       "Weather thresholds of adverse conditions" (title and DOI not in the seed text).
.. [2] IMO, "2013 Interim guidelines for determining minimum propulsion power to maintain the
       manoeuvrability of ships in adverse conditions," MEPC.1/Circ.850/Rev.2, adverse-condition
       table (the seed's footnote 6).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from thresholds.assessment import Assessment, RuleResult
from thresholds.errors import StormlaneError
from thresholds.imo_msc1228 import ImoSettings

PERIOD_KINDS = {"peak": "tp_s", "mean": "tm_s"}


class OperatorProfileError(StormlaneError):
    """A profile is unknown, malformed, or has no variant for a vessel."""


class MissingWeatherVariableError(StormlaneError):
    """A rule needs a weather variable that was not provided."""


def _interval_list(value, what: str) -> tuple:
    if value is None:
        return ()
    out = []
    for item in value:
        if len(item) != 2:
            raise OperatorProfileError(f"{what}: each range needs [low, high], got {item!r}")
        lo, hi = float(item[0]), float(item[1])
        if not lo <= hi:
            raise OperatorProfileError(f"{what}: range [{lo}, {hi}] has low > high")
        out.append((lo, hi))
    return tuple(out)


def _lpp_table(value, what: str) -> tuple:
    """``[[lpp, value], ...]`` -> a tuple of (lpp, value) pairs, lpp strictly increasing, values >= 0."""
    rows = []
    for item in value:
        if not isinstance(item, (list, tuple)) or len(item) != 2:
            raise OperatorProfileError(f"{what}: a table of [lpp_m, value] pairs, got {item!r}")
        rows.append((float(item[0]), float(item[1])))
    if not rows or any(b[0] <= a[0] for a, b in zip(rows, rows[1:])) or any(v < 0 or not math.isfinite(v) for _, v in rows):
        raise OperatorProfileError(f"{what}: Lpp must increase and values be non-negative numbers, got {value!r}")
    return tuple(rows)


@dataclass(frozen=True)
class OperatorLimits:
    """One set of operator limits, applying to a vessel class and a range of Lpp.

    Attributes
    ----------
    name : str
        Label used in reports (``"container, Lpp >= 200 m"``).
    vessel_class : str
        Class it applies to (``Vessel.vessel_class``), ``"*"`` for any.
    lpp_min_m, lpp_max_m : float
        Applies when lpp_min_m ≤ Lpp < lpp_max_m. [m]
    hs_max_m : float, table or None
        Significant wave height limit (fires when Hs > limit). A table ``((lpp, value), ...)`` is
        interpolated linearly in the vessel's Lpp (held beyond its ends), as MEPC.1/Circ.850/Rev.2
        does between 200 and 250 m (:meth:`for_lpp`). [m]
    hs_period_range_s : (low, high) or None
        The Hs limit applies to sea states whose period (``period_kind``) lies in this closed
        range: the adverse-condition table of MEPC.1/Circ.850/Rev.2 (and [1] Table 1, its copy)
        gives each wave height with a peak-period range, 7.0-15.0 s; without the period in the
        data the limit applies at every period and the assessment says so. [s]
    wind_max_ms : float, table or None
        Mean wind speed limit at 10 m (fires when wind > limit); a table as for ``hs_max_m``. [m/s]
    period_kind : {"peak", "mean"}
        Which period the period rules use: ``tp_s`` or ``tm_s``.
    period_min_s, period_max_s : float or None
        Allowed range (fires when the period is below min or above max). [s]
    period_forbidden_s : tuple of (low, high)
        Forbidden closed ranges (fires when low ≤ period ≤ high). [s]
    beam_sectors_deg : tuple of (low, high)
        Forbidden closed ranges of the encounter angle α (0 = head seas); [1] Table 1:
        60–120 and 240–300 (symmetric, so the 0/180 convention does not matter). [deg]
    gate_hs_m : float
        Period and beam rules fire only where Hs ≥ this (0 = always). [m]
    source : str
        Where the numbers come from.
    """

    name: str
    vessel_class: str = "*"
    lpp_min_m: float = 0.0
    lpp_max_m: float = math.inf
    hs_max_m: float | tuple | None = None
    wind_max_ms: float | tuple | None = None
    hs_period_range_s: tuple | None = None
    period_kind: str = "peak"
    period_min_s: float | None = None
    period_max_s: float | None = None
    period_forbidden_s: tuple = ()
    beam_sectors_deg: tuple = ()
    gate_hs_m: float = 0.0
    source: str = ""

    def __post_init__(self):
        if self.period_kind not in PERIOD_KINDS:
            raise OperatorProfileError(f"limits {self.name!r}: period_kind must be one of {sorted(PERIOD_KINDS)}, got {self.period_kind!r}")
        object.__setattr__(self, "period_forbidden_s", _interval_list(self.period_forbidden_s, f"limits {self.name!r} period_forbidden_s"))
        object.__setattr__(self, "beam_sectors_deg", _interval_list(self.beam_sectors_deg, f"limits {self.name!r} beam_sectors_deg"))
        for key in ("hs_max_m", "wind_max_ms"):
            v = getattr(self, key)
            if isinstance(v, (list, tuple)):
                object.__setattr__(self, key, _lpp_table(v, f"limits {self.name!r} {key}"))
        if self.hs_period_range_s is not None:
            rng = _interval_list([self.hs_period_range_s], f"limits {self.name!r} hs_period_range_s")
            object.__setattr__(self, "hs_period_range_s", rng[0])
        for key in ("hs_max_m", "wind_max_ms", "period_min_s", "period_max_s"):
            v = getattr(self, key)
            if v is not None and not isinstance(v, tuple) and not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise OperatorProfileError(f"limits {self.name!r}: {key} must be a non-negative number, got {v!r}")
        if not self.lpp_min_m < self.lpp_max_m:
            raise OperatorProfileError(f"limits {self.name!r}: lpp_min_m must be below lpp_max_m")

    @property
    def uses_period(self) -> bool:
        return self.period_min_s is not None or self.period_max_s is not None or bool(self.period_forbidden_s)

    @property
    def period_var(self) -> str:
        return PERIOD_KINDS[self.period_kind]

    def for_lpp(self, lpp_m: float) -> "OperatorLimits":
        """The limits with Lpp tables resolved for a vessel of length ``lpp_m`` (linear between the
        table's points, held beyond them)."""
        out = {}
        for key in ("hs_max_m", "wind_max_ms"):
            v = getattr(self, key)
            if isinstance(v, tuple):
                out[key] = float(np.interp(float(lpp_m), [a for a, _ in v], [b for _, b in v]))
        return replace(self, **out) if out else self

    def applies_to(self, vessel_class: str, lpp_m: float) -> bool:
        return self.vessel_class in ("*", vessel_class) and self.lpp_min_m <= lpp_m < self.lpp_max_m

    def to_dict(self) -> dict:
        d = asdict(self)
        for key in ("hs_max_m", "wind_max_ms"):
            if isinstance(d[key], tuple):
                d[key] = [list(x) for x in d[key]]
        if d["hs_period_range_s"] is not None:
            d["hs_period_range_s"] = list(d["hs_period_range_s"])
        d["period_forbidden_s"] = [list(x) for x in self.period_forbidden_s]
        d["beam_sectors_deg"] = [list(x) for x in self.beam_sectors_deg]
        return d

    @classmethod
    def from_dict(cls, data: dict, where: str = "") -> "OperatorLimits":
        """Build from a TOML table; unknown keys are an error naming them (typos must not pass)."""
        known = set(cls.__dataclass_fields__)
        unknown = sorted(set(data) - known)
        if unknown:
            raise OperatorProfileError(f"{where}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
        if "name" not in data:
            raise OperatorProfileError(f"{where}: every limits table needs a 'name'")
        kwargs = dict(data)
        for key in ("lpp_min_m", "lpp_max_m", "gate_hs_m"):
            if key in kwargs:
                kwargs[key] = float(kwargs[key])
        try:
            return cls(**kwargs)
        except OperatorProfileError as err:
            raise OperatorProfileError(f"{where}: {err}") from None
        except (TypeError, ValueError) as err:
            raise OperatorProfileError(f"{where}: {err}") from None


@dataclass(frozen=True)
class OperatorProfile:
    """A named set of :class:`OperatorLimits` variants (per vessel class and length)."""

    name: str
    limits: tuple = field(default_factory=tuple)
    description: str = ""
    imo: ImoSettings = field(default_factory=ImoSettings)

    def limits_for(self, vessel_class: str, lpp_m: float) -> OperatorLimits:
        """The variant for a vessel: an exact class match first, then a ``"*"`` variant."""
        for wanted in (vessel_class, "*"):
            for lim in self.limits:
                if lim.vessel_class == wanted and lim.applies_to(vessel_class, lpp_m):
                    return lim.for_lpp(lpp_m)
        raise OperatorProfileError(
            f"operator profile {self.name!r} has no limits for vessel class {vessel_class!r} with Lpp {lpp_m} m "
            f"(variants: {', '.join(l.name for l in self.limits) or 'none'})"
        )

    @classmethod
    def from_dict(cls, name: str, data: dict, where: str = "") -> "OperatorProfile":
        where = where or f"profile {name!r}"
        rows = data.get("limits")
        if not rows:
            raise OperatorProfileError(f"{where}: needs at least one [[...limits]] table")
        extra = sorted(set(data) - {"limits", "description", "imo"})
        if extra:
            raise OperatorProfileError(f"{where}: unknown key(s) {', '.join(extra)} (allowed: description, imo, limits)")
        limits = tuple(OperatorLimits.from_dict(row, f"{where} limits[{i}]") for i, row in enumerate(rows))
        try:
            imo = ImoSettings.from_dict(data.get("imo"), f"{where} imo")
        except StormlaneError as err:
            raise OperatorProfileError(str(err)) from None
        return cls(name=name, limits=limits, description=str(data.get("description", "")), imo=imo)


def _arr(x):
    return None if x is None else np.asarray(x, dtype=float)


def _in_ranges(x, ranges):
    """(inside any closed range, depth inside the best range: min(x − lo, hi − x))."""
    inside = np.zeros(np.shape(x), dtype=bool)
    depth = np.full(np.shape(x), -np.inf)
    for lo, hi in ranges:
        d = np.minimum(x - lo, hi - x)
        inside |= d >= 0
        depth = np.fmax(depth, d)
    return inside, depth


def evaluate_operator(
    limits: OperatorLimits,
    hs_m=None,
    wave_from_deg=None,
    tp_s=None,
    tm_s=None,
    wind_u_ms=None,
    wind_v_ms=None,
    wind_ms=None,
    heading_deg=None,
    missing: str = "raise",
) -> Assessment:
    """Evaluate operator limits ([1] Table 1 or a user profile) over arrays of any shape.

    Parameters
    ----------
    limits : OperatorLimits
    hs_m : numeric
        Significant wave height. [m]
    wave_from_deg : numeric, optional
        Mean wave direction, coming FROM. [deg]
    tp_s, tm_s : numeric, optional
        Peak and mean wave period; the one named by ``limits.period_kind`` is required when the
        limits have a period rule. [s]
    wind_u_ms, wind_v_ms : numeric, optional
        10 m wind components (or give ``wind_ms`` directly). [m/s]
    heading_deg : numeric, optional
        Ship's course; without it the beam-seas rule is not evaluated (heading-free screening).
    missing : {"raise", "skip"}
        What to do when a configured rule lacks its variable (e.g. a wave-only product and a wind
        limit): raise :class:`MissingWeatherVariableError`, or skip the rule and list it in
        ``Assessment.skipped`` so reports say it was not evaluated.

    Returns
    -------
    Assessment
        Rules ``hs`` (margin Hs − limit, m), ``wind`` (m/s), ``period`` (s: distance into the
        forbidden range / outside the allowed range), ``beam_seas`` (deg into the sector). A gated
        rule has NaN margin and limit where Hs < ``gate_hs_m``. ``no_data`` where an input of an
        evaluated rule is NaN (land).

    Raises
    ------
    MissingWeatherVariableError
        When a configured rule needs a variable that was not passed.

    Examples
    --------
    >>> lim = OperatorLimits(name="x", hs_max_m=6.0, wind_max_ms=22.6)
    >>> a = evaluate_operator(lim, hs_m=[5.0, 6.5], wind_ms=[25.0, 10.0])
    >>> a.reason_code.tolist()
    [4, 1]
    """
    if missing not in ("raise", "skip"):
        raise ValueError(f"missing must be 'raise' or 'skip', not {missing!r}")
    skipped: list[str] = []

    def lacking(rule: str, message: str) -> None:
        if missing == "raise":
            raise MissingWeatherVariableError(f"operator limits {limits.name!r}: {message}")
        skipped.append(f"{rule}: {message}")

    hs = _arr(hs_m)
    if hs is None and (limits.hs_max_m is not None or limits.gate_hs_m > 0):
        raise MissingWeatherVariableError(f"operator limits {limits.name!r} need hs_m (significant wave height)")
    gate = None
    if hs is not None:
        with np.errstate(invalid="ignore"):
            gate = hs >= limits.gate_hs_m if limits.gate_hs_m > 0 else ~np.isnan(hs)
    if isinstance(limits.hs_max_m, tuple) or isinstance(limits.wind_max_ms, tuple):
        raise OperatorProfileError(f"operator limits {limits.name!r} hold Lpp tables: resolve them with .for_lpp(lpp_m) first")
    p = _arr(tp_s if limits.period_kind == "peak" else tm_s)
    w = _arr(wind_ms) if wind_ms is not None else (
        np.hypot(_arr(wind_u_ms), _arr(wind_v_ms)) if wind_u_ms is not None and wind_v_ms is not None else None)
    results = [
        _hs_rule(limits, hs, p, skipped) if limits.hs_max_m is not None else None,
        _wind_rule(limits, w, lacking) if limits.wind_max_ms is not None else None,
        _period_rule(limits, p, gate, lacking) if limits.uses_period else None,
        _beam_rule(limits, wave_from_deg, heading_deg, gate, lacking) if limits.beam_sectors_deg and heading_deg is not None else None,
    ]
    rules = {r.name: r for r, _ in filter(None, results)}
    nan_masks = [m for _, m in filter(None, results)]
    no_data = np.logical_or.reduce(np.broadcast_arrays(*nan_masks)) if nan_masks else None
    return Assessment(rules, no_data, tuple(skipped))


def _hs_rule(limits: OperatorLimits, hs, p, skipped: list[str]):
    """The Hs limit; with a period range (MEPC.1/Circ.850/Rev.2's adverse-condition row) it fires
    only with a period in the row's range. Returns (rule, NaN mask of its input)."""
    with np.errstate(invalid="ignore"):
        fired = hs > limits.hs_max_m
        margin = hs - limits.hs_max_m
        if limits.hs_period_range_s is not None and p is not None:
            lo, hi = limits.hs_period_range_s
            in_range = (p >= lo) & (p <= hi)
            fired = fired & in_range
            margin = np.where(in_range, margin, np.nan)
    if limits.hs_period_range_s is not None and p is None:
        skipped.append(f"hs: no {limits.period_var} in the data: the Hs limit applied at every period "
                       f"(the table gives it for {limits.hs_period_range_s[0]:g}-{limits.hs_period_range_s[1]:g} s)")
    return RuleResult("hs", fired, margin, "m", hs, limits.hs_max_m), np.isnan(hs)


def _wind_rule(limits: OperatorLimits, w, lacking):
    """The 10 m wind limit; None (and the rule listed as lacking) without wind."""
    if w is None:
        lacking("wind", "needs 10 m wind (wind_ms or wind_u_ms + wind_v_ms), not in the data")
        return None
    with np.errstate(invalid="ignore"):
        return RuleResult("wind", w > limits.wind_max_ms, w - limits.wind_max_ms, "ms", w, limits.wind_max_ms), np.isnan(w)


def _period_rule(limits: OperatorLimits, p, gate, lacking):
    """The wave-period rule: outside the allowed range or inside a forbidden one, gated by Hs.
    Margin > 0 outside the allowed range, >= 0 inside a forbidden range."""
    if p is None:
        lacking("period", f"needs {limits.period_var} ({limits.period_kind} wave period), not in the data")
        return None
    with np.errstate(invalid="ignore"):
        out_lo = (limits.period_min_s - p) if limits.period_min_s is not None else np.full(p.shape, -np.inf)
        out_hi = (p - limits.period_max_s) if limits.period_max_s is not None else np.full(p.shape, -np.inf)
        margin = np.maximum(out_lo, out_hi)
        fired = margin > 0
        if limits.period_forbidden_s:
            inside, depth = _in_ranges(p, limits.period_forbidden_s)
            fired = fired | inside
            margin = np.maximum(margin, depth)
        if gate is not None and limits.gate_hs_m > 0:
            fired = fired & gate
            margin = np.where(gate, margin, np.nan)
    limit = limits.period_max_s if limits.period_max_s is not None else np.nan
    return RuleResult("period", fired, margin, "s", p, np.where(np.isnan(margin), np.nan, limit)), np.isnan(p)


def _beam_rule(limits: OperatorLimits, wave_from_deg, heading_deg, gate, lacking):
    """The beam-seas sectors of the wave direction relative to the heading, gated by Hs."""
    if wave_from_deg is None:
        lacking("beam_seas", "needs wave_from_deg (mean wave direction), not in the data")
        return None
    alpha = np.mod(_arr(wave_from_deg) - _arr(heading_deg), 360.0)
    with np.errstate(invalid="ignore"):
        fired, margin = _in_ranges(alpha, limits.beam_sectors_deg)
        if gate is not None and limits.gate_hs_m > 0:
            fired = fired & np.broadcast_to(gate, np.broadcast_shapes(gate.shape, fired.shape))
            margin = np.where(gate, margin, np.nan)
    return RuleResult("beam_seas", fired, margin, "deg", alpha, np.nan), np.isnan(alpha)
