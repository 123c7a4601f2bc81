"""Where the lines of a large text file start and end, found with numpy over a memory map.

The bulk CSV ingest lets DuckDB's typed CSV scanner parse a file and needs, next to it, the
physical line of every record and the raw text of the few records that are quarantined or
re-typed exactly. :class:`LineIndex` provides both without a second parse: one vectorised
pass finds every ``\\n`` (the file is read through ``mmap``; numpy releases the GIL, so this
runs in a thread while DuckDB parses), and the text of any line is then a slice of the map.

Line rules are those of :func:`ais.io.csv_formats.read_lines`: lines are split on ``\\n``,
one trailing ``\\r`` is removed, a final newline does not add a line, text is UTF-8 with
undecodable bytes replaced. Besides the offsets the index records what a one-record-per-line
scanner cannot be trusted with: lines holding a double quote (typed from their text by the
caller), empty lines, and whether any ``\\r`` stands anywhere but right before a
``\\n`` (then the caller must not rely on the index at all).
"""

from __future__ import annotations

import mmap
from pathlib import Path

import numba
import numpy as np

_CHUNK = 1 << 24  # bytes per vectorised step (bounded temporary memory)
_NL, _CR = 0x0A, 0x0D


def _positions(buf: np.ndarray, mm: mmap.mmap, byte: int) -> np.ndarray:
    """Offsets of every occurrence of ``byte`` (a quick ``find`` first: most files have none)."""
    first = mm.find(bytes([byte]))
    if first < 0:
        return np.empty(0, dtype=np.int64)
    parts = [np.flatnonzero(buf[i:i + _CHUNK] == byte) + i
             for i in range(first - first % _CHUNK, len(buf), _CHUNK)]
    return np.concatenate(parts).astype(np.int64, copy=False)


@numba.njit(nogil=True, cache=True)
def _gather(buf, starts, ends, offsets, out):
    """Each line's bytes ``buf[starts[k]:ends[k]]`` to ``out[offsets[k]:]``."""
    for k in range(len(starts)):
        a = offsets[k]
        for j in range(ends[k] - starts[k]):
            out[a + j] = buf[starts[k] + j]


