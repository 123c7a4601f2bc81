"""A large NMEA file decoded chunk by chunk and split into groups of whole vessels.

The NMEA reader (:func:`ais.io.nmea.read_nmea`) holds the whole file's lines and its decoded
stage: about 17 bytes of memory per byte of NMEA (measured, issue 23: 2.3 GB for a 111 MB file
of 1 M messages, 6.1 GB for 333 MB). Here the file is read in chunks of lines
(:func:`iter_line_chunks`, the same lines as :func:`ais.io.nmea.iter_lines`) and each chunk is
decoded by :func:`ais.io.nmea.parse_fast` with what crosses a chunk's end carried to the next
(:class:`ais.io.nmea.Carry`: the open multipart groups, the time context, the line numbers),
so every message is the one the whole file gives. The one rule over the whole file, a payload
heard twice within 60 s (``duplicate_payload``), compares payloads of one vessel only (the MMSI
is part of the payload): it is applied per group (:func:`mark_duplicates`), where the vessel's
rows all are.

The decoded chunks are spilled to Arrow IPC files, then dealt into MMSI ranges of about equal
rows (:func:`ais.io.csv_buckets.mmsi_bounds`): each group an Arrow IPC file of its stage rows in
line order, beside the input's line numbers of its rows (a group's stage is renumbered 1..n, and
``pipelines.ingest_groups`` maps the lines back, as for CSV groups). Rows without an MMSI (bad
sentences, payloads that do not decode) go to the first group. Memory: one chunk's lines and
stage, then one chunk's spill.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np
import pandas as pd

from ais.io.csv_buckets import Group, _add_counts, by_group, mmsi_bounds
from ais.io.ipc import read_ipc, write_ipc

#: Bytes of NMEA text decoded at a time (about 0.3 M messages of DMA's framing).
CHUNK_BYTES = 32 << 20


@dataclass(frozen=True)
class NmeaGroup(Group):
    """A group of an NMEA file: its stage rows (Arrow IPC), and the lines of the file that carry
    no AIS item (blank lines, other sentences), counted on the first group."""

    ignored: int = 0


def iter_line_chunks(path, chunk_bytes: int = CHUNK_BYTES) -> Iterator[tuple[list[str], bool]]:
    """The lines of the plain file ``path`` as :func:`ais.io.nmea.iter_lines` gives them, in
    chunks of about ``chunk_bytes`` ending at a newline; (lines, whether the chunk is the last)."""
    with open(path, "rb") as fh:
        tail = b""
        block = fh.read(chunk_bytes)
        while True:
            nxt = fh.read(chunk_bytes) if block else b""
            data = tail + block
            if nxt:
                cut = data.rfind(b"\n") + 1
                data, tail = data[:cut], data[cut:]
            lines = data.decode("ascii", errors="replace").split("\n")
            if lines and lines[-1] == "":
                lines.pop()
            if lines or not nxt:
                yield lines, not nxt
            if not nxt:
                return
            block = nxt


def decode_chunks(path, chunk_bytes: int = CHUNK_BYTES) -> Iterator[tuple[pd.DataFrame, dict]]:
    """Each chunk's stage (with ``dup_payload``, duplicates not yet marked) and counts."""
    from ais.io.nmea import Carry, orphan_statics, parse_fast

    carry = Carry()
    for lines, last in iter_line_chunks(path, chunk_bytes):
        carry.last = last
        yield orphan_statics(*parse_fast(lines, carry))


def mark_duplicates(stage: pd.DataFrame) -> pd.DataFrame:
    """A group's stage (every row of its vessels, in line order) with the duplicate payloads
    marked as the whole file's parse marks them: ``duplicate_payload``, nothing decoded (the
    parse skips decoding them), ``dup_payload`` dropped."""
    from ais.clean import DUPLICATE_PAYLOAD, KIND_POSITION
    from ais.io.nmea import duplicate_mask

    payload = stage.pop("dup_payload").to_numpy()
    cand = np.flatnonzero(pd.notna(payload))
    if len(cand):
        t = stage["time_utc"].to_numpy(dtype="datetime64[ns]")[cand]  # UTC, as the parse holds it
        dup = cand[duplicate_mask(list(payload[cand]), t)]
        if len(dup):
            at = stage.index[dup]
            stage.loc[at, "parse_error"] = DUPLICATE_PAYLOAD
            stage.loc[at, "kind"] = KIND_POSITION
            stage.loc[at, "mmsi"] = pd.NA
            for c in stage.columns:
                if c not in ("line", "raw", "kind", "parse_error", "mmsi", "time_utc"):
                    stage.loc[at, c] = np.nan if stage[c].dtype.kind == "f" else None
    return stage


