"""The AIS writers on hand-built records: exact DMA CSV lines, NMEA decoded back by pyais."""

from __future__ import annotations

import pandas as pd
import pyais
import pytest

from scenario.writers import DMA_HEADER, nmea_checksum, write_dma_csv, write_nmea

T0 = int(pd.Timestamp("2025-01-14T06:30:05Z").timestamp())
ETA = int(pd.Timestamp("2025-01-14T12:00:00Z").timestamp())

VESSELS = pd.DataFrame([{
    "mmsi": 224087350, "imo": 9412220, "name": "SA DRAGONERA", "callsign": "EAKQ", "flag": "ES",
    "service": "S", "ship_type": 60, "length_m": 186.0, "beam_m": 26.0, "draught_m": 6.6, "dwt_t": 7200,
    "service_speed_kn": 21.0, "to_bow": 150, "to_stern": 36, "to_port": 13, "to_starboard": 13,
    "ais_format": "nmea", "status_at_berth": 5, "vessel_class": "ro-pax",
}])


def record(**kw):
    base = {"mmsi": 224087350, "time_s": T0, "lat_deg": 41.123456, "lon_deg": 2.654321, "sog_kn": 19.8,
            "cog_deg": 123.4, "heading_deg": 121.0, "nav_status": 0, "msg_type": 1, "channel": "A",
            "fmt": "dma_csv", "vessel_index": 0, "voyage_id": "224087350_3", "destination": "PALMA",
            "eta_s": ETA, "draught_m": 6.4, "dirty_kind": "", "dirty_detail": "", "time_text": "",
            "sort_s": T0, "sort_sub": 0, "phase": "sea"}
    base.update(kw)
    if "sort_s" not in kw:
        base["sort_s"] = base["time_s"]
    return base


def test_dma_csv_line_is_exactly_the_dma_layout(tmp_path):
    recs = pd.DataFrame([
        record(),
        record(time_s=T0 + 60, nav_status=5, sog_kn=102.3, cog_deg=360.0, heading_deg=511.0),
        record(time_s=T0 + 120, mmsi=22408735, vessel_index=-1, dirty_kind="invalid_mmsi"),
        record(time_s=T0 + 180, dirty_kind="bad_timestamp", time_text="32/01/2025 10:00:00"),
        record(time_s=T0 + 240, dirty_kind="malformed_row"),
        record(time_s=T0 + 86400, sort_s=T0 + 86400),  # next UTC day: next file
    ])
    loc = write_dma_csv(recs, VESSELS, tmp_path)
    assert list(loc.file) == ["aisdk-2025-01-14.csv"] * 5 + ["aisdk-2025-01-15.csv"]
    assert list(loc.line) == [2, 3, 4, 5, 6, 2]
    lines = (tmp_path / "aisdk-2025-01-14.csv").read_text().splitlines()
    assert lines[0] == DMA_HEADER
    static = "9412220,EAKQ,SA DRAGONERA,Passenger,No additional information,26,186,GPS,6.4,PALMA,14/01/2025 12:00:00,AIS,150,36,13,13"
    assert lines[1] == ("14/01/2025 06:30:05,Class A,224087350,41.123456,2.654321,Under way using engine,,19.8,"
                        "123.4,121," + static)
    assert lines[2] == "14/01/2025 06:31:05,Class A,224087350,41.123456,2.654321,Moored,,102.3,360.0,511," + static
    assert lines[3] == ("14/01/2025 06:32:05,Class A,22408735,41.123456,2.654321,Under way using engine,,19.8,123.4,"
                        "121,Unknown,Unknown,,Undefined,,,,Undefined,,,,AIS,,,,")
    assert lines[4].startswith("32/01/2025 10:00:00,Class A,224087350,")
    assert lines[5] == "14/01/2025 06:34:05,Class A,224087350,41.123456,2.654321,Under way using engine"
    assert all(len(x.split(",")) == 26 for x in lines[:5])
    nxt = (tmp_path / "aisdk-2025-01-15.csv").read_text().splitlines()
    assert nxt[1].startswith("15/01/2025 06:30:05,")


