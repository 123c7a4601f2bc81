"""The year-scale scenario: a large fleet over a long period, one ship at a time (issue 23).

The demo scenario (:mod:`scenario.generator`) holds the whole fleet's fixes in memory, which
suits 20 ships for a month (0.6 M rows) but not a year of a few hundred ships (about 0.36 M rows
per ship-year at the demo's cadence: 108.5 M rows for 300 ships, measured in docs/scale.md). Here the same sailing
(:func:`scenario.sailing._sail_vessel`) and the same records (:func:`scenario.records.build_records`:
message 1/3, dirty rows, the crew's voyage fields) run for one ship at a time, each ship on its
own random streams (``(seed, 1, index)`` for its sailing as in the demo, ``(seed, 2, index)``
for its records), so the result does not depend on the order or the process the ships are
sailed in; the caller (:mod:`pipelines.scenario_fleet`) spills each ship's records and writes
the days from the spill.

:func:`fleet_spec` grows the configured fleet to ``n`` ships: the configured ships first, then
copies of them (ship ``k`` copies ship ``k mod 20``: class, service, particulars, flag) with
their own valid identities (an MMSI with the flag's MID [1], an IMO number with its check
digit [2], a call sign with the flag's prefix, a name with a number). Every ship is written in
the DMA CSV layout. The copies join their model's service, staggered by their rank in it as the
demo's ships are.

References
----------
.. [1] ITU-R M.585-9, "Assignment and use of identities in the maritime mobile service," 2022.
.. [2] IMO Resolution A.1117(30), "IMO ship identification number scheme," 2017.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from scenario.generator import service_ranks, vessel_table
from scenario.records import _quantise, record_columns
from scenario.sailing import _sail_vessel
from scenario.spec import MED_MIDS, ScenarioSettings, ScenarioSpec, VesselSpec

#: Six-digit ship numbers of the copies start here (after the MID: ``MID 1xxxxx``).
_COPY_SERIAL0 = 100_000
#: First six digits of the copies' IMO numbers (the seventh is the check digit).
_COPY_IMO0 = 800_000


def imo_with_check_digit(first_six: int) -> int:
    """The 7-digit IMO number whose first six digits are ``first_six`` [2]."""
    digits = f"{int(first_six):06d}"
    if len(digits) != 6:
        raise ValueError(f"an IMO number has six digits before its check digit, got {first_six}")
    check = sum(int(c) * w for c, w in zip(digits, range(7, 1, -1))) % 10
    return int(digits) * 10 + check


def fleet_spec(spec: ScenarioSpec, n_vessels: int) -> ScenarioSpec:
    """``spec`` with ``n_vessels`` ships (the configured ones first, then numbered copies), all
    written as DMA CSV (see the module docstring)."""
    if n_vessels < 1:
        raise ValueError(f"a fleet needs at least one vessel, got {n_vessels}")
    base = [replace(v, ais_format="dma_csv") for v in spec.vessels]
    if n_vessels <= len(base):
        return replace(spec, vessels=tuple(base[:n_vessels]))
    used = {v.mmsi for v in base}
    out = list(base)
    serial = _COPY_SERIAL0
    for k in range(len(base), n_vessels):
        model = base[k % len(base)]
        mid = MED_MIDS[model.flag][0]
        while mid * 1_000_000 + serial in used:
            serial += 1
        mmsi = mid * 1_000_000 + serial
        used.add(mmsi)
        serial += 1
        number = k // len(base) + 1
        out.append(replace(model, mmsi=mmsi, imo=imo_with_check_digit(_COPY_IMO0 + k),
                           name=f"{model.name[:16]} {number}"[:20], callsign=f"{model.callsign[:3]}{k:04d}"[:7]))
    return replace(spec, vessels=tuple(out))


def sail_ship(spec: ScenarioSpec, st: ScenarioSettings, index: int, vessels: pd.DataFrame | None = None,
              ranks: list[int] | None = None, frame: bool = True) -> dict:
    """One ship of ``spec`` over the period of ``st``: its records (output order; a DataFrame,
    or with ``frame=False`` the dict of columns of :func:`scenario.records.record_columns`),
    voyages, port stays and gaps, and how many fixes it reported.

    ``vessels`` (:func:`scenario.generator.vessel_table`) and ``ranks``
    (:func:`scenario.generator.service_ranks`) may be given when sailing many ships of one spec.
    Deterministic: the ship's streams are seeded by ``(st.seed, index)`` only.
    """
    vessels = vessel_table(spec) if vessels is None else vessels
    ranks = service_ranks(spec) if ranks is None else ranks
    v: VesselSpec = spec.vessels[index]
    fx, voyages, stays, gaps = _sail_vessel(index, v, ranks[index], spec, st)
    fixes = _quantise(fx)
    voy = pd.DataFrame(voyages)
    recs = record_columns(np.random.default_rng([st.seed, 2, index]), st, spec, fixes, vessels, voy)
    recs = pd.DataFrame(recs) if frame else recs
    return {"records": recs, "voyages": voy, "stays": pd.DataFrame(stays),
            "gaps": pd.DataFrame(gaps, columns=["mmsi", "kind", "start_s", "end_s", "fixes_lost"]),
            "fixes": int(len(fixes)), "received": int(fixes["received"].sum()) if len(fixes) else 0}
