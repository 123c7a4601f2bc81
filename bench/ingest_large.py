"""Large-file ingest benchmark (issue 23): memory and time of one file of N rows, in groups and whole.

``python bench/ingest_large.py --rows N`` generates the fleet scenario of about N rows
(``bench/scale.py``'s generator: daily gzip files in the DMA layout), joins its days into ONE
plain DMA CSV file (one header: a real DMA daily file holds about 20 M rows), and ingests it
into a new workspace twice, each in a fresh process, in alternating order over ``--repeat``
rounds so that both sides see the same machine load. With ``--format parquet`` the one file is
that CSV file written as Parquet (:func:`to_parquet`), split by rows instead of bytes; with
``--format nmea`` it is an NMEA file of N messages in DMA's framing (:func:`nmea_file`):

* ``groups``: the product's ingest (``pipelines.ingest.ingest_paths``) of a file above
  ``pipelines.ingest_groups.GROUP_MIN_BYTES`` (Parquet: ``PARQUET_GROUP_MIN_ROWS``; forced
  whatever the file's size): split into MMSI ranges of ``GROUP_BYTES`` (``PARQUET_GROUP_ROWS``),
  committed one after the other in the file's transaction;
* ``whole`` (the baseline): the same call with the file staged and committed whole (what the
  ingest does with files up to ``GROUP_MIN_BYTES``, and did with every file before the groups).

Printed per side (medians over the rounds): wall seconds, rows/s, the process's peak resident
memory (``getrusage``: mapped file pages included) and its peak anonymous memory (the
process's own, ``RssAnon`` sampled every 20 ms), the ratio of each to the baseline, and whether
the two workspaces hold the same tables (``bench.scale.table_digests``) and the same positions
dataset (file digests).
"""

from __future__ import annotations

if __name__ == "__main__":  # run as a file: import `bench` from the repository root
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import gzip
import hashlib
import shutil
import statistics
import tempfile
import time
from pathlib import Path

from bench._harness import Config, _child

TABLES = ("ais_positions", "ais_quarantine", "vessels", "ais_files", "ais_track_ends", "ais_parquet_parts")


def join_days(folder: Path, out: Path) -> int:
    """The scenario's daily gzip files as one plain CSV file (the first header only); its rows."""
    rows = 0
    with open(out, "wb") as dst:
        for k, day in enumerate(sorted((folder / "ais").glob("*.csv.gz"))):
            with gzip.open(day, "rb") as src:
                header = src.readline()
                if k == 0:
                    dst.write(header)
                for block in iter(lambda: src.read(1 << 24), b""):
                    rows += block.count(b"\n")
                    dst.write(block)
    return rows


def to_parquet(csv: Path, out: Path) -> None:
    """The joined DMA file as one Parquet file of typed columns under the canonical names (what
    a user converting DMA's CSV files would write): numbers as DOUBLE, the MMSI as BIGINT, the
    time as TIMESTAMP, the status and ship type as DMA's words; a value that does not type is
    missing (DuckDB's ``TRY_CAST``). Row groups of 122,880 rows, zstd."""
    import duckdb

    num = "TRY_CAST({} AS DOUBLE)"
    cols = {"time_utc": "try_strptime(\"# Timestamp\", '%d/%m/%Y %H:%M:%S')", "mmsi": "TRY_CAST(MMSI AS BIGINT)",
            "lat_deg": num.format("Latitude"), "lon_deg": num.format("Longitude"), "sog_kn": num.format("SOG"),
            "cog_deg": num.format("COG"), "heading_deg": num.format("Heading"),
            "nav_status": "\"Navigational status\"", "imo": "IMO", "name": "Name", "callsign": "Callsign",
            "ship_type": "\"Ship type\"", "length_m": num.format("Length"), "beam_m": num.format("Width"),
            "draught_m": num.format("Draught"), "destination": "Destination"}
    select = ", ".join(f"{v} AS {k}" for k, v in cols.items())
    con = duckdb.connect(config={"memory_limit": "2GB", "preserve_insertion_order": True})
    try:
        con.execute(f"COPY (SELECT {select} FROM read_csv($src, all_varchar = true, delim = ',', header = true, "
                    f"quote = '\"', strict_mode = false, ignore_errors = true)) TO $out "
                    "(FORMAT parquet, ROW_GROUP_SIZE 122880, COMPRESSION zstd)", {"src": str(csv), "out": str(out)})
    finally:
        con.close()


