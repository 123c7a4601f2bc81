"""Mesh and land, speed-loss models, time-dependent A*, deviations, emissions, evaluation."""
