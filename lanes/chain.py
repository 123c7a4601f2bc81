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
from typing import Callable

import numpy as np
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
    points: pd.DataFrame | None
    n_positions: int
    n_jumps: int
    timings: dict
    n_points: int = -1  # resampled points (``len(points)``, also when they went to a sink instead)

    def __post_init__(self):
        if self.n_points < 0:
            self.n_points = 0 if self.points is None else int(len(self.points))


#: The columns of the positions the chain reads (beside the track id); the others are ignored.
POSITION_COLUMNS = ("time_utc", "lat_deg", "lon_deg", "sog_kn")


def _clean_track_points(positions: pd.DataFrame, params: ChainParams) -> tuple[pd.DataFrame, int]:
    """Step 1 on canonical positions: sorted by track and time, jumps dropped."""
    cols = [c for c in (params.id_col, *POSITION_COLUMNS) if c in positions.columns]
    pts = sort_track_points(positions[cols], params.id_col)
    return drop_position_jumps(pts, params.max_jump_speed_kn, id_col=params.id_col)


def prepare_chain(positions: pd.DataFrame, known_ports: pd.DataFrame | None = None,
                  params: ChainParams | None = None) -> PreparedChain:
    """Steps 1-5 of the chain (jump filter, stops, ports, voyages, resampling); see :func:`build_lanes`."""
    return prepare_chain_in_buckets(lambda k: positions, 1, known_ports, params)


def bucket_stops(read_bucket: Callable[[int], pd.DataFrame], k: int, params: ChainParams, keep: bool = False) -> dict:
    """Pass 1 of bucket ``k`` (see :func:`prepare_chain_in_buckets`): its positions read, step 1
    (jumps dropped) and step 2 (stops). Returns ``stops``, ``n_positions``, ``n_jumps``, the step
    ``timings`` and, with ``keep``, the ``cleaned`` points; with a picklable ``read_bucket`` it
    runs in any process."""
    positions = read_bucket(k)
    t0 = time.perf_counter()
    pts, jumps = _clean_track_points(positions, params)
    t1 = time.perf_counter()
    stops = detect_stops(pts, params.stops, id_col=params.id_col)
    return {"stops": stops, "n_positions": int(len(positions)), "n_jumps": int(jumps),
            "timings": {"clean_s": t1 - t0, "stops_s": time.perf_counter() - t1}, "cleaned": pts if keep else None}


def bucket_voyages(read_bucket: Callable[[int], pd.DataFrame] | None, k: int, params: ChainParams, stops: pd.DataFrame,
                   stop_port_id: np.ndarray, places: pd.DataFrame | None, ports: pd.DataFrame | None,
                   points_sink: Callable[[int, pd.DataFrame], None] | None = None, cleaned: pd.DataFrame | None = None) -> dict:
    """Pass 2 of bucket ``k``: its positions read and cleaned again (or ``cleaned``, pass 1's),
    step 4 (voyages, from the bucket's ``stops`` and their ``stop_port_id``) and step 5
    (resampling). Returns ``voyages``, ``points`` (``None`` when they went to ``points_sink``),
    ``n_points`` and the step ``timings``."""
    timings = {}
    if cleaned is None:
        t = time.perf_counter()
        cleaned = _clean_track_points(read_bucket(k), params)[0]
        timings["clean_s"] = time.perf_counter() - t
    t = time.perf_counter()
    voyages = segment_voyages(cleaned, stops, stop_port_id, places, params.voyages, id_col=params.id_col, ports=ports)
    timings["voyages_s"] = time.perf_counter() - t
    t = time.perf_counter()
    points = resample_voyages(cleaned, voyages, params.resample)
    timings["resample_s"] = time.perf_counter() - t
    del cleaned
    n_points = int(len(points))
    if points_sink is not None:
        t = time.perf_counter()
        points_sink(k, points)
        timings["points_sink_s"] = time.perf_counter() - t
        points = None
    return {"voyages": voyages, "points": points, "n_points": n_points, "timings": timings}


def _in_turn(fn: Callable, calls: list[tuple]) -> list:
    """The default ``map_buckets``: each call in this process, in order."""
    return [fn(*args) for args in calls]


def _add_timings(timings: dict, parts: list[dict]) -> None:
    for part in parts:
        for name, s in part["timings"].items():
            timings[name] = timings.get(name, 0.0) + s


