"""The demo scenario generator, its AIS writers and `stormlane scenario`.

The files are re-read here with the standard library ``csv`` module and pyais' decoder, and the
expected facts (dirty rows, cadence, positions at sea) are recomputed independently of the
generator's own bookkeeping.
"""

from __future__ import annotations

import csv
import filecmp
import gzip
import json
from collections import Counter
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from thresholds import land_raster as globe  # the package's 30" mask through its cache
from pyproj import Geod

from pipelines.scenario import build_scenario

GEOD = Geod(ellps="WGS84")
NMI = 1852.0
DAYS = 2.0
SEED = 7
DMA_FIELDS = 26


@pytest.fixture(scope="module")
def scen(tmp_path_factory):
    """A two-day scenario written once for the module."""
    out = tmp_path_factory.mktemp("scenario")
    truth = build_scenario(out, seed=SEED, days=DAYS)
    return out, truth


def _dma_rows(path: Path):
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt", newline="") as fh:
        lines = fh.read().splitlines()
    return lines


def _parse_dma_time(text: str):
    try:
        return datetime.strptime(text, "%d/%m/%Y %H:%M:%S").replace(tzinfo=timezone.utc)
    except ValueError:
        return None


def _valid_mmsi(text: str) -> bool:
    return text.isdigit() and len(text) == 9 and 201 <= int(text[:3]) <= 775


def _nmea_checksum_ok(sentence: str) -> bool:
    body, _, cs = sentence[1:].partition("*")
    x = 0
    for ch in body.encode():
        x ^= ch
    return f"{x:02X}" == cs[:2].upper()


def _read_dma(out: Path, truth: dict) -> pd.DataFrame:
    """Every data line of every DMA CSV file, classified by independent rules."""
    rows = []
    for f in truth["ais"]["files"]:
        if f["format"] != "dma_csv":
            continue
        lines = _dma_rows(out / f["file"])
        assert lines[0].startswith("# Timestamp,Type of mobile,MMSI,Latitude,Longitude,Navigational status")
        for lineno, (text, fields) in enumerate(zip(lines[1:], csv.reader(lines[1:])), start=2):
            r = {"file": f["file"], "line": lineno, "text": text, "n_fields": len(fields)}
            if len(fields) == DMA_FIELDS:
                r.update(ts=fields[0], mmsi=fields[2], lat=float(fields[3]), lon=float(fields[4]),
                         sog=float(fields[7]), cog=float(fields[8]), hdg=float(fields[9]))
            rows.append(r)
    return pd.DataFrame(rows)


def _read_nmea(out: Path, truth: dict) -> pd.DataFrame:
    """Every NMEA message (single sentences and two-part groups), decoded by pyais."""
    import pyais

    rows = []
    for f in truth["ais"]["files"]:
        if f["format"] != "nmea":
            continue
        lines = _dma_rows(out / f["file"])
        i = 0
        while i < len(lines):
            line = lines[i]
            assert line.startswith("\\"), line
            tag, sentence = line[1:].split("\\", 1)
            params = dict(p.split(":", 1) for p in tag.split("*")[0].split(","))
            r = {"file": f["file"], "line": i + 1, "text": line, "checksum_ok": _nmea_checksum_ok(sentence),
                 "t": int(params["c"]) if "c" in params else None}
            parts = [sentence]
            if "g" in params:
                k, n, _ = params["g"].split("-")
                assert k == "1"
                for j in range(1, int(n)):
                    nxt = lines[i + j]
                    ntag, nsen = nxt[1:].split("\\", 1)
                    assert ntag.startswith(f"g:{j + 1}-{n}-"), nxt
                    parts.append(nsen)
                i += int(n)
            else:
                i += 1
            if r["checksum_ok"]:
                msg = pyais.decode(*parts).asdict()
                r.update(msg_type=msg["msg_type"], mmsi=msg["mmsi"])
                if msg["msg_type"] in (1, 2, 3):
                    r.update(lat=msg["lat"], lon=msg["lon"], sog=msg["speed"], cog=msg["course"],
                             hdg=float(msg["heading"]), second=msg["second"])
                else:
                    r.update(name=msg["shipname"], destination=msg["destination"], imo=msg["imo"])
            rows.append(r)
    return pd.DataFrame(rows)


