"""Generated AIS inputs of ``bench/ingest.py`` and ``bench/ingest_dask.py`` (deterministic).

* :func:`generate_dma_csv` — DMA-style CSV (the real DMA column layout, 26 columns, day-first
  timestamps, static fields on every row) or the NOAA MarineCadastre layout, with ~0.5 % dirty
  rows of six kinds (sentinel positions, bad MMSI, bad time, out-of-range latitude, sentinel
  speed/course/heading, 2-degree one-fix jumps).
* :func:`generate_nmea` — ``$PGHP`` + tag-block framed ``!AIVDM`` messages (99 % type 1
  positions encoded here, ITU-R M.1371-5; a few real type 4/5 sentences).
* :func:`pyais_loop` — the plain pyais decode loop, the NMEA baseline.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

DMA_HEADER = ("# Timestamp,Type of mobile,MMSI,Latitude,Longitude,Navigational status,ROT,SOG,COG,Heading,IMO,"
              "Callsign,Name,Ship type,Cargo type,Width,Length,Type of position fixing device,Draught,Destination,"
              "ETA,Data source type,A,B,C,D")


NOAA_HEADER = ("MMSI,BaseDateTime,LAT,LON,SOG,COG,Heading,VesselName,IMO,CallSign,VesselType,Status,Length,Width,"
               "Draft,Cargo,TransceiverClass")
#: Time layout of each generated CSV layout (strftime) and a bad time written in it.
TIME_LAYOUT = {"dma": ("%d/%m/%Y %H:%M:%S", "31/02/2025 25:61:00"), "noaa": ("%Y-%m-%dT%H:%M:%S", "2025-02-31T25:61:00")}


def generate_dma_csv(path: Path, n_rows: int, n_vessels: int = 2000, seed: int = 0, dirty_frac: float = 0.005,
                     layout: str = "dma", start: str = "2025-01-01T00:00:00") -> dict:
    """Write ``n_rows`` DMA-style rows (time-ordered, ``n_vessels`` ships at 6-20 kn, 10 s
    cadence) with a share of dirty rows; returns what was injected. ``layout="noaa"`` writes the
    same fleet in the MarineCadastre layout (17 columns, ISO times, numeric status). ``start``:
    the first time (the same seed and another start: the fleet's next day)."""
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.csv as pcsv

    rng = np.random.default_rng(seed)
    i = np.arange(n_rows)
    v = i % n_vessels
    step = i // n_vessels
    mmsi_v = rng.choice(np.arange(219000000, 220000000), n_vessels, replace=False)
    lat0 = rng.uniform(54.5, 57.5, n_vessels)
    lon0 = rng.uniform(8.0, 14.0, n_vessels)
    sog_v = rng.uniform(6, 20, n_vessels)
    cog_v = rng.uniform(0, 360, n_vessels)
    dt_s = step * 10 + (v % 10)
    dist_deg = sog_v[v] * dt_s / 3600.0 / 60.0
    lat = lat0[v] + dist_deg * np.cos(np.radians(cog_v[v])) + rng.normal(0, 2e-5, n_rows)
    lon = lon0[v] + dist_deg * np.sin(np.radians(cog_v[v])) / np.cos(np.radians(lat0[v])) + rng.normal(0, 2e-5, n_rows)
    t0 = np.datetime64(start, "s")
    tstr = pc.strftime(pa.array(t0 + dt_s.astype("timedelta64[s]")), format=TIME_LAYOUT[layout][0]).to_numpy(
        zero_copy_only=False).astype(object)
    sog = np.round(np.abs(sog_v[v] + rng.normal(0, 0.2, n_rows)), 1).astype(object)
    cog = (np.round(cog_v[v] + rng.normal(0, 1, n_rows), 1) % 360).astype(object)
    hdg = (np.round(cog_v[v]).astype(int) % 360).astype(object)
    mmsi = mmsi_v[v].astype(object)
    lat_s = np.char.mod("%.6f", lat).astype(object)
    lon_s = np.char.mod("%.6f", lon).astype(object)
    status = np.full(n_rows, "Under way using engine", dtype=object)
    names = np.array([f"VESSEL {k}" for k in range(n_vessels)], dtype=object)

    # Dirty rows: spread over the file, ~dirty_frac of the rows in total.
    n_dirty = int(n_rows * dirty_frac)
    idx = rng.choice(n_rows, n_dirty, replace=False)
    kinds = np.array(["sentinel_pos", "bad_mmsi", "bad_time", "out_of_range", "sentinels", "jump"])
    kind = kinds[rng.integers(0, len(kinds), n_dirty)]
    for k in kinds:
        sel = idx[kind == k]
        if k == "sentinel_pos":
            lat_s[sel], lon_s[sel] = "91.000000", "181.000000"
        elif k == "bad_mmsi":
            mmsi[sel] = 12345678
        elif k == "bad_time":
            tstr[sel] = TIME_LAYOUT[layout][1]
        elif k == "out_of_range":
            lat_s[sel] = "95.500000"
        elif k == "sentinels":
            sog[sel], cog[sel], hdg[sel] = 102.3, 360.0, 511
        elif k == "jump":
            lat_s[sel] = np.char.mod("%.6f", lat[sel] + 2.0).astype(object)
    injected = {str(k): int((kind == k).sum()) for k in kinds}
    if layout == "noaa":
        table = pa.table({
            "mmsi": pa.array(mmsi.astype(str), pa.string()), "ts": pa.array(tstr, pa.string()),
            "lat": pa.array(lat_s, pa.string()), "lon": pa.array(lon_s, pa.string()),
            "sog": pa.array(sog.astype(str), pa.string()), "cog": pa.array(cog.astype(str), pa.string()),
            "hdg": pa.array(hdg.astype(str), pa.string()), "name": pa.array(names[v], pa.string()),
            "imo": pa.array(np.full(n_rows, "IMO9123456", dtype=object), pa.string()),
            "cs": pa.array(np.full(n_rows, "OXAB2", dtype=object), pa.string()), "type": pa.array(np.full(n_rows, 70)),
            "st": pa.array(np.zeros(n_rows, dtype=int)), "l": pa.array(np.full(n_rows, 120)),
            "w": pa.array(np.full(n_rows, 20)), "dr": pa.array(np.full(n_rows, 7.5)),
            "cargo": pa.array(np.full(n_rows, 70)), "tc": pa.array(np.full(n_rows, "A", dtype=object), pa.string()),
        })
        with open(path, "wb") as fh:
            fh.write((NOAA_HEADER + "\n").encode())
            pcsv.write_csv(table, fh, pcsv.WriteOptions(include_header=False, quoting_style="none"))
        return injected
    table = pa.table({
        "ts": pa.array(tstr, pa.string()), "mob": pa.array(np.full(n_rows, "Class A", dtype=object), pa.string()),
        "mmsi": pa.array(mmsi.astype(str), pa.string()), "lat": pa.array(lat_s, pa.string()),
        "lon": pa.array(lon_s, pa.string()), "st": pa.array(status, pa.string()),
        "rot": pa.array(np.zeros(n_rows)), "sog": pa.array(sog.astype(str), pa.string()),
        "cog": pa.array(cog.astype(str), pa.string()), "hdg": pa.array(hdg.astype(str), pa.string()),
        "imo": pa.array(np.full(n_rows, "Unknown", dtype=object), pa.string()),
        "cs": pa.array(np.full(n_rows, "OXAB2", dtype=object), pa.string()),
        "name": pa.array(names[v], pa.string()), "type": pa.array(np.full(n_rows, "Cargo", dtype=object), pa.string()),
        "cargo": pa.nulls(n_rows, pa.string()), "w": pa.array(np.full(n_rows, 20)), "l": pa.array(np.full(n_rows, 120)),
        "fix": pa.array(np.full(n_rows, "GPS", dtype=object), pa.string()), "dr": pa.array(np.full(n_rows, 7.5)),
        "dest": pa.array(np.full(n_rows, "AARHUS", dtype=object), pa.string()), "eta": pa.nulls(n_rows, pa.string()),
        "src": pa.array(np.full(n_rows, "AIS", dtype=object), pa.string()),
        "A": pa.array(np.full(n_rows, 100)), "B": pa.array(np.full(n_rows, 20)),
        "C": pa.array(np.full(n_rows, 10)), "D": pa.array(np.full(n_rows, 10)),
    })
    with open(path, "wb") as fh:
        fh.write((DMA_HEADER + "\n").encode())
        pcsv.write_csv(table, fh, pcsv.WriteOptions(include_header=False, quoting_style="none"))
    return injected


def noaa_csv_to_geoparquet(csv_path: Path, path: Path) -> int:
    """Write the rows of a NOAA-layout CSV file (:func:`generate_dma_csv` with ``layout="noaa"``)
    as a GeoParquet file shaped like MarineCadastre's daily files from 2024 on: snake_case
    columns, the position only in a WKB point ``geometry`` (OGC 06-103r4 section 8.2: byte order
    1, type 1, x = longitude, y = latitude), the data dictionary's types (SOG, COG, heading,
    length, width and draft as 4-byte floats; vessel type and status short integers) [1].
    Values that are no number or time are written as missing. Returns the rows written.

    .. [1] NOAA Office for Coastal Management, "AIS data dictionary" (MarineCadastre.gov,
       Nationwide Automatic Identification System): field names, types and sizes.
    """
    import duckdb
    import pyarrow as pa
    import pyarrow.parquet as pq

    con = duckdb.connect()
    con.execute("SET TimeZone = 'UTC'")
    t = con.execute("""
        SELECT TRY_CAST("MMSI" AS BIGINT) AS mmsi, TRY_CAST("BaseDateTime" AS TIMESTAMPTZ) AS base_date_time,
               TRY_CAST("SOG" AS FLOAT) AS sog, TRY_CAST("COG" AS FLOAT) AS cog, TRY_CAST("Heading" AS FLOAT) AS heading,
               "VesselName" AS vessel_name, "IMO" AS imo, "CallSign" AS call_sign,
               TRY_CAST("VesselType" AS SMALLINT) AS vessel_type, TRY_CAST("Status" AS SMALLINT) AS status,
               TRY_CAST("Length" AS FLOAT) AS length, TRY_CAST("Width" AS FLOAT) AS width,
               TRY_CAST("Draft" AS FLOAT) AS draft, "Cargo" AS cargo, "TransceiverClass" AS transceiver,
               TRY_CAST("LON" AS DOUBLE) AS x, TRY_CAST("LAT" AS DOUBLE) AS y
        FROM read_csv(?, all_varchar = true, header = true, delim = ',', quote = '', escape = '')""",
                    [str(csv_path)]).to_arrow_table()
    con.close()
    n = t.num_rows
    rec = np.zeros((n, 21), np.uint8)
    rec[:, 0] = 1  # little-endian (NDR)
    rec[:, 1:5] = np.frombuffer(np.uint32(1).astype("<u4").tobytes(), np.uint8)  # point
    rec[:, 5:13] = t["x"].to_numpy().astype("<f8").view(np.uint8).reshape(n, 8)
    rec[:, 13:21] = t["y"].to_numpy().astype("<f8").view(np.uint8).reshape(n, 8)
    offsets = (np.arange(n + 1, dtype=np.int64) * 21).astype(np.int32)
    geometry = pa.Array.from_buffers(pa.binary(), n, [None, pa.py_buffer(offsets), pa.py_buffer(rec.ravel())])
    pq.write_table(t.drop(["x", "y"]).append_column("geometry", geometry), path)
    return n


# --- NMEA -----------------------------------------------------------------------------------
def _armour(values: np.ndarray) -> np.ndarray:
    """6-bit values -> AIS payload characters (ITU-R M.1371-5 Annex 8 Table 44)."""
    return np.where(values < 40, values + 48, values + 56).astype(np.uint8)


def _bits(value: np.ndarray, width: int) -> np.ndarray:
    value = np.asarray(value, dtype=np.int64) & ((1 << width) - 1)
    shifts = np.arange(width - 1, -1, -1, dtype=np.int64)
    return ((value[:, None] >> shifts) & 1).astype(np.uint8)


def encode_type1(mmsi, status, sog_kn, lon_deg, lat_deg, cog_deg, hdg) -> list[str]:
    """Vectorised encoder of 168-bit message 1 payloads (28 characters each)."""
    n = len(mmsi)
    parts = [
        _bits(np.full(n, 1), 6), _bits(np.zeros(n), 2), _bits(mmsi, 30), _bits(status, 4), _bits(np.full(n, 128), 8),
        _bits(np.round(np.asarray(sog_kn) * 10), 10), _bits(np.zeros(n), 1),
        _bits(np.round(np.asarray(lon_deg) * 600000), 28), _bits(np.round(np.asarray(lat_deg) * 600000), 27),
        _bits(np.round(np.asarray(cog_deg) * 10), 12), _bits(hdg, 9), _bits(np.zeros(n), 6), _bits(np.zeros(n), 2),
        _bits(np.zeros(n), 3), _bits(np.zeros(n), 1), _bits(np.zeros(n), 19),
    ]
    bits = np.concatenate(parts, axis=1)
    six = bits.reshape(n, 28, 6) @ (1 << np.arange(5, -1, -1))
    chars = _armour(six)
    return [bytes(row).decode("ascii") for row in chars]


def _checksum(body: str) -> str:
    c = 0
    for ch in body.encode():
        c ^= ch
    return f"{c:02X}"


def generate_nmea(path: Path, n_messages: int, n_vessels: int = 1500, seed: int = 1) -> None:
    """DMA-like framing: a ``\\si:...\\`` tag block line, a ``$PGHP`` time line and the sentence;
    99 % message 1 positions, some message 4/5 from a real feed."""
    rng = np.random.default_rng(seed)
    v = rng.integers(0, n_vessels, n_messages)
    mmsi_v = rng.choice(np.arange(219000000, 220000000), n_vessels, replace=False)
    t_ms = np.sort(rng.integers(0, 3600 * 1000 * 6, n_messages))
    lat = rng.uniform(54.5, 57.5, n_vessels)[v] + t_ms * 1e-9
    lon = rng.uniform(8.0, 14.0, n_vessels)[v] + t_ms * 1e-9
    payloads = encode_type1(mmsi_v[v], np.zeros(n_messages, dtype=int), rng.uniform(0, 20, n_messages).round(1),
                            lon, lat, rng.uniform(0, 359.9, n_messages).round(1), rng.integers(0, 360, n_messages))
    extra = ["!BSVDM,1,1,,A,402R3bQunn;ss0s>KfPOeUQ0080:,0*09",
             "!BSVDM,2,1,1,B,53uRcl02<VQA<A5B22098U=@tj2222222222220N3`?5540Ht@4jhAiC,0*62\n"
             "!BSVDM,2,2,1,B,`88888888888880,2*67"]
    out = []
    for k in range(n_messages):
        ms = int(t_ms[k])
        h, rem = divmod(ms, 3600000)
        m, rem = divmod(rem, 60000)
        s, msec = divmod(rem, 1000)
        gh = f"PGHP,1,2025,1,1,{h},{m},{s},{msec},219,,2190067,1,00"
        out.append("\\si:AISD*3F\\")
        out.append(f"${gh}*{_checksum(gh)}")
        if k % 100 == 99:
            out.append(extra[(k // 100) % 2])
        else:
            body = f"AIVDM,1,1,,A,{payloads[k]},0"
            out.append(f"!{body}*{_checksum(body)}")
    path.write_text("\n".join(out) + "\n", encoding="ascii")


def pyais_loop(path: Path) -> tuple[int, float]:
    from pyais.stream import FileReaderStream

    t = time.perf_counter()
    n = 0
    for msg in FileReaderStream(str(path)):
        try:
            msg.decode()
        except Exception:  # noqa: BLE001
            pass
        n += 1
    return n, time.perf_counter() - t
