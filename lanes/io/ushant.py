"""Reader for the Ushant AIS trajectories (Gloaguen et al., figshare 2019) stored as Parquet.

The file (``ushant_ais_subset.parquet``, see ``shared/data/ais/PROVENANCE.md`` §1) has the
columns ``traj_id, t_s, lon, lat, vx_kn, vy_kn``:

* ``traj_id`` is an anonymous trajectory id, **not an MMSI**: one ship may appear in several
  trajectories, and there is no MMSI, name or ship type at all. The reader returns it as
  ``track_id`` (int64) and leaves ``mmsi`` out on purpose, so that nothing downstream mistakes
  it for a vessel identity. The lanes chain runs with ``id_col="track_id"``: a track is then one
  trajectory, "vessel" counts in the lane tables are trajectory counts (an upper bound on the
  number of ships), and the chain never joins two trajectories into one voyage.
* ``t_s`` is seconds since the trajectory's first fix; the data has **no absolute time**. The
  caller must give an explicit ``epoch_utc``; every trajectory then starts at that instant
  (``time_utc = epoch_utc + t_s``). Times are therefore only meaningful within one trajectory;
  the lanes chain only compares times within a track, so it is unaffected. Do not join these
  times with weather.
* ``vx_kn, vy_kn`` are the eastward and northward velocity from the AIS message, so
  ``sog_kn = hypot(vx, vy)`` and ``cog_deg = atan2(vx, vy)`` (clockwise from north) recover SOG
  and COG; heading and navigational status are not in the data (NaN).

Rows with impossible coordinates (the AIS "not available" sentinel lat 91 / lon 181, or any
latitude outside [-90, 90] or longitude outside [-180, 180]) cannot be positions: they are
dropped and counted in the metadata under ``rejected`` with a reason code, never silently.
Spurious but valid far-away fixes are left to :func:`lanes.interpolate.drop_position_jumps`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from thresholds.errors import StormlaneError

USHANT_COLUMNS = ["traj_id", "t_s", "lon", "lat", "vx_kn", "vy_kn"]


class UshantFormatError(StormlaneError):
    """The file is not the Ushant trajectory Parquet the reader expects."""


def _parse_epoch(epoch_utc) -> pd.Timestamp:
    try:
        ts = pd.Timestamp(epoch_utc)
    except (TypeError, ValueError) as err:
        raise UshantFormatError(f"epoch_utc {epoch_utc!r} is not a timestamp (use e.g. '2019-01-01T00:00Z')") from err
    if ts.tzinfo is None:
        raise UshantFormatError(f"epoch_utc {epoch_utc!r} has no time zone; give it in UTC, e.g. '2019-01-01T00:00Z'")
    return ts.tz_convert("UTC")


def read_ushant(path: str | Path, epoch_utc, columns_only: bool = False) -> tuple[pd.DataFrame, dict]:
    """Read the Ushant trajectories as canonical AIS positions keyed by ``track_id``.

    Parameters
    ----------
    path : str or Path
        The Parquet file.
    epoch_utc : str or Timestamp
        Time zone aware instant assigned to ``t_s = 0`` of every trajectory (required: the
        data has no absolute time).
    columns_only : bool
        Return only ``track_id, time_utc, lat_deg, lon_deg, sog_kn, cog_deg`` (less memory).

    Returns
    -------
    (DataFrame, dict)
        Positions with ``track_id`` (int64), ``time_utc`` (UTC), ``lat_deg``, ``lon_deg``,
        ``sog_kn``, ``cog_deg``, and unless ``columns_only`` also ``heading_deg``,
        ``nav_status`` (NaN), ``source_file`` and ``source_line`` (1-based row number in the
        file); rows keep the file's order (by trajectory, then time). The metadata holds
        ``source``, ``rows``, ``loaded``, ``rejected`` (reason -> count), ``epoch_utc``,
        ``id_col`` (``"track_id"``) and ``id_is_mmsi`` (False).

    Examples
    --------
    >>> df, meta = read_ushant("ushant_ais_subset.parquet", "2019-01-01T00:00Z")  # doctest: +SKIP
    >>> meta["id_col"], meta["id_is_mmsi"]  # doctest: +SKIP
    ('track_id', False)
    """
    import pyarrow.parquet as pq

    path = Path(path)
    epoch = _parse_epoch(epoch_utc)
    try:
        schema = pq.read_schema(path)
    except FileNotFoundError as err:
        raise UshantFormatError(f"{path}: file not found") from err
    except Exception as err:  # pyarrow raises several types for non-Parquet input
        raise UshantFormatError(f"{path}: not a Parquet file ({err})") from err
    missing = [c for c in USHANT_COLUMNS if c not in schema.names]
    if missing:
        raise UshantFormatError(f"{path}: missing column(s) {missing}; expected {USHANT_COLUMNS} (Ushant trajectory schema)")
    table = pq.read_table(path, columns=USHANT_COLUMNS)
    raw = table.to_pandas()
    n = len(raw)
    lat = raw["lat"].to_numpy(dtype=float)
    lon = raw["lon"].to_numpy(dtype=float)
    sentinel = (lat == 91.0) & (lon == 181.0)
    bad_lat = ~sentinel & ~((lat >= -90.0) & (lat <= 90.0))
    bad_lon = ~sentinel & ~bad_lat & ~((lon >= -180.0) & (lon <= 180.0))
    bad_t = ~sentinel & ~bad_lat & ~bad_lon & raw["t_s"].isna().to_numpy()
    reject = sentinel | bad_lat | bad_lon | bad_t
    rejected = {k: int(v.sum()) for k, v in (("latlon_not_available", sentinel), ("lat_out_of_range", bad_lat),
                                              ("lon_out_of_range", bad_lon), ("time_missing", bad_t)) if v.any()}
    keep = ~reject
    vx = raw["vx_kn"].to_numpy(dtype=float)[keep]
    vy = raw["vy_kn"].to_numpy(dtype=float)[keep]
    lon_k = lon[keep]
    lon_k = np.where(lon_k >= 180.0, lon_k - 360.0, lon_k)
    out = pd.DataFrame({
        "track_id": raw["traj_id"].to_numpy()[keep].astype(np.int64),
        "time_utc": epoch + pd.to_timedelta(raw["t_s"].to_numpy()[keep].astype(np.int64), unit="s"),
        "lat_deg": lat[keep],
        "lon_deg": lon_k,
        "sog_kn": np.hypot(vx, vy),
        "cog_deg": np.mod(np.rad2deg(np.arctan2(vx, vy)), 360.0),
    })
    if not columns_only:
        out["heading_deg"] = np.nan
        out["nav_status"] = np.nan
        out["source_file"] = str(path)
        out["source_line"] = np.flatnonzero(keep).astype(np.int64) + 1
    meta = {
        "source": "ushant",
        "path": str(path),
        "rows": int(n),
        "loaded": int(keep.sum()),
        "rejected": rejected,
        "epoch_utc": epoch.isoformat(),
        "id_col": "track_id",
        "id_is_mmsi": False,
    }
    return out, meta
