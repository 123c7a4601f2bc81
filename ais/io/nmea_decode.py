"""Decoding NMEA AIS payloads: six-bit characters, checksums, tag-block times, and the 168-bit
position reports (types 1, 2, 3, 18) vectorised with numpy; other types through pyais.

Used by :mod:`ais.io.nmea`, which classifies the lines and assembles the messages. Bit offsets
from ITU-R M.1371-5 Annex 2 Table 45 (types 1-3) and Table 49 (type 18); checksums per
IEC 61162-1:2016.
"""

from __future__ import annotations

import datetime as _dt

import numpy as np


#: Message types stored as positions, and those joined as static vessel data.
POSITION_TYPES = frozenset({1, 2, 3, 18, 19, 27})
STATIC_TYPES = frozenset({5, 24})
#: Identical payloads received again within this many seconds are one transmission.
DUPLICATE_WINDOW_S = 60.0
#: White space trimmed around every line.
WS = " \t\n\r\x0b\x0c"

_EPOCH = _dt.datetime(1970, 1, 1)


def _sixbit(ch: int) -> int:
    v = ch - 48
    return v - 8 if v > 40 else v


def _msg_type(payload: str) -> int:
    return _sixbit(ord(payload[0])) if payload else -1


def _checksum_ok(s: str) -> bool:
    star = s.rfind("*")
    if star < 0 or len(s) < star + 3:
        return False
    try:
        want = int(s[star + 1:star + 3], 16)
    except ValueError:
        return False
    got = 0
    for b in s[1:star].encode("ascii", errors="replace"):
        got ^= b
    return got == want


def _tag_time(tag: str):
    """The ``c:`` time of a tag block body (``c:1234567890,s:xx*hh``), in seconds, or None."""
    body = tag.split("*", 1)[0]
    for part in body.split(","):
        if part.startswith("c:"):
            try:
                v = float(part[2:])
            except ValueError:
                return None
            return v / 1000.0 if v > 1e11 else v  # some feeds write milliseconds
    return None


# ---------------------------------------------------------------------------------------------
# Vectorised decoding of the fixed-length position reports (168 bits: types 1, 2, 3, 18).
# Bit offsets from ITU-R M.1371-5 Annex 2 Table 45 (types 1-3) and Table 49 (type 18).
# ---------------------------------------------------------------------------------------------
_LAYOUT_123 = {"mmsi": (8, 30, False), "status": (38, 4, False), "sog": (50, 10, False),
               "lon": (61, 28, True), "lat": (89, 27, True), "cog": (116, 12, False), "hdg": (128, 9, False)}
_LAYOUT_18 = {"mmsi": (8, 30, False), "sog": (46, 10, False), "lon": (57, 28, True), "lat": (85, 27, True),
              "cog": (112, 12, False), "hdg": (124, 9, False)}


def _field(six: np.ndarray, start: int, width: int, signed: bool) -> np.ndarray:
    """Bits [start, start+width) of rows of 6-bit values (MSB first), as int64."""
    k0 = start // 6
    k1 = (start + width - 1) // 6 + 1
    acc = np.zeros(six.shape[0], dtype=np.int64)
    for k in range(k0, k1):
        acc = (acc << 6) | six[:, k].astype(np.int64)
    acc >>= (6 * (k1 - k0) - (start - 6 * k0) - width)
    v = acc & ((1 << width) - 1)
    if signed:
        v = np.where(v >= (1 << (width - 1)), v - (1 << width), v)
    return v


def decode_positions_168(payloads, types: np.ndarray) -> dict[str, np.ndarray]:
    """Decode 28-character payloads of types 1/2/3/18 at once (a list of str, or a uint8 array
    of shape (n, 28)).

    Returns arrays ``mmsi``, ``nav_status`` (NaN for type 18), ``sog_kn``, ``lon_deg``,
    ``lat_deg``, ``cog_deg``, ``heading_deg`` as the raw scaled values (sentinels kept; the
    cleaning turns them into NULL), and ``ok`` (False where a character is not a valid 6-bit
    ASCII armour character).
    """
    n = len(payloads)
    if n == 0:
        return {k: np.empty(0) for k in ("mmsi", "nav_status", "sog_kn", "lon_deg", "lat_deg", "cog_deg", "heading_deg", "ok")}
    if isinstance(payloads, np.ndarray):
        chars = payloads
    else:
        chars = np.frombuffer("".join(payloads).encode("latin-1", errors="replace"), dtype=np.uint8).reshape(n, 28)
    ok = np.all(((chars >= 48) & (chars <= 87)) | ((chars >= 96) & (chars <= 119)), axis=1)
    v = chars.astype(np.int16) - 48
    bits = (np.where(v > 40, v - 8, v) & 0x3F).astype(np.uint8)  # the 28 six-bit values
    out = {k: np.full(n, np.nan) for k in ("nav_status", "sog_kn", "lon_deg", "lat_deg", "cog_deg", "heading_deg")}
    out["mmsi"] = np.zeros(n, dtype=np.int64)
    for is18, layout in ((False, _LAYOUT_123), (True, _LAYOUT_18)):
        sel = (types == 18) if is18 else (types != 18)
        if not sel.any():
            continue
        b = bits[sel]
        out["mmsi"][sel] = _field(b, *layout["mmsi"])
        if "status" in layout:
            out["nav_status"][sel] = _field(b, *layout["status"])
        out["sog_kn"][sel] = _field(b, *layout["sog"]) / 10.0
        out["lon_deg"][sel] = _field(b, *layout["lon"]) / 600000.0
        out["lat_deg"][sel] = _field(b, *layout["lat"]) / 600000.0
        out["cog_deg"][sel] = _field(b, *layout["cog"]) / 10.0
        out["heading_deg"][sel] = _field(b, *layout["hdg"]).astype(float)
    out["ok"] = ok
    return out