def _jumps(df: pd.DataFrame) -> pd.Series:
    """Rows whose implied speed to both neighbours of the same MMSI exceeds 60 kn."""
    flag = pd.Series(False, index=df.index)
    for _, g in df.sort_values(["mmsi", "t"]).groupby("mmsi"):
        if len(g) < 2:
            continue
        lat, lon, t = g.lat.to_numpy(), g.lon.to_numpy(), g.t.to_numpy(dtype=float)
        d = GEOD.inv(lon[:-1], lat[:-1], lon[1:], lat[1:])[2] / NMI
        kn = d / np.maximum(np.diff(t), 1) * 3600
        prev = np.r_[0, kn]
        nxt = np.r_[kn, 0]
        both = (prev > 60) & (nxt > 60)
        edge = np.zeros(len(g), bool)  # a jump at the end of a ship's track has one neighbour
        edge[-1] = prev[-1] > 60 and (len(g) < 3 or kn[-2] < 60)
        flag.loc[g.index] = both | edge
    return flag


def test_dma_csv_dirty_rows_match_scenario_json(scen):
    out, truth = scen
    df = _read_dma(out, truth)
    counts = truth["dirty_rows"]["by_format"]["dma_csv"]
    ok = df.n_fields == DMA_FIELDS
    assert (~ok).sum() == counts["malformed_row"] > 0
    df = df[ok].copy()
    df["time"] = [_parse_dma_time(t) for t in df.ts]
    bad_time = df.time.isna()
    assert bad_time.sum() == counts["bad_timestamp"] > 0
    bad_mmsi = ~df.mmsi.map(_valid_mmsi)
    assert bad_mmsi.sum() == counts["invalid_mmsi"] > 0
    sentinel = (df.lat == 91) & (df.lon == 181)
    assert sentinel.sum() == counts["sentinel_position"] > 0
    out_of_range = ~sentinel & ((df.lat.abs() > 90) | (df.lon.abs() > 180))
    assert out_of_range.sum() == counts["out_of_range"] > 0
    sentinel_fields = (df.sog == 102.3) | (df.cog == 360.0) | (df.hdg == 511)
    assert sentinel_fields.sum() == counts["sentinel_fields"] > 0
    good = df[~(bad_time | bad_mmsi | sentinel | out_of_range)].copy()
    exact = good.duplicated("text", keep="first")
    assert exact.sum() == counts["duplicate_exact"] > 0
    good = good[~exact]
    same_key = good.duplicated(["mmsi", "time"], keep="first")
    assert same_key.sum() == counts["duplicate_timestamp"] > 0
    good = good[~same_key].copy()
    good["mmsi"] = good.mmsi.astype(int)
    good["t"] = [x.timestamp() for x in good.time]
    assert _jumps(good).sum() == counts["speed_jump"] > 0
    # no other dirty kinds in the CSV files
    assert counts["bad_checksum"] == 0


def test_nmea_dirty_rows_match_scenario_json(scen):
    out, truth = scen
    df = _read_nmea(out, truth)
    counts = truth["dirty_rows"]["by_format"]["nmea"]
    assert (~df.checksum_ok).sum() == counts["bad_checksum"] > 0
    df = df[df.checksum_ok]
    assert df.t.notna().all()
    pos = df[df.msg_type.isin([1, 3])].copy()
    assert (pos.msg_type == 3).sum() > 0 and (pos.msg_type == 1).sum() > 0
    static = df[df.msg_type == 5]
    assert len(static) > 0 and set(static.mmsi) <= {v["mmsi"] for v in truth["vessels"]}
    assert len(pos) + len(static) + counts["bad_checksum"] == sum(
        f["records"] for f in truth["ais"]["files"] if f["format"] == "nmea")
    assert (pos.t % 60 == pos.second).all()  # the message's UTC second agrees with the tag block
    pos["mmsi"] = pos.mmsi.astype(np.int64)
    bad_mmsi = ~pos.mmsi.astype(str).map(_valid_mmsi)
    assert bad_mmsi.sum() == counts["invalid_mmsi"] > 0
    sentinel = (pos.lat == 91) & (pos.lon == 181)
    assert sentinel.sum() == counts["sentinel_position"] > 0
    out_of_range = ~sentinel & ((pos.lat.abs() > 90) | (pos.lon.abs() > 180))
    assert out_of_range.sum() == counts["out_of_range"] > 0
    assert ((pos.sog == 102.3) | (pos.cog == 360.0) | (pos.hdg == 511)).sum() == counts["sentinel_fields"] > 0
    good = pos[~(bad_mmsi | sentinel | out_of_range)]
    exact = good.duplicated("text", keep="first")
    assert exact.sum() == counts["duplicate_exact"] > 0
    good = good[~exact]
    same_key = good.duplicated(["mmsi", "t"], keep="first")
    assert same_key.sum() == counts["duplicate_timestamp"] > 0
    assert _jumps(good[~same_key].copy()).sum() == counts["speed_jump"] > 0
    assert counts["bad_timestamp"] == counts["malformed_row"] == 0


