"""Real AIS files from ../shared/data/ais, read in place (skipped with a reason when absent)."""

from __future__ import annotations

import collections
import gzip

import numpy as np
import pandas as pd
import pytest

from conftest import shared_file
from ais.errors import AisFormatError
from ais.io.nmea import POSITION_TYPES, decode_positions_168, iter_lines, parse_fast, parse_lines, read_nmea
from pipelines.ingest import ingest_paths
from pipelines.storage import open_workspace
from pipelines.storage.ais import read_positions, read_quarantine, read_vessels

NMEA_DIR = "ais/nmea"
DMA_NMEA = "ais/nmea/dma_ais-sample_20131112.nmea.gz"
AISLIB_NMEA = "ais/nmea/dma_aislib_stream_example_20100611.nmea"
PYAIS_NMEA = "ais/nmea/pyais_nmea_data_sample.nmea"
NOAA_CSV = "ais/noaa_marinecadastre_20230111_sample.csv"
NY_PARQUET = "ais/portcalls/nyharbor_marinecadastre_20210101.parquet"
USHANT = "ais/ushant_ais_subset.parquet"


def _pyais_position_messages(path):
    """Independent count with a plain pyais loop: messages whose decoded type is a position."""
    from pyais.stream import BinaryIOStream

    fh = gzip.open(path, "rb") if str(path).endswith(".gz") else open(path, "rb")
    types = collections.Counter()
    decoded = []
    with fh:
        for msg in BinaryIOStream(fh):
            try:
                d = msg.decode()
            except Exception:  # noqa: BLE001 - empty payloads in the pyais sample
                types["failed"] += 1
                continue
            types[d.msg_type] += 1
            if d.msg_type in POSITION_TYPES:
                decoded.append(d)
            if d.msg_type in (5, 24) and not 201_000_000 <= int(d.mmsi) <= 775_999_999:
                types["static_bad_mmsi"] += 1  # joinable to no ship: quarantined as bad_mmsi
    return types, decoded


def _adds_up(s):
    assert s["read"] == s["loaded"] + s["quarantined"] + s["duplicates"]
    assert sum(s["reasons"].values()) == s["quarantined"] + s["duplicates"]


@pytest.mark.parametrize("rel", [DMA_NMEA, AISLIB_NMEA, PYAIS_NMEA])
def test_nmea_position_messages_match_pyais_and_every_sentence_is_accounted_for(shared_data, tmp_path, rel):
    path = shared_file(shared_data, rel)
    types, _ = _pyais_position_messages(path)
    n_pos_pyais = sum(n for t, n in types.items() if t in POSITION_TYPES)
    n_static_pyais = types[5] + types[24] - types["static_bad_mmsi"]
    stage, meta = read_nmea(path)
    assert meta["position_messages"] == n_pos_pyais
    assert meta["static"] == n_static_pyais

    s = ingest_paths([path], tmp_path / "ws.duckdb")
    _adds_up(s)
    assert s["static"] == n_static_pyais
    if rel == AISLIB_NMEA:  # 498 static messages, 3 of them from MMSIs outside the ship range
        assert (n_static_pyais, types["static_bad_mmsi"]) == (495, 3)
        from pyais import decode

        with open_workspace(tmp_path / "ws.duckdb") as ws:
            raws = [r[0] for r in ws.con.execute("SELECT raw FROM ais_quarantine WHERE reason = 'bad_mmsi'").fetchall()]
        static_raws = [r for r in raws if decode(*r.split("\n")).msg_type in (5, 24)]
        assert len(static_raws) == 3  # each kept with its raw sentences
    # Every AIS sentence of the file belongs to exactly one item (a message or a rejected
    # sentence/fragment group); items are loaded, static, quarantined or duplicates.
    opener = gzip.open if str(path).endswith(".gz") else open
    with opener(path, "rt", encoding="ascii", errors="replace") as fh:
        n_sentences = sum(1 for line in fh if "VDM," in line or "VDO," in line)
    assert int((stage["raw"].str.count("\n") + 1).sum()) == n_sentences
    assert (stage.kind == "P").sum() == s["read"] and (stage.kind == "S").sum() == s["static"]
    with open_workspace(tmp_path / "ws.duckdb") as ws:
        n_loaded = ws.con.execute("SELECT count(*) FROM ais_positions").fetchone()[0]
        n_quarantine = ws.con.execute("SELECT count(*) FROM ais_quarantine").fetchone()[0]
    assert n_loaded == s["loaded"] and n_quarantine == s["quarantined"] + s["duplicates"]


