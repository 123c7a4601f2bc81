"""Opening AIS files: gzip, zstd and zip by content, fingerprints, format detection by content.

Formats: ``dma`` (Danish Maritime Authority CSV), ``noaa`` (NOAA MarineCadastre CSV), ``nmea``
(raw ``!AIVDM``/``!AIVDO`` sentences with optional tag blocks and ``$PGHP`` lines) and
``parquet`` (canonical column names, or the mapped aliases in :mod:`ais.io.parquet`).
Gzip, Zstandard (RFC 8878 [1]; NOAA's CSV files from 2024 on, ``.csv.zst``) and zip (an archive
holding one file, :mod:`ais.io.archives`) are recognised by their magic bytes, whatever the file
is called; their content is what is read and fingerprinted.

.. [1] Y. Collet, M. Kucherawy (ed.), "Zstandard Compression and the 'application/zstd' Media
   Type," RFC 8878, 2021 (section 3.1.1: the frame's magic number 0xFD2FB528, little-endian).
"""

from __future__ import annotations

import gzip
import hashlib
import logging
import os
from dataclasses import dataclass
from pathlib import Path

from ais.errors import AisFormatError, AisInputError
from ais.io.archives import ZIP_MAGIC, open_member, pump, unzip_into

log = logging.getLogger(__name__)

FORMATS = ("dma", "noaa", "nmea", "parquet")
GZIP_MAGIC = b"\x1f\x8b"
ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"
PARQUET_MAGIC = b"PAR1"
#: File names a directory scan picks up (content decides the format; case-insensitive).
AIS_SUFFIXES = (".csv", ".txt", ".nmea", ".nm4", ".ais", ".log", ".parquet", ".pq")
#: Archives a directory scan picks up whatever the name before (DMA's ``aisdk-2025-01-01.zip``).
ARCHIVE_SUFFIXES = (".zip",)


@dataclass(frozen=True)
class AisFile:
    """One input file: where it is, what it is, and its content fingerprint."""

    path: Path
    format: str
    gzip: bool
    size_bytes: int
    fingerprint: str  # "blake3:<hex>" of the content (decompressed when compressed)
    zip: bool = False  # a zip archive holding the file (:mod:`ais.io.archives`)
    zstd: bool = False  # Zstandard-compressed

    @property
    def compressed(self) -> bool:
        """Whether the content must be decompressed (gzip, zstd, or a zip archive's member)."""
        return self.gzip or self.zip or self.zstd

    @property
    def staged_from_plain_copy(self) -> bool:
        """Whether only a decompressed copy can be staged (zip, zstd: the readers take plain
        files and gzip streams)."""
        return self.zip or self.zstd


def compression(path: str | Path) -> str:
    """How the file's content is stored, from its first bytes: ``"gzip"``, ``"zstd"``, ``"zip"``
    (an archive, :mod:`ais.io.archives`) or ``""`` (plain)."""
    with open(path, "rb") as fh:
        head = fh.read(4)
    if head.startswith(GZIP_MAGIC):
        return "gzip"
    return {ZSTD_MAGIC: "zstd", ZIP_MAGIC: "zip"}.get(head, "")


def is_compressed(path: str | Path) -> bool:
    """Whether the file's content must be decompressed to be read (gzip, zstd, a zip archive)."""
    return compression(path) != ""


def open_binary(path: str | Path):
    """Open for binary reading, decompressing gzip, zstd and a zip archive's one file transparently."""
    kind = compression(path)
    if kind == "gzip":
        return gzip.open(path, "rb")
    if kind == "zstd":
        import pyarrow as pa

        return pa.CompressedInputStream(pa.OSFile(str(path)), "zstd")
    return open_member(path) if kind == "zip" else open(path, "rb")


def inflate_into(path: str | Path, sink, chunk: int = 1 << 22) -> int:
    """Decompress a gzip file (:func:`gunzip_into`), a zstd file (:func:`unzstd_into`) or a zip
    archive's one file (:func:`ais.io.archives.unzip_into`) into ``sink``; returns the content's size."""
    inflate = {"zip": unzip_into, "zstd": unzstd_into}.get(compression(path), gunzip_into)
    return inflate(path, sink, chunk)


def unzstd_into(path: str | Path, sink, chunk: int = 1 << 22) -> int:
    """Decompress a Zstandard file (every frame; pyarrow's zstd codec, which checks a frame's
    checksum when the frame has one, as the ``zstd`` tool writes by default) into ``sink``;
    returns the content's size. A stream that ends inside a frame or does not decode is an
    :class:`AisInputError` naming the file."""
    try:
        with open_binary(path) as fh:
            return pump(fh, sink, chunk)
    except OSError as err:
        raise AisInputError(path, f"truncated or corrupt zstd stream ({err}); a partial download or copy?") from None