def _decode_with_pyais(sentences: list[str]):
    """Decode one (possibly multipart) message with pyais; None when it cannot be decoded."""
    import pyais

    try:
        return pyais.decode(*sentences)
    except Exception:  # noqa: BLE001 - any decoder failure means "bad payload"
        return None


def _position_from_pyais(msg) -> dict | None:
    t = msg.msg_type
    if t in (1, 2, 3, 18, 19):
        lon, lat = msg.lon, msg.lat
    elif t == 27:
        lon, lat = msg.lon, msg.lat
    else:
        return None
    status = getattr(msg, "status", None)
    return {
        "mmsi": int(msg.mmsi),
        "lat_deg": float(lat) if lat is not None else np.nan,
        "lon_deg": float(lon) if lon is not None else np.nan,
        "sog_kn": float(msg.speed) if msg.speed is not None else np.nan,
        "cog_deg": float(msg.course) if msg.course is not None else np.nan,
        "heading_deg": float(getattr(msg, "heading", np.nan)) if getattr(msg, "heading", None) is not None else np.nan,
        "nav_status": float(int(status)) if status is not None else np.nan,
    }


def _static_from_pyais(msg) -> dict:
    out: dict = {"mmsi": int(msg.mmsi)}
    t = msg.msg_type

    def text(x):
        if x is None:
            return None
        s = str(x).replace("@", "").strip()
        return s or None

    def dims():
        a, b = getattr(msg, "to_bow", 0) or 0, getattr(msg, "to_stern", 0) or 0
        c, d = getattr(msg, "to_port", 0) or 0, getattr(msg, "to_starboard", 0) or 0
        return (float(a + b) if a + b > 0 else np.nan), (float(c + d) if c + d > 0 else np.nan)

    if t == 5:
        out["imo"] = int(msg.imo) if msg.imo else None
        out["callsign"] = text(msg.callsign)
        out["name"] = text(msg.shipname)
        st = int(msg.ship_type) if msg.ship_type is not None else 0
        out["ship_type"] = st if 1 <= st <= 99 else None
        out["length_m"], out["beam_m"] = dims()
        out["draught_m"] = float(msg.draught) if msg.draught else np.nan
        out["destination"] = text(msg.destination)
    elif t == 24:
        if getattr(msg, "partno", 0) == 0:
            out["name"] = text(msg.shipname)
        else:
            st = int(msg.ship_type) if msg.ship_type is not None else 0
            out["ship_type"] = st if 1 <= st <= 99 else None
            out["callsign"] = text(msg.callsign)
            out["length_m"], out["beam_m"] = dims()
    return out


def _split_once(body, i):
    b = body[int(i)].as_py()
    return b, b.split(",")


_HEX = np.full(256, -1, dtype=np.int64)
for _i, _c in enumerate("0123456789ABCDEF"):
    _HEX[ord(_c)] = _i
    _HEX[ord(_c.lower())] = _i


def _checksums_ok(sentences: list[str]) -> np.ndarray:
    """Vectorised NMEA checksum test: XOR of the bytes between the delimiter and the last ``*``
    equals the two hex digits after it (same rule as :func:`_checksum_ok`)."""
    n = len(sentences)
    if n == 0:
        return np.zeros(0, dtype=bool)
    enc = [x.encode("latin-1", errors="replace") for x in sentences]
    lens = np.fromiter((len(x) for x in enc), dtype=np.int64, count=n)
    blob = np.frombuffer(b"".join(enc), dtype=np.uint8)
    starts = np.concatenate([[0], np.cumsum(lens)[:-1]])
    ends = starts + lens
    stars_all = np.flatnonzero(blob == ord("*"))
    # the last '*' of each sentence: the last star position < end
    k = np.searchsorted(stars_all, ends, side="left") - 1
    star = np.where(k >= 0, stars_all[np.clip(k, 0, None)] if len(stars_all) else -1, -1)
    ok = (star - starts > 1) & (ends >= star + 3)
    got = np.zeros(n, dtype=np.int64)
    xor_all = np.concatenate([np.zeros(1, np.uint8), np.bitwise_xor.accumulate(blob)]) if len(blob) else np.zeros(1, np.uint8)
    sel = np.flatnonzero(ok)
    # XOR over blob[start+1 : star] = prefix[star] ^ prefix[start+1]
    got[sel] = (xor_all[star[sel]] ^ xor_all[starts[sel] + 1]).astype(np.int64)
    hi = np.full(n, -1, dtype=np.int64)
    lo = np.full(n, -1, dtype=np.int64)
    hi[sel] = _HEX[blob[star[sel] + 1]]
    lo[sel] = _HEX[blob[star[sel] + 2]]
    want = np.where((hi >= 0) & (lo >= 0), hi * 16 + lo, -1)
    return ok & (got == want)