def test_listed_dirty_rows_point_at_their_lines(scen):
    out, truth = scen
    rows = truth["dirty_rows"]["rows"]
    assert Counter(r["kind"] for r in rows) == {k: n for k, n in truth["dirty_rows"]["counts"].items() if n}
    cache = {}
    for r in rows:
        lines = cache.setdefault(r["file"], _dma_rows(out / r["file"]))
        text = lines[r["line"] - 1]
        if r["format"] == "dma_csv":
            if r["kind"] == "malformed_row":
                assert len(text.split(",")) < DMA_FIELDS
            elif r["kind"] == "sentinel_position":
                assert ",91.000000,181.000000," in text
            elif r["kind"] == "duplicate_exact":
                assert lines[r["line"] - 2] == text
            elif r["kind"] == "invalid_mmsi":
                assert not _valid_mmsi(text.split(",")[2])
            elif r["kind"] == "bad_timestamp":
                assert _parse_dma_time(text.split(",")[0]) is None
        else:
            if r["kind"] == "bad_checksum":
                assert not _nmea_checksum_ok(text.split("\\")[2])
            else:
                assert _nmea_checksum_ok(text.split("\\")[2])
            if r["kind"] == "duplicate_exact":
                assert lines[r["line"] - 2] == text


def test_expected_ingest_counts_add_up(scen):
    out, truth = scen
    exp = truth["expected_ingest"]
    rejected = sum(n for k, n in truth["dirty_rows"]["counts"].items() if k != "sentinel_fields")
    assert exp["rejected"] == rejected
    assert exp["loaded"] + exp["rejected"] == exp["position_records"]
    assert exp["position_records"] == sum(f["position_records"] for f in truth["ais"]["files"])
    # the dirty share stays small (a realistic feed, not a fuzzing corpus)
    assert 0.002 < exp["rejected"] / exp["position_records"] < 0.02


def test_same_seed_same_files_other_seed_other_files(scen, tmp_path):
    out, truth = scen
    again = tmp_path / "again"
    build_scenario(again, seed=SEED, days=DAYS)
    names = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file())
    assert names == sorted(p.relative_to(again).as_posix() for p in again.rglob("*") if p.is_file())
    _, mismatch, errors = filecmp.cmpfiles(out, again, names, shallow=False)
    assert mismatch == [] and errors == []
    other = tmp_path / "other"
    build_scenario(other, seed=SEED + 1, days=DAYS)
    assert (other / "scenario.json").read_bytes() != (out / "scenario.json").read_bytes()
    first_csv = [f["file"] for f in truth["ais"]["files"] if f["format"] == "dma_csv"][0]
    assert (other / first_csv).read_bytes() != (out / first_csv).read_bytes()


def test_gzip_output_holds_the_same_text(scen, tmp_path):
    out, truth = scen
    gz = tmp_path / "gz"
    truth_gz = build_scenario(gz, seed=SEED, days=DAYS, gzip=True)
    for f_plain, f_gz in zip(truth["ais"]["files"], truth_gz["ais"]["files"]):
        assert f_gz["file"] == f_plain["file"] + ".gz"
        assert gzip.decompress((gz / f_gz["file"]).read_bytes()) == (out / f_plain["file"]).read_bytes()