def read_content(path: str | Path) -> bytes:
    """The whole content of a file, decompressed when compressed; a truncated or corrupt one is
    an :class:`AisInputError` naming it (see :func:`inflate_into`)."""
    if not is_compressed(path):
        return Path(path).read_bytes()
    parts: list[bytes] = []
    inflate_into(path, parts.append)
    return b"".join(parts)


def content_has(path: str | Path, byte: bytes, stray_cr: bool = False) -> bool:
    """Whether the content (decompressed when compressed) holds ``byte`` (a single byte), or
    with ``stray_cr`` also a ``\r`` that is not right before a ``\n`` (at the end included)."""
    import re

    pattern = re.compile(re.escape(byte) + (rb"|\r(?!\n)" if stray_cr else b""))
    if is_compressed(path):
        state = {"found": False, "tail": b""}

        def sink(block: bytes) -> None:
            if state["found"]:
                return
            data = state["tail"] + block
            cut = len(data) - 1 if data.endswith(b"\r") else len(data)  # a last \r: decided with what follows
            state["found"] = pattern.search(data, 0, cut) is not None
            state["tail"] = data[cut:]

        inflate_into(path, sink)
        return state["found"] or (stray_cr and state["tail"] == b"\r")
    if Path(path).stat().st_size == 0:
        return False
    import mmap

    with open(path, "rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as m:
        return pattern.search(m) is not None


#: Algorithm of new fingerprints, then those that earlier versions stored (still recognised).
FINGERPRINT_ALGOS = ("blake3", "sha256")


def fingerprint(path: str | Path, algo: str = FINGERPRINT_ALGOS[0], chunk: int = 1 << 22) -> str:
    """Cryptographic hash of the file's content: ``"blake3:<hex>"`` (BLAKE3 [1], one thread:
    0.19 s for an 846 MB file here, against 0.48 s for SHA-256, and it runs beside DuckDB's
    two-threaded insert) of the bytes, decompressed when the file is gzip, zstd or zip (so that
    ``x.csv``, ``x.csv.gz``, ``x.csv.zst`` and ``x.zip`` are the same input; reading the whole stream also
    proves it complete), or
    ``"sha256:<hex>"`` of the bytes as stored, the fingerprint of files loaded by earlier
    versions.

    Raises
    ------
    AisInputError
        For ``blake3`` of a compressed file that is truncated or corrupt (its message says which).

    .. [1] J. O'Connor, J.-P. Aumasson, S. Neves, Z. Wilcox-O'Hearn, "BLAKE3: one function,
       fast everywhere," 2020, https://github.com/BLAKE3-team/BLAKE3-specs.
    """
    if algo == "blake3":
        import blake3

        h = blake3.blake3(max_threads=1)
        if is_compressed(path):
            inflate_into(path, h.update, chunk)
        else:
            # Read in blocks, not through update_mmap: a map of the whole file made the process's
            # resident memory grow with the file (1.9 GB for a 1.9 GB file), at the same speed
            # (0.78 against 0.82 s here). The hash releases the GIL on such blocks.
            _read_blocks(path, h.update, 16 << 20)
        return "blake3:" + h.hexdigest()
    if algo != "sha256":
        raise ValueError(f"unknown fingerprint algorithm {algo!r} (known: {', '.join(FINGERPRINT_ALGOS)})")
    h = hashlib.sha256()
    _read_blocks(path, h.update, chunk)
    return "sha256:" + h.hexdigest()


def _read_blocks(path, sink, chunk: int) -> None:
    """Pass a plain file's bytes to ``sink`` in blocks of ``chunk`` bytes (one reused buffer)."""
    buf = bytearray(chunk)
    view = memoryview(buf)
    with open(path, "rb", buffering=0) as fh:
        while n := fh.readinto(buf):
            sink(view[:n])


def gunzip_into(path: str | Path, sink, chunk: int = 1 << 22) -> int:
    """Decompress a gzip file (every member of it, RFC 1952 [1]; zero padding after a member is
    skipped, as Python's gzip does) and pass the content to ``sink`` block by block; returns the
    content's size. Each member's CRC-32 and length are checked.

    The inflate is Intel's ISA-L [2] (``isal.isal_zlib``, zlib's interface): about 2.9 times
    zlib's speed on AIS CSV (a 12.6 MB daily file of 0.3 M rows: 0.095 against 0.274 CPU s,
    measured for issue 23), and the largest single cost of a gzip file's ingest.

    Raises
    ------
    AisInputError
        When the file ends inside a member (a partial download or copy: ``truncated gzip``) or
        a member is corrupt (``corrupt gzip``), naming the file and how far it got.

    .. [1] P. Deutsch, "GZIP file format specification version 4.3," RFC 1952, 1996.
    .. [2] Intel, "Intelligent Storage Acceleration Library (ISA-L)", igzip;
       https://github.com/intel/isa-l (Python binding: python-isal, https://pypi.org/project/isal/).
    """
    from isal import isal_zlib as zlib

    size_in = Path(path).stat().st_size
    out = read = 0
    d = zlib.decompressobj(16 + zlib.MAX_WBITS)
    in_member = False  # bytes of the current member were given to d
    with open(path, "rb") as fh:
        try:
            while block := fh.read(chunk):
                read += len(block)
                while block:
                    if not in_member:
                        block = block.lstrip(b"\0")
                        if not block:
                            break
                    in_member = True
                    data = d.decompress(block)
                    if data:
                        sink(data)
                        out += len(data)
                    block = b""
                    if d.eof:  # end of a member: another may follow (concatenated gzip files)
                        block = d.unused_data
                        d = zlib.decompressobj(16 + zlib.MAX_WBITS)
                        in_member = False
        except zlib.error as err:
            raise AisInputError(path, f"corrupt gzip within its first {read:,} bytes ({err})") from None
    if in_member:
        raise AisInputError(path, f"truncated gzip: the {size_in:,}-byte file ends inside a compressed member "
                                  f"({out:,} bytes of content decompressed); a partial download or copy?")
    return out


def quick_key(path: str | Path, n: int = 1 << 20) -> str:
    """A cheap identity of the bytes: size plus SHA-256 of the first and last ``n`` bytes. Files
    with different quick keys differ; equal keys need the full :func:`fingerprint`."""
    size = Path(path).stat().st_size
    h = hashlib.sha256(str(size).encode())
    with open(path, "rb") as fh:
        h.update(fh.read(n))
        if size > n:
            fh.seek(max(n, size - n))
            h.update(fh.read(n))
    return "quick:" + h.hexdigest()


def _unreadable(path, err: Exception) -> AisInputError:
    """The one error for a file its first bytes could not be read from; a gzip file that ends
    inside its member (EOFError) is said as :func:`gunzip_into` says it, not in Python's words."""
    if isinstance(err, EOFError):
        return AisInputError(path, f"truncated gzip: the {Path(path).stat().st_size:,}-byte file ends inside a compressed "
                                   "member; a partial download or copy?")
    if compression(path) == "zstd":
        return AisInputError(path, f"truncated or corrupt zstd stream ({err}); a partial download or copy?")
    return AisInputError(path, f"cannot read: {err}")


def head_text(path: str | Path, n_bytes: int = 65536) -> str:
    """The first ``n_bytes`` of the (decompressed) content as text (undecodable bytes replaced)."""
    try:
        with open_binary(path) as fh:
            data = fh.read(n_bytes)
    except (OSError, EOFError) as err:
        raise _unreadable(path, err) from err
    return data.decode("utf-8", errors="replace").lstrip("\ufeff")


def normalise_header_name(name: str) -> str:
    """Header names compare trimmed, unquoted, lower-case and without a leading ``#``."""
    s = name.strip().strip('"').strip()
    if s.startswith("#"):
        s = s[1:].strip()
    return s.lower()


def detect_format(path: str | Path) -> str:
    """The AIS format of a file, from its content (see module docstring).

    Raises
    ------
    AisFormatError
        When the content matches no supported format; the message shows the first line.
    """
    path = Path(path)
    try:
        with open_binary(path) as fh:
            magic = fh.read(4)
    except (OSError, EOFError) as err:
        raise _unreadable(path, err) from err
    if magic == PARQUET_MAGIC:
        return "parquet"
    text = head_text(path)
    lines = [ln.strip() for ln in text.split("\n")]
    first = next((ln for ln in lines if ln), "")
    if not first:
        raise AisFormatError(path, "empty file: no AIS content to detect the format from")
    if first[0] in "!$\\":
        return "nmea"
    names = {normalise_header_name(x) for x in first.split(",")}
    if "mmsi" in names and names & {"basedatetime", "base_date_time"}:  # NOAA's header until 2023, from 2024
        return "noaa"
    if {"timestamp", "mmsi", "latitude", "longitude"} <= names:
        return "dma"
    head = first[:200]
    garbled = sum(1 for ch in head if ch == "\ufffd" or (ord(ch) < 32 and ch != "\t"))
    if garbled > max(2, len(head) // 10):  # not text: say so rather than print the bytes as a "line"
        shown = f"binary content: {garbled} of its first {len(head)} characters are not text"
    else:
        shown = "first line: " + repr(first if len(first) <= 120 else first[:117] + "...")
    raise AisFormatError(
        path,
        f"unknown AIS format ({shown}); expected a DMA CSV header ('# Timestamp,...,MMSI,"
        "Latitude,Longitude,...'), a NOAA MarineCadastre header ('MMSI,BaseDateTime,...' or "
        "'mmsi,base_date_time,...'), NMEA sentences ('!AIVDM,...') or Parquet, each plain, gzip, zstd "
        "or alone in a zip archive; use --format to force one",
        line=1,
    )


def is_empty(path: str | Path) -> bool:
    """No content at all: zero bytes, or (files under 1 MiB, after gunzip) only whitespace."""
    path = Path(path)
    size = path.stat().st_size
    return size == 0 or (size < (1 << 20) and not head_text(path, 1 << 20).strip())


def identity_suffix(path: str | Path, fmt: str | None) -> str:
    """What distinguishes a file read in a forced format from the same bytes read as detected.

    ``""`` when ``fmt`` is None or is the format detected from the content, else ``"#as-<fmt>"``:
    bytes once loaded under a wrong ``--format`` (every row quarantined) can then still be
    loaded as what they are; the same bytes under the same format are still loaded only once.
    """
    if fmt is None:
        return ""
    try:
        detected = detect_format(path)
    except AisFormatError:
        detected = None
    return "" if detected == fmt else f"#as-{fmt}"


def expand_paths(paths) -> list[Path]:
    """Files named by ``paths``: a directory means every AIS-looking file inside it (recursive,
    sorted; names ending in one of :data:`AIS_SUFFIXES`, optionally followed by ``.gz`` or ``.zst``,
    or in one of :data:`ARCHIVE_SUFFIXES`).

    Inside a directory, hidden entries (``.name``: editor and system files), empty files and
    links to nothing are skipped, each with a warning; named on their own, an empty file is an
    error (see :func:`detect_format`) and a hidden one is loaded.

    Raises
    ------
    AisInputError
        For an empty path, a path that does not exist or a directory with no AIS file.
    """
    out: list[Path] = []
    for arg in paths:
        if str(arg).strip() == "":
            raise AisInputError(repr(str(arg)), "empty path (name a file or a directory)")
        p = Path(arg)
        if p.is_dir():
            found = []
            for root, dirs, files in os.walk(p):
                for d in sorted(x for x in dirs if x.startswith(".")):
                    log.warning("%s: hidden folder in %s, skipped", Path(root) / d, p)
                dirs[:] = sorted(d for d in dirs if not d.startswith("."))
                for f in sorted(files):
                    name = f.lower()
                    base = name.removesuffix(".gz").removesuffix(".zst")
                    if not base.endswith(AIS_SUFFIXES) and not name.endswith(ARCHIVE_SUFFIXES):
                        continue
                    path = Path(root) / f
                    if f.startswith("."):
                        log.warning("%s: hidden file in %s, skipped", path, p)
                        continue
                    if not path.exists():
                        log.warning("%s: link to nothing in %s, skipped", path, p)
                        continue
                    if is_empty(path):  # no content: not an AIS file (named alone, it is an error)
                        log.warning("%s: empty file in %s, skipped", path, p)
                        continue
                    found.append(path)
            if not found:
                raise AisInputError(p, f"directory contains no AIS file (looked for {', '.join(AIS_SUFFIXES)}, "
                                       f"optionally .gz or .zst, and {', '.join(ARCHIVE_SUFFIXES)}; hidden files are skipped)")
            out.extend(found)
        elif p.is_file():
            out.append(p)
        else:
            raise AisInputError(p, "no such file or directory")
    # The same file named twice is loaded once.
    seen, unique = set(), []
    for p in out:
        key = p.resolve()
        if key not in seen:
            seen.add(key)
            unique.append(p)
    return unique


def inspect(path: str | Path, fmt: str | None = None, with_fingerprint: bool = True) -> AisFile:
    """Format (detected unless forced), compression, size and fingerprint of one file."""
    path = Path(path)
    if not path.is_file():
        raise AisInputError(path, "no such file")
    if fmt is not None and fmt not in FORMATS:
        raise AisFormatError(path, f"unknown format {fmt!r}; choose one of {', '.join(FORMATS)}")
    found = fmt or detect_format(path)
    kind = compression(path)
    return AisFile(
        path=path,
        format=found,
        gzip=kind == "gzip",
        size_bytes=path.stat().st_size,
        fingerprint=fingerprint(path) if with_fingerprint else "",
        zip=kind == "zip",
        zstd=kind == "zstd",
    )
