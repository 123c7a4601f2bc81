"""The engine setting of every leg of a route, from the speed it made, and STEAM2 at that setting (issue 20).

A route's legs carry times, not engine settings (an AIS track, a lane, an A* route, a least-fuel route in a
comparison table). The evaluation charges each leg the engine setting ``s`` (a calm-water speed) whose speed
made in the weather met equals the leg's own speed ``v`` (its distance over its time):

    u(s) = sum_i w_i * g_i(s) / sum_i w_i = v,     g_i(s) = sog_i(max(s - loss_i(s), min(floor, s)))

over the leg's samples i (:func:`routing.samples.densify`'s pieces, ``w_i`` their hours), ``loss_i(s)`` the
chosen speed-loss model at the setting ``s`` in sample i's weather (:func:`routing.speed_loss.speed_loss`; NaN, no
weather, counts as calm), ``floor`` the vessel's ``min_speed_kn``, and ``sog_i`` the speed over ground in the
sample's current (the ship crabs to hold its course: ``sqrt(v^2 - cross^2) + along``, the planner's pace of
:mod:`routing._kernels.speed`; no current: ``sog_i(v) = v``). The time-weighted mean of the pieces' speeds is the
leg's distance over its time (equal pieces: :func:`routing.samples.densify`), which is why the mean is of speeds.
The leg is then charged as a planned setting is (:func:`setting_legs`): the power ``P(s)``
(:func:`routing.emissions.leg_power_kw` with the loss at ``s``: the wave increase restores the setting) over the
leg's time. A route planned with a setting per leg therefore evaluates to the fuel it was planned with, whether
or not it carries its settings, up to the difference between the planner's weather (a mesh edge's, or a polyline
piece's, two ends averaged at the quarter-hour nearest the time the ship leaves: :mod:`routing._kernels.edge`) and
the evaluation's samples (every 15 min along the leg, at the time the ship is there).

Monotonicity (why bisection finds the root). Every wave model's loss is affine in the setting at a given sea:
Bowditch ``f H^2`` (no ``s``), Aertssen ``c s`` and a learned table ``(1 - r) s`` with ``c`` or ``1 - r`` in
[0, 1), Khokhlov ``A (1 - C D s)`` (speed made ``s (1 + A C D) - A``, slope > 0 since ``|A C D| < 1`` in its
published range); so ``s - loss(s)`` is non-decreasing, and so are the floor's ``max`` and the current's ``sog``.
Kwon's loss ``s C_beta C_U(Fn) C_form`` falls in relative terms as the Froude number grows (``C_U`` decreases), so
its speed made rises with ``s`` too up to Beaufort 10 head winds; beyond, its raw loss exceeds the speed and the
floor holds the speed made (both checked in the tests). (The evaluation gives Kwon no wind: its loss is NaN there,
counted as calm, and the evaluation's speed-loss warnings say so.) Affine losses are solved in closed form
(``s = (v + A) / (1 - B)``, ``A`` and ``B`` the leg's time-weighted intercept and slope, from the model at s = 0 and
1 and checked against its loss at the service speed on every sample, a third point), each root checked with the
floor applied; legs where a check fails (a sample at the floor, a current, a loss that is not affine) are bisected.

Where several settings make the leg's speed (every sample of the leg held at the floor: the speed does not tell the
setting) the one nearest the vessel's service speed is taken, so a route sailed at the service speed evaluates as
it was sailed (``floor_legs`` counts them). A leg whose speed no setting up to the engine's maximum-power speed
(:func:`routing.fuel.max_power_speed_kn`) makes is charged the maximum continuous power over its time and flagged
``power_limited`` (``above_max_power_legs``): the model says this engine could not have sailed it so fast.

References
----------
.. [1] J.-P. Jalkanen et al., Atmos. Chem. Phys. 9, 9209-9223, 2009, doi:10.5194/acp-9-9209-2009 (STEAM2, P(v)).
.. [2] M. Grifoll et al., Ocean Eng. 255, 111427, 2022, doi:10.1016/j.oceaneng.2022.111427 (Eq. 2-3, Appendix I).
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from routing.emissions import Engine, steam2_legs

#: Speed-made tolerance of the solved setting (closed-form check and bisection stop). [kn]
SOLVE_TOL_KN = 1e-9
#: Bisection steps: a bracket of at most ~30 kn halved down to 1e-9 kn needs 35.
BISECTION_STEPS = 48


class _Samples:
    """What the solver needs of a leg's samples: leg index, hours, sea, encounter, current (along, cross) [kn]."""

    def __init__(self, samples: pd.DataFrame, weather: dict, enc, n_legs: int, model: str, vessel, learned, at_service=None):
        from thresholds.units import MS_PER_KN

        n = len(samples)
        self.leg = samples["leg"].to_numpy() if n else np.zeros(0, dtype=np.int64)
        self.w = samples["dt_h"].to_numpy(dtype=float) if n else np.zeros(0)
        self.den = np.bincount(self.leg, weights=self.w, minlength=n_legs)
        self.hs = np.nan_to_num(np.asarray(weather.get("hs_m", np.zeros(n)), dtype=float), nan=0.0)
        self.enc = np.nan_to_num(np.asarray(enc, dtype=float), nan=0.0)
        self.model, self.vessel, self.learned, self.n_legs = model, vessel, learned, n_legs
        self.floor = float(vessel.min_speed_kn)
        self.cur = None
        if n and "current_u_ms" in weather and "current_v_ms" in weather:
            u = np.nan_to_num(np.asarray(weather["current_u_ms"], dtype=float), nan=0.0) / MS_PER_KN
            v = np.nan_to_num(np.asarray(weather["current_v_ms"], dtype=float), nan=0.0) / MS_PER_KN
            if np.any(u != 0.0) or np.any(v != 0.0):
                h = np.deg2rad(samples["heading_deg"].to_numpy(dtype=float))
                self.cur = (u * np.sin(h) + v * np.cos(h), u * np.cos(h) - v * np.sin(h))  # (along, cross), as the planner's pace
        self.affine = None
        if n and at_service is not None:
            self.affine = self._affine(np.nan_to_num(np.asarray(at_service, dtype=float), nan=0.0))

    def _model(self, s, hs, enc, floor: bool):
        from routing.speed_loss import speed_loss

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the evaluation reports the model's warnings once (its speed-loss columns)
            out = speed_loss(s, hs, enc, self.model, vessel=self.vessel, learned=self.learned, floor_kn=None if floor else -np.inf)
        return np.nan_to_num(np.asarray(out, dtype=float).reshape(-1), nan=0.0)

    def _affine(self, at_service):
        """``(a, b)`` with the unfloored loss ``a + b s`` (from s = 0 and 1), when that reproduces the model's loss at
        the service speed (the evaluation's column) on every sample the floor does not hold; else None."""
        n = self.leg.size
        ab = self._model(np.r_[np.zeros(n), np.ones(n)], np.r_[self.hs, self.hs], np.r_[self.enc, self.enc], floor=False)
        a, b = ab[:n], ab[n:] - ab[:n]
        v0 = float(self.vessel.speed_kn)
        raw = a + b * v0
        free = raw < v0 - min(self.floor, v0) - 1e-9  # not held at the floor at the service speed: the column is the raw loss
        if not free.any() or np.any(np.abs(raw[free] - at_service[free]) > 1e-9 * np.maximum(1.0, np.abs(at_service[free]))):
            return None
        return a, b

    def loss(self, s, floor: bool = True, idx=None):
        """The model's loss at setting ``s`` (per sample) in the samples ``idx`` (NaN = calm), the floor applied. [kn]"""
        s = np.asarray(s, dtype=float)
        if self.affine is None:
            hs, enc = (self.hs, self.enc) if idx is None else (self.hs[idx], self.enc[idx])
            return self._model(s, hs, enc, floor)
        a, b = self.affine if idx is None else (self.affine[0][idx], self.affine[1][idx])
        raw = a + b * s
        return np.minimum(raw, s - np.minimum(self.floor, s)) if floor else raw

    def made(self, s, idx=None):
        """Speed made (over ground) at setting ``s`` per sample ``idx``. [kn]"""
        s = np.asarray(s, dtype=float)
        v = s - self.loss(np.maximum(s, 0.0), idx=idx)
        if self.cur is not None:
            along, cross = (c if idx is None else c[idx] for c in self.cur)
            v = np.sqrt(np.maximum(v * v - cross * cross, 0.0)) + along
        return v

    def leg_mean(self, x, idx=None, legs=None):
        leg = self.leg if idx is None else self.leg[idx]
        w = self.w if idx is None else self.w[idx]
        num = np.bincount(leg, weights=x * w, minlength=self.n_legs)
        out = np.divide(num, self.den, out=np.zeros(self.n_legs), where=self.den > 0)
        return out if legs is None else out[legs]


