"""Weather file and network adapters: one module per product, each returning ``(data, metadata)``."""
