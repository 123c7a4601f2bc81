"""AIS writers: DMA-style CSV and raw NMEA 0183 (``!AIVDM`` with NMEA 4.0 tag blocks).

They write what :func:`scenario.generator.generate_scenario` produced (``records`` plus the
``vessels`` table) into one file per UTC day and return, for every record, the file and the
1-based line it went to, so the scenario's ground truth can point at each dirty row.

DMA CSV
    The Danish Maritime Authority's export (aisdata.ais.dk): header
    ``# Timestamp,Type of mobile,MMSI,Latitude,Longitude,Navigational status,ROT,SOG,COG,Heading,
    IMO,Callsign,Name,Ship type,Cargo type,Width,Length,Type of position fixing device,Draught,
    Destination,ETA,Data source type,A,B,C,D``; day-first timestamps ``31/12/2015 23:59:59``;
    status and ship type as words; static fields repeated on every row; raw AIS "not available"
    values (SOG 102.3, COG 360, heading 511, lat 91, lon 181) written as received.
NMEA
    Every message is preceded by a tag block ``\\s:<source>,c:<unix seconds>*hh\\`` (IEC 61162-1
    ed. 4 / NMEA 4.0: ``c`` = UNIX time of reception); message 5 spans two sentences grouped by
    the tag-block ``g:<n>-<total>-<group id>`` parameter, the first carrying ``s`` and ``c``.
    Payloads are encoded with pyais' encoder (ITU-R M.1371-5 messages 1, 3 and 5).

References
----------
.. [1] Danish Maritime Authority, "AIS data" (historical CSV export, column description),
       https://web.ais.dk/aisdata/
.. [2] ITU-R M.1371-5, Annex 8 (message 1/3 and 5 fields, not-available values), 2014.
.. [3] NMEA 0183 v4.10 / IEC 61162-1:2016, section 7.9 (TAG blocks: c, g, s parameters).
"""

from __future__ import annotations

import gzip as _gzip
import io
from functools import reduce
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa

from scenario.dma_text import concatenated_bytes, dma_lines

DMA_HEADER = (
    "# Timestamp,Type of mobile,MMSI,Latitude,Longitude,Navigational status,ROT,SOG,COG,Heading,IMO,"
    "Callsign,Name,Ship type,Cargo type,Width,Length,Type of position fixing device,Draught,Destination,"
    "ETA,Data source type,A,B,C,D"
)
#: Record columns a DMA CSV line is made of (:func:`scenario.dma_text.dma_lines`).
DMA_COLUMNS = ("time_s", "mmsi", "lat_deg", "lon_deg", "nav_status", "sog_kn", "cog_deg", "heading_deg",
               "vessel_index", "draught_m", "destination", "eta_s", "dirty_kind", "time_text")
#: Rows formatted at once (about 200 bytes of text each).
DMA_SLICE_ROWS = 200_000
#: Navigational status words as the DMA export prints them (ITU-R M.1371-5 codes).
DMA_NAV_STATUS = {
    0: "Under way using engine",
    1: "At anchor",
    2: "Not under command",
    3: "Restricted manoeuverability",
    4: "Constrained by her draught",
    5: "Moored",
    6: "Aground",
    7: "Engaged in fishing",
    8: "Under way sailing",
    15: "Unknown value",
}
#: Cargo category from the second digit of the AIS ship type (ITU-R M.1371-5 Table 53).
_CARGO_CATEGORY = {0: "No additional information", 1: "Category X", 2: "Category Y", 3: "Category Z",
                   4: "Category OS"}


def dma_ship_type(code: int) -> str:
    """The DMA export's ship-type word for an AIS ship-type code."""
    first = int(code) // 10
    return {3: "Other", 4: "HSC", 5: "Other", 6: "Passenger", 7: "Cargo", 8: "Tanker", 9: "Other"}.get(
        first, "Undefined"
    )


def _open(path: Path, gzip: bool, compresslevel: int = 9):
    """A text handle; gzip output is byte-identical across runs (no name, mtime 0)."""
    if gzip:
        raw = open(path, "wb")
        gz = _gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0, compresslevel=compresslevel)
        return io.TextIOWrapper(gz, encoding="ascii", newline="\n"), (gz, raw)
    return open(path, "w", encoding="ascii", newline="\n"), ()


