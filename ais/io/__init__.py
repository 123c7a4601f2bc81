"""AIS file adapters: one module per source format, each producing the typed stage of :mod:`ais.clean`."""
