"""Safety-constrained routing: the vessel's limits on the routing mesh, per weather slice and heading.

The time-optimal A* minimises sailing time only; on Storm Gloria its reroute still sails through
cells that break a container feeder's operator limits. This module turns the vessel's thresholds
(operator limits of :mod:`thresholds.operator` and the IMO MSC.1/Circ.1228 criteria of
:mod:`thresholds.imo_msc1228`, both through :func:`thresholds.safety.assess`) into flags the
compiled search reads (:func:`routing._kernels.astar_safe`):

``unsafe[k, row]`` (uint16)
    bit ``s`` set when a rule fires at sea node ``row`` in weather slice ``k`` for a ship whose
    course lies in heading sector ``s``. Sector ``s`` spans ``[s·w − w/2, s·w + w/2)`` with
    ``w = 360°/sectors`` (16 sectors: 22.5° each, sector 0 centred on north).

The flags are computed **vectorised, once per weather slice**, never per edge: the heading-free
rules (Hs, wind, period) on every node of the slice at once; the heading-dependent rules (beam
seas, surf-riding, successive high waves -- its encounter-period band depends on the heading --,
synchronous and parametric roll) only where the heading-free ones pass and the rules' Hs gate
is reached (for high waves: its wave conditions hold), for ``samples_per_sector`` headings
across each sector (both edges included, every 5.6° by default), a sector being unsafe when a rule
fires at any of them. The speed entering the IMO rules is the speed through the water the ship
makes on that heading in that weather (the router's speed-loss model), as the search sails it.
Beam seas are judged exactly by the edge samples (the forbidden sectors of [1] Table 1 are wider
than a heading sector); the resonance bands of the roll rules can be narrower than the sample
spacing, so a route is always re-judged afterwards at its exact headings and ETAs
(:func:`limits_exposure`).

How the search uses them (documented in :func:`routing._kernels.astar_safe`): an edge is unsafe
when any mesh cell it touches (start, end and crossed cells) is flagged for the edge's heading
sector in a weather slice bracketing the time the ship sails it. ``hard`` forbids unsafe edges;
``soft`` charges ``penalty_per_h`` extra hours per hour sailed on them (penalties only add cost,
so the A* heuristic stays admissible; penalty 0 is the plain time-optimal search). The start and
goal nodes are exempt (the ship must leave and reach them); their conditions still show in
:func:`limits_exposure`.

References
----------
.. [1] K. Spyrou-Sioula et al., "AIS-enabled weather routing for cargo loss prevention," J. Mar.
       Sci. Eng., vol. 10, no. 11, 1755, 2022, doi:10.3390/jmse10111755, §3.2 and Table 1.
.. [2] IMO, "Revised guidance to the master for avoiding dangerous situations in adverse weather
       and sea conditions," MSC.1/Circ.1228, 2007.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np
import pandas as pd

from routing.route import Route

#: Safety modes of the router: no constraint, penalised exposure, forbidden exposure.
SAFETY_MODES = ("none", "soft", "hard")
#: Default extra cost of one hour sailed over the limits in ``soft`` mode (hours of cost per
#: hour of exposure: an hour in breaking conditions weighs like 11 hours of sailing). [h/h]
DEFAULT_PENALTY_PER_H = 10.0
#: Heading sectors of the flags (22.5° each).
DEFAULT_SECTORS = 16
#: Headings judged per sector, both edges included (every 22.5°/4 = 5.6°).
DEFAULT_SAMPLES_PER_SECTOR = 5
#: The flags are uint16: at most 16 sectors.
MAX_SECTORS = 16
#: Elements (headings × cells) per vectorised evaluation, to bound memory.
_CHUNK_ELEMENTS = 2_000_000
#: Longest piece of a route judged as one by :func:`limits_exposure`. [h]
EXPOSURE_STEP_H = 0.1


@dataclass(frozen=True)
class SafetySpec:
    """What the safety-constrained search respects, and how.

    Attributes
    ----------
    mode : {"none", "soft", "hard"}
    vessel : thresholds.vessel.Vessel
        Class and Lpp (operator-limit variant, IMO L), beam, draught and GM or roll period (IMO
        roll rules).
    limits : OperatorProfile, OperatorLimits or None
        Operator limits (a profile brings its IMO settings); ``None`` = IMO rules only.
    penalty_per_h : float
        ``soft``: extra hours of cost per hour sailed over the limits (≥ 0). Also used by
        ``hard`` when it falls back to ``soft``.
    sectors : int
        Heading sectors of the flags, 1–16.
    samples_per_sector : int
        Headings judged per sector, both edges included (≥ 2).
    imo_settings : ImoSettings, optional
        Overrides the profile's IMO settings.
    """

    mode: str
    vessel: object
    limits: object = None
    penalty_per_h: float = DEFAULT_PENALTY_PER_H
    sectors: int = DEFAULT_SECTORS
    samples_per_sector: int = DEFAULT_SAMPLES_PER_SECTOR
    imo_settings: object = None

    def __post_init__(self):
        if self.mode not in SAFETY_MODES:
            raise ValueError(f"safety must be one of {', '.join(SAFETY_MODES)}, got {self.mode!r}")
        if self.mode != "none" and self.vessel is None:
            raise ValueError("safety-constrained routing needs the vessel (class, Lpp, beam, draught, GM)")
        p = self.penalty_per_h
        if not (isinstance(p, (int, float)) and math.isfinite(p) and p >= 0.0):
            raise ValueError(f"penalty_per_h must be a finite number >= 0, got {p!r}")
        if not (isinstance(self.sectors, (int, np.integer)) and 1 <= int(self.sectors) <= MAX_SECTORS):
            raise ValueError(f"sectors must be an integer in 1..{MAX_SECTORS}, got {self.sectors!r}")
        if not (isinstance(self.samples_per_sector, (int, np.integer)) and int(self.samples_per_sector) >= 2):
            raise ValueError(f"samples_per_sector must be an integer >= 2, got {self.samples_per_sector!r}")

    @property
    def operator_limits(self):
        """The :class:`~thresholds.operator.OperatorLimits` variant for the vessel (or None)."""
        from thresholds.operator import OperatorProfile

        if self.limits is None:
            return None
        if isinstance(self.limits, OperatorProfile):
            return self.limits.limits_for(self.vessel.vessel_class, self.vessel.lpp_m)
        return self.limits.for_lpp(self.vessel.lpp_m)

    @property
    def imo(self):
        """IMO settings in force: the override, else the profile's, else the defaults."""
        from thresholds.imo_msc1228 import ImoSettings
        from thresholds.operator import OperatorProfile

        if self.imo_settings is not None:
            return self.imo_settings
        if isinstance(self.limits, OperatorProfile):
            return self.limits.imo
        return ImoSettings()

    def describe(self) -> dict:
        """JSON-serialisable summary for route properties."""
        lim = self.operator_limits
        return {
            "mode": self.mode,
            "operator_limits": None if lim is None else lim.name,
            "imo_rules": bool(self.imo.enabled),
            "penalty_per_h": float(self.penalty_per_h),
            "sectors": int(self.sectors),
            "samples_per_sector": int(self.samples_per_sector),
        }