def test_dma_nmea_sample_counts(shared_data, tmp_path):
    path = shared_file(shared_data, DMA_NMEA)
    s = ingest_paths([path], tmp_path / "ws.duckdb")
    # PROVENANCE.md: 26,146 sentences -> 26,077 messages: 1 x20044, 3 x4151, 4 x1234, 18 x493,
    # 5 x69, 24 x61, 21 x25. Positions 1/3/18 = 24,688; static 5/24 = 130; 4 and 21 carry no ship
    # position (1,259 other_msg_type); 973 $PSTT/$PFEC status lines are not AIS.
    assert s["read"] == 24688 + 1259
    assert s["static"] == 130
    assert s["reasons"]["other_msg_type"] == 1259
    assert s["ignored"] == 973
    _adds_up(s)
    with open_workspace(tmp_path / "ws.duckdb") as ws:
        p = read_positions(ws)
        v = read_vessels(ws)
    # Times come from the $PGHP lines: 2013-11-12 12:00:00 to 12:04:59 UTC.
    assert p.time_utc.min() >= pd.Timestamp("2013-11-12T12:00:00Z")
    assert p.time_utc.max() < pd.Timestamp("2013-11-12T12:05:00Z")
    # Danish waters (PROVENANCE bbox lon 7.50..16.15, lat 54.09..58.00, printed to 0.01 deg).
    assert p.lon_deg.between(7.495, 16.155).all() and p.lat_deg.between(54.085, 58.005).all()
    assert len(v) > 0 and v["name"].notna().sum() > 50


def test_vectorised_decoder_equals_pyais(shared_data):
    import pyais

    for rel in (DMA_NMEA, AISLIB_NMEA, PYAIS_NMEA):
        path = shared_file(shared_data, rel)
        _, decoded = _pyais_position_messages(path)
        opener = gzip.open if rel.endswith(".gz") else open
        payloads = []
        with opener(path, "rt", encoding="ascii") as fh:
            for line in fh:
                line = line.strip()
                i = line.find("!")
                if i < 0:
                    continue
                f = line[i:].split(",")
                if len(f) >= 7 and f[1] == "1" and len(f[5]) == 28:
                    payloads.append(f[5])
        types = np.array([(ord(p[0]) - 48) - (8 if ord(p[0]) - 48 > 40 else 0) for p in payloads])
        keep = np.isin(types, [1, 2, 3, 18])
        payloads = [p for p, k in zip(payloads, keep) if k]
        types = types[keep]
        assert len(payloads) > 500
        ours = decode_positions_168(payloads, types)
        assert ours["ok"].all()
        for i, p in enumerate(payloads):
            ref = pyais.decode(f"!AIVDM,1,1,,A,{p},0*00".encode(), error_if_checksum_invalid=False)
            assert ours["mmsi"][i] == ref.mmsi
            assert ours["lat_deg"][i] == pytest.approx(ref.lat, abs=6e-7)
            assert ours["lon_deg"][i] == pytest.approx(ref.lon, abs=6e-7)
            assert ours["sog_kn"][i] == pytest.approx(ref.speed, abs=1e-9)
            assert ours["cog_deg"][i] == pytest.approx(ref.course, abs=1e-9)
            assert ours["heading_deg"][i] == ref.heading
            if types[i] != 18:
                assert ours["nav_status"][i] == int(ref.status)


def test_noaa_sample_sentinels_and_counts(shared_data, tmp_path):
    path = shared_file(shared_data, NOAA_CSV)
    raw = pd.read_csv(path)
    s = ingest_paths([path], tmp_path / "ws.duckdb")
    _adds_up(s)
    assert s["read"] == 1000
    # Two MMSIs are 7 and 8 digits long: the only rows rejected.
    assert s["reasons"] == {"bad_mmsi": 2}
    assert s["loaded"] == 998
    with open_workspace(tmp_path / "ws.duckdb") as ws:
        p = read_positions(ws)
        v = read_vessels(ws)
    good = raw[raw.MMSI.astype(str).str.len() == 9].set_index("MMSI")
    merged = p.set_index("mmsi").join(good, how="inner")
    assert len(merged) == 998
    # PROVENANCE.md: heading 511 in 426 rows, COG 360.0 in 90, SOG >= 102.2 in 4 (all 102.3);
    # one heading-511 row is also one of the two bad-MMSI rows.
    assert (raw.Heading == 511).sum() == 426 and (raw.COG == 360).sum() == 90 and (raw.SOG >= 102.2).sum() == 4
    assert (good.Heading == 511).sum() == 425
    assert merged.loc[merged.Heading == 511, "heading_deg"].isna().all()
    assert merged.loc[merged.Heading != 511, "heading_deg"].eq(merged.loc[merged.Heading != 511, "Heading"]).all()
    assert merged.heading_deg.isna().sum() == 425
    assert merged.loc[merged.COG == 360, "cog_deg"].isna().sum() == (good.COG == 360).sum() == 90
    assert merged.cog_deg.isna().sum() == 90
    assert merged.loc[merged.SOG >= 102.2, "sog_kn"].isna().sum() == 4 and merged.sog_kn.isna().sum() == 4
    # Status 0-15 kept as the code; static data joined, e.g. the row with IMO9307839.
    assert merged.nav_status.dropna().between(0, 15).all()
    msc = v.set_index("mmsi").loc[636021061]
    assert msc["imo"] == 9307839 and msc["name"] == "MSC NAISHA III" and msc["ship_type"] == 70
    assert msc["length_m"] == 208.0 and msc["beam_m"] == 30.0 and msc["draught_m"] == 8.0