def _open_bytes(path: Path, gzip: bool, compresslevel: int = 9):
    """A binary handle (a context manager); gzip output is byte-identical across runs (no name, mtime 0)."""
    if gzip:
        return _GzipFileClosingRaw(filename="", mode="wb", fileobj=open(path, "wb"), mtime=0,
                                   compresslevel=compresslevel)
    return open(path, "wb")


class _GzipFileClosingRaw(_gzip.GzipFile):
    """A GzipFile that also closes the file object it writes to, with the sync flush the text
    handle of :func:`_open` gives at closing (so that both write the same bytes)."""

    def close(self) -> None:
        raw = self.fileobj
        try:
            if raw is not None:
                self.flush()
            super().close()
        finally:
            if raw is not None:
                raw.close()


def _close(handle, extra) -> None:
    handle.close()
    for h in extra:
        h.close()


def _day_groups(records: pd.DataFrame):
    """(day string, positional index array) per UTC day of ``sort_s``, in day order."""
    day = records["sort_s"].to_numpy() // 86400
    for d in np.unique(day):
        yield pd.Timestamp(int(d) * 86400, unit="s").strftime("%Y-%m-%d"), np.flatnonzero(day == d)


def dma_statics(vessels: pd.DataFrame) -> list[tuple[str, str]]:
    """Per vessel (row of the vessel table): the identity fields and the dimension fields of its
    DMA lines (the static data repeated on every row)."""
    statics = []
    for v in vessels.itertuples(index=False):
        ident = f"{v.imo},{v.callsign},{v.name},{dma_ship_type(v.ship_type)},{_CARGO_CATEGORY.get(v.ship_type % 10, '')}"
        statics.append((f"{ident},{v.beam_m:g},{v.length_m:g},GPS",
                        f"{v.to_bow},{v.to_stern},{v.to_port},{v.to_starboard}"))
    return statics


#: Static fields of a row whose MMSI is no vessel of the table.
DMA_UNKNOWN_STATIC = ("Unknown,Unknown,,Undefined,,,,Undefined", ",,,")
#: Status words of the codes 0..15 (the last one for any other code).
DMA_NAV_WORDS = [DMA_NAV_STATUS.get(code, "Unknown value") for code in range(16)]


def write_dma_rows(path: Path, cols: dict, statics: list[tuple[str, str]], *, gzip: bool = False,
                   compresslevel: int = 9) -> int:
    """Write one DMA CSV file: the header, then one line per row of ``cols`` (the columns of
    :data:`DMA_COLUMNS`, numpy or Arrow, in file order); returns the bytes written to disk."""
    n = len(cols["time_s"])
    with _open_bytes(path, gzip, compresslevel) as handle:
        handle.write((DMA_HEADER + "\n").encode("ascii"))
        # slices of rows: the lines' text is held for one slice at a time
        for lo in range(0, n, DMA_SLICE_ROWS):
            part = {c: (x.slice(lo, DMA_SLICE_ROWS) if isinstance(x, (pa.Array, pa.ChunkedArray))
                        else x[lo:lo + DMA_SLICE_ROWS]) for c, x in cols.items()}
            handle.write(concatenated_bytes(dma_lines(part, statics, DMA_UNKNOWN_STATIC, DMA_NAV_WORDS)))
    return path.stat().st_size


