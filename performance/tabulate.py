"""The learned model on a grid for one vessel: the table the router interpolates.

:func:`sea_context` summarises, when a model is learned, the sea states its training segments
met: per Hs band and heading sector the median peak period and head and cross wind, and per
class the calm-water speeds and lengths it saw. :func:`speed_table` evaluates the model once per
request on a regular Hs x encounter grid for the request's vessel, with the period and the wind
of each cell taken from that context (the router's weather arrays carry Hs and the wave direction
only: :mod:`routing.learned`), and returns a :class:`routing.learned.LearnedSpeedTable`.

A vessel outside what the model was trained on is refused (:class:`OutsideTraining`): a class it
never saw, or a calm-water speed or length outside the class's trained range by more than
:data:`RANGE_MARGIN_FRAC`. Trees do not extrapolate; a number from outside their data would be a
guess presented as a measurement.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from performance.features import CLASS_NAMES, class_code
from performance.formulas import prior_ratio_for
from routing.learned import LearnedSpeedTable

#: Context grid: Hs bands [m] and heading sectors [deg] over which Tp and the wind are summarised.
CONTEXT_HS_STEP_M = 0.5
CONTEXT_ENC_STEP_DEG = 30.0
#: The table's grid: Hs step [m] and encounter step [deg].
TABLE_HS_STEP_M = 0.25
TABLE_ENC_STEP_DEG = 15.0
#: How far beyond a class's trained calm speeds and lengths a vessel may lie (share of the range's ends).
RANGE_MARGIN_FRAC = 0.10
#: Profile vessel classes (``data/vessels/*.toml``) -> the model's ship classes (AIS ship types).
PROFILE_CLASS = {"ro-pax": "passenger", "passenger": "passenger", "ferry": "passenger", "container": "cargo",
                 "bulk": "cargo", "general-cargo": "cargo", "cargo": "cargo", "tanker": "tanker"}


class OutsideTraining(ValueError):
    """The request's vessel lies outside what the model was trained on."""


def sea_context(seg: pd.DataFrame) -> dict:
    """The training segments' sea states and ships, as plain JSON (stored with the model)."""
    hs_top = float(np.nanmax(seg["hs_m"])) if len(seg) else 0.0
    n_hs = int(np.floor(hs_top / CONTEXT_HS_STEP_M)) + 1
    n_enc = int(round(180.0 / CONTEXT_ENC_STEP_DEG))
    i = np.clip(np.floor(seg["hs_m"].to_numpy(float) / CONTEXT_HS_STEP_M), 0, n_hs - 1).astype(int)
    j = np.clip(np.floor(seg["encounter_deg"].to_numpy(float) / CONTEXT_ENC_STEP_DEG), 0, n_enc - 1).astype(int)
    cells = {}
    for col in ("tp_s", "wind_head_ms", "wind_cross_ms"):
        g = pd.Series(seg[col].to_numpy(float)).groupby([i, j]).median()
        grid = np.full((n_hs, n_enc), np.nan)
        for (a, b), v in g.items():
            grid[a, b] = v
        band = pd.Series(seg[col].to_numpy(float)).groupby(i).median().reindex(range(n_hs)).ffill().bfill()
        fill = np.broadcast_to(band.to_numpy()[:, None], grid.shape)
        grid = np.where(np.isfinite(grid), grid, fill)
        cells[col] = np.nan_to_num(grid, nan=float(np.nanmedian(seg[col])) if seg[col].notna().any() else 0.0).tolist()
    ships = {}
    for cls, sub in seg.groupby("ship_class"):
        ships[str(cls)] = {"v0_kn": [float(sub["v0_kn"].min()), float(sub["v0_kn"].max())],
                           "length_m": [float(sub["length_m"].min()), float(sub["length_m"].max())],
                           "vessels": int(sub["mmsi"].nunique())}
    return {"hs_step_m": CONTEXT_HS_STEP_M, "enc_step_deg": CONTEXT_ENC_STEP_DEG, "hs_max_m": hs_top, "cells": cells,
            "ships": ships}