def test_nmea_messages_decode_back_with_pyais(tmp_path):
    recs = pd.DataFrame([
        record(fmt="nmea"),
        record(fmt="nmea", msg_type=3, time_s=T0 + 61, lat_deg=-33.5, lon_deg=-70.25, channel="B", nav_status=5),
        record(fmt="nmea", msg_type=5, time_s=T0 + 90),
        record(fmt="nmea", time_s=T0 + 100, lat_deg=91.0, lon_deg=181.0, sog_kn=102.3, cog_deg=360.0,
               heading_deg=511.0, dirty_kind="sentinel_position"),
        record(fmt="nmea", time_s=T0 + 110, dirty_kind="bad_checksum"),
    ])
    loc = write_nmea(recs, VESSELS, tmp_path)
    assert list(loc.line) == [1, 2, 3, 5, 6]
    lines = (tmp_path / "nmea-2025-01-14.nmea").read_text().splitlines()
    assert len(lines) == 6

    def split(line):
        assert line[0] == "\\"
        tag, sentence = line[1:].split("\\", 1)
        body, cs = tag.split("*")
        assert nmea_checksum(body) == cs  # tag-block checksum
        return dict(p.split(":", 1) for p in body.split(",")), sentence

    tag, s = split(lines[0])
    assert tag == {"s": "stormlane", "c": str(T0)}
    assert s.startswith("!AIVDM,1,1,,A,")
    m = pyais.decode(s).asdict()
    assert (m["msg_type"], m["mmsi"], m["status"], m["second"]) == (1, 224087350, 0, T0 % 60)
    # positions carry 1/10000 minute, speed and course 0.1 (ITU-R M.1371-5 message 1)
    assert m["lat"] == pytest.approx(41.123456, abs=1 / 600000) and m["lon"] == pytest.approx(2.654321, abs=1 / 600000)
    assert (m["speed"], m["course"], m["heading"]) == (19.8, 123.4, 121)
    m = pyais.decode(split(lines[1])[1]).asdict()
    assert (m["msg_type"], m["status"], m["lat"], m["lon"]) == (3, 5, -33.5, -70.25)
    assert split(lines[1])[1].split(",")[4] == "B"
    t1, s1 = split(lines[2])
    t2, s2 = split(lines[3])
    assert t1["g"].startswith("1-2-") and t2["g"] == "2-2-" + t1["g"].split("-")[2] and t1["c"] == str(T0 + 90)
    assert "c" not in t2
    m = pyais.decode(s1, s2).asdict()
    assert (m["msg_type"], m["mmsi"], m["imo"], m["callsign"], m["shipname"]) == (5, 224087350, 9412220, "EAKQ",
                                                                                   "SA DRAGONERA")
    assert (m["to_bow"], m["to_stern"], m["to_port"], m["to_starboard"], m["draught"]) == (150, 36, 13, 13, 6.4)
    assert (m["month"], m["day"], m["hour"], m["minute"], m["destination"]) == (1, 14, 12, 0, "PALMA")
    m = pyais.decode(split(lines[4])[1]).asdict()
    assert (m["lat"], m["lon"], m["speed"], m["course"], m["heading"]) == (91.0, 181.0, 102.3, 360.0, 511)
    bad = split(lines[5])[1]
    body, cs = bad[1:].split("*")
    assert nmea_checksum(body) != cs[:2]


def test_batch_armoring_equals_pyais_encode_dict():
    """The vectorised armoring gives byte-identical sentences to pyais' own encoder."""
    import numpy as np
    from pyais.encode import encode_dict
    from pyais.messages import MessageType1, MessageType3

    from scenario.writers import armor_position_payloads

    rng = np.random.default_rng(5)
    datas, payloads, channels = [], [], []
    for i in range(300):
        mt = int(rng.choice([1, 3]))
        d = {"msg_type": mt, "mmsi": int(rng.integers(1, 999_999_999)), "status": int(rng.integers(0, 16)),
             "turn": -128, "speed": round(float(rng.uniform(0, 102.3)), 1), "accuracy": int(rng.integers(0, 2)),
             "lon": round(float(rng.uniform(-181, 181)), 6), "lat": round(float(rng.uniform(-91, 91)), 6),
             "course": round(float(rng.uniform(0, 360)), 1), "heading": int(rng.integers(0, 512)),
             "second": int(rng.integers(0, 61)), "maneuver": 0, "raim": 0, "radio": 0}
        if i == 0:
            d.update(lat=91.0, lon=181.0, speed=102.3, course=360.0, heading=511)
        cls = MessageType1 if mt == 1 else MessageType3
        payloads.append(cls.create(**d).to_bytes()[0])
        channels.append("A" if i % 2 else "B")
        datas.append(d)
    ours = armor_position_payloads(payloads, channels)
    for d, ch, sen in zip(datas, channels, ours):
        (ref,) = encode_dict({"type": d["msg_type"], **d}, talker_id="AI", sentence_type="VDM", radio_channel=ch)
        assert sen == ref


def test_vectorised_number_and_time_texts_equal_python_formatting():
    """The Arrow-built texts of the DMA writer (scenario.dma_text) are Python's own: f"{x:.6f}" and
    f"{x:.1f}" on quantised AIS values, unquantised values, exact rounding ties, negatives, -0.0,
    tiny negatives, NaN and huge values; int(); and the day-first times."""
    import numpy as np

    from scenario.dma_text import dma_time_text, fixed_text, int_text

    rng = np.random.default_rng(23)
    quantised = np.round(rng.uniform(-181, 181, 20000) * 600000.0) / 600000.0
    raw = rng.uniform(-200, 200, 20000)
    ties = np.array([0.5, 1.5, 2.5, 0.25, 0.125, 0.0000005, 0.05, 0.15, 0.35, 2.675, 1e-7, -2.5e-7, 0.45])
    edge = np.array([0.0, -0.0, -1e-9, -0.04, 102.3, 360.0, 511.0, 91.0, 181.0, -99.1234, np.nan, np.inf, -np.inf,
                     1e13, -1e13, 2.0 ** 40 / 1e6, 12.600000000000001, 6.35])
    for x in (quantised, raw, ties, edge, np.round(rng.uniform(0, 102.2, 5000), 1)):
        for d in (1, 6):
            assert fixed_text(x, d).to_pylist() == [f"{v:.{d}f}" for v in x.tolist()]
    h = np.array([0.0, 359.0, 511.0, 12.7, -0.5])
    assert int_text(h).to_pylist() == [str(int(v)) for v in h.tolist()]
    t = np.array([0, 86399, 86400, 1736899205, 1740787199], dtype=np.int64)
    assert dma_time_text(t).to_pylist() == [pd.Timestamp(int(v), unit="s").strftime("%d/%m/%Y %H:%M:%S")
                                            for v in t]