def write_dma_csv(records: pd.DataFrame, vessels: pd.DataFrame, out_dir: Path, *, gzip: bool = False,
                  prefix: str = "aisdk", compresslevel: int = 9) -> pd.DataFrame:
    """Write the ``dma_csv`` records, one file per UTC day (``{prefix}-YYYY-MM-DD.csv[.gz]``,
    gzip at ``compresslevel``; the lines of :func:`scenario.dma_text.dma_lines`).

    Returns a DataFrame indexed like the written records with ``file`` (name) and ``line``
    (1-based; the header is line 1).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    recs = records[(records["fmt"] == "dma_csv") & (records["msg_type"] != 5)]
    statics = dma_statics(vessels)
    locs = []
    for day, pos in _day_groups(recs):
        sub = recs.iloc[pos]
        name = f"{prefix}-{day}.csv" + (".gz" if gzip else "")
        write_dma_rows(out_dir / name, {c: sub[c].to_numpy() for c in DMA_COLUMNS}, statics, gzip=gzip,
                       compresslevel=compresslevel)
        locs.append(pd.DataFrame({"file": name, "line": np.arange(2, len(sub) + 2)}, index=sub.index))
    if not locs:
        return pd.DataFrame({"file": pd.Series(dtype=object), "line": pd.Series(dtype=np.int64)})
    return pd.concat(locs)


def nmea_checksum(body: str) -> str:
    """XOR of the characters between the delimiters, as two upper-case hex digits (NMEA 0183)."""
    return format(reduce(lambda a, b: a ^ b, body.encode("ascii"), 0), "02X")


def tag_block(params: str) -> str:
    """``\\params*hh\\`` with the NMEA 4.0 tag-block checksum."""
    return f"\\{params}*{nmea_checksum(params)}\\"


def _corrupt(sentence: str) -> str:
    """Flip one payload character of a sentence and keep the old checksum (a transmission error)."""
    parts = sentence.split(",")
    payload = parts[5]
    i = min(12, len(payload) - 1)
    ch = payload[i]
    parts[5] = payload[:i] + ("w" if ch != "w" else "0") + payload[i + 1:]
    return ",".join(parts)


#: Six-bit ASCII armoring of AIS payloads (ITU-R M.1371-5 Annex 8 / IEC 61162-1 "6-bit
#: encapsulation"): value v -> chr(v + 48) for v < 40, chr(v + 56) otherwise.
_ARMOR = np.array([v + 48 if v < 40 else v + 56 for v in range(64)], dtype=np.uint8)
_POSITION_BITS = 168  # messages 1, 2 and 3


def _xor(text: str) -> int:
    return reduce(lambda a, b: a ^ b, text.encode("ascii"), 0)


def armor_position_payloads(payloads: list[bytes], channels: list[str]) -> list[str]:
    """``!AIVDM`` sentences for 168-bit position payloads (pyais ``to_bytes`` output), armored
    and check-summed in one vectorised pass.

    Gives byte-identical sentences to ``pyais.encode.encode_dict`` (tested); pyais' own armoring
    loop is about half of its encoding time.
    """
    n = len(payloads)
    if n == 0:
        return []
    raw = np.frombuffer(b"".join(payloads), dtype=np.uint8).reshape(n, _POSITION_BITS // 8)
    bits = np.unpackbits(raw, axis=1).reshape(n, _POSITION_BITS // 6, 6)
    values = bits @ np.array([32, 16, 8, 4, 2, 1], dtype=np.uint8)
    chars = _ARMOR[values]
    xor_payload = np.bitwise_xor.reduce(chars, axis=1)
    text = chars.tobytes().decode("ascii")
    width = _POSITION_BITS // 6
    base = _xor("AIVDM,1,1,,") ^ _xor(",") ^ _xor(",0")
    out = []
    for i, (ch, xp) in enumerate(zip(channels, xor_payload.tolist())):
        cs = base ^ ord(ch) ^ xp
        out.append(f"!AIVDM,1,1,,{ch},{text[i * width:(i + 1) * width]},0*{cs:02X}")
    return out


def write_nmea(records: pd.DataFrame, vessels: pd.DataFrame, out_dir: Path, *, gzip: bool = False,
               prefix: str = "nmea", source: str = "stormlane") -> pd.DataFrame:
    """Write the ``nmea`` records as ``!AIVDM`` sentences with tag blocks, one file per UTC day.

    Message bits come from pyais' encoder (``MessageType1/3.create(...).to_bytes()``, and
    ``encode_dict`` for the two-sentence message 5); position payloads are armored in a batch
    (:func:`armor_position_payloads`). Returns ``file`` and the 1-based ``line`` of each
    record's first sentence.
    """
    from pyais.encode import encode_dict
    from pyais.messages import MessageType1, MessageType3

    classes = {1: MessageType1, 3: MessageType3}
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    recs = records[records["fmt"] == "nmea"]
    vess = vessels.to_dict("records")
    tag_base = _xor(f"s:{source},c:")
    locs = []
    group_id = 0
    for day, pos in _day_groups(recs):
        sub = recs.iloc[pos]
        name = f"{prefix}-{day}.nmea" + (".gz" if gzip else "")
        lines: list[str] = []
        first_line = np.empty(len(sub), dtype=np.int64)
        pending: list[tuple[int, str, bool]] = []  # (line index, tag block, corrupt) per position message
        payloads: list[bytes] = []
        channels: list[str] = []
        cols = zip(sub["msg_type"].tolist(), sub["mmsi"].tolist(), sub["time_s"].tolist(),
                   sub["lat_deg"].tolist(), sub["lon_deg"].tolist(), sub["sog_kn"].tolist(),
                   sub["cog_deg"].tolist(), sub["heading_deg"].tolist(), sub["nav_status"].tolist(),
                   sub["channel"].tolist(), sub["vessel_index"].tolist(), sub["destination"].tolist(),
                   sub["eta_s"].tolist(), sub["draught_m"].tolist(), sub["dirty_kind"].tolist())
        for j, (mt, mmsi, t, lat, lon, sog, cog, hdg, nav, ch, vi, dest, eta_s, dr, kind) in enumerate(cols):
            first_line[j] = len(lines) + 1
            if mt == 5:
                v = vess[vi]
                eta = pd.Timestamp(max(eta_s, 0), unit="s")
                data = {
                    "type": 5, "msg_type": 5, "mmsi": mmsi, "ais_version": 0, "imo": int(v["imo"]),
                    "callsign": v["callsign"], "shipname": v["name"], "ship_type": int(v["ship_type"]),
                    "to_bow": int(v["to_bow"]), "to_stern": int(v["to_stern"]), "to_port": int(v["to_port"]),
                    "to_starboard": int(v["to_starboard"]), "epfd": 1,
                    "month": eta.month if eta_s >= 0 else 0, "day": eta.day if eta_s >= 0 else 0,
                    "hour": eta.hour if eta_s >= 0 else 24, "minute": eta.minute if eta_s >= 0 else 60,
                    "draught": float(dr) if dr == dr else 0.0, "destination": dest or "", "dte": 0,
                }
                sentences = encode_dict(data, talker_id="AI", sentence_type="VDM", radio_channel=ch,
                                        seq_id=group_id % 10)
                group_id += 1
                n = len(sentences)
                for k, sen in enumerate(sentences, start=1):
                    params = f"g:{k}-{n}-{group_id},s:{source},c:{t}" if k == 1 else f"g:{k}-{n}-{group_id}"
                    lines.append(tag_block(params) + sen)
                continue
            msg = classes[mt].create(
                msg_type=mt, mmsi=mmsi, status=nav if nav >= 0 else 15, turn=-128, speed=sog, accuracy=1,
                lon=lon, lat=lat, course=cog, heading=int(hdg), second=t % 60, maneuver=0, raim=0, radio=0,
            )
            data, nbits = msg.to_bytes()
            if nbits != _POSITION_BITS:  # pragma: no cover - messages 1/3 are always 168 bits
                raise ValueError(f"message {mt} of {nbits} bits")
            payloads.append(data)
            channels.append(ch)
            stamp = str(t)
            pending.append((len(lines), f"\\s:{source},c:{stamp}*{tag_base ^ _xor(stamp):02X}\\",
                            kind == "bad_checksum"))
            lines.append("")
        for (i, tb, corrupt), sen in zip(pending, armor_position_payloads(payloads, channels)):
            lines[i] = tb + (_corrupt(sen) if corrupt else sen)
        handle, extra = _open(out_dir / name, gzip)
        handle.write("\n".join(lines) + "\n")
        _close(handle, extra)
        locs.append(pd.DataFrame({"file": name, "line": first_line}, index=sub.index))
    if not locs:
        return pd.DataFrame({"file": pd.Series(dtype=object), "line": pd.Series(dtype=np.int64)})
    return pd.concat(locs)