def _check_range(context: dict, cls: str, speed_kn: float, length_m: float, name: str) -> None:
    ships = context["ships"]
    if cls not in ships:
        raise OutsideTraining(f"learned model {name!r} was trained on {', '.join(sorted(ships))} ships, not {cls}: "
                              "use a formula (--speed-loss bowditch|aertssen|khokhlov) or learn from that class")
    for what, value, unit in (("v0_kn", speed_kn, "kn calm-water speed"), ("length_m", length_m, "m length")):
        lo, hi = ships[cls][what]
        pad = RANGE_MARGIN_FRAC * max(abs(lo), abs(hi))
        if not (lo - pad <= value <= hi + pad):
            raise OutsideTraining(f"learned model {name!r} saw {cls} ships of {lo:.1f}-{hi:.1f} {unit}; "
                                  f"this vessel's {value:.1f} lies outside: use a formula or learn from such ships")


def speed_table(model, context: dict, name: str, *, speed_kn: float, vessel) -> LearnedSpeedTable:
    """The model's P50, P10 and P90 speed ratios on the grid for ``vessel`` at ``speed_kn``.

    ``vessel`` is a vessel profile (:func:`pipelines.config.load_vessel`): its class, Lpp, beam,
    draught, deadweight and speed floor (the residual model's prior formula reads them)."""
    cls = PROFILE_CLASS.get(str(getattr(vessel, "vessel_class", "")), "other")
    if cls not in CLASS_NAMES:
        cls = "other"
    _check_range(context, cls, float(speed_kn), float(vessel.lpp_m), name)
    hs_top = float(context["hs_max_m"])
    hs = np.arange(0.0, np.ceil(hs_top / TABLE_HS_STEP_M) * TABLE_HS_STEP_M + 1e-9, TABLE_HS_STEP_M)
    if hs.size < 2:
        hs = np.array([0.0, TABLE_HS_STEP_M])
    enc = np.arange(0.0, 180.0 + 1e-9, TABLE_ENC_STEP_DEG)
    H, E = np.meshgrid(hs, enc, indexing="ij")
    i = np.clip(np.floor(H / context["hs_step_m"]), 0, len(context["cells"]["tp_s"]) - 1).astype(int)
    j = np.clip(np.floor(E / context["enc_step_deg"]), 0, len(context["cells"]["tp_s"][0]) - 1).astype(int)
    grid = pd.DataFrame({"hs_m": H.ravel(), "encounter_deg": E.ravel()})
    for col in ("tp_s", "wind_head_ms", "wind_cross_ms"):
        grid[col] = np.asarray(context["cells"][col], dtype=float)[i, j].ravel()
    grid["v0_kn"] = float(speed_kn)
    grid["length_m"], grid["beam_m"], grid["draught_m"] = float(vessel.lpp_m), float(vessel.beam_m), float(vessel.draught_m)
    grid["class_code"] = class_code([cls])[0]
    prior = None
    if model.kind == "residual":
        prior = prior_ratio_for(model.prior, grid, lpp_m=float(vessel.lpp_m), dwt_t=float(vessel.dwt_t),
                                floor_kn=float(vessel.min_speed_kn))
    pred = model.predict(grid, prior)
    shape = H.shape
    return LearnedSpeedTable(
        name=name, hs_m=hs, encounter_deg=enc, ratio=pred["p50"].to_numpy().reshape(shape),
        p10=pred["p10"].to_numpy().reshape(shape), p90=pred["p90"].to_numpy().reshape(shape), hs_max_trained_m=hs_top,
        note=(f"{model.kind} gradient-boosted model of {cls} ships, tabulated over Hs 0-{hs[-1]:g} m x encounter 0-180 deg; "
              "wave period and wind at the training fixes' median for each Hs band and heading"),
        meta={"ship_class": cls, "kind": model.kind, "prior": model.prior})
