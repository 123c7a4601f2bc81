"""AIS files inside zip archives, as the two public sources publish them.

The Danish Maritime Authority publishes one zip archive per day (``aisdk-YYYY-MM-DD.zip``, one
CSV file inside) [1]; NOAA MarineCadastre one per day (``AIS_YYYY_MM_DD.zip``, one CSV file
inside) [2]. An archive holding exactly one file (folders, macOS resource forks ``__MACOSX/`` and
hidden entries aside) is read as that file: its content decompressed, as a gzip file's is.
Anything else (several files, none, an encrypted or unreadable archive) is one
:class:`ais.errors.AisInputError` naming the archive.

The member's deflate stream is inflated by ISA-L (as gzip files are, :func:`ais.io.files.
gunzip_into`) from the offset its local file header gives, and its CRC-32 and size are checked
against the central directory (PKWARE APPNOTE.TXT [3], sections 4.3.7 and 4.4); a member stored
or compressed otherwise is read through Python's :mod:`zipfile`.

.. [1] Danish Maritime Authority, "AIS data," http://web.ais.dk/aisdata/ (daily zip files).
.. [2] NOAA Office for Coastal Management, "Vessel traffic data," MarineCadastre.gov,
   https://coast.noaa.gov/htdata/CMSP/AISDataHandler/ (daily zip files).
.. [3] PKWARE Inc., "APPNOTE.TXT - .ZIP File Format Specification," version 6.3.10, 2022.
"""

from __future__ import annotations

import struct
import zipfile
from pathlib import Path

from ais.errors import AisInputError

ZIP_MAGIC = b"PK\x03\x04"
#: The local file header's fixed part: signature, version, flags, method, time, date, CRC-32,
#: sizes, name length, extra field length (APPNOTE 4.3.7): 30 bytes.
_LOCAL_HEADER = struct.Struct("<4sHHHHHIIIHH")
_ENCRYPTED = 0x1  # general purpose bit 0 (APPNOTE 4.4.4)


def _skipped(name: str) -> bool:
    """Entries that are not content: folders, macOS resource forks, hidden files."""
    base = name.rstrip("/").rsplit("/", 1)[-1]
    return name.endswith("/") or name.startswith("__MACOSX/") or base.startswith(".")


def member(path: str | Path) -> zipfile.ZipInfo:
    """The one file of the archive ``path``; :class:`AisInputError` when it holds none or
    several, or is encrypted or unreadable (a truncated archive lacks its central directory)."""
    try:
        with zipfile.ZipFile(path) as zf:
            infos = [i for i in zf.infolist() if not _skipped(i.filename)]
    except (zipfile.BadZipFile, OSError, EOFError) as err:
        raise AisInputError(path, f"not a readable zip archive ({err}); a partial download or copy?") from None
    if len(infos) != 1:
        shown = ", ".join(i.filename for i in infos[:3]) + (", ..." if len(infos) > 3 else "")
        what = f"{len(infos)} files ({shown})" if infos else "no file"
        raise AisInputError(path, f"zip archive holds {what}: an archive is read when it holds one AIS file "
                                  "(as DMA and NOAA publish them); unpack it and pass the files or their folder")
    if infos[0].flag_bits & _ENCRYPTED:
        raise AisInputError(path, f"zip archive member {infos[0].filename} is encrypted: unpack it and pass the file")
    return infos[0]


def open_member(path: str | Path):
    """The archive's one file, opened for binary reading (decompressed)."""
    info = member(path)
    try:
        zf = zipfile.ZipFile(path)
        fh = zf.open(info)
        zf.close()  # the member's stream keeps the file open until it is closed itself
    except (zipfile.BadZipFile, NotImplementedError, OSError) as err:
        raise AisInputError(path, f"cannot read zip archive member {info.filename}: {err}") from None
    return fh


def unzip_into(path: str | Path, sink, chunk: int = 1 << 22) -> int:
    """Decompress the archive's one file and pass its content to ``sink`` block by block;
    returns the content's size. :class:`AisInputError` naming the archive when the member is
    truncated or corrupt (its CRC-32 or size differs from the central directory's)."""
    info = member(path)
    if info.compress_type != zipfile.ZIP_DEFLATED:
        return _copy_stream(path, info, sink, chunk)
    from isal import isal_zlib as zlib

    d, crc, out = zlib.decompressobj(-zlib.MAX_WBITS), 0, 0  # raw deflate (RFC 1951), no header
    with open(path, "rb") as fh:
        fh.seek(info.header_offset)
        head = fh.read(_LOCAL_HEADER.size)
        if len(head) < _LOCAL_HEADER.size or _LOCAL_HEADER.unpack(head)[0] != ZIP_MAGIC:
            raise AisInputError(path, f"corrupt zip archive: no local header for {info.filename}")
        fields = _LOCAL_HEADER.unpack(head)
        fh.seek(info.header_offset + _LOCAL_HEADER.size + fields[9] + fields[10])
        left = info.compress_size
        try:
            while left > 0 and (block := fh.read(min(chunk, left))):
                left -= len(block)
                data = d.decompress(block)
                crc, out = zlib.crc32(data, crc), out + len(data)
                sink(data)
            data = d.flush()
        except zlib.error as err:
            raise AisInputError(path, f"corrupt zip archive member {info.filename} ({err})") from None
    crc, out = zlib.crc32(data, crc), out + len(data)
    if data:
        sink(data)
    if left > 0 or not d.eof or crc != info.CRC or out != info.file_size:
        raise AisInputError(path, f"corrupt zip archive member {info.filename}: {out:,} bytes decompressed of "
                                  f"{info.file_size:,}, CRC-32 {'differs' if crc != info.CRC else 'matches'}")
    return out


def _copy_stream(path, info: zipfile.ZipInfo, sink, chunk: int) -> int:
    """A member stored, or compressed by another method, through :mod:`zipfile` (which checks
    its CRC-32 at the end)."""
    try:
        with open_member(path) as fh:
            return pump(fh, sink, chunk)
    except (zipfile.BadZipFile, EOFError, OSError) as err:
        raise AisInputError(path, f"corrupt zip archive member {info.filename} ({err})") from None


def pump(fh, sink, chunk: int) -> int:
    """Pass a readable stream's content to ``sink`` block by block; returns its size."""
    out = 0
    while block := fh.read(chunk):
        sink(block)
        out += len(block)
    return out
