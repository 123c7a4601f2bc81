"""Raw NMEA 0183 AIS (``!xxVDM`` / ``!xxVDO``) into the typed stage.

What one *item* of the stage is (the unit of ``read``):

* every AIS message after multipart assembly (one row, ``line`` = the line of its first
  sentence, ``raw`` = its sentences joined by ``\\n``);
* every sentence or fragment group that cannot form a message (bad checksum, a fragment with
  no start or out of order, a group still incomplete at the end of the file, an unparsable
  ``!`` line, or a line that is not NMEA at all) - one quarantined row each.

Messages 1, 2, 3, 18, 19 and 27 are position reports (``kind`` "P"). Messages 5 and 24 carry
static data only (``kind`` "S"): they are joined to ``vessels`` by MMSI and counted as
``static``, outside ``read``. Every other message type is read and quarantined as
``other_msg_type`` (no ship position). Lines that carry no AIS item are not counted in
``read``: blank lines, ``$PGHP`` time stamps and stand-alone tag blocks (metadata for the next
sentence) and other NMEA sentences such as ``$PSTT`` (counted as ``ignored``).

Time of a message: the ``c:`` field of its tag block (UNIX seconds), else the ``$PGHP`` line
or stand-alone tag block just before its first sentence; such context applies to the next AIS
sentence only. Messages without time are quarantined as ``bad_time`` by the cleaning.

Speed: position messages of the common fixed length (types 1-3 and 18, 168 bits) are decoded
vectorised with numpy straight from the 6-bit payload characters (ITU-R M.1371-5, Annex 2,
Tables 45 and 49); rarer types and odd lengths go through :func:`pyais.decode`. Message types
that are not stored are never decoded. A test checks the vectorised decoder against pyais on
every position message of the real samples.

References
----------
.. [1] ITU-R, Rec. ITU-R M.1371-5, 2014, Annex 2 Sec. 3.3 and Annex 8 (message layouts).
.. [2] IEC 61162-1:2016 (NMEA 0183 sentences, checksum, tag blocks: IEC 61162-450 Annex).
.. [3] Gatehouse, "$PGHP proprietary sentence" as used in the DMA AIS feeds (year, month, day,
       hour, minute, second, millisecond, MID, region, source MMSI).
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

import numpy as np
import pandas as pd

from lanes.clean import (
    BAD_CHECKSUM,
    BAD_PAYLOAD,
    BAD_SENTENCE,
    DUPLICATE_PAYLOAD,
    INCOMPLETE_MULTIPART,
    KIND_POSITION,
    KIND_STATIC,
    OTHER_MSG_TYPE,
    conform_stage,
)
from lanes.io.files import open_binary

#: Message types stored as positions, and those joined as static vessel data.
POSITION_TYPES = frozenset({1, 2, 3, 18, 19, 27})
STATIC_TYPES = frozenset({5, 24})
#: Identical payloads received again within this many seconds are one transmission.
DUPLICATE_WINDOW_S = 60.0

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


def _field(bits: np.ndarray, start: int, width: int, signed: bool) -> np.ndarray:
    weights = (1 << np.arange(width - 1, -1, -1, dtype=np.int64))
    v = bits[:, start:start + width].astype(np.int64) @ weights
    if signed:
        v = np.where(v >= (1 << (width - 1)), v - (1 << width), v)
    return v


def decode_positions_168(payloads: list[str], types: np.ndarray) -> dict[str, np.ndarray]:
    """Decode 28-character payloads of types 1/2/3/18 at once.

    Returns arrays ``mmsi``, ``nav_status`` (NaN for type 18), ``sog_kn``, ``lon_deg``,
    ``lat_deg``, ``cog_deg``, ``heading_deg`` as the raw scaled values (sentinels kept; the
    cleaning turns them into NULL), and ``ok`` (False where a character is not a valid 6-bit
    ASCII armour character).
    """
    n = len(payloads)
    if n == 0:
        return {k: np.empty(0) for k in ("mmsi", "nav_status", "sog_kn", "lon_deg", "lat_deg", "cog_deg", "heading_deg", "ok")}
    chars = np.frombuffer("".join(payloads).encode("latin-1"), dtype=np.uint8).reshape(n, 28)
    ok = np.all(((chars >= 48) & (chars <= 87)) | ((chars >= 96) & (chars <= 119)), axis=1)
    v = chars.astype(np.int16) - 48
    v = np.where(v > 40, v - 8, v).astype(np.uint8) & 0x3F
    bits = np.unpackbits(v[:, :, None], axis=2)[:, :, 2:].reshape(n, 168)
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


class _Items:
    """Column buffers of the stage being built (plain lists: appending is the hot path)."""

    def __init__(self):
        self.line: list[int] = []
        self.raw: list[str] = []
        self.perr: list = []
        self.t: list = []          # seconds since the epoch, a $PGHP field list, or None
        self.payload: list[str] = []
        self.sentences: list = []  # None for single-sentence messages
        self.single: list[bool] = []  # a single sentence whose checksum is still to be checked

    def add(self, line, raw, perr, t=None, payload="", sentences=None, single=False):
        self.line.append(line)
        self.raw.append(raw)
        self.perr.append(perr)
        self.t.append(t)
        self.payload.append(payload)
        self.sentences.append(sentences)
        self.single.append(single)


def parse_lines(lines, progress=None) -> tuple[pd.DataFrame, dict]:
    """Parse NMEA text lines (without line ends) into a typed stage. See the module docstring."""
    items = _Items()
    blank = ignored = 0
    pending_t = None
    # Multipart buffers: key -> (first line, time, [sentences], [payloads])
    buffers: dict = {}
    step = 50000
    add = items.add

    def flush_incomplete(key):
        first, t, sents, _ = buffers.pop(key)
        add(first, "\n".join(sents), INCOMPLETE_MULTIPART, t)

    for lineno, s in enumerate(lines, start=1):
        if progress is not None and lineno % step == 0:
            progress(step)
        if not s or s.isspace():
            blank += 1
            continue
        t_here = None
        c0 = s[0]
        if c0 in " \t":
            s = s.strip()
            c0 = s[0]
        if c0 == "\\":
            end = s.find("\\", 1)
            if end < 0:
                add(lineno, s.strip(), BAD_SENTENCE)
                pending_t = None
                continue
            tag = s[1:end]
            t_tag = _tag_time(tag) if "c:" in tag else None
            s = s[end + 1:].strip()
            if not s:
                if t_tag is not None:
                    pending_t = t_tag
                continue
            t_here = t_tag
            c0 = s[0]
        if c0 == "$":
            if s.startswith("$PGHP,1,"):
                pending_t = s
                continue
            ignored += 1
            continue
        if c0 != "!":
            s = s.strip()
            if not s:
                blank += 1
                continue
            add(lineno, s, BAD_SENTENCE)
            pending_t = None
            continue
        f = s.split(",")
        if len(f) < 7 or f[0][3:6] not in ("VDM", "VDO"):
            s = s.strip()
            if len(f) >= 2 and len(f[0]) == 6 and f[0][3:6].isalpha() and _checksum_ok(s):
                ignored += 1  # a valid non-AIS "!" sentence (e.g. !AIABK)
            else:
                add(lineno, s, BAD_SENTENCE)
            pending_t = None
            continue
        t = t_here if t_here is not None else pending_t
        pending_t = None
        if f[1] == "1" and f[2] == "1":
            add(lineno, s.rstrip(), None, t, f[5], None, True)
            continue
        s = s.rstrip()
        if not _checksum_ok(s):
            add(lineno, s, BAD_CHECKSUM, t)
            continue
        try:
            cnt, num = int(f[1]), int(f[2])
        except ValueError:
            add(lineno, s, BAD_SENTENCE, t)
            continue
        payload = f[5]
        if not (1 <= num <= cnt <= 9):
            add(lineno, s, BAD_SENTENCE, t)
            continue
        key = (f[3], f[4], f[0][1:6], cnt)
        if num == 1:
            if key in buffers:
                flush_incomplete(key)
            buffers[key] = (lineno, t, [s], [payload])
            continue
        buf = buffers.get(key)
        if buf is None or len(buf[2]) != num - 1:
            add(lineno, s, INCOMPLETE_MULTIPART, t)
            continue
        buf[2].append(s)
        buf[3].append(payload)
        if len(buf[2]) == cnt:
            first, t0, sents, pays = buffers.pop(key)
            add(first, "\n".join(sents), None, t0, "".join(pays), sents)
    for key in list(buffers):
        flush_incomplete(key)

    stage, counts = _decode_items(items)
    meta = {"ignored": ignored + blank, "blank_lines": blank, "other_sentences": ignored, **counts}
    return stage, meta


def _checksums_ok(sentences: list[str]) -> np.ndarray:
    """Vectorised NMEA checksum test: XOR of the bytes between the delimiter and ``*``."""
    n = len(sentences)
    if n == 0:
        return np.zeros(0, dtype=bool)
    stars = np.fromiter((x.rfind("*") for x in sentences), dtype=np.int64, count=n)
    lens = np.fromiter((len(x) for x in sentences), dtype=np.int64, count=n)
    ok = (stars > 1) & (lens >= stars + 3)
    bodies = [x[1:k] if good else "" for x, k, good in zip(sentences, stars, ok)]
    blob = np.frombuffer(("".join(bodies)).encode("latin-1", errors="replace"), dtype=np.uint8)
    blens = np.fromiter((len(b) for b in bodies), dtype=np.int64, count=n)
    starts = np.concatenate([[0], np.cumsum(blens)[:-1]])
    got = np.zeros(n, dtype=np.int64)
    nz = blens > 0
    if nz.any():
        got[nz] = np.bitwise_xor.reduceat(blob, starts[nz]) if len(blob) else 0
    hexes = [x[k + 1:k + 3] if good else "" for x, k, good in zip(sentences, stars, ok)]
    want = np.full(n, -1, dtype=np.int64)
    for i, h in enumerate(hexes):
        try:
            want[i] = int(h, 16) if len(h) == 2 else -1
        except ValueError:
            want[i] = -1
    return ok & (got == want)


def _times(raw_t: list) -> np.ndarray:
    """UTC times (``datetime64[ns]``, NaT when unknown) from tag-block seconds, ``$PGHP`` lines
    (parsed vectorised) or None."""
    n = len(raw_t)
    out = np.full(n, np.datetime64("NaT"), dtype="datetime64[ns]")
    pghp_idx, pghp_fields, sec_idx, secs = [], [], [], []
    for i, v in enumerate(raw_t):
        if v is None:
            continue
        if isinstance(v, str):
            f = v.split(",")
            if len(f) >= 9:
                pghp_idx.append(i)
                pghp_fields.append(f[2:9])
        else:
            sec_idx.append(i)
            secs.append(v)
    if pghp_idx:
        try:
            arr = np.array(pghp_fields, dtype=np.int64)
            parts = pd.DataFrame(arr, columns=["year", "month", "day", "hour", "minute", "second", "ms"])
        except (ValueError, OverflowError):
            parts = pd.DataFrame(pghp_fields, columns=["year", "month", "day", "hour", "minute", "second", "ms"])
            parts = parts.apply(pd.to_numeric, errors="coerce")
        ts = pd.to_datetime(parts, errors="coerce")
        out[np.asarray(pghp_idx)] = ts.to_numpy(dtype="datetime64[ns]")
    if sec_idx:
        ms = np.round(np.asarray(secs, dtype=float) * 1000.0)
        valid = np.isfinite(ms) & (np.abs(ms) < 4e12)
        vals = np.full(len(ms), np.datetime64("NaT"), dtype="datetime64[ns]")
        vals[valid] = ms[valid].astype(np.int64).astype("datetime64[ms]").astype("datetime64[ns]")
        out[np.asarray(sec_idx)] = vals
    return out


def _decode_items(items: _Items) -> tuple[pd.DataFrame, dict]:
    n = len(items.line)
    perr = np.asarray(items.perr, dtype=object)
    single = np.asarray(items.single, dtype=bool)
    if single.any():
        idx = np.flatnonzero(single)
        bad = ~_checksums_ok([items.raw[i] for i in idx])
        perr[idx[bad]] = BAD_CHECKSUM
    payloads = items.payload
    mtype = np.array([_msg_type(p) if e is None else -1 for p, e in zip(payloads, perr)], dtype=np.int64)
    kind = np.full(n, KIND_POSITION, dtype=object)
    t = _times(items.t)
    last_seen: dict = {}

    cols = {k: np.full(n, np.nan) for k in ("lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "nav_status",
                                            "length_m", "beam_m", "draught_m")}
    mmsi = np.full(n, -1, dtype=np.int64)
    statics = {k: np.full(n, None, dtype=object) for k in ("imo", "name", "callsign", "ship_type", "destination")}

    perr0 = perr.copy()
    open_ = np.equal(perr, None)
    empty = open_ & np.array([len(p) == 0 for p in payloads], dtype=bool)
    perr[empty] = BAD_PAYLOAD
    open_ &= ~empty

    # Identical position payloads re-received within the window: one transmission (keep the first).
    for i in np.flatnonzero(open_ & np.isin(mtype, list(POSITION_TYPES))):
        p = payloads[i]
        prev = last_seen.get(p, "unseen")
        ti = None if np.isnat(t[i]) else t[i]
        if prev != "unseen" and (prev is None or ti is None
                                 or abs((ti - prev) / np.timedelta64(1, "s")) <= DUPLICATE_WINDOW_S):
            perr[i] = DUPLICATE_PAYLOAD
            open_[i] = False
        else:
            last_seen[p] = ti

    other = open_ & ~np.isin(mtype, list(POSITION_TYPES | STATIC_TYPES))
    perr[other] = OTHER_MSG_TYPE
    open_ &= ~other

    lens = np.array([len(p) for p in payloads], dtype=np.int64)
    fast = open_ & np.isin(mtype, [1, 2, 3, 18]) & (lens == 28) & np.array(
        [items.sentences[i] is None for i in range(n)], dtype=bool)
    idx = np.flatnonzero(fast)
    if len(idx):
        dec = decode_positions_168([payloads[i] for i in idx], mtype[idx])
        good = dec["ok"]
        perr[idx[~good]] = BAD_PAYLOAD
        gi = idx[good]
        mmsi[gi] = dec["mmsi"][good]
        for k in ("lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "nav_status"):
            cols[k][gi] = dec[k][good]
    n_static = 0
    for i in np.flatnonzero(open_ & ~fast):
        sents = items.sentences[i] if items.sentences[i] is not None else [items.raw[i]]
        msg = _decode_with_pyais(sents)
        if msg is None:
            perr[i] = BAD_PAYLOAD
            continue
        if mtype[i] in STATIC_TYPES:
            st = _static_from_pyais(msg)
            kind[i] = KIND_STATIC
            n_static += 1
            mmsi[i] = st.pop("mmsi")
            for k, v in st.items():
                if k in cols:
                    cols[k][i] = v
                else:
                    statics[k][i] = v
        else:
            pos = _position_from_pyais(msg)
            if pos is None:
                perr[i] = BAD_PAYLOAD
                continue
            mmsi[i] = pos.pop("mmsi")
            for k, v in pos.items():
                cols[k][i] = v

    # Static messages whose payload failed to decode stay position-kind items (quarantined).
    time_utc = pd.DatetimeIndex(t).tz_localize("UTC")
    df = pd.DataFrame({
        "line": np.asarray(items.line, dtype=np.int64),
        "raw": np.asarray(items.raw, dtype=object),
        "kind": kind,
        "parse_error": perr,
        "mmsi": pd.array(np.where(mmsi >= 0, mmsi, 0), dtype="Int64"),
        "time_utc": time_utc,
        **cols,
        **statics,
    })
    df.loc[mmsi < 0, "mmsi"] = pd.NA
    assembled = ~np.isin(perr0, [BAD_SENTENCE, BAD_CHECKSUM, INCOMPLETE_MULTIPART])
    types, freq = np.unique(mtype[assembled], return_counts=True)
    counts = {"messages": int(assembled.sum()),
              "position_messages": int(np.sum(assembled & np.isin(mtype, list(POSITION_TYPES)))),
              "msg_types": {int(k): int(v) for k, v in zip(types, freq)},
              "static": n_static}
    return conform_stage(df), counts


def iter_lines(path) -> list[str]:
    """Physical lines of a (possibly gzipped) text file: split on ``\\n``, one trailing ``\\r``
    removed, non-ASCII bytes replaced (NMEA is ASCII)."""
    with open_binary(path) as fh:
        data = fh.read()
    lines = data.decode("ascii", errors="replace").split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    return [x[:-1] if x.endswith("\r") else x for x in lines]


def read_nmea(path, progress=None) -> tuple[pd.DataFrame, dict]:
    """Read an NMEA AIS file (gzip transparent) into a typed stage.

    Returns
    -------
    (pandas.DataFrame, dict)
        The typed stage and metadata: ``format``, ``path``, ``ignored`` (blank lines and
        non-AIS sentences), ``messages``, ``static``.
    """
    stage, meta = parse_lines(iter_lines(path), progress=progress)
    return stage, {"format": "nmea", "path": str(Path(path)), **meta}
