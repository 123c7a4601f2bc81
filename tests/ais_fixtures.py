"""Small hand-built AIS inputs whose outcome is known line by line (shared by the ingest tests)."""

from __future__ import annotations

DMA_HEADER = (
    "# Timestamp,Type of mobile,MMSI,Latitude,Longitude,Navigational status,ROT,SOG,COG,Heading,IMO,Callsign,"
    "Name,Ship type,Cargo type,Width,Length,Type of position fixing device,Draught,Destination,ETA,"
    "Data source type,A,B,C,D"
)


def dma_row(ts, mmsi, lat, lon, status="Under way using engine", sog="10.0", cog="90.0", hdg="90", imo="Unknown",
            callsign="OXAB1", name="ALPHA", ship="Cargo", width="20", length="120", draught="7.5", dest="AARHUS",
            mobile="Class A"):
    return (f"{ts},{mobile},{mmsi},{lat},{lon},{status},0.0,{sog},{cog},{hdg},{imo},{callsign},{name},{ship},,"
            f"{width},{length},GPS,{draught},{dest},,AIS,100,20,10,10")


# One vessel moving east at 0.005 deg of longitude per minute (~10.3 kn at 55 N), plus every
# kind of dirty row. Line numbers are those of the file (header = line 1, a blank line at 8).
DMA_LINES = [
    DMA_HEADER,                                                                           # 1
    dma_row("01/01/2025 00:00:00", "219000001", "55.000000", "11.000000"),                # 2 loaded
    dma_row("01/01/2025 00:01:00", "219000001", "55.000000", "11.005000"),                # 3 loaded
    dma_row("01/01/2025 00:01:00", "219000001", "55.000000", "11.005000"),                # 4 duplicate
    dma_row("01/01/2025 00:01:00", "219000001", "55.100000", "11.005000"),                # 5 duplicate_time
    dma_row("01/01/2025 00:02:00", "219000001", "56.000000", "11.010000"),                # 6 speed_jump
    dma_row("01/01/2025 00:03:00", "219000001", "55.000000", "11.015000", status="Moored", sog="102.3",
            cog="360.0", hdg="511", imo="9123456", name='"ALPHA, THE"', ship="Tanker"),   # 7 loaded, sentinels NULL
    "",                                                                                   # 8 blank: ignored
    dma_row("01/01/2025 00:04:00", "219000001", "91.000000", "181.000000"),               # 9 no_position
    dma_row("31/02/2025 00:05:00", "219000001", "55.000000", "11.02"),                    # 10 bad_time
    dma_row("01/01/2025 00:06:00", "002190001", "55.000000", "11.02", mobile="Base Station"),  # 11 bad_mmsi
    dma_row("01/01/2025 00:07:00", "219000001", "55.000000", "abc"),                      # 12 bad_lon (text)
    "01/01/2025 00:08:00,Class A,219000001,55.000000,11.03,Under way using engine,0.0,10.0",  # 13 bad_line
    dma_row("01/01/2025 00:09:00", "219000001", "55.000000", "11.045", status="Flying"),  # 14 bad_nav_status
    dma_row("01/01/2025 00:10:00", "219000001", "95.000000", "11.05"),                    # 15 bad_lat
    dma_row("01/01/2025 00:11:00", "219000001", "55.000000", "11.055", sog="150.0"),      # 16 bad_sog
    dma_row("01/01/2025 00:12:00", "219000001", "55.000000", "11.060", cog="400.0"),      # 17 bad_cog
    dma_row("01/01/2025 00:13:00", "219000001", "55.000000", "11.065", hdg="400"),        # 18 bad_heading
    dma_row("01/01/2025 00:14:00", "219000001", "55.000000", "11.070", sog="102.2"),      # 19 loaded, SOG NULL
    dma_row("01/01/2025 00:15:00", "999000001", "55.000000", "11.07"),                    # 20 bad_mmsi (MID 999)
    dma_row("01/01/2025 00:16:00", "21900001", "55.000000", "11.07"),                     # 21 bad_mmsi (8 digits)
    dma_row("01/01/2025 00:00:00", "219000002", "54.000000", "180.000000"),               # 22 loaded, lon -> -180
]

DMA_EXPECTED = {
    4: "duplicate", 5: "duplicate_time", 6: "speed_jump", 9: "no_position", 10: "bad_time", 11: "bad_mmsi",
    12: "bad_lon", 13: "bad_line", 14: "bad_nav_status", 15: "bad_lat", 16: "bad_sog", 17: "bad_cog",
    18: "bad_heading", 20: "bad_mmsi", 21: "bad_mmsi",
}
DMA_LOADED_LINES = [2, 3, 7, 19, 22]


def write_dma(path, lines=DMA_LINES, newline="\n"):
    path.write_text(newline.join(lines) + newline, encoding="utf-8")
    return path