@dataclass(frozen=True)
class SafetyFlags:
    """The flags the compiled search reads, for one mesh and weather.

    Attributes
    ----------
    unsafe : ndarray of uint16, shape (n_slices, n_sea)
        Bit ``s`` = unsafe for heading sector ``s`` (see the module docstring).
    sectors : int
    n_times : int
        Slices of the weather on the mesh; the flags cover ``unsafe.shape[0]`` of them.
    hard : bool
    penalty_per_h : float
    skipped : tuple of str
        Rules not evaluated (variable absent from the weather, no GM ...).
    """

    unsafe: np.ndarray
    sectors: int
    n_times: int
    hard: bool
    penalty_per_h: float
    skipped: tuple = ()

    @property
    def complete(self) -> bool:
        return self.unsafe.shape[0] >= self.n_times

    def with_mode(self, mode: str, penalty_per_h: float | None = None) -> "SafetyFlags":
        if mode not in ("soft", "hard"):
            raise ValueError(f"mode must be 'soft' or 'hard', got {mode!r}")
        pen = self.penalty_per_h if penalty_per_h is None else float(penalty_per_h)
        return dataclasses.replace(self, hard=mode == "hard", penalty_per_h=pen)


def sector_width_deg(sectors: int) -> float:
    return 360.0 / int(sectors)


def sector_of(course_deg, sectors: int):
    """Heading sector of a course (sector 0 centred on north). int ndarray

    Examples
    --------
    >>> sector_of([0.0, 11.0, 12.0, 90.0, 350.0], 16).tolist()
    [0, 0, 1, 4, 0]
    """
    w = sector_width_deg(sectors)
    s = np.floor(np.mod(np.asarray(course_deg, dtype=float) + 0.5 * w, 360.0) / w).astype(np.int64)
    return np.clip(s, 0, int(sectors) - 1)


