"""AIS file adapters: one module per source format, each returning ``(data, metadata)``."""
