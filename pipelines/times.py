"""Times the user types (``--now``, ``--depart``, ``--start`` ...): ISO 8601, naive means UTC."""

from __future__ import annotations

import datetime as _dt
import re

import pandas as pd

#: The ISO 8601 forms accepted: ``YYYY-MM-DD``, optionally ``T`` (or a space) and ``HH:MM``,
#: ``HH:MM:SS`` or ``HH:MM:SS.f`` (1-9 digits), optionally ``Z`` or an offset ``+HH:MM`` /
#: ``-HH:MM`` after a time. Nothing else: ``01/02/2025`` is January 2nd to one reader and
#: February 1st to another (the DMA AIS files are day-first), ``now`` or ``Jan 5`` are not times.
ISO_8601 = re.compile(
    r"(?P<y>\d{4})-(?P<mo>\d{2})-(?P<d>\d{2})"
    r"(?:[T ](?P<h>\d{2}):(?P<mi>\d{2})(?::(?P<s>\d{2})(?:\.(?P<f>\d{1,9}))?)?"
    r"(?P<tz>Z|[+-]\d{2}:\d{2})?)?",
    re.ASCII,
)


def utc_or_none(text) -> pd.Timestamp | None:
    """``text`` as a tz-aware UTC Timestamp (a naive time is taken as UTC); None when it is not an
    ISO 8601 time (:data:`ISO_8601`) or lies outside what pandas holds (years 1677-2262).
    Callers raise their own error naming the option or field.

    A ``datetime``/``Timestamp`` (from the Python API, not typed) is taken as it is.

    Examples
    --------
    >>> utc_or_none("2025-01-14T12:00+01:00")
    Timestamp('2025-01-14 11:00:00+0000', tz='UTC')
    >>> utc_or_none("2025-01-14")
    Timestamp('2025-01-14 00:00:00+0000', tz='UTC')
    >>> utc_or_none("01/02/2025") is None, utc_or_none("now") is None
    (True, True)
    """
    if isinstance(text, (pd.Timestamp, _dt.datetime)):
        t = pd.Timestamp(text)
    elif isinstance(text, str):
        t = _parse_iso(text.strip())
    else:
        return None
    if t is None or t is pd.NaT:
        return None
    try:
        t = t.as_unit("ns")
    except (OverflowError, ValueError):  # OutOfBoundsDatetime is a ValueError
        return None
    return t.tz_localize("UTC") if t.tzinfo is None else t.tz_convert("UTC")


def _parse_iso(text: str) -> pd.Timestamp | None:
    m = ISO_8601.fullmatch(text)
    if m is None:
        return None
    g = m.groupdict()
    frac = (g["f"] or "").ljust(9, "0")
    tz = None
    if g["tz"] == "Z":
        tz = _dt.timezone.utc
    elif g["tz"]:
        sign = -1 if g["tz"][0] == "-" else 1
        oh, om = int(g["tz"][1:3]), int(g["tz"][4:6])
        if oh > 23 or om > 59:
            return None
        tz = _dt.timezone(sign * _dt.timedelta(hours=oh, minutes=om))
    try:
        d = _dt.datetime(int(g["y"]), int(g["mo"]), int(g["d"]), int(g["h"] or 0), int(g["mi"] or 0), int(g["s"] or 0),
                         int(frac[:6]), tzinfo=tz)
    except ValueError:  # month 13, February 30th, hour 24 ...
        return None
    t = pd.Timestamp(d)
    ns = int(frac[6:])
    return t + pd.Timedelta(nanoseconds=ns) if ns else t