#: NOAA's header until 2023 -> the snake_case names of its files from 2024 on
NOAA_2024_NAMES = {"MMSI": "mmsi", "BaseDateTime": "base_date_time", "LAT": "latitude", "LON": "longitude", "SOG": "sog",
                   "COG": "cog", "Heading": "heading", "VesselName": "vessel_name", "IMO": "imo", "CallSign": "call_sign",
                   "VesselType": "vessel_type", "Status": "status", "Length": "length", "Width": "width", "Draft": "draft",
                   "Cargo": "cargo", "TransceiverClass": "transceiver"}


@pytest.mark.parametrize("fast", [False, True], ids=["lines", "scan"])
def test_noaa_sample_under_the_2024_header_loads_the_same_rows(shared_data, tmp_path, monkeypatch, fast):
    """The sample with NOAA's 2024 column names (and its times with a space): format detected as
    NOAA, the same positions, quarantine and vessels as under the old header."""
    from pipelines import ingest_stage

    if fast:
        monkeypatch.setattr(ingest_stage, "FAST_CSV_MIN_BYTES", 0)
    path = shared_file(shared_data, NOAA_CSV)
    head, body = path.read_text().split("\n", 1)
    renamed = tmp_path / "ais-2023-01-11.csv"  # the 2024 files also write the time with a space
    renamed.write_text(",".join(NOAA_2024_NAMES[h] for h in head.split(",")) + "\n" + body.replace("2023-01-11T", "2023-01-11 "))
    tables = []
    for src in (path, renamed):
        db = tmp_path / f"{src.stem}.duckdb"
        s = ingest_paths([src], db)
        assert s["per_file"][0]["format"] == "noaa" and s["read"] == 1000 and s["reasons"] == {"bad_mmsi": 2}
        with open_workspace(db) as ws:
            q = read_quarantine(ws)[["line", "reason", "mmsi"]]
            tables.append((read_positions(ws), q, read_vessels(ws)))
    for a, b in zip(*tables):
        pd.testing.assert_frame_equal(a, b, check_exact=True)


def test_ny_harbour_parquet(shared_data, tmp_path):
    path = shared_file(shared_data, NY_PARQUET)
    s = ingest_paths([path], tmp_path / "ws.duckdb")
    _adds_up(s)
    # PROVENANCE.md: 82,334 fixes of 172 MMSI, no duplicate (mmsi, time), one step > 50 kn.
    assert s["read"] == 82334
    with open_workspace(tmp_path / "ws.duckdb") as ws:
        p = read_positions(ws)
        v = read_vessels(ws)
    assert p.mmsi.nunique() == 172
    assert s["duplicates"] == 0
    src = pd.read_parquet(path)
    assert (src.sog_kn == 102.3).sum() == 6 and (src.cog_deg == 360.0).sum() == 7606
    loaded = p.set_index(["mmsi", "time_utc"])
    key = src.assign(time_utc=pd.to_datetime(src.time, utc=True)).set_index(["mmsi", "time_utc"])
    j = key.join(loaded, how="inner", rsuffix="_db")
    assert j.loc[j.sog_kn == 102.3, "sog_kn_db"].isna().all()
    assert j.loc[j.cog_deg == 360.0, "cog_deg_db"].isna().all()
    assert (j.lat_deg == j.lat).all() and (j.lon_deg == j.lon).all()
    # Static columns are mapped: vessel_name -> name, vessel_type -> ship_type, width 0 -> NULL.
    ferry = v[v["name"].fillna("").str.contains("SAMUEL I NEWHOUSE")]
    assert len(ferry) == 1 and ferry.iloc[0]["ship_type"] == 60
    assert (v["beam_m"].dropna() > 0).all()


def test_ushant_trajectories_are_refused_with_a_pointer(shared_data, tmp_path):
    path = shared_file(shared_data, USHANT)
    with pytest.raises(AisFormatError, match="Ushant trajectory set"):
        ingest_paths([path], tmp_path / "ws.duckdb")


def test_whole_nmea_directory(shared_data, tmp_path):
    d = shared_file(shared_data, NMEA_DIR)
    s = ingest_paths([d], tmp_path / "ws.duckdb")
    assert s["files"] == 3
    _adds_up(s)
    for f in s["per_file"]:
        _adds_up(f)


@pytest.mark.parametrize("rel", [DMA_NMEA, AISLIB_NMEA, PYAIS_NMEA])
def test_fast_nmea_parser_equals_the_reference_loop(shared_data, rel):
    lines = iter_lines(shared_file(shared_data, rel))
    ref, meta_ref = parse_lines(lines)
    fast, meta_fast = parse_fast(lines)
    assert fast.equals(ref)
    assert meta_fast == meta_ref
