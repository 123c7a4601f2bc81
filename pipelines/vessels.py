"""The one rule for the vessel a command uses when ``--vessel`` is not given.

Where AIS says which ship it is, the ship's own profile: by its AIS ship type and length
(:func:`vessel_for_ship`: an audited voyage), or for a lane the profile most of its voyages' ships
get (:func:`lane_vessel_profiles`: ``nightly``, ``deviate``). Where no AIS ship is known
(``route``, ``weather exceedance``, a lane without AIS statics), :data:`DEFAULT_VESSEL`: the
container feeder, whose Lpp < 200 m limits are the strictest published ones (Spyrou-Sioula et al.
2022, Section 3.2). ``docs/configuration.md`` states the rule for users.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

#: The vessel profile used where no AIS ship is known.
DEFAULT_VESSEL = "container-feeder"


def vessel_for_ship(static: dict) -> str:
    """Vessel profile for an AIS ship: by AIS ship type and length.

    Passenger (60-69): ``ro-pax``; tanker (80-89): ``tanker-aframax``; any other ship of 200 m or
    more: ``container-large``; else :data:`DEFAULT_VESSEL` (``container-feeder``).
    """
    kind = static.get("ship_type")
    length = static.get("length_m")
    kind = int(kind) if kind is not None and np.isfinite(kind) else None
    if kind is not None and 60 <= kind <= 69:
        return "ro-pax"
    if kind is not None and 80 <= kind <= 89:
        return "tanker-aframax"
    if length is not None and np.isfinite(length) and float(length) >= 200.0:
        return "container-large"
    return DEFAULT_VESSEL


def lane_vessel_profiles(lanes: pd.DataFrame, lane_voyages: pd.DataFrame, voyages: pd.DataFrame,
                         vessels: pd.DataFrame) -> dict[str, str]:
    """A vessel profile per lane: the most common profile of the ships that sailed it.

    Each ship's profile comes from :func:`vessel_for_ship`; a lane is weighted by voyages, ties go
    to the alphabetically first profile; lanes without AIS statics get :data:`DEFAULT_VESSEL`.
    """
    out = {str(lid): DEFAULT_VESSEL for lid in lanes["lane_id"]}
    if lane_voyages.empty or voyages.empty or vessels.empty:
        return out
    static = {int(r["mmsi"]): {k: (None if pd.isna(v) else v) for k, v in r.items()} for r in vessels.to_dict("records")}
    mmsi_of = dict(zip(voyages["voyage_id"].astype(str), voyages["mmsi"]))
    counts: dict[str, dict[str, int]] = {}
    for lid, vid in zip(lane_voyages["lane_id"].astype(str), lane_voyages["voyage_id"].astype(str)):
        mmsi = mmsi_of.get(vid)
        if mmsi is None or pd.isna(mmsi) or int(mmsi) not in static:
            continue
        prof = vessel_for_ship(static[int(mmsi)])
        counts.setdefault(lid, {}).setdefault(prof, 0)
        counts[lid][prof] += 1
    for lid, c in counts.items():
        if lid in out:
            out[lid] = sorted(c.items(), key=lambda kv: (-kv[1], kv[0]))[0][0]
    return out


def workspace_lane_profiles(ws) -> dict[str, str]:
    """:func:`lane_vessel_profiles` of every lane in an open workspace."""
    from pipelines.storage.ais import read_vessels
    from pipelines.storage.lanes import read_lane_voyages, read_lanes, read_voyages

    return lane_vessel_profiles(read_lanes(ws), read_lane_voyages(ws), read_voyages(ws), read_vessels(ws))
