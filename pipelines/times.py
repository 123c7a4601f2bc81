"""Times the user types (``--now``, ``--depart``, ``--start`` ...): ISO 8601, naive means UTC."""

from __future__ import annotations

import pandas as pd


def utc_or_none(text) -> pd.Timestamp | None:
    """``text`` as a tz-aware UTC Timestamp (a naive time is taken as UTC); None when it is not an
    ISO 8601 time. Callers raise their own error naming the option or field."""
    try:
        t = pd.Timestamp(text)
    except (ValueError, TypeError):
        return None
    if t is pd.NaT:
        return None
    return t.tz_localize("UTC") if t.tzinfo is None else t.tz_convert("UTC")