def prepare_chain_in_buckets(read_bucket: Callable[[int], pd.DataFrame], n_buckets: int,
                             known_ports: pd.DataFrame | None = None, params: ChainParams | None = None,
                             points_sink: Callable[[int, pd.DataFrame], None] | None = None,
                             map_buckets: Callable[[Callable, list[tuple]], list] | None = None) -> PreparedChain:
    """Steps 1-5 over the tracks in ``n_buckets`` buckets, in two passes, holding one bucket's
    positions at a time.

    ``read_bucket(k)`` returns the canonical positions of bucket ``k``: whole tracks, the
    buckets' track ids in ascending, disjoint ranges (e.g. MMSI ranges). Every step but the
    ports works track by track, so pass 1 (:func:`bucket_stops`: clean, stops) and pass 2
    (:func:`bucket_voyages`: clean again, voyages, resampling) run bucket by bucket; the ports are
    detected once, here, from every bucket's stops (few: one row per stop episode). The result
    equals :func:`prepare_chain` of all positions (stops, ports, voyages and points in the same
    order; tested), except that the voyages' and stops' ``first_row``/``last_row`` index their own
    bucket's points. Memory: one bucket's positions plus the stops, voyages and resampled points of
    all (the resampled points grow with the fleet's time at sea divided by the step, not with the
    AIS cadence).

    ``points_sink(k, points)``, when given, receives each bucket's resampled points in pass 2
    instead (e.g. to write them to disk partition by partition); the result's ``points`` is then
    ``None`` and ``n_points`` their count, so nothing held grows with the resampled points.

    ``map_buckets(fn, calls)`` runs ``fn(*args)`` for every ``args`` of ``calls`` and returns the
    results in order: by default one after the other here; a task runner may run them on other
    processes (``read_bucket`` and ``points_sink`` must then be picklable and the buckets' data
    visible there). The passes are the same functions either way, so the result is the same.
    """
    params = params or ChainParams()
    timings = {k: 0.0 for k in ("clean_s", "stops_s", "ports_s", "voyages_s", "resample_s")}
    one_here = map_buckets is None and n_buckets == 1  # one bucket here: pass 2 reuses pass 1's points
    map_buckets = map_buckets or _in_turn
    firsts = map_buckets(bucket_stops, [(read_bucket, k, params, one_here) for k in range(n_buckets)])
    kept = firsts[0].pop("cleaned")
    _add_timings(timings, firsts)
    stops_per_bucket = [f["stops"] for f in firsts]

    t = time.perf_counter()
    offsets = np.cumsum([0] + [len(s) for s in stops_per_bucket])
    stops = pd.concat([s.assign(stop_id=s["stop_id"] + offsets[k]) for k, s in enumerate(stops_per_bucket)],
                      ignore_index=True) if n_buckets > 1 else stops_per_bucket[0]
    ports, stop_port_id = detect_ports(stops, known_ports, params.ports)
    stops = stops.assign(port_id=stop_port_id)
    places = [ports[["lat_deg", "lon_deg"]]] if len(ports) else []
    if known_ports is not None and len(known_ports):
        places.append(known_ports[["lat_deg", "lon_deg"]])
    places_df = pd.concat(places, ignore_index=True).astype(float) if places else None
    timings["ports_s"] += time.perf_counter() - t

    port_rows = ports if len(ports) else None
    calls = [(read_bucket, k, params, stops_per_bucket[k], stop_port_id[offsets[k]:offsets[k + 1]], places_df,
              port_rows, points_sink) for k in range(n_buckets)]
    if one_here:
        seconds = [bucket_voyages(*calls[0], cleaned=kept)]
    else:
        seconds = map_buckets(bucket_voyages, calls)
    del kept
    _add_timings(timings, seconds)
    voyages_df = seconds[0]["voyages"] if n_buckets == 1 else pd.concat([s["voyages"] for s in seconds], ignore_index=True)
    points_df = None if points_sink is not None else seconds[0]["points"] if n_buckets == 1 else pd.concat(
        [s["points"] for s in seconds], ignore_index=True)
    return PreparedChain(ports, stops, voyages_df, points_df, sum(f["n_positions"] for f in firsts),
                         sum(f["n_jumps"] for f in firsts), timings, sum(s["n_points"] for s in seconds))


def finish_chain(prep: PreparedChain, lanes: LaneResult, lanes_s: float,
                 lane_voyages: pd.DataFrame | None = None) -> ChainResult:
    """The chain's result from the serial part and the lanes of every partition (step 6).

    ``lanes`` is :func:`lanes.extract.extract_lanes` of ``prep.points``, or the same computed
    partition by partition and merged with :func:`lanes.extract.merge_lane_results`; ``lanes_s``
    is the wall time it took. ``timings["total_s"]`` is the sum of the step times.
    ``lane_voyages``: :func:`lanes.extract.lane_voyage_table` computed partition by partition
    (:func:`lanes.extract.merge_lane_voyage_tables`), when the points are not held (``prep.points``
    is ``None``).
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
        "resampled_points": int(prep.n_points),
        "slow_points": int(lanes.n_slow),
        "sampled_partitions": int(lanes.n_sampled_partitions),
        "timings": {k: round(v, 3) for k, v in timings.items()},
    }
    log.info("lanes chain: %s", summary)
    if lane_voyages is None:
        lane_voyages = lane_voyage_table(points, lanes.point_lane)
    return ChainResult(ports, prep.stops, voyages, points, lanes, lane_voyages, summary)


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


__all__ = ["ChainParams", "ChainResult", "PreparedChain", "bucket_stops", "bucket_voyages", "build_lanes", "finish_chain",
           "prepare_chain", "prepare_chain_in_buckets", "voyages_as_table"]
