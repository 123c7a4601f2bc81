"""AIS readers (DMA / NOAA CSV, NMEA, Parquet; gzip), the cleaning rules and quarantine codes.

:mod:`ais.clean` defines the rules (one definition, run as pandas here and as SQL by the storage
layer), :mod:`ais.io` holds one reader per source format, each producing the same typed stage;
:mod:`ais._jumps` and :mod:`ais._tracks` are the compiled speed-jump walk and the streaming
first-load pass of the bulk ingest.
"""
