"""AIS tables: files, positions, vessels, quarantine - and the SQL of the bulk ingest.

Tables (component ``ais``):

``ais_files``
    one row per loaded file: ``file_id``, ``fingerprint`` (``blake3:<hex>`` of the bytes, unique; ``sha256:<hex>`` for
    files loaded by earlier versions),
    (``ais_file_keys``: ``quick_key`` = size + SHA-256 of the first and last MiB),
    ``path``, ``format``, ``size_bytes``, the counts (``n_read`` = ``n_loaded`` +
    ``n_quarantined`` + ``n_duplicates``; ``n_static``, ``n_ignored``), ``reasons`` (JSON),
    ``max_speed_kn``, ``loaded_at``.
``ais_positions``
    the canonical positions (``mmsi``, ``time_utc`` TIMESTAMPTZ, ``lat_deg``, ``lon_deg``,
    ``sog_kn``, ``cog_deg``, ``heading_deg``, ``nav_status``) plus ``file_id`` and
    ``source_line``. (mmsi, time_utc) is unique: the ingest counts later rows with the same key
    as duplicates.
``vessels``
    static data, one row per MMSI, the latest non-missing value of each field wins.
``ais_quarantine``
    every row not loaded: ``file_id``, ``line`` (CSV/NMEA line, Parquet row, 1-based),
    ``reason`` (a code of :mod:`ais.clean`), ``raw`` text, ``mmsi`` and ``time_utc`` when known.
    Duplicates are kept here too, with their ``duplicate*`` code.

Modules, by table family: :mod:`.schema` (the tables), :mod:`.files` (``ais_files``), the
stages (:mod:`.stage_lines`, :mod:`.stage_fast`, :mod:`.stage_tables`, helpers in :mod:`._sql`),
:mod:`.commit` (rules 7-8 and the commit), :mod:`.vessels`, :mod:`.read`.

Bulk ingest, per file: the reader fills the temporary typed stage ``ais_stage`` (CSV straight
from DuckDB's ``read_csv`` over raw lines, Parquet from ``read_parquet``, NMEA from the Python
decoder), then :func:`classify_and_commit` applies the rules of :mod:`ais.clean` as SQL (the
speed-jump kernel runs in numpy on the few tracks with a candidate jump) and writes everything
in **one transaction**: a crash leaves the workspace as before the file. Readers in the same
process use their own cursor (``ws.con.cursor()``) and see the state before or after a file,
never half of it (DuckDB MVCC); other processes wait for the writer's file lock
(:func:`open_for_reading`).
"""

from pipelines.storage.ais.commit import AlreadyLoaded, classify_and_commit, discard_stage, limit_ingest_memory
from pipelines.storage.ais.parquet import check_dataset_folders, positions_root, sync_positions_parquet
from pipelines.storage.ais.files import file_record, fingerprint_algos, quick_key_known, read_files
from pipelines.storage.ais.read import (open_for_reading, positions_per_mmsi, read_positions, read_positions_parquet,
                                        read_quarantine, read_vessels)
from pipelines.storage.ais.schema import COMPONENT, MIGRATIONS
from pipelines.storage.ais.stage_lines import stage_csv
from pipelines.storage.ais.stage_fast import stage_csv_arrow, stage_csv_fast, stage_csv_scan
from pipelines.storage.ais.stage_tables import (
    parquet_columns, read_stage, stage_arrow, stage_frame, stage_parquet, stage_table,
)


__all__ = [
    "COMPONENT", "MIGRATIONS", "AlreadyLoaded", "classify_and_commit", "discard_stage", "file_record", "limit_ingest_memory", "fingerprint_algos",
    "check_dataset_folders", "open_for_reading", "parquet_columns", "positions_per_mmsi", "positions_root", "sync_positions_parquet", "quick_key_known", "read_files", "read_positions", "read_positions_parquet", "read_quarantine", "read_stage",
    "read_vessels", "stage_arrow", "stage_csv", "stage_csv_arrow", "stage_csv_fast", "stage_csv_scan", "stage_frame",
    "stage_parquet", "stage_table",
]
