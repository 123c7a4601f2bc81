"""The demo scenario: a deterministic fleet sailing liner services in the Western Mediterranean.

Demo machinery, not part of the AIS ingest or the lanes: :mod:`scenario.generator` makes the
traffic (pure), :mod:`scenario.writers` writes it as DMA CSV and NMEA files;
:mod:`pipelines.scenario` reads the configuration in ``data/`` and runs both.
"""
