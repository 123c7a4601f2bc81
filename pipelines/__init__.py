"""Prefect flows and tasks (thin), the DuckDB storage layer and the ``stormlane`` CLI."""

import os

# Quiet and offline by default (STACK.md): no telemetry DNS look-ups, no analytics.
os.environ.setdefault("PREFECT_SERVER_ANALYTICS_ENABLED", "false")
os.environ.setdefault("DO_NOT_TRACK", "1")
os.environ.setdefault("PREFECT_LOGGING_EXTRA_LOGGERS", "lanes,weather,routing,thresholds,dashboards")
# Domain loggers (above) also log outside flow runs (CLI, demo steps): no UserWarning from Prefect's
# API log handler for those records.
os.environ.setdefault("PREFECT_LOGGING_TO_API_WHEN_MISSING_FLOW", "ignore")