def split_nmea(path, group_rows: int, folder, chunk_bytes: int = CHUNK_BYTES) -> list[NmeaGroup]:
    """Decode the plain NMEA file ``path`` in chunks and deal its stage rows into groups of whole
    vessels of about ``group_rows`` rows in ``folder`` (module docstring), in MMSI order."""
    folder = Path(folder)
    spills, ignored, no_key = [], 0, 0
    mmsi, rows = np.empty(0, np.int64), np.empty(0, np.int64)
    for k, (stage, meta) in enumerate(decode_chunks(path, chunk_bytes)):
        ignored += int(meta["ignored"])
        ok = stage["mmsi"].notna().to_numpy()
        mmsi, rows = _add_counts(mmsi, rows, stage["mmsi"].to_numpy()[ok].astype(np.int64))
        no_key += int((~ok).sum())
        spills.append(folder / f"chunk-{k:05d}.arrow")
        write_ipc(_arrow(stage), spills[-1])
        del stage
    total = int(rows.sum()) + no_key
    bounds = mmsi_bounds(mmsi, rows, max(1, -(-total // max(1, int(group_rows)))), no_key)
    return _deal(spills, bounds, folder, ignored)


def _deal(spills: list[Path], bounds: np.ndarray, folder: Path, ignored: int) -> list[NmeaGroup]:
    """The spilled chunks' rows into the groups of ``bounds``; each spill removed once dealt."""
    import pyarrow as pa
    import pyarrow.compute as pc

    n = len(bounds) + 1
    names = [folder / f"group-{g:04d}.arrow" for g in range(n)]
    line_files = [folder / f"group-{g:04d}.lines.i64" for g in range(n)]
    counts = np.zeros(n, dtype=np.int64)
    sinks, writers = [None] * n, [None] * n
    louts = [open(p, "wb") for p in line_files]
    try:
        for k, spill in enumerate(spills):
            table = read_ipc(spill)
            if k == 0:  # the first group's file always (it counts the ignored lines)
                sinks[0] = pa.OSFile(str(names[0]), "wb")
                writers[0] = pa.ipc.new_file(sinks[0], table.schema)
            order, cuts = by_group(pc.fill_null(table.column("mmsi"), -1).to_numpy(), bounds)
            lines = table.column("line").to_numpy()
            for g in range(n):
                at = order[cuts[g]:cuts[g + 1]]
                if len(at):
                    if writers[g] is None:
                        sinks[g] = pa.OSFile(str(names[g]), "wb")
                        writers[g] = pa.ipc.new_file(sinks[g], table.schema)
                    writers[g].write_table(table.take(at))
                    lines[at].astype(np.int64).tofile(louts[g])
                    counts[g] += len(at)
            del table
            spill.unlink()
    finally:
        for w, sink in zip(writers, sinks):
            if w is not None:
                w.close()
                sink.close()
        for f in louts:
            f.close()
    groups = []
    for g in range(n):
        if counts[g] or (g == 0 and not counts.any()):  # no row at all: the ignored lines' group
            npy = line_files[g].with_suffix(".npy")
            np.save(npy, np.sort(np.fromfile(line_files[g], dtype=np.int64)))
            groups.append(NmeaGroup(names[g], npy, int(counts[g]), ignored if not groups else 0))
        line_files[g].unlink()
    return groups


def read_group(group: NmeaGroup) -> pd.DataFrame:
    """A group's stage: its rows in line order, numbered 1..n (``group.line_numbers()`` maps
    them back), the duplicate payloads marked (:func:`mark_duplicates`)."""
    from ais.clean import conform_stage

    stage = read_ipc(group.path).to_pandas()
    stage = stage.sort_values("line", kind="stable").reset_index(drop=True)
    stage["line"] = np.arange(1, len(stage) + 1, dtype=np.int64)
    payload = stage.pop("dup_payload")
    stage = conform_stage(stage)
    stage["dup_payload"] = payload.to_numpy()
    return mark_duplicates(stage)


def _arrow(stage: pd.DataFrame):
    """A chunk's stage as Arrow with the same types whatever its values (a column of None only
    is still text)."""
    import pyarrow as pa

    from ais.clean import STAGE_COLUMNS

    kinds = {"int64": pa.int64(), "Int64": pa.int64(), "float64": pa.float64(), "object": pa.string(),
             "datetime64[ns, UTC]": pa.timestamp("ns", tz="UTC")}
    schema = pa.schema([(c, kinds[t]) for c, t in STAGE_COLUMNS.items()] + [("dup_payload", pa.string())])
    return pa.Table.from_pandas(stage[schema.names], schema=schema, preserve_index=False)
