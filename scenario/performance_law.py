"""How the demo fleet's ships really sail in a seaway: the generator's own performance law.

**Kept to the generator.** The learning code (:mod:`performance`, ``pipelines.learn``,
``pipelines.storage.training``) never imports this module (an import-linter contract in
``pyproject.toml`` holds it) and never reads the truth it writes: the learned model has to find
the law from the AIS and the weather alone, as it would on a real fleet. Tests and the demo's
report read it to say how close the learned model came.

The law is deliberately **none of the published formulas** (Bowditch's f(theta) H^2, Aertssen's
table, Khokhlov's linear-in-H loss, Kwon's Beaufort polynomial) but is built from the same
physical ingredients, so that a formula is a fair but imperfect prior:

* **Involuntary loss in waves**, a fraction of the set speed:
  ``F_w = k_c * h_i * Hs**1.7 * D(alpha) * R(lambda / L) / 100`` where ``D`` falls from 1 in
  head seas to 0.25 in following seas (``0.25 + 0.75 ((1 + cos alpha) / 2)**1.5``), ``R`` is a
  wave-length factor peaking when the peak wave length ``lambda = g Tp^2 / 2 pi`` is about the
  ship's length (added resistance is largest near lambda/L = 1: Faltinsen, *Sea Loads on Ships
  and Offshore Structures*, 1990, ch. 8), ``k_c`` a class constant and ``h_i`` a hull factor
  of the ship (N(1, 0.08): sisters differ).
* **Wind resistance**: ``F_a = w_c * max(0, U cos beta)**2`` with ``U cos beta`` the head-wind
  component (the air resistance grows with the square of the relative wind, ITTC 7.5-04-01-01.2
  section 2.2); no gain from a following wind.
* **Voluntary slow-down**: above a class sea state (the master's own threshold, the class value
  plus N(0, 0.12 m)) in head to bow seas the master takes off up to ``r_c`` of the speed,
  growing over 0.4 m of Hs: ``F_v = r_c * clip((Hs - H_master) / 0.4, 0, 1) * G(alpha)``,
  ``G`` = 1 up to 60 deg off the bow, falling linearly to 0 at 110 deg. Masters slow down to
  limit slamming, green water and propeller racing (Lloyd, *Seakeeping*, 1989, ch. 14 gives
  the criteria; the class values here are made up for the demo).

Speed through the water = ``set speed * (1 - F_w - F_a) * (1 - F_v)``, the loss capped at 60 %.
Around it the ship's reported speed over ground fluctuates: per fix N(0, 0.004 * Hs * v) kn of
surge in a seaway, on top of the generator's sensor noise and slow along-track wander.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Gravity [m/s^2] for the deep-water wave length lambda = g Tp^2 / (2 pi).
_G_MS2 = 9.80665


@dataclass(frozen=True)
class ClassLaw:
    """One ship class's constants of the law (see the module notes)."""

    k_wave: float  # [% per m^1.7]
    w_wind: float  # [fraction per (m/s)^2 of head wind]
    voluntary_hs_m: float  # the class's voluntary slow-down threshold
    voluntary_max_frac: float  # largest voluntary reduction


#: The law per demo vessel class (``scenario.spec.VESSEL_CLASSES``).
CLASS_LAW = {
    "ro-pax": ClassLaw(k_wave=2.2, w_wind=2.5e-4, voluntary_hs_m=3.5, voluntary_max_frac=0.14),
    "container": ClassLaw(k_wave=2.0, w_wind=2.0e-4, voluntary_hs_m=2.75, voluntary_max_frac=0.20),
    "tanker": ClassLaw(k_wave=2.6, w_wind=1.0e-4, voluntary_hs_m=2.5, voluntary_max_frac=0.22),
}

#: Spread between sister ships: hull factor sd, and the masters' thresholds sd [m] (clipped at 2 sd).
HULL_SD = 0.08
MASTER_SD_M = 0.12
#: Hs over which the voluntary reduction grows from nothing to its maximum. [m]
VOLUNTARY_RAMP_M = 0.4
#: Sd of the surge fluctuation of the speed over ground per metre of Hs, as a fraction of speed.
SURGE_SD_FRAC_PER_M = 0.004
MAX_LOSS_FRAC = 0.6