def test_tracks_follow_the_routes_at_sea_with_realistic_cadence(scen):
    out, truth = scen
    df = _read_dma(out, truth)
    df = df[df.n_fields == DMA_FIELDS]
    dirty = {(r["file"], r["line"]) for r in truth["dirty_rows"]["rows"] if r["kind"] != "sentinel_fields"}
    df = df[[(f, ln) not in dirty for f, ln in zip(df.file, df.line)]].copy()
    df["mmsi"] = df.mmsi.astype(int)
    df["t"] = [_parse_dma_time(t).timestamp() for t in df.ts]
    assert len(df) == sum(f["clean_positions"] for f in truth["ais"]["files"] if f["format"] == "dma_csv")
    routes = {r["route_id"]: np.array(r["waypoints"]) for r in truth["routes"]}
    ports = {p["locode"]: p for p in truth["ports"]}
    intervals_sea, intervals_berth = [], []
    checked = 0
    for v in truth["voyages"]:
        if not v["complete"]:
            continue
        t0 = datetime.fromisoformat(v["sea_start_utc"].replace("Z", "+00:00")).timestamp()
        t1 = datetime.fromisoformat(v["sea_end_utc"].replace("Z", "+00:00")).timestamp()
        g = df[(df.mmsi == v["mmsi"]) & (df.t > t0) & (df.t < t1)]
        if g.empty:
            continue  # an NMEA ship
        checked += 1
        assert not globe.is_land(g.lat.to_numpy(), g.lon.to_numpy()).any(), v["voyage_id"]
        # distance of each fix to the route, sampled every 0.25 nmi along the geodesic
        wp = routes[v["route_id"]]
        lats, lons = [wp[0, 0]], [wp[0, 1]]
        for a, b in zip(wp[:-1], wp[1:]):
            n = int(GEOD.inv(a[1], a[0], b[1], b[0])[2] / NMI / 0.25)
            pts = GEOD.npts(a[1], a[0], b[1], b[0], n)
            lons += [p[0] for p in pts] + [b[1]]
            lats += [p[1] for p in pts] + [b[0]]
        lats, lons = np.array(lats), np.array(lons)
        far = 0
        for la, lo in zip(g.lat.to_numpy()[::10], g.lon.to_numpy()[::10]):
            d = GEOD.inv(np.full(len(lats), lo), np.full(len(lats), la), lons, lats)[2].min() / NMI
            far = max(far, d)
        assert far < 3.5, (v["voyage_id"], far)  # lateral offset <= 2 nmi + waypoint jitter
        dt = np.diff(g.t.to_numpy())
        intervals_sea += list(dt[dt < 300])
        # mean sea speed from the fixes is the voyage speed (within the slow fluctuation)
        sog = g.sog[g.sog < 100].median()
        assert sog == pytest.approx(v["speed_kn"], rel=0.06)
        orig = ports[v["origin"]]
        assert v["route_id"] in (f"{v['origin']}-{v['dest']}", f"{v['dest']}-{v['origin']}")
        assert orig["locode"] == v["origin"]
    assert checked >= 15
    for s in truth["port_stays"]:
        a = datetime.fromisoformat(s["arrive_utc"].replace("Z", "+00:00")).timestamp()
        b = datetime.fromisoformat(s["depart_utc"].replace("Z", "+00:00")).timestamp()
        g = df[(df.mmsi == s["mmsi"]) & (df.t > a + 60) & (df.t < b - 60)]
        if len(g) > 3:
            intervals_berth += list(np.diff(g.t.to_numpy()))
            assert (g.sog[g.sog < 100] < 0.5).all()
            assert (g["text"].str.contains("Moored") | g["text"].str.contains("Under way")).all()
    # 60 s +- 4 s under way, 180 s +- 12 s alongside (module docstring of scenario.generator)
    assert np.median(intervals_sea) == pytest.approx(60, abs=2)
    assert np.percentile(intervals_sea, 1) >= 56 - 1 and np.percentile(intervals_sea, 99) <= 64 + 1
    assert np.median(intervals_berth) == pytest.approx(180, abs=4)


def test_voyage_truth_is_consistent(scen):
    _, truth = scen
    by_ship = {}
    for v in truth["voyages"]:
        assert v["depart_utc"] < v["sea_start_utc"] < v["sea_end_utc"] < v["arrive_utc"]
        assert v["sea_dist_nmi"] < v["dist_nmi"] < v["sea_dist_nmi"] + 12
        by_ship.setdefault(v["mmsi"], []).append(v)
    services = {s["id"]: s for s in truth["services"]}
    for mmsi, vs in by_ship.items():
        for a, b in zip(vs[:-1], vs[1:]):
            assert a["dest"] == b["origin"] and a["arrive_utc"] < b["depart_utc"]
        rot = services[vs[0]["service"]]["rotation"]
        for v in vs:
            assert rot.index(v["dest"]) == (rot.index(v["origin"]) + 1) % len(rot)
    # ro-pax keep their timetable: departures within 0.4 h after a listed hour
    for v in truth["voyages"]:
        hours = services[v["service"]]["departure_hours_utc"]
        if hours:
            t = datetime.fromisoformat(v["depart_utc"].replace("Z", "+00:00"))
            assert any(0 <= (t.hour + t.minute / 60 + t.second / 3600) - h <= 0.4 for h in hours), v


