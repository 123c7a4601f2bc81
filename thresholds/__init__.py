"""IMO and operator criteria, units and constants: the leaf every domain package may import."""