@dataclass(frozen=True)
class ShipTraits:
    """A ship's own deviation from its class: hull factor and its master's threshold."""

    hull_factor: float
    voluntary_hs_m: float


def ship_traits(rng: np.random.Generator, vessel_class: str) -> ShipTraits:
    """Draw a ship's hull factor and its master's slow-down threshold (two draws from ``rng``)."""
    law = CLASS_LAW[vessel_class]
    hull = 1.0 + HULL_SD * float(np.clip(rng.normal(), -2.0, 2.0))
    master = law.voluntary_hs_m + MASTER_SD_M * float(np.clip(rng.normal(), -2.0, 2.0))
    return ShipTraits(hull_factor=hull, voluntary_hs_m=master)


def _fold(angle_deg):
    a = np.mod(angle_deg, 360.0)
    return np.where(a > 180.0, 360.0 - a, a)


def speed_factor(vessel_class: str, traits: ShipTraits, length_m: float, course_deg, hs_m, wave_from_deg, tp_s,
                 wind_u_ms, wind_v_ms) -> tuple[np.ndarray, np.ndarray]:
    """Speed through the water as a fraction of the set speed, and the voluntary part alone.

    Unknown weather (NaN: a coastal cell the wave grid calls land) leaves the speed unchanged.

    Returns
    -------
    (factor, voluntary_frac) : ndarray, ndarray
        ``(1 - F_w - F_a) (1 - F_v)`` and ``F_v`` (module notes).
    """
    law = CLASS_LAW[vessel_class]
    hs = np.nan_to_num(np.asarray(hs_m, float), nan=0.0)
    hs = np.maximum(hs, 0.0)
    alpha = _fold(np.asarray(wave_from_deg, float) - np.asarray(course_deg, float))
    alpha = np.nan_to_num(alpha, nan=0.0)
    d = 0.25 + 0.75 * ((1.0 + np.cos(np.deg2rad(alpha))) / 2.0) ** 1.5
    tp = np.nan_to_num(np.asarray(tp_s, float), nan=4.0)
    lam_ratio = np.maximum(_G_MS2 * tp**2 / (2.0 * np.pi) / float(length_m), 1e-3)
    r = 0.55 + 0.45 * np.exp(-np.log(lam_ratio / 1.1) ** 2 / 0.6)
    f_wave = law.k_wave * traits.hull_factor * hs**1.7 * d * r / 100.0
    u = np.nan_to_num(np.asarray(wind_u_ms, float))
    v = np.nan_to_num(np.asarray(wind_v_ms, float))
    speed = np.hypot(u, v)
    wind_from = np.rad2deg(np.arctan2(-u, -v))
    head_wind = speed * np.cos(np.deg2rad(wind_from - np.asarray(course_deg, float)))
    f_air = law.w_wind * np.maximum(head_wind, 0.0) ** 2
    g = np.clip((110.0 - alpha) / 50.0, 0.0, 1.0)
    f_vol = law.voluntary_max_frac * np.clip((hs - traits.voluntary_hs_m) / VOLUNTARY_RAMP_M, 0.0, 1.0) * g
    factor = np.maximum(1.0 - f_wave - f_air, 1.0 - MAX_LOSS_FRAC) * (1.0 - f_vol)
    return factor, f_vol


def surge_sd_kn(speed_kn, hs_m) -> np.ndarray:
    """Sd of the per-fix surge fluctuation of the speed over ground. [kn]"""
    hs = np.maximum(np.nan_to_num(np.asarray(hs_m, float)), 0.0)
    return SURGE_SD_FRAC_PER_M * hs * np.asarray(speed_kn, float)


def describe() -> dict:
    """The class thresholds and limits as JSON (for ``scenario.json``: the truth the demo checks)."""
    return {
        "law": "scenario/performance_law.py (kept to the generator; the learning code never reads it)",
        "classes": {name: {"voluntary_hs_m": c.voluntary_hs_m, "voluntary_max_frac": c.voluntary_max_frac,
                           "voluntary_sector_deg": [0, 110]}
                    for name, c in CLASS_LAW.items()},
    }
