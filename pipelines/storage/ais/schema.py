"""The AIS tables of the workspace (component ``ais``) and their migrations."""

from __future__ import annotations


COMPONENT = "ais"

MIGRATIONS = [
    [
        "CREATE SEQUENCE ais_file_id_seq START 1",
        """CREATE TABLE ais_files (
            file_id       INTEGER PRIMARY KEY,
            fingerprint   VARCHAR NOT NULL UNIQUE,
            path          VARCHAR NOT NULL,
            format        VARCHAR NOT NULL,
            size_bytes    BIGINT NOT NULL,
            n_read        BIGINT NOT NULL,
            n_loaded      BIGINT NOT NULL,
            n_quarantined BIGINT NOT NULL,
            n_duplicates  BIGINT NOT NULL,
            n_static      BIGINT NOT NULL,
            n_ignored     BIGINT NOT NULL,
            reasons       VARCHAR NOT NULL,
            max_speed_kn  DOUBLE NOT NULL,
            loaded_at     TIMESTAMPTZ NOT NULL DEFAULT now()
        )""",
        """CREATE TABLE ais_positions (
            mmsi        BIGINT NOT NULL,
            time_utc    TIMESTAMPTZ NOT NULL,
            lat_deg     DOUBLE NOT NULL,
            lon_deg     DOUBLE NOT NULL,
            sog_kn      DOUBLE,
            cog_deg     DOUBLE,
            heading_deg DOUBLE,
            nav_status  DOUBLE,
            file_id     INTEGER NOT NULL,
            source_line BIGINT NOT NULL
        )""",
        """CREATE TABLE vessels (
            mmsi        BIGINT PRIMARY KEY,
            imo         BIGINT,
            name        VARCHAR,
            callsign    VARCHAR,
            ship_type   INTEGER,
            length_m    DOUBLE,
            beam_m      DOUBLE,
            draught_m   DOUBLE,
            destination VARCHAR,
            updated_utc TIMESTAMPTZ,
            file_id     INTEGER NOT NULL
        )""",
        """CREATE TABLE ais_quarantine (
            file_id  INTEGER NOT NULL,
            line     BIGINT NOT NULL,
            reason   VARCHAR NOT NULL,
            raw      VARCHAR,
            mmsi     BIGINT,
            time_utc TIMESTAMPTZ
        )""",
    ],
    # v2: a cheap identity (size + first/last MiB) so that new files are staged while their
    # full SHA-256 is still being computed.
    # (A separate table, not ALTER TABLE ais_files: DuckDB 1.5.6 cannot replay that ALTER from
    # its WAL after a crash - "GetDefaultDatabase with no default database set".)
    [
        """CREATE TABLE ais_file_keys (
            file_id   INTEGER PRIMARY KEY,
            quick_key VARCHAR NOT NULL
        )""",
    ],
    # v3 (issue 23): each MMSI's latest stored fix, so that a file is checked against the stored
    # tracks without reading their history (the per-file cost stays bounded as the workspace
    # grows), and the days of each file's rows in the positions Parquet dataset beside the
    # workspace (what must exist there: see pipelines.storage.ais.parquet).
    [
        """CREATE TABLE ais_track_ends (
            mmsi     BIGINT PRIMARY KEY,
            time_utc TIMESTAMPTZ NOT NULL,
            lat_deg  DOUBLE NOT NULL,
            lon_deg  DOUBLE NOT NULL
        )""",
        """INSERT INTO ais_track_ends
           SELECT mmsi, max(time_utc), arg_max(lat_deg, time_utc), arg_max(lon_deg, time_utc)
           FROM ais_positions GROUP BY mmsi""",
        """CREATE TABLE ais_parquet_parts (
            file_id INTEGER NOT NULL,
            day     DATE NOT NULL,
            n_rows  BIGINT NOT NULL,
            PRIMARY KEY (file_id, day)
        )""",
        """INSERT INTO ais_parquet_parts
           SELECT file_id, CAST(timezone('UTC', time_utc) AS DATE) AS day, count(*)
           FROM ais_positions GROUP BY file_id, day""",
    ],
]