class LineIndex:
    """Line offsets of an uncompressed text file.

    Attributes
    ----------
    n_lines : int
        Physical lines (a last line without a newline counts; an empty file has none).
    starts, ends : numpy.ndarray of int64
        Byte offset of each line's first byte and one past its last (without ``\\n`` and one
        trailing ``\\r``); line ``k`` (1-based) is ``starts[k - 1]:ends[k - 1]``.
    blank_lines : numpy.ndarray of int64
        1-based numbers of the empty lines.
    quote_lines : numpy.ndarray of int64
        1-based numbers of the lines containing ``"`` (sorted, unique).
    stray_cr : bool
        True when a ``\\r`` is not immediately followed by ``\\n``.
    """

    def __init__(self, path: str | Path, offsets_from=None):
        """``offsets_from`` (optional): a function of the file's bytes (uint8 array over the map)
        returning ``(starts, ends, quote_lines, stray_cr)`` found by another scan of the same
        rules (e.g. :func:`ais.io.csv_scan.scan_csv`), or None to let the index find them."""
        self.path = Path(path)
        self._fh = open(self.path, "rb")
        size = self.path.stat().st_size
        self._mm = mmap.mmap(self._fh.fileno(), 0, access=mmap.ACCESS_READ) if size else None
        if self._mm is None:
            self.n_lines = 0
            self.starts = self.ends = self.blank_lines = np.empty(0, dtype=np.int64)
            self.quote_lines = np.empty(0, dtype=np.int64)
            self.stray_cr = False
            return
        buf = np.frombuffer(self._mm, dtype=np.uint8)
        found = offsets_from(buf) if offsets_from is not None else None
        if found is not None:
            self.starts, self.ends, self.quote_lines, self.stray_cr = found
            self.n_lines = len(self.starts)
            self.blank_lines = np.flatnonzero(self.ends == self.starts) + 1
            del buf
            return
        nl = _positions(buf, self._mm, _NL)
        last_open = buf[-1] != _NL
        self.n_lines = len(nl) + int(last_open)
        self.starts = np.empty(self.n_lines, dtype=np.int64)
        self.starts[0] = 0
        self.starts[1:] = nl[: self.n_lines - 1] + 1
        self.ends = np.concatenate([nl, [size]]) if last_open else nl.copy()
        cr = _positions(buf, self._mm, _CR)
        if len(cr):
            after = cr + 1
            self.stray_cr = bool((after >= size).any() or (buf[np.minimum(after, size - 1)] != _NL).any())
            nonempty = self.ends > self.starts
            has_cr = np.zeros(self.n_lines, dtype=bool)
            has_cr[nonempty] = buf[self.ends[nonempty] - 1] == _CR
            self.ends = self.ends - has_cr
        else:
            self.stray_cr = False
        self.blank_lines = np.flatnonzero(self.ends == self.starts) + 1
        self.quote_lines = self.lines_of(_positions(buf, self._mm, ord('"')))
        del buf

    def lines_of(self, offsets: np.ndarray) -> np.ndarray:
        """1-based numbers (sorted, unique) of the lines holding these byte offsets."""
        if len(offsets) == 0:
            return np.empty(0, dtype=np.int64)
        return np.unique(np.searchsorted(self.starts, offsets, side="right")).astype(np.int64)

    def lines_equal_to(self, texts) -> np.ndarray:
        """1-based numbers (sorted) of the lines whose bytes (without ``\\n`` and one trailing
        ``\\r``) are one of ``texts`` (a set of ``bytes``). Only lines of a matching length are
        compared."""
        texts = set(texts)
        if not texts or self._mm is None:
            return np.empty(0, dtype=np.int64)
        lengths = self.ends - self.starts
        cand = np.flatnonzero(np.isin(lengths, np.fromiter((len(b) for b in texts), dtype=np.int64)))
        mm = self._mm
        found = [k + 1 for k, s, e in zip(cand.tolist(), self.starts[cand].tolist(), self.ends[cand].tolist())
                 if mm[s:e] in texts]
        return np.asarray(found, dtype=np.int64)

    def raw(self, lines) -> list[bytes]:
        """The bytes of the 1-based ``lines`` (without ``\\n`` and one trailing ``\\r``)."""
        lines = np.asarray(lines, dtype=np.int64)
        if len(lines) and (lines.min() < 1 or lines.max() > self.n_lines):
            raise IndexError(f"{self.path}: line out of range 1..{self.n_lines}")
        mm = self._mm
        return [mm[s:e] for s, e in zip(self.starts[lines - 1].tolist(), self.ends[lines - 1].tolist())]

    def text(self, lines) -> list[str]:
        """The text of the 1-based ``lines`` (UTF-8, undecodable bytes replaced)."""
        lines = np.asarray(lines, dtype=np.int64)
        if len(lines) and (lines.min() < 1 or lines.max() > self.n_lines):
            raise IndexError(f"{self.path}: line out of range 1..{self.n_lines}")
        mm = self._mm
        return [mm[s:e].decode("utf-8", errors="replace")
                for s, e in zip(self.starts[lines - 1].tolist(), self.ends[lines - 1].tolist())]

    def text_array(self, lines):
        """:meth:`text` of the 1-based ``lines`` as one Arrow ``large_string`` array, copied
        straight from the map (no Python string per line: a file of 2.9 M quarantined lines took
        10.8 s and 4.3 GB in its quarantine step with :meth:`text`, issue 23). Lines that are not
        valid UTF-8 take :meth:`text` (their bytes replaced)."""
        import pyarrow as pa

        lines = np.asarray(lines, dtype=np.int64)
        if len(lines) and (lines.min() < 1 or lines.max() > self.n_lines):
            raise IndexError(f"{self.path}: line out of range 1..{self.n_lines}")
        starts, ends = self.starts[lines - 1], self.ends[lines - 1]
        offsets = np.zeros(len(lines) + 1, dtype=np.int64)
        np.cumsum(ends - starts, out=offsets[1:])
        data = np.empty(int(offsets[-1]), dtype=np.uint8)
        if len(data):
            _gather(np.frombuffer(self._mm, dtype=np.uint8), starts, ends, offsets, data)
        raw = pa.LargeBinaryArray.from_buffers(pa.large_binary(), len(lines),
                                               [None, pa.py_buffer(offsets), pa.py_buffer(data)])
        try:
            return raw.cast(pa.large_string())  # checks the UTF-8
        except pa.ArrowInvalid:
            return pa.array(self.text(lines), pa.large_string())

    def close(self) -> None:
        if self._mm is not None:
            self._mm.close()
            self._mm = None
        self._fh.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False