def test_cli_scenario_json(tmp_path):
    from typer.testing import CliRunner

    from pipelines.cli import app

    res = CliRunner().invoke(app, ["scenario", "--out", str(tmp_path / "s"), "--days", "0.5", "--seed", "3", "--json"])
    assert res.exit_code == 0, res.output
    obj = json.loads(res.stdout)
    assert obj["vessels"] == 20 and obj["end_utc"] == "2025-01-01T12:00:00Z"
    assert obj["expected_ingest"]["loaded"] > 5000
    assert (tmp_path / "s" / "scenario.json").is_file()


def test_cli_scenario_rejects_a_bad_start(tmp_path):
    from pipelines.cli import main

    with pytest.raises(SystemExit) as ex:
        main(["scenario", "--out", str(tmp_path / "s"), "--start", "yesterday-ish"])
    assert ex.value.code == 2


def _small_spec(anchorage_prob=0.0):
    from scenario.generator import parse_scenario_spec

    ports = pd.DataFrame({"locode": ["ESBCN", "ESPMI"], "name": ["Barcelona", "Palma de Mallorca"],
                          "lat_deg": [41.352, 39.56], "lon_deg": [2.17, 2.63],
                          "approach_lat_deg": [41.31, 39.52], "approach_lon_deg": [2.22, 2.62]})
    doc = {
        "routes": {"ESBCN-ESPMI": {"waypoints": [[41.31, 2.22], [39.62, 2.20], [39.44, 2.36], [39.40, 2.53],
                                                 [39.52, 2.62]]}},
        "services": [{"id": "T", "vessel_class": "tanker", "rotation": ["ESBCN", "ESPMI"], "stay_h": [2, 3],
                      "anchorage_wait_prob": anchorage_prob, "anchorage_wait_h": [4, 5]}],
        "vessels": [{"mmsi": 224776000, "imo": 9245782, "name": "MONTSENY", "callsign": "EAMT", "flag": "ES",
                     "service": "T", "ship_type": 80, "length_m": 150, "beam_m": 24, "draught_m": 9.2,
                     "dwt_t": 17900, "service_speed_kn": 13, "to_bow": 124, "to_stern": 26, "to_port": 12,
                     "to_starboard": 12}],
    }
    return parse_scenario_spec(doc, ports)


def test_generator_period_rates_and_anchorage_waits():
    from scenario.generator import DIRTY_KINDS, ScenarioConfigError, ScenarioSettings, generate_scenario

    st = ScenarioSettings(seed=1, start_utc="2025-03-01T00:00Z", days=3,
                          dirty_rates={k: 0.0 for k in DIRTY_KINDS}, gap_prob_per_voyage=0.0,
                          outage_prob_per_vessel=0.0)
    sc = generate_scenario(_small_spec(anchorage_prob=1.0), st)
    t = pd.to_datetime(sc.records.time_s, unit="s", utc=True)
    assert t.min() >= pd.Timestamp("2025-03-01T00:00Z") and t.max() < pd.Timestamp("2025-03-04T00:00Z")
    assert (sc.records.dirty_kind == "").all() and sc.fixes.received.all()
    # every voyage waited 4-5 h at an anchorage 1.5 nmi from the destination's approach point
    waited = sc.voyages[sc.voyages.anchorage_wait_h > 0]
    assert len(waited) >= 2 and waited.anchorage_wait_h.between(4, 5).all()
    anchor = sc.fixes[sc.fixes.phase == "anchor"]
    assert (anchor.nav_status == 1).all() and (anchor.sog_kn < 1.0).all()
    appr = {"ESBCN": (41.31, 2.22), "ESPMI": (39.52, 2.62)}
    for v in waited.itertuples():
        la, lo = appr[v.dest]
        d = GEOD.inv(lo, la, v.anchorage_lon_deg, v.anchorage_lat_deg)[2] / NMI
        assert d == pytest.approx(1.5, abs=0.01)
        a = anchor[anchor.voyage_id == v.voyage_id]
        if len(a):
            assert not globe.is_land(a.lat_deg.to_numpy(), a.lon_deg.to_numpy()).any()
    with pytest.raises(ScenarioConfigError, match="days must be positive"):
        ScenarioSettings(days=0)
    with pytest.raises(ScenarioConfigError, match="unknown dirty kind"):
        ScenarioSettings(dirty_rates={"cosmic_ray": 0.1})