def _closed_form(sm: _Samples, v_kn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Settings of the legs an affine loss solves exactly (``ok``), no current: ``s = (v + A) / (1 - B)``, checked with
    the floor applied (a sample the floor holds fails the check)."""
    n = sm.n_legs
    if sm.cur is not None or sm.affine is None:
        return np.zeros(n), np.zeros(n, dtype=bool)
    A, B = sm.leg_mean(sm.affine[0]), sm.leg_mean(sm.affine[1])
    s = np.divide(v_kn + A, 1.0 - B, out=np.zeros(n), where=(1.0 - B) > 1e-9)
    check = sm.leg_mean(sm.made(s[sm.leg]))  # the model itself, the floor applied: a floored sample fails here
    ok = (sm.den > 0) & ((1.0 - B) > 1e-9) & (np.abs(check - v_kn) <= 1e3 * SOLVE_TOL_KN) & (s >= 0.0)
    return s, ok


def _bisect(sm: _Samples, v_kn: np.ndarray, legs: np.ndarray, pivot: float, top: float) -> np.ndarray:
    """Settings of ``legs`` by bisection on [0, top]: the service speed ``pivot`` when it makes the leg's speed,
    else the root on its side (nearest the service speed where the speed made is flat, at the floor)."""
    idx = np.flatnonzero(np.isin(sm.leg, legs))
    at = sm.leg_mean(sm.made(np.full(idx.size, pivot), idx), idx, legs)
    up = at < v_kn[legs] - SOLVE_TOL_KN  # the root lies above the service speed: the least setting making v
    lo = np.where(up, pivot, 0.0)
    hi = np.where(up, top, pivot)
    pos = np.searchsorted(legs, sm.leg[idx])
    for _ in range(BISECTION_STEPS):
        mid = 0.5 * (lo + hi)
        m = sm.leg_mean(sm.made(mid[pos], idx), idx, legs)
        go_up = np.where(up, m < v_kn[legs], m <= v_kn[legs])  # below: the greatest setting making no more than v
        lo, hi = np.where(go_up, mid, lo), np.where(go_up, hi, mid)
        if np.all(hi - lo <= SOLVE_TOL_KN):
            break
    s = np.where(up, hi, lo)
    return np.where(np.abs(at - v_kn[legs]) <= SOLVE_TOL_KN * 1e3, pivot, s)


def solve_settings(v_kn, samples: pd.DataFrame, weather: dict, enc, model: str, vessel, learned=None, at_service=None, *,
                   sm: _Samples | None = None) -> tuple[np.ndarray, dict]:
    """The engine setting of each leg whose speed made in the weather met equals the leg's speed ``v_kn`` (module
    doc). Returns ``(setting_kn, info)``: 0 on a leg without distance (a wait); ``info`` has ``above_max_power``
    (legs no setting up to the maximum-power speed makes: their setting is that speed) and ``floor`` (legs held at
    the floor in every sample, where the speed does not tell the setting) as boolean arrays. ``at_service``: the
    model's loss per sample at the service speed (the evaluation's column), which lets an affine loss be used in
    closed form (checked against it) instead of calling the model at every bisection step."""
    from routing.fuel import max_power_speed_kn

    v = np.nan_to_num(np.asarray(v_kn, dtype=float), nan=0.0)
    n = v.size
    sm = sm or _Samples(samples, weather, enc, n, model, vessel, learned, at_service)
    top = max_power_speed_kn(Engine.from_vessel(vessel))
    s = np.where(sm.den > 0, 0.0, v)  # a leg without samples (no time): calm water
    sailed = (v > 0) & (sm.den > 0)
    closed, ok = _closed_form(sm, v)
    ok &= sailed
    s = np.where(ok, closed, s)
    rest = np.flatnonzero(sailed & ~ok)
    if rest.size:
        s[rest] = _bisect(sm, v, rest, min(float(vessel.speed_kn), top), top)
    over = sailed & (s > top)
    if rest.size:  # a bisected leg pinned at the top may still fall short of its speed there
        over |= sailed & (sm.leg_mean(sm.made(np.minimum(s, top)[sm.leg])) < v - 1e3 * SOLVE_TOL_KN)
    s = np.where(over, top, s)
    at_floor = np.zeros(n, dtype=bool)
    if rest.size:
        held = sm.loss(s[sm.leg], floor=True) < sm.loss(s[sm.leg], floor=False) - 1e-12
        at_floor = sailed & (sm.leg_mean(held.astype(float)) >= 1.0 - 1e-12)
    return s, {"above_max_power": over, "floor": at_floor}


def setting_legs(leg_dt, setting_kn, samples: pd.DataFrame, weather: dict, enc, model: str, vessel, learned=None, *,
                 at_service=None, sm: _Samples | None = None) -> pd.DataFrame:
    """STEAM2 legs of a route sailed at a known setting per leg (0 on a wait).

    The loss of each sample at its leg's setting (``model`` in the weather met, 0 = calm), averaged over
    the leg's time; the leg's speed through the water ``setting - loss`` (at least the vessel's floor)
    and that loss give the power ``P(setting)`` (:func:`routing.emissions.leg_power_kw`: the wave
    increase restores the setting), over the leg's time: the fuel the planner charged
    (:mod:`routing.fuel`). A wait burns nothing (speed 0). ``at_service``: as :func:`solve_settings`.
    """
    setting_kn = np.asarray(setting_kn, dtype=float)
    n_legs = setting_kn.size
    loss = np.zeros(n_legs)
    if len(samples):
        sm = sm or _Samples(samples, weather, enc, n_legs, model, vessel, learned, at_service)
        s = setting_kn[sm.leg]
        per = np.where(s > 0, sm.loss(np.maximum(s, 1e-9)), 0.0)
        loss = sm.leg_mean(per)
    floor = np.minimum(float(vessel.min_speed_kn), setting_kn)  # the speed models never drop below the floor
    through_water = np.where(setting_kn > 0, np.maximum(setting_kn - loss, floor), 0.0)
    return steam2_legs(leg_dt, through_water, setting_kn - through_water, Engine.from_vessel(vessel))


def route_legs(leg_dt, leg_speed_kn, planned_kn, samples: pd.DataFrame, weather: dict, enc, model: str, vessel, learned=None,
               at_service=None) -> tuple[pd.DataFrame, dict]:
    """STEAM2 legs of a route at the planned settings ``planned_kn`` (one per leg, 0 = a wait) when given, else at the
    settings :func:`solve_settings` finds from ``leg_speed_kn``; the legs gain ``setting_kn``, and ``power_limited``
    marks the legs above the maximum-power speed too. Returns ``(legs, info)`` (``info`` as :func:`solve_settings`'s)."""
    n_legs = len(leg_dt)
    sm = _Samples(samples, weather, enc, n_legs, model, vessel, learned, at_service) if len(samples) else None
    if planned_kn is not None:
        s = np.nan_to_num(np.asarray(planned_kn, dtype=float), nan=0.0)
        info = {"above_max_power": np.zeros(n_legs, dtype=bool), "floor": np.zeros(n_legs, dtype=bool)}
    else:
        s, info = solve_settings(leg_speed_kn, samples, weather, enc, model, vessel, learned, at_service,
                                 sm=sm or _Samples(samples, weather, enc, n_legs, model, vessel, learned))
    legs = setting_legs(leg_dt, s, samples, weather, enc, model, vessel, learned, sm=sm)
    if info["above_max_power"].any():
        legs["power_limited"] = legs["power_limited"].to_numpy() | info["above_max_power"]
    legs.insert(0, "setting_kn", s)
    return legs, info


__all__ = ["BISECTION_STEPS", "SOLVE_TOL_KN", "route_legs", "setting_legs", "solve_settings"]
