"""The whole lanes chain as one plain function: positions in, ports / voyages / lanes out.

``build_lanes(positions, known_ports, params)`` runs, in order (seed paper §3.1, Figure 1):

1. :func:`lanes.interpolate.drop_position_jumps` - fixes implying impossible speeds;
2. :func:`lanes.stops.detect_stops` - stop episodes;
3. :func:`lanes.ports.detect_ports` - DBSCAN on stops, named from the port list;
4. :func:`lanes.voyages.segment_voyages` - port-to-port voyages with the gap rule;
5. :func:`lanes.interpolate.resample_voyages` - regular time step on great circles;
6. :func:`lanes.extract.extract_lanes` - DBSCAN on position and motion per O-D pair.

Steps 1-5 are :func:`prepare_chain`, step 6 plus the summary :func:`finish_chain`. The Prefect
flow (``pipelines/lanes.py``) runs them between a reader and a writer, with step 6 fanned out one
task per origin-destination partition; the benchmark and the tests call ``build_lanes`` directly.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import pandas as pd

from lanes.extract import LaneParams, LaneResult, extract_lanes, lane_voyage_table
from lanes.interpolate import ResampleParams, drop_position_jumps, resample_voyages
from lanes.ports import PortParams, detect_ports
from lanes.stops import StopParams, detect_stops, sort_track_points
from lanes.voyages import VoyageParams, segment_voyages

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ChainParams:
    """All parameters of the chain; ``id_col`` names the track id (``mmsi`` or ``track_id``)."""

    stops: StopParams = field(default_factory=StopParams)
    ports: PortParams = field(default_factory=PortParams)
    voyages: VoyageParams = field(default_factory=VoyageParams)
    resample: ResampleParams = field(default_factory=ResampleParams)
    lanes: LaneParams = field(default_factory=LaneParams)
    max_jump_speed_kn: float = 50.0
    id_col: str = "mmsi"

    def to_dict(self) -> dict:
        from dataclasses import asdict

        return asdict(self)


@dataclass
class ChainResult:
    """Everything the chain produced, plus a summary with counts and step timings."""

    ports: pd.DataFrame
    stops: pd.DataFrame
    voyages: pd.DataFrame
    points: pd.DataFrame
    lanes: LaneResult
    lane_voyages: pd.DataFrame
    summary: dict


@dataclass
class PreparedChain:
    """The serial part of the chain (steps 1-5): everything lane extraction needs."""

    ports: pd.DataFrame
    stops: pd.DataFrame
    voyages: pd.DataFrame
    points: pd.DataFrame
    n_positions: int
    n_jumps: int
    timings: dict


def prepare_chain(positions: pd.DataFrame, known_ports: pd.DataFrame | None = None,
                  params: ChainParams | None = None) -> PreparedChain:
    """Steps 1-5 of the chain (jump filter, stops, ports, voyages, resampling); see :func:`build_lanes`."""
    params = params or ChainParams()
    timings: dict[str, float] = {}
    t = time.perf_counter()
    cols = [c for c in (params.id_col, "time_utc", "lat_deg", "lon_deg", "sog_kn") if c in positions.columns]
    pts = sort_track_points(positions[cols], params.id_col)
    pts, n_jumps = drop_position_jumps(pts, params.max_jump_speed_kn, id_col=params.id_col)
    timings["clean_s"] = time.perf_counter() - t

    t = time.perf_counter()
    stops = detect_stops(pts, params.stops, id_col=params.id_col)
    timings["stops_s"] = time.perf_counter() - t

    t = time.perf_counter()
    ports, stop_port_id = detect_ports(stops, known_ports, params.ports)
    stops = stops.assign(port_id=stop_port_id)
    timings["ports_s"] = time.perf_counter() - t

    t = time.perf_counter()
    places = [ports[["lat_deg", "lon_deg"]]] if len(ports) else []
    if known_ports is not None and len(known_ports):
        places.append(known_ports[["lat_deg", "lon_deg"]])
    places_df = pd.concat(places, ignore_index=True).astype(float) if places else None
    voyages = segment_voyages(pts, stops, stop_port_id, places_df, params.voyages, id_col=params.id_col,
                              ports=ports if len(ports) else None)
    timings["voyages_s"] = time.perf_counter() - t

    t = time.perf_counter()
    points = resample_voyages(pts, voyages, params.resample)
    timings["resample_s"] = time.perf_counter() - t
    return PreparedChain(ports, stops, voyages, points, int(len(positions)), int(n_jumps), timings)


def finish_chain(prep: PreparedChain, lanes: LaneResult, lanes_s: float) -> ChainResult:
    """The chain's result from the serial part and the lanes of every partition (step 6).

    ``lanes`` is :func:`lanes.extract.extract_lanes` of ``prep.points``, or the same computed
    partition by partition and merged with :func:`lanes.extract.merge_lane_results`; ``lanes_s``
    is the wall time it took. ``timings["total_s"]`` is the sum of the step times.
    """
    timings = {**prep.timings, "lanes_s": lanes_s}
    timings["total_s"] = sum(timings.values())
    ports, voyages, points = prep.ports, prep.voyages, prep.points
    kinds = voyages["kind"].value_counts().to_dict() if len(voyages) else {}
    summary = {
        "ports": int(len(ports)),
        "voyages": int(kinds.get("port_to_port", 0)),
        "lanes": int(len(lanes.lanes)),
        "noise_points": int(lanes.n_noise),
        "positions": prep.n_positions,
        "dropped_jumps": prep.n_jumps,
        "stops": int(len(prep.stops)),
        "named_ports": int((ports["kind"] == "port").sum()) if len(ports) else 0,
        "voyage_kinds": {k: int(v) for k, v in kinds.items()},
        "resampled_points": int(len(points)),
        "slow_points": int(lanes.n_slow),
        "sampled_partitions": int(lanes.n_sampled_partitions),
        "timings": {k: round(v, 3) for k, v in timings.items()},
    }
    log.info("lanes chain: %s", summary)
    return ChainResult(ports, prep.stops, voyages, points, lanes, lane_voyage_table(points, lanes.point_lane), summary)


def build_lanes(positions: pd.DataFrame, known_ports: pd.DataFrame | None = None,
                params: ChainParams | None = None) -> ChainResult:
    """Run the whole chain on canonical AIS positions.

    :func:`prepare_chain` (steps 1-5), :func:`lanes.extract.extract_lanes` (step 6, every
    origin-destination partition in this process), :func:`finish_chain`. The Prefect lanes flow
    runs the same three pieces with step 6 fanned out, one task per partition.

    Parameters
    ----------
    positions : DataFrame
        Canonical AIS positions (``params.id_col``, ``time_utc``, ``lat_deg``, ``lon_deg``,
        ``sog_kn``; other columns are ignored).
    known_ports : DataFrame, optional
        The port list (``locode``, ``name``, ``lat_deg``, ``lon_deg``), e.g. ``data/ports.csv``.
    params : ChainParams

    Returns
    -------
    ChainResult
        ``summary`` holds ``{"ports", "voyages", "lanes", "noise_points"}`` (the CLI contract;
        ``voyages`` counts port-to-port voyages) and more detail.
    """
    params = params or ChainParams()
    prep = prepare_chain(positions, known_ports, params)
    t = time.perf_counter()
    lanes = extract_lanes(prep.points, params.lanes)
    return finish_chain(prep, lanes, time.perf_counter() - t)


def voyages_as_table(voyages: pd.DataFrame) -> pd.DataFrame:
    """Voyages without the row bookkeeping columns, port id 0 as missing (for storage)."""
    out = voyages.drop(columns=["first_row", "last_row"], errors="ignore").copy()
    for col in ("origin_port_id", "dest_port_id"):
        out[col] = out[col].astype("Int64").where(out[col] > 0, pd.NA)
    return out


__all__ = ["ChainParams", "ChainResult", "PreparedChain", "build_lanes", "finish_chain", "prepare_chain", "voyages_as_table"]