def sample_headings(sectors: int, samples_per_sector: int) -> tuple[np.ndarray, np.ndarray]:
    """Headings judged for the flags and, per sector, the indices of its samples.

    Returns
    -------
    headings : ndarray, shape (sectors · (samples − 1),)
        Sector s contributes its left edge and the interior samples; its right edge is the next
        sector's left edge. [deg, in [0, 360)]
    members : ndarray of int, shape (sectors, samples)
        ``headings[members[s]]`` are the samples of sector s, both edges included.

    Examples
    --------
    >>> h, m = sample_headings(4, 3)
    >>> h.tolist(), h[m[0]].tolist()
    ([315.0, 0.0, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0], [315.0, 0.0, 45.0])
    """
    w = sector_width_deg(sectors)
    n = int(samples_per_sector)
    per = n - 1
    total = int(sectors) * per
    idx = np.arange(total)
    headings = np.mod((idx // per) * w - 0.5 * w + (idx % per) * (w / per), 360.0)
    members = (np.arange(int(sectors))[:, None] * per + np.arange(n)[None, :]) % total
    return headings, members


def edge_sector_bits(mesh, sectors: int) -> np.ndarray:
    """Bit of the heading sector of every stencil edge's initial course, per mesh row. (ny, K) uint16"""
    _, ecos, esin = mesh.edge_geometry
    course = np.degrees(np.arctan2(esin, ecos))
    return (np.uint16(1) << sector_of(course, sectors).astype(np.uint16)).astype(np.uint16)


def _heading_limits(lim):
    """The heading-dependent part of an operator-limits variant (beam seas and its gate)."""
    if lim is None or not lim.beam_sectors_deg:
        return None
    return dataclasses.replace(lim, hs_max_m=None, wind_max_ms=None, hs_period_range_s=None, period_min_s=None, period_max_s=None,
                               period_forbidden_s=())


def unsafe_flags(spec: SafetySpec, ship, weather: Mapping[str, np.ndarray], *, method: str = "compiled") -> tuple[np.ndarray, tuple]:
    """Per-heading-sector unsafe flags of weather arrays, by the vessel's threshold functions.

    Parameters
    ----------
    spec : SafetySpec
    ship : routing.astar.ShipModel
        Calm-water speed and speed-loss model: the IMO rules see the speed through the water the
        ship makes on each heading (``speed_kn``, ``model``, ``lpp_m``, ``dwt_t``, ``floor_kn``,
        ``bowditch_sectors``).
    weather : mapping of str -> ndarray, shape S
        ``hs_m`` and, as available, ``wave_from_deg``, ``tp_s``, ``tm_s``, ``wind_u_ms``,
        ``wind_v_ms`` (canonical names, one shape, e.g. (slices, nodes)).
    method : {"compiled", "numpy"}
        How the heading-dependent rules are evaluated on the candidate cells: ``"numpy"`` calls
        :func:`thresholds.safety.assess` on (headings × cells) arrays; ``"compiled"`` (default,
        about 20× faster: on R6 2 s against 0.1 s) runs its compiled twin
        :func:`routing._kernels.heading_flags`, tested equal to it. The heading-free rules always
        go through :func:`thresholds.safety.assess`.

    Returns
    -------
    flags : ndarray of uint16, shape S
        Bit s set where a rule fires for a course in sector s; all sector bits where a heading-free
        rule fires (or data are missing).
    skipped : tuple of str
        Rules not evaluated, as :func:`thresholds.safety.assess` lists them.
    """
    from routing.speed_loss import SpeedLossValidityWarning
    from thresholds.safety import assess

    hs = np.asarray(weather["hs_m"], dtype=float)
    shape = hs.shape
    sectors = int(spec.sectors)
    all_bits = np.uint16((1 << sectors) - 1)
    names = ("tp_s", "tm_s", "wind_u_ms", "wind_v_ms")
    free_kw = {k: np.asarray(weather[k], dtype=float).reshape(-1) for k in names if k in weather}
    hs_f = hs.reshape(-1)
    imo = spec.imo
    lim = spec.operator_limits
    a0 = assess(spec.vessel, lim, hs_m=hs_f, heading_deg=None, imo_settings=imo, missing="skip", **free_kw)
    free_unsafe = np.broadcast_to(a0.reason_code != 0, hs_f.shape)
    flags = np.where(free_unsafe, all_bits, np.uint16(0)).astype(np.uint16)

    # rules not evaluated, as a route with a heading would list them
    probe_kw = {k: v[:1] for k, v in free_kw.items()}
    wf = weather.get("wave_from_deg")
    if wf is not None:
        probe_kw["wave_from_deg"] = np.asarray(wf, dtype=float).reshape(-1)[:1]
    skipped = tuple(assess(spec.vessel, lim, hs_m=hs_f[:1], heading_deg=np.zeros(1), imo_settings=imo, missing="skip", **probe_kw).skipped)

    lim_h = _heading_limits(lim)
    if wf is None or (lim_h is None and not imo.enabled):
        return flags.reshape(shape), skipped
    gates = []
    if lim_h is not None:
        gates.append(lim_h.gate_hs_m)
    if imo.enabled:
        gates.append(imo.gate_hs_m)
    gate = min(gates)
    hw_pre = _high_wave_conditions(spec, hs_f, free_kw)
    with np.errstate(invalid="ignore"):
        cand = ~free_unsafe & (hs_f >= gate) if gate > 0 else ~free_unsafe & np.isfinite(hs_f)
        cand |= ~free_unsafe & hw_pre
    idx = np.flatnonzero(cand)
    if idx.size == 0:
        return flags.reshape(shape), skipped
    headings, members = sample_headings(sectors, spec.samples_per_sector)
    H = headings.size
    wf_f = np.asarray(wf, dtype=float).reshape(-1)
    if method == "compiled":
        flags[idx] |= _heading_flags_compiled(spec, ship, lim_h, imo, hs_f[idx], wf_f[idx], {k: v[idx] for k, v in free_kw.items()},
                                              headings, members, hw_pre[idx])  # fmt: skip
        return flags.reshape(shape), skipped
    if method != "numpy":
        raise ValueError(f"method must be 'compiled' or 'numpy', got {method!r}")
    bit_of = (np.uint16(1) << np.arange(sectors, dtype=np.uint16)).astype(np.uint16)
    chunk = max(1, _CHUNK_ELEMENTS // H)
    heading = headings[:, None]
    for a in range(0, idx.size, chunk):
        sel = idx[a : a + chunk]
        hs_c = hs_f[sel][None, :]
        wf_c = wf_f[sel][None, :]
        enc = np.mod(wf_c - heading, 360.0)  # 0 = head seas
        wind_kw = {}
        if ship.wind_driven:
            u, v = free_kw["wind_u_ms"][sel][None, :], free_kw["wind_v_ms"][sel][None, :]
            wind_kw = {"wind_ms": np.broadcast_to(np.hypot(u, v), enc.shape),
                       "wind_encounter_deg": np.mod(np.degrees(np.arctan2(-u, -v)) - heading, 360.0)}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SpeedLossValidityWarning)
            speed = ship.attained_kn(np.broadcast_to(hs_c, enc.shape), enc, **wind_kw)
        kw = {k: v[sel][None, :] for k, v in free_kw.items()}
        a1 = assess(spec.vessel, lim_h, hs_m=hs_c, wave_from_deg=wf_c, heading_deg=heading, speed_kn=speed, imo_settings=imo,
                    missing="skip", **kw)  # fmt: skip
        fired = np.broadcast_to(a1.reason_code != 0, (H, sel.size))
        sec = fired[members].any(axis=1)  # (sectors, m)
        bits = np.bitwise_or.reduce(np.where(sec, bit_of[:, None], np.uint16(0)), axis=0).astype(np.uint16)
        flags[sel] |= bits
    return flags.reshape(shape), skipped


def _high_wave_conditions(spec, hs, free_kw) -> np.ndarray:
    """Where the wave conditions of successive high-wave attack hold (MSC.1/Circ.1228 4.2.2.1:
    λ(T_W) > 0.8 L and Hs > 0.04 L, T_W the mean period, else the peak): the heading decides the rest."""
    from thresholds import imo_msc1228 as imo_rules

    tw = free_kw.get("tm_s", free_kw.get("tp_s"))
    if not spec.imo.enabled or tw is None:
        return np.zeros(hs.shape, dtype=bool)
    length = float(spec.vessel.lpp_m)
    with np.errstate(invalid="ignore"):
        return (imo_rules.wave_length_m(tw) > imo_rules.HIGH_WAVE_LENGTH_FRAC * length) & (hs > imo_rules.HIGH_WAVE_HEIGHT_FRAC * length)


def _heading_flags_compiled(spec, ship, lim_h, imo, hs, wf, free_kw, headings, members, hw_pre) -> np.ndarray:
    """Sector bits of the heading-dependent rules by :func:`routing._kernels.heading_flags`."""
    from routing import _kernels
    from thresholds import imo_msc1228 as imo_rules
    from thresholds.safety import roll_period_of

    use_beam = lim_h is not None
    ranges = np.asarray(lim_h.beam_sectors_deg if use_beam else np.zeros((0, 2)), dtype=float).reshape(-1, 2)
    # which rules assess() would evaluate (it skips the roll rules without a period or T_R)
    period = free_kw.get("tp_s", free_kw.get("tm_s"))  # encounter period: Tp, else Tm (thresholds.safety)
    tr = roll_period_of(spec.vessel)
    use_roll = bool(imo.enabled and period is not None and tr is not None)
    length = float(spec.vessel.lpp_m)
    surf_num = imo_rules.SURF_RIDING_COEFF * math.sqrt(length)
    v_max = ship.max_speed_kn(float(np.max(hs)) if hs.size else 0.0)
    use_surf = bool(imo.enabled and v_max > surf_num)  # V > 1.8 sqrt(L) / cos(.) >= 1.8 sqrt(L) is then impossible
    if imo_rules.SURF_RIDING_SECTOR_DEG != (135.0, 225.0):  # the compiled twin hard-codes the circular's sector
        raise RuntimeError("thresholds.imo_msc1228.SURF_RIDING_SECTOR_DEG changed; update routing._kernels.heading_flags")
    spd_mag, spd_from = hs, wf  # the sea state the speed model reads: waves, or the wind for Kwon
    if ship.wind_driven:
        u, v = free_kw["wind_u_ms"], free_kw["wind_v_ms"]
        spd_mag, spd_from = np.hypot(u, v), np.mod(np.degrees(np.arctan2(-u, -v)), 360.0)
    return _kernels.heading_flags(
        np.ascontiguousarray(hs, dtype=float), np.ascontiguousarray(wf, dtype=float),
        np.ascontiguousarray(period if period is not None else np.zeros(hs.size), dtype=float),
        np.ascontiguousarray(spd_mag, dtype=float), np.ascontiguousarray(spd_from, dtype=float),
        np.ascontiguousarray(headings, dtype=float), np.ascontiguousarray(members, dtype=np.int64), ship.params(),
        np.ascontiguousarray(ranges[:, 0]), np.ascontiguousarray(ranges[:, 1]), float(lim_h.gate_hs_m if use_beam else 0.0), use_beam,
        float(imo.gate_hs_m), bool(imo.enabled), float(surf_num), use_surf, float(tr or 1.0), float(imo.roll_tolerance_frac), use_roll,
        np.ascontiguousarray(free_kw.get("tm_s", free_kw.get("tp_s", np.zeros(hs.size))), dtype=float),
        np.ascontiguousarray(hw_pre, dtype=np.bool_), float(imo_rules.HIGH_WAVE_TE_RANGE[0]), float(imo_rules.HIGH_WAVE_TE_RANGE[1]),
    )  # fmt: skip


def mesh_weather_slices(mw, k0: int, k1: int) -> dict:
    """The canonical weather of slices ``k0:k1`` of a :class:`routing.field.MeshWeather` (slices × sea nodes)."""
    out = {"hs_m": mw.wave[k0:k1, :, 0]}
    if mw.has_direction:
        out["wave_from_deg"] = np.mod(np.degrees(np.arctan2(mw.wave[k0:k1, :, 2], mw.wave[k0:k1, :, 1])), 360.0)
    for name in ("tp_s", "tm_s", "wind_u_ms", "wind_v_ms"):
        if name in mw.extra:
            out[name] = mw.extra[name][k0:k1]
    return out


def build_flags(spec: SafetySpec, ship, mw, n_sea: int, n_slices: int | None = None, *, extend: SafetyFlags | None = None) -> SafetyFlags:
    """Unsafe flags of the mesh weather's first ``n_slices`` slices (all by default).

    Slices are evaluated in blocks of about a million node-slices (memory stays bounded on
    MEDSEA-size meshes); ``extend`` reuses the slices an earlier call computed. Without weather
    (calm sea) nothing is flagged.
    """
    mode = spec.mode if spec.mode != "none" else "soft"
    if mw is None:
        return SafetyFlags(np.zeros((1, n_sea), dtype=np.uint16), int(spec.sectors), 1, mode == "hard", float(spec.penalty_per_h),
                           ("no weather: every cell passes",))  # fmt: skip
    n_times = int(mw.n_times)
    n = n_times if n_slices is None else int(min(max(n_slices, 1), n_times))
    k_start = 0
    skipped: tuple = ()
    if extend is not None:
        if extend.unsafe.shape[0] >= n:
            return extend
        k_start = extend.unsafe.shape[0]
        skipped = extend.skipped
    out = np.empty((n, mw.wave.shape[1]), dtype=np.uint16)
    if k_start:
        out[:k_start] = extend.unsafe
    block = max(1, 1_000_000 // max(mw.wave.shape[1], 1))
    for k0 in range(k_start, n, block):
        k1 = min(n, k0 + block)
        out[k0:k1], skipped = unsafe_flags(spec, ship, mesh_weather_slices(mw, k0, k1))
    if extend is not None:
        return dataclasses.replace(extend, unsafe=out, skipped=skipped)
    return SafetyFlags(out, int(spec.sectors), n_times, mode == "hard", float(spec.penalty_per_h), skipped)


def limits_exposure(route: Route, weather_at: Callable, spec: SafetySpec, *, max_step_h: float = EXPOSURE_STEP_H) -> dict:
    """Hours a route spends over the vessel's limits, judged at its own ETAs and exact headings.

    Every leg is cut into pieces of at most ``max_step_h``; at the middle of each piece the
    weather (``weather_at(times, lat, lon)``, canonical names, NaN off the data) meets
    :func:`thresholds.safety.assess` with the piece's course and the leg's speed. Independent of
    the search's flags (sectors, slices, cells), so it says what the route really meets.

    Returns
    -------
    dict
        ``hours_over_limits`` (any operator or IMO rule), ``operator_h``, ``imo_h``,
        ``hours_by_rule`` (rules that fired), ``no_weather_h``, ``rules_not_evaluated``.
    """
    from routing.evaluate import IMO_RULES, densify
    from thresholds.safety import assess

    samples = densify(route, max_step_h)
    out = {"hours_over_limits": 0.0, "operator_h": 0.0, "imo_h": 0.0, "hours_by_rule": {}, "no_weather_h": 0.0, "rules_not_evaluated": []}
    if samples.empty:
        return out
    times = pd.DatetimeIndex(samples["time_utc"])
    raw = weather_at(times, samples["lat_deg"].to_numpy(), samples["lon_deg"].to_numpy())
    kw = {k: np.asarray(raw[k], dtype=float).reshape(-1) for k in ("hs_m", "wave_from_deg", "tp_s", "tm_s", "wind_u_ms", "wind_v_ms") if k in raw}
    if "hs_m" not in kw:
        kw["hs_m"] = np.full(len(samples), np.nan)
    heading = samples["heading_deg"].to_numpy()
    a = assess(spec.vessel, spec.operator_limits, heading_deg=heading, speed_kn=samples["speed_kn"].to_numpy(), imo_settings=spec.imo,
               missing="skip", **kw)  # fmt: skip
    dt = samples["dt_h"].to_numpy()
    n = dt.size
    any_op = np.zeros(n, dtype=bool)
    any_imo = np.zeros(n, dtype=bool)
    by_rule = {}
    for name, rule in a.rules.items():
        fired = np.broadcast_to(np.asarray(rule.fired, dtype=bool), (n,))
        if fired.any():
            by_rule[name] = round(float(dt[fired].sum()), 6)
        if name in IMO_RULES:
            any_imo |= fired
        else:
            any_op |= fired
    nd = np.broadcast_to(np.asarray(a.no_data, dtype=bool), (n,)) if a.no_data is not None else np.zeros(n, dtype=bool)
    out.update(
        hours_over_limits=round(float(dt[any_op | any_imo].sum()), 6),
        operator_h=round(float(dt[any_op].sum()), 6),
        imo_h=round(float(dt[any_imo].sum()), 6),
        hours_by_rule=by_rule,
        no_weather_h=round(float(dt[nd].sum()), 6),
        rules_not_evaluated=list(a.skipped),
    )
    return out
