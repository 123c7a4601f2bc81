"""The positions dataset's parts of a file committed in groups of whole vessels (issue 23).

A large CSV file is split by MMSI range (:mod:`ais.io.csv_buckets`) and its groups are committed
one after the other in one transaction (:func:`pipelines.storage.ais.commit.classify_and_commit`),
so that no step holds the whole file. Its parts must still be the parts of the whole file (one
per UTC day, rows in (MMSI, time) order, row groups of :data:`parquet.ROW_GROUP_ROWS`, the day's
bounding box in the ``geo`` metadata): the same bytes a single commit, or
:func:`parquet.sync_positions_parquet` writing them again from the workspace, would write.

:meth:`GroupParts.add` sorts each group's new rows by (day, MMSI, time) and spills each day's
slice to an Arrow IPC file (LZ4), noting the day's rows and bounding box. :meth:`GroupParts.finish`
then writes each day's part by streaming the group slices in group order (the groups are
ascending MMSI ranges, so their concatenation is the day's (MMSI, time) order) in slices of
exactly one row group, the ``geo`` metadata carrying the whole day's box from the start.
Memory: one group's rows and one row group.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from pipelines.storage.ais import parquet as P


class GroupParts:
    """A file's parts gathered from its groups inside the file's transaction."""

    def __init__(self, ws, file_id: int, root: Path, spill: Path):
        self._ws, self._file_id, self._root, self._spill = ws, int(file_id), root, spill
        self._days: dict[str, dict] = {}
        self._n_groups = 0
        self._parts: list[P.Part] = []

    @classmethod
    def start(cls, ws, file_id: int) -> "GroupParts | None":
        """None for an in-memory workspace (no dataset)."""
        root = P.positions_root(getattr(ws, "path", None))
        if root is None:
            return None
        spill = root.parent / f".groups-{int(file_id):09d}-{os.getpid()}.tmp"
        shutil.rmtree(spill, ignore_errors=True)
        spill.mkdir(parents=True)
        return cls(ws, file_id, root, spill)

    def add(self, table) -> None:
        """Spill the group's new rows (an Arrow table in the canonical columns) by day."""
        import pyarrow as pa

        k = self._n_groups
        self._n_groups += 1
        if table.num_rows == 0:
            return
        table, slices = P._sorted_by_day(table)
        options = pa.ipc.IpcWriteOptions(compression="lz4")
        for day, start, n in slices:
            part = table.slice(start, n)
            box = P.bbox_of(part.column("lon_deg").to_numpy(), part.column("lat_deg").to_numpy())
            d = self._days.setdefault(day, {"rows": 0, "box": box, "files": []})
            d["rows"] += n
            d["box"] = [min(d["box"][0], box[0]), min(d["box"][1], box[1]),
                        max(d["box"][2], box[2]), max(d["box"][3], box[3])]
            path = self._spill / f"{day}-{k:04d}.arrow"
            with pa.OSFile(str(path), "wb") as sink, pa.ipc.new_file(sink, part.schema, options=options) as w:
                w.write_table(part)
            d["files"].append(path)

    def finish(self) -> list[P.Part]:
        """Write every day's part under its temporary name and record it in ``ais_parquet_parts``
        (still inside the transaction); returns the parts (published after the commit)."""
        try:
            for day in sorted(self._days):
                d = self._days[day]
                self._parts.append(P.new_part(self._root, day, self._file_id, d["rows"]))
                self._write_day(self._parts[-1].tmp, d)  # listed first: abandon() removes a partial write
            P.record_parts(self._ws.con, self._file_id, self._parts)
        finally:
            shutil.rmtree(self._spill, ignore_errors=True)
        return self._parts

    def _write_day(self, path: Path, d: dict) -> None:
        """Stream the day's group slices into ``path`` in slices of whole row groups."""
        import pyarrow as pa

        rows = P.ROW_GROUP_ROWS
        writer = carry = None
        try:
            for spilled in d["files"]:
                with pa.memory_map(str(spilled), "r") as src:
                    table = pa.ipc.open_file(src).read_all()
                table = table if carry is None else pa.concat_tables([carry, table])
                full = table.num_rows // rows * rows
                if full:
                    writer = self._write(writer, path, table.slice(0, full), d["box"])
                carry = table.slice(full)
                spilled.unlink()
            if carry is not None and carry.num_rows:
                writer = self._write(writer, path, carry, d["box"])
        finally:
            if writer is not None:
                writer.close()

    @staticmethod
    def _write(writer, path: Path, table, box: list):
        import pyarrow.parquet as pq

        geo = P.geoparquet_table(table.combine_chunks(), extent=box)
        if writer is None:
            writer = pq.ParquetWriter(str(path), geo.schema, **P.writer_options())
        writer.write_table(geo, row_group_size=P.ROW_GROUP_ROWS)
        return writer

    def abandon(self) -> None:
        """After an error in the transaction: remove the spill and the parts written."""
        shutil.rmtree(self._spill, ignore_errors=True)
        P.discard(self._parts)
