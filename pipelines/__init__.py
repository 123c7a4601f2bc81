"""Prefect flows and tasks (thin), the DuckDB storage layer and the ``stormlane`` CLI."""

import os

# Quiet and offline by default (STACK.md): no telemetry DNS look-ups, no analytics.
os.environ.setdefault("PREFECT_SERVER_ANALYTICS_ENABLED", "false")
os.environ.setdefault("DO_NOT_TRACK", "1")
os.environ.setdefault("PREFECT_LOGGING_EXTRA_LOGGERS", "lanes,weather,routing,thresholds,dashboards")
# Domain loggers (above) also log outside flow runs (CLI, demo steps): no UserWarning from Prefect's
# API log handler for those records.
os.environ.setdefault("PREFECT_LOGGING_TO_API_WHEN_MISSING_FLOW", "ignore")
# A flow run without PREFECT_API_URL starts a temporary local API server (SQLite migrations
# first): Prefect waits 20 s for it, too short for a first run on a fresh venv on 2 busy cores.
os.environ.setdefault("PREFECT_SERVER_EPHEMERAL_STARTUP_TIMEOUT_SECONDS", "180")
