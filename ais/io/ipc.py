"""Arrow IPC files: written whole, read back memory-mapped (the table's buffers are the file's
pages, which the kernel can drop: how the ingest keeps large temporary tables out of its own
memory, issue 23)."""

from __future__ import annotations

from pathlib import Path


def write_ipc(tbl, path: Path) -> None:
    """Write the Arrow table ``tbl`` to the IPC file ``path``."""
    import pyarrow as pa

    with pa.OSFile(str(path), "wb") as sink, pa.ipc.new_file(sink, tbl.schema) as writer:
        writer.write_table(tbl)


def read_ipc(path: Path):
    """The table of an IPC file, memory-mapped (its buffers are the file's pages)."""
    import pyarrow as pa

    return pa.ipc.open_file(pa.memory_map(str(path), "r")).read_all()
