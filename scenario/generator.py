"""The demo AIS scenario: a deterministic fleet sailing liner services in the Western Mediterranean.

Pure: the caller passes the parsed configuration (``data/scenario.toml`` and ``data/ports.csv``,
read by :mod:`pipelines.scenario`) and gets DataFrames back; the writers in
:mod:`scenario.writers` turn them into DMA CSV and NMEA files. The configuration, settings and
result types are in :mod:`scenario.spec`, the sailing of one vessel in :mod:`scenario.sailing`,
the records and dirty rows in :mod:`scenario.records`; this module puts them together.

How the traffic is made
-----------------------
* Every vessel belongs to one service (a rotation of ports). It starts alongside at one port of
  the rotation (vessels of a service are staggered) and sails voyage after voyage: berth ->
  harbour leg -> the service route between the two approach points -> harbour leg -> berth,
  then stays alongside (ro-pax lines wait for the next timetable slot; cargo ships stay a
  random time; tankers sometimes wait at an anchorage before berthing).
* Given the weather (``seaway``), each ship answers to the waves and wind it meets by the
  generator's own performance law (:mod:`scenario.performance_law`: wave and wind resistance,
  a voluntary slow-down above its class's sea state, surge), which the learning code never sees.
* Each voyage sails the route with a lateral offset (a keep-right bias plus a random offset
  per voyage, and a small jitter per waypoint), checked against the land mask and shrunk when it
  would touch land, and with a voyage speed drawn around the vessel's service speed plus a
  slow along-track fluctuation. Lanes therefore have a width of about 1-2 nmi and emerge from
  clustering rather than being a single line.
* Reporting cadence. Class A transponders report every 2-10 s under way and every 3 min at
  anchor or moored (ITU-R M.1371-5, Annex 1, Table 1). Public archives thin that: NOAA
  MarineCadastre keeps about one fix per minute (the New York Harbor day under ../shared has a
  median interval of 70 s). The scenario follows the archives: one fix every 60 s (+-4 s)
  under way and every 180 s alongside or at anchor, which keeps 30 days of 20 ships at about
  0.6 M rows, small enough for a demo and dense enough for lanes.
* Positions carry GPS noise (8 m, 1 sigma), SOG/COG/heading carry sensor noise, and signal
  gaps drop fixes: a coverage gap at sea on some voyages and a long transponder outage on some
  vessels.
* A small share of dirty rows of every kind the ingest must quarantine is added on top of the
  clean fixes (:data:`DIRTY_KINDS`); one kind, ``sentinel_fields``, edits clean rows in place
  (SOG 102.3 / COG 360 / heading 511 mean "not available" and are loaded as NULL).

All randomness comes from ``numpy.random.default_rng`` seeded with ``(seed, vessel index)`` or
``(seed, stream id)``, so the same seed gives the same rows.

References
----------
.. [1] ITU-R M.1371-5, "Technical characteristics for an automatic identification system using
       time division multiple access in the VHF maritime mobile band," 2014, Annex 1 Table 1
       (reporting intervals), Annex 8 (message fields and not-available values).
.. [2] ITU-R M.585-9, "Assignment and use of identities in the maritime mobile service," 2022
       (MMSI structure, maritime identification digits).
.. [3] IMO Resolution A.1117(30), "IMO ship identification number scheme," 2017 (check digit).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from scenario.records import _quantise, build_records
from scenario.sailing import _sail_vessel
from scenario.spec import (  # noqa: F401 (the configuration and result types, re-exported)
    DEFAULT_DAYS, DEFAULT_START_UTC, DIRTY_KINDS, Scenario, ScenarioConfigError, ScenarioSettings, ScenarioSpec,
    VesselSpec, imo_check_digit_ok, mmsi_problem, parse_scenario_spec,
)


def generate_scenario(spec: ScenarioSpec, settings: ScenarioSettings | None = None, seaway=None) -> Scenario:
    """Sail the fleet of ``spec`` over the period of ``settings``; deterministic by seed.

    Parameters
    ----------
    spec : ScenarioSpec
        Ports, routes, services and fleet (:func:`parse_scenario_spec`).
    settings : ScenarioSettings, optional
        Seed, period, cadences, noise and dirty-row rates; defaults make the demo scenario.
    seaway : callable(time_s, lat, lon) -> dict, optional
        The weather the fleet sails through: arrays ``hs_m``, ``wave_from_deg``, ``tp_s``,
        ``wind_u_ms``, ``wind_v_ms`` at Unix times and positions. Ships then answer to it by
        :mod:`scenario.performance_law` (wave and wind resistance, voluntary slow-down, surge);
        ``None`` sails in calm water.

    Returns
    -------
    Scenario
        Truth tables and the records to write.

    Examples
    --------
    >>> import pandas as pd
    >>> ports = pd.DataFrame({"locode": ["ESBCN", "ESPMI"], "name": ["Barcelona", "Palma"],
    ...     "lat_deg": [41.352, 39.56], "lon_deg": [2.17, 2.63],
    ...     "approach_lat_deg": [41.31, 39.52], "approach_lon_deg": [2.22, 2.62]})
    >>> doc = {"routes": {"ESBCN-ESPMI": {"waypoints": [[41.31, 2.22], [39.62, 2.20], [39.44, 2.36],
    ...        [39.40, 2.53], [39.52, 2.62]]}},
    ...        "services": [{"id": "S", "vessel_class": "ro-pax", "rotation": ["ESBCN", "ESPMI"]}],
    ...        "vessels": [{"mmsi": 224087350, "imo": 9412220, "name": "A", "callsign": "EAKQ", "flag": "ES",
    ...        "service": "S", "ship_type": 60, "length_m": 186, "beam_m": 26, "draught_m": 6.6,
    ...        "dwt_t": 7200, "service_speed_kn": 21, "to_bow": 150, "to_stern": 36, "to_port": 13,
    ...        "to_starboard": 13}]}
    >>> sc = generate_scenario(parse_scenario_spec(doc, ports), ScenarioSettings(days=1))
    >>> len(sc.voyages) >= 2
    True
    """
    st = settings or ScenarioSettings()
    all_fixes, all_voyages, all_stays, all_gaps = [], [], [], []
    for i, (v, rank) in enumerate(zip(spec.vessels, service_ranks(spec))):
        fx, voy, stays, gaps = _sail_vessel(i, v, rank, spec, st, seaway)
        all_fixes.append(fx)
        all_voyages += voy
        all_stays += stays
        all_gaps += gaps
    vessels = vessel_table(spec)
    fixes = pd.concat(all_fixes, ignore_index=True)
    fixes = _quantise(fixes)
    voyages = pd.DataFrame(all_voyages)
    stays = pd.DataFrame(all_stays)
    gaps = pd.DataFrame(all_gaps, columns=["mmsi", "kind", "start_s", "end_s", "fixes_lost"])

    recs = build_records(np.random.default_rng([st.seed, 2]), st, spec, fixes, vessels, voyages)
    return Scenario(st, spec, vessels, fixes, recs, voyages, stays, gaps)


def service_ranks(spec: ScenarioSpec) -> list[int]:
    """Each vessel's rank among the vessels of its service (0 for the first): it staggers where
    and when the ships of one service start."""
    seen: dict[str, int] = {}
    ranks = []
    for v in spec.vessels:
        ranks.append(seen.get(v.service, 0))
        seen[v.service] = ranks[-1] + 1
    return ranks


def vessel_table(spec: ScenarioSpec) -> pd.DataFrame:
    """One row per vessel of the fleet: its :class:`VesselSpec` fields and ``vessel_class``."""
    rows = []
    for v in spec.vessels:
        row = {k: getattr(v, k) for k in VesselSpec.__dataclass_fields__}
        row["vessel_class"] = spec.services[v.service].vessel_class
        rows.append(row)
    return pd.DataFrame(rows)


def with_settings(settings: ScenarioSettings, **changes) -> ScenarioSettings:
    """A copy of ``settings`` with some fields changed (validated again)."""
    return replace(settings, **changes)


def to_utc(seconds) -> pd.DatetimeIndex | pd.Timestamp:
    """Unix seconds to tz-aware UTC timestamps."""
    return pd.to_datetime(seconds, unit="s", utc=True)