def nmea_file(out: Path, messages: int, block: int = 1_000_000) -> None:
    """An NMEA file of about ``messages`` messages in DMA's framing (a tag block, a ``$PGHP``
    time line, the sentence: ``bench._ingest_data.generate_nmea``), written in blocks of
    ``block`` messages (seeds 1, 2, ...; each block its own 1,500 vessels and 6 hours)."""
    from bench._ingest_data import generate_nmea

    with open(out, "wb") as dst:
        for k in range(-(-messages // block)):
            part = out.with_suffix(f".part{k}")
            generate_nmea(part, min(block, messages - k * block), seed=k + 1)
            dst.write(part.read_bytes())
            part.unlink()


def ingest_side(path: str, db: str, grouped: bool) -> dict:
    """One ingest in this (fresh) process, sampling its anonymous memory; ``grouped``: the file
    is split whatever its size (else committed whole)."""
    import threading

    import pipelines.ingest_groups as groups
    from pipelines.ingest import ingest_paths

    groups.GROUP_MIN_BYTES = 0 if grouped else 1 << 62
    groups.PARQUET_GROUP_MIN_ROWS = 0 if grouped else 1 << 62
    groups.NMEA_GROUP_MIN_BYTES = 0 if grouped else 1 << 62
    peak = {"anon_mb": 0.0}
    done = threading.Event()

    def sample():
        while not done.wait(0.02):
            for line in open("/proc/self/status"):
                if line.startswith("RssAnon"):
                    peak["anon_mb"] = max(peak["anon_mb"], int(line.split()[1]) * 1024 / 1e6)

    th = threading.Thread(target=sample, daemon=True)
    th.start()
    try:
        out = ingest_paths([path], db)
    finally:
        done.set()
        th.join()
    return {"work": int(out["read"]), "loaded": int(out["loaded"]), "staging": out["per_file"][0].get("staging"),
            "peak_anon_mb": peak["anon_mb"]}


def _dataset_digest(db: Path) -> str:
    root = db.parent / f"{db.stem}.parquet" / "positions"
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.parquet")):
        h.update(str(p.relative_to(root)).encode() + p.read_bytes())
    return h.hexdigest()


def run(rows: int, workdir: Path, vessels: int = 300, repeat: int = 3, fmt: str = "dma") -> dict:
    from bench.scale import ROWS_PER_SHIP_DAY, generate, table_digests

    workdir.mkdir(parents=True, exist_ok=True)
    if fmt == "nmea":
        one, gen = workdir / "one.nmea", {"work": rows}
        if not one.exists():
            nmea_file(one, rows)
    else:
        days = max(1.0, round(rows / (vessels * ROWS_PER_SHIP_DAY), 2))
        gen = generate(str(workdir / "scenario"), vessels, days, 23, 2)
        one = workdir / "one.csv"
        if not one.exists():
            join_days(workdir / "scenario", one)
    if fmt == "parquet":
        one, csv = workdir / "one.parquet", one
        if not one.exists():
            to_parquet(csv, one)
    size = one.stat().st_size
    cfg = Config(timeout_s=7200)
    tmp = Path(tempfile.mkdtemp(prefix="bench-large-"))
    results: dict = {"groups": [], "whole": []}
    digests = {}
    for k in range(repeat):
        for side in (("groups", "whole") if k % 2 == 0 else ("whole", "groups")):
            db = workdir / side / "w.duckdb"
            shutil.rmtree(db.parent, ignore_errors=True)
            db.parent.mkdir(parents=True)
            kwargs = {"path": str(one), "db": str(db), "grouped": side == "groups"}
            rec = _child(cfg, tmp, None, "bench.ingest_large:ingest_side", kwargs, 1, {}, call_with_kwargs=True)
            if rec.get("failed"):
                raise SystemExit(f"{side}: {rec['failed']}")
            r = rec["runs"][0]
            results[side].append({"wall_s": r["wall_s"], "peak_mb": rec["peak_mb"], **r["info"]})
            digests[side] = (table_digests(db, TABLES), _dataset_digest(db))
    shutil.rmtree(tmp, ignore_errors=True)
    summary = {"format": fmt, "rows": results["whole"][0]["work"], "file_mb": size / 1e6, "generated_rows": gen["work"],
               "same_tables": digests["groups"][0] == digests["whole"][0],
               "same_dataset": digests["groups"][1] == digests["whole"][1]}
    for side, runs in results.items():
        summary[side] = {key: statistics.median(r[key] for r in runs) for key in ("wall_s", "peak_mb", "peak_anon_mb")}
        summary[side]["staging"] = runs[0]["staging"]
    return summary


def print_summary(s: dict) -> None:
    kind = {"parquet": "Parquet", "nmea": "NMEA"}.get(s.get("format"), "plain DMA")
    print(f"one {kind} file: {s['rows']:,} rows, {s['file_mb']:,.0f} MB; medians of the rounds")
    print(f"{'side':<8}{'staging':<9}{'wall s':>9}{'rows/s':>11}{'peak MB':>9}{'anon MB':>9}"
          f"{'x wall':>8}{'x peak':>8}{'x anon':>8}")
    base = s["whole"]
    for side in ("whole", "groups"):
        r = s[side]
        print(f"{side:<8}{r['staging']:<9}{r['wall_s']:>9.1f}{s['rows'] / r['wall_s']:>11,.0f}{r['peak_mb']:>9,.0f}"
              f"{r['peak_anon_mb']:>9,.0f}{r['wall_s'] / base['wall_s']:>8.2f}{r['peak_mb'] / base['peak_mb']:>8.2f}"
              f"{r['peak_anon_mb'] / base['peak_anon_mb']:>8.2f}")
    print(f"same tables: {s['same_tables']}; same positions dataset: {s['same_dataset']}")


def main(argv=None) -> dict:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, required=True, help="AIS rows of the one file (about)")
    ap.add_argument("--vessels", type=int, default=300)
    ap.add_argument("--repeat", type=int, default=3, help="rounds of both sides (medians are printed)")
    ap.add_argument("--format", choices=("dma", "parquet", "nmea"), default="dma",
                    help="the one file: the joined DMA CSV, that file as Parquet (bench.ingest_large.to_parquet), "
                         "or NMEA messages (bench.ingest_large.nmea_file; --rows messages)")
    ap.add_argument("--workdir", type=Path, default=None, help="default: $TMPDIR/stormlane-large-ROWS")
    a = ap.parse_args(argv)
    workdir = a.workdir or Path(tempfile.gettempdir()) / f"stormlane-large-{a.rows}"
    t = time.perf_counter()
    s = run(a.rows, workdir, a.vessels, a.repeat, a.format)
    print_summary(s)
    print(f"({time.perf_counter() - t:.0f} s)")
    return s


if __name__ == "__main__":
    main()
