"""A learned speed model as the router reads it: a table of speed ratios over Hs x encounter angle.

The router never runs a learned model per edge. ``stormlane learn performance`` fits one
(:mod:`performance`); for a request, :meth:`pipelines.learn.SpeedLossChoice.table` evaluates it once on a
grid for the request's vessel and hands this module a :class:`LearnedSpeedTable`. The compiled
kernels (:mod:`routing._kernels.core`) and the vectorised evaluation here interpolate the same
table bilinearly, so a route is timed identically by the search and by its re-timing.

What the table holds, exactly
-----------------------------
``ratio[i, j]``: the model's median (P50) speed through the water as a fraction of the calm-water
speed at Hs ``hs_m[i]`` and folded encounter angle ``encounter_deg[j]`` (0 = head seas); ``p10``
and ``p90`` the band. The router's weather arrays carry Hs and the wave direction only, so the
wave period and the wind the model also reads are taken, for each table cell, as the training
data's median in that Hs band and heading sector (stored with the model): the table is the
model along the sea states the fleet actually met, and :attr:`LearnedSpeedTable.note` says so in
every output that uses it.

Outside the table: Hs above the largest Hs the model was trained on is held at the table's last
row (trees predict flat beyond their data, the table makes it explicit) and
:meth:`LearnedSpeedTable.beyond_training` reports it; a vessel the model was not trained for is
refused where the table is built.

Admissibility: bilinear interpolation is a convex combination of grid values, so no speed the
router computes exceeds ``v0 * max(ratio)`` (:meth:`LearnedSpeedTable.max_ratio`), the A*
heuristic's speed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Layout of the packed table appended to the kernels' parameter vector (see :meth:`pack`).
PACK_HEADER = 6  # n_hs, n_enc, hs0, dhs, enc0, denc


@dataclass(frozen=True, eq=False)
class LearnedSpeedTable:
    """The model's speed ratio on a regular Hs x encounter grid for one vessel (module notes)."""

    name: str
    hs_m: np.ndarray  # regular, ascending, from 0
    encounter_deg: np.ndarray  # regular, 0 .. 180
    ratio: np.ndarray  # (n_hs, n_enc) P50
    p10: np.ndarray
    p90: np.ndarray
    hs_max_trained_m: float
    note: str = ""
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        for name in ("hs_m", "encounter_deg"):
            a = np.asarray(getattr(self, name), dtype=float)
            if a.ndim != 1 or a.size < 2 or not np.allclose(np.diff(a), a[1] - a[0]) or a[1] <= a[0]:
                raise ValueError(f"learned table axis {name} must be regular and ascending")
        shape = (len(self.hs_m), len(self.encounter_deg))
        for name in ("ratio", "p10", "p90"):
            if np.shape(getattr(self, name)) != shape:
                raise ValueError(f"learned table {name} must have shape {shape}")
            if not np.all(np.isfinite(getattr(self, name))):
                raise ValueError(f"learned table {name} holds non-finite values")

    def max_ratio(self) -> float:
        """The largest ratio of the P50 table (the heuristic's bound: module notes)."""
        return float(np.max(self.ratio))

    def beyond_training(self, hs_max_m: float) -> bool:
        """True when the weather holds Hs above the largest the model was trained on."""
        return float(hs_max_m) > self.hs_max_trained_m + 1e-9

    def ratio_at(self, hs_m, encounter_deg, which: str = "p50") -> np.ndarray:
        """Bilinear ratio at (Hs, encounter) points (Hs clamped to the table; encounter folded).

        NaN Hs (land) gives NaN, as the formulas do."""
        grid = {"p50": self.ratio, "p10": self.p10, "p90": self.p90}[which]
        hs = np.asarray(hs_m, dtype=float)
        enc = np.mod(np.asarray(encounter_deg, dtype=float), 360.0)
        enc = np.where(enc > 180.0, 360.0 - enc, enc)
        x, i0, fx = _axis(self.hs_m, hs)
        y, j0, fy = _axis(self.encounter_deg, enc)
        n_j = len(self.encounter_deg)
        n_i = len(self.hs_m)
        i1 = np.minimum(i0 + 1, n_i - 1)
        j1 = np.minimum(j0 + 1, n_j - 1)
        out = (grid[i0, j0] * (1 - fx) * (1 - fy) + grid[i1, j0] * fx * (1 - fy) + grid[i0, j1] * (1 - fx) * fy
               + grid[i1, j1] * fx * fy)
        return np.where(np.isnan(hs), np.nan, out)

    def band(self, which: str) -> "LearnedSpeedTable":
        """The same table with its ``p10`` or ``p90`` ratios as the speed (for ETA bands)."""
        return LearnedSpeedTable(f"{self.name}:{which}", self.hs_m, self.encounter_deg, getattr(self, which), self.p10,
                                 self.p90, self.hs_max_trained_m, self.note, dict(self.meta, band=which))

    def pack(self) -> np.ndarray:
        """The table as the flat float64 array the kernels read after the parameter vector:
        ``n_hs, n_enc, hs0, dhs, enc0, denc`` then the P50 ratios row by row."""
        h = np.asarray(self.hs_m, dtype=float)
        e = np.asarray(self.encounter_deg, dtype=float)
        head = [len(h), len(e), h[0], h[1] - h[0], e[0], e[1] - e[0]]
        return np.concatenate([np.asarray(head, dtype=np.float64), np.ascontiguousarray(self.ratio, dtype=np.float64).ravel()])


def _axis(axis: np.ndarray, x: np.ndarray):
    a = np.asarray(axis, dtype=float)
    step = a[1] - a[0]
    pos = np.clip((np.nan_to_num(x) - a[0]) / step, 0.0, a.size - 1)
    i0 = np.minimum(np.floor(pos).astype(np.int64), a.size - 2)
    return pos, i0, pos - i0


def attained_speed_kn(table: LearnedSpeedTable, speed_kn, hs_m, encounter_deg, floor_kn: float, which: str = "p50"):
    """Speed through the water by the learned table, with the vessel's speed floor. [kn]"""
    v0 = float(speed_kn)
    v = v0 * table.ratio_at(hs_m, encounter_deg, which)
    return np.where(np.isnan(v), np.nan, np.maximum(v, min(float(floor_kn), v0)))
