"""Raw NMEA 0183 AIS (``!xxVDM`` / ``!xxVDO``) into the typed stage.

What one *item* of the stage is (the unit of ``read``):

* every AIS message after multipart assembly (one row, ``line`` = the line of its first
  sentence, ``raw`` = its sentences joined by ``\\n``);
* every sentence or fragment group that cannot form a message (bad checksum, a fragment with
  no start or out of order, a group still incomplete at the end of the file, an unparsable
  ``!`` line, or a line that is not NMEA at all) - one quarantined row each.

Messages 1, 2, 3, 18, 19 and 27 are position reports (``kind`` "P"). Messages 5 and 24 carry
static data only (``kind`` "S"): they are joined to ``vessels`` by MMSI and counted as
``static``, outside ``read``. Every other message type is read and quarantined as
``other_msg_type`` (no ship position). Lines that carry no AIS item are not counted in
``read``: blank lines, ``$PGHP`` time stamps and stand-alone tag blocks (metadata for the next
sentence) and other NMEA sentences such as ``$PSTT`` (counted as ``ignored``).

Time of a message: the ``c:`` field of its tag block (UNIX seconds), else the ``$PGHP`` line
or stand-alone tag block just before its first sentence; such context applies to the next AIS
sentence only. Messages without time are quarantined as ``bad_time`` by the cleaning.

Two parsers give the same stage: :func:`parse_lines` (a plain loop over the lines, the
reference) and :func:`parse_fast` (used by the ingest): the regular lines (time stamps, tag
blocks, single-sentence messages) are classified with pyarrow compute kernels and only the
irregular ones (fragments of multipart messages, junk) go through the loop's rules; the time
context is propagated with cumulative maxima instead of a loop. Tests compare both on the real
samples and on fuzzed lines.

Every line is first trimmed of ASCII white space. A payload identical to the previous
occurrence of the same position payload in the file, received within 60 s of it (or with an
unknown time), is ``duplicate_payload`` (the same transmission heard twice).

Speed: position messages of the common fixed length (types 1-3 and 18, 168 bits) are decoded
vectorised with numpy straight from the 6-bit payload characters (ITU-R M.1371-5, Annex 2,
Tables 45 and 49); rarer types and odd lengths go through :func:`pyais.decode`. Message types
that are not stored are never decoded. A test checks the vectorised decoder against pyais on
every position message of the real samples.

References
----------
.. [1] ITU-R, Rec. ITU-R M.1371-5, 2014, Annex 2 Sec. 3.3 and Annex 8 (message layouts).
.. [2] IEC 61162-1:2016 (NMEA 0183 sentences, checksum, tag blocks: IEC 61162-450 Annex).
.. [3] Gatehouse, "$PGHP proprietary sentence" as used in the DMA AIS feeds (year, month, day,
       hour, minute, second, millisecond, MID, region, source MMSI).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ais.clean import (
    BAD_CHECKSUM,
    BAD_PAYLOAD,
    BAD_SENTENCE,
    DUPLICATE_PAYLOAD,
    INCOMPLETE_MULTIPART,
    KIND_POSITION,
    KIND_STATIC,
    OTHER_MSG_TYPE,
    conform_stage,
    valid_mmsi,
)
from ais.io.files import read_content
from ais.io.nmea_decode import (  # noqa: F401 (the constants and decoders, re-exported)
    DUPLICATE_WINDOW_S,
    POSITION_TYPES,
    STATIC_TYPES,
    WS,
    _checksum_ok,
    _checksums_ok,
    _decode_with_pyais,
    _position_from_pyais,
    _split_once,
    _static_from_pyais,
    _tag_time,
    decode_positions_168,
)


# ---------------------------------------------------------------------------------------------
# Items: the columns every parser fills, sorted by line before decoding
# ---------------------------------------------------------------------------------------------
class _Items:
    """Column buffers of the stage being built (plain lists: appending is the hot path)."""

    def __init__(self):
        self.line: list[int] = []
        self.raw: list[str] = []
        self.perr: list = []
        self.t: list = []          # datetime64 (numpy) or None
        self.payload: list[str] = []
        self.sentences: list = []  # None for single-sentence messages
        self.single: list[bool] = []  # a single sentence whose checksum is still to be checked

    def add(self, line, raw, perr, t=None, payload="", sentences=None, single=False):
        self.line.append(line)
        self.raw.append(raw)
        self.perr.append(perr)
        self.t.append(t)
        self.payload.append(payload)
        self.sentences.append(sentences)
        self.single.append(single)


_NAT = np.datetime64("NaT", "ns")


def pghp_times(lines: list[str]) -> np.ndarray:
    """UTC times (``datetime64[ns]``, NaT when invalid) of ``$PGHP,1,y,m,d,h,m,s,ms,...`` lines."""
    import pyarrow as pa
    import pyarrow.compute as pc

    n = len(lines)
    out = np.full(n, _NAT, dtype="datetime64[ns]")
    if n == 0:
        return out
    parts = pc.split_pattern(pa.array(lines, pa.string()), ",")
    ok = (pc.list_value_length(parts).to_numpy(zero_copy_only=False) >= 9)
    if not ok.any():
        return out
    parts = parts.filter(pa.array(ok))
    names = ["year", "month", "day", "hour", "minute", "second", "ms"]
    cols = {}
    for k, name in enumerate(names, start=2):
        txt = pc.list_element(parts, k)
        try:
            cols[name] = pc.cast(txt, pa.int64()).to_numpy(zero_copy_only=False)
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
            cols[name] = pd.to_numeric(pd.Series(txt.to_pylist(), dtype=object), errors="coerce").to_numpy()
    ts = pd.to_datetime(pd.DataFrame(cols), errors="coerce")
    out[np.flatnonzero(ok)] = ts.to_numpy(dtype="datetime64[ns]")
    return out


def _tag_dt(tag: str):
    """The ``c:`` time of a tag block body as ``datetime64[ns]``, or None."""
    v = _tag_time(tag) if "c:" in tag else None
    if v is None or not np.isfinite(v) or abs(v) >= 4e9:
        return None
    return np.datetime64(int(round(v * 1000.0)), "ms").astype("datetime64[ns]")


def _other_bang_ignored(s: str, f: list[str]) -> bool:
    """A valid non-AIS ``!`` sentence (e.g. ``!AIABK``): ignored rather than quarantined."""
    return len(f) >= 2 and len(f[0]) == 6 and f[0][3:6].isalpha() and _checksum_ok(s)


class _Multipart:
    """The fragment rules shared by both parsers (for sentences that are not 1-of-1)."""

    def __init__(self, items: _Items):
        self.items = items
        self.buffers: dict = {}

    def _flush(self, key):
        first, t, sents, _ = self.buffers.pop(key)
        self.items.add(first, "\n".join(sents), INCOMPLETE_MULTIPART, t)

    def add(self, lineno: int, s: str, f: list[str], t) -> None:
        add = self.items.add
        if not _checksum_ok(s):
            add(lineno, s, BAD_CHECKSUM, t)
            return
        try:
            cnt, num = int(f[1]), int(f[2])
        except ValueError:
            add(lineno, s, BAD_SENTENCE, t)
            return
        if not (1 <= num <= cnt <= 9):
            add(lineno, s, BAD_SENTENCE, t)
            return
        if cnt == 1:  # "01,1" and the like: a single sentence written unusually
            add(lineno, s, None, t, f[5], None, True)
            return
        key = (f[3], f[4], f[0][1:6], cnt)
        if num == 1:
            if key in self.buffers:
                self._flush(key)
            self.buffers[key] = (lineno, t, [s], [f[5]])
            return
        buf = self.buffers.get(key)
        if buf is None or len(buf[2]) != num - 1:
            add(lineno, s, INCOMPLETE_MULTIPART, t)
            return
        buf[2].append(s)
        buf[3].append(f[5])
        if len(buf[2]) == cnt:
            first, t0, sents, pays = self.buffers.pop(key)
            add(first, "\n".join(sents), None, t0, "".join(pays), sents)

    def finish(self) -> None:
        for key in list(self.buffers):
            self._flush(key)


def parse_lines(lines, progress=None) -> tuple[pd.DataFrame, dict]:
    """Reference parser: NMEA text lines (without line ends) into a typed stage, one line at a
    time. See the module docstring; :func:`parse_fast` gives the same result faster."""
    items = _Items()
    multi = _Multipart(items)
    blank = ignored = 0
    pending_t = None  # a $PGHP line (parsed at the end, all at once) or a datetime64
    step = 50000
    add = items.add

    for lineno, s in enumerate(lines, start=1):
        if progress is not None and lineno % step == 0:
            progress(step)
        s = s.strip(WS)
        if not s:
            blank += 1
            continue
        t_here = None
        if s[0] == "\\":
            end = s.find("\\", 1)
            if end < 0:
                add(lineno, s, BAD_SENTENCE)
                pending_t = None
                continue
            tag = s[1:end]
            t_tag = _tag_dt(tag)
            s = s[end + 1:].strip(WS)
            if not s:
                if t_tag is not None:
                    pending_t = t_tag
                continue
            t_here = t_tag
        c0 = s[0]
        if c0 == "$":
            if s.startswith("$PGHP,1,"):
                pending_t = s
            else:
                ignored += 1
            continue
        if c0 != "!":
            add(lineno, s, BAD_SENTENCE)
            pending_t = None
            continue
        f = s.split(",")
        if len(f) < 7 or f[0][3:6] not in ("VDM", "VDO"):
            if _other_bang_ignored(s, f):
                ignored += 1
            else:
                add(lineno, s, BAD_SENTENCE)
            pending_t = None
            continue
        t = t_here if t_here is not None else pending_t
        pending_t = None
        if f[1] == "1" and f[2] == "1":
            add(lineno, s, None, t, f[5], None, True)
            continue
        multi.add(lineno, s, f, t)
    multi.finish()
    texts = [i for i, x in enumerate(items.t) if isinstance(x, str)]
    if texts:
        parsed = pghp_times([items.t[i] for i in texts])
        for i, v in zip(texts, parsed):
            items.t[i] = None if np.isnat(v) else v
    order = np.argsort(np.asarray(items.line, dtype=np.int64), kind="stable")
    for name in ("line", "raw", "perr", "t", "payload", "sentences", "single"):
        col = getattr(items, name)
        setattr(items, name, [col[i] for i in order])
    stage, counts = _decode_items(items)
    meta = {"ignored": ignored + blank, "blank_lines": blank, "other_sentences": ignored, **counts}
    return stage, meta


class Carry:
    """What :func:`parse_fast` carries from one chunk of a file's lines to the next
    (:mod:`ais.io.nmea_chunks`): the first line's number, the multipart groups still open, the
    time context waiting for the next AIS sentence, and whether this chunk is the last."""

    def __init__(self):
        self.first_line = 1
        self.buffers: dict = {}
        self.ctx_t = _NAT
        self.last = False


def parse_fast(lines: list[str], carry: Carry | None = None) -> tuple[pd.DataFrame, dict]:
    """Vectorised parser with the same result as :func:`parse_lines` (see the module docstring).
    With ``carry`` the lines are one chunk of a file (updated for the next; duplicates not
    marked: :func:`_decode_columns` without ``dedupe``)."""
    # Long by design: one column-wise pass (pyarrow kernels) over the lines whose steps share
    # the same masks; its plain-loop twin :func:`parse_lines` is the readable reference.
    import pyarrow as pa
    import pyarrow.compute as pc

    n = len(lines)
    items = _Items()
    if n == 0 and carry is None:
        stage, counts = _decode_items(items)
        return stage, {"ignored": 0, "blank_lines": 0, "other_sentences": 0, **counts}
    base = 0 if carry is None else carry.first_line - 1
    s = pc.utf8_trim(pa.array(lines, pa.string()), characters=WS)
    blank = pc.equal(pc.utf8_length(s), 0).to_numpy(zero_copy_only=False)
    is_tag = pc.starts_with(s, "\\").to_numpy(zero_copy_only=False)
    m = pc.extract_regex(s, r"^\\(?P<tag>[^\\]*)\\(?P<rest>.*)$")
    matched = m.is_valid().to_numpy(zero_copy_only=False) & is_tag
    rest = pc.utf8_trim(pc.struct_field(m, "rest"), characters=WS)
    body = pc.if_else(pa.array(matched), rest, s)
    bad_tag = is_tag & ~matched
    standalone = matched & pc.equal(pc.utf8_length(body), 0).to_numpy(zero_copy_only=False)

    # Tag times (c:), only where a tag carries one.
    tag_t = np.full(n, _NAT, dtype="datetime64[ns]")
    tags = pc.struct_field(m, "tag")
    has_c = matched & pc.fill_null(pc.match_substring(tags, "c:"), False).to_numpy(zero_copy_only=False)
    idx_c = np.flatnonzero(has_c)
    if len(idx_c):
        tag_list = tags.take(pa.array(idx_c)).to_pylist()
        for i, tg in zip(idx_c, tag_list):
            v = _tag_dt(tg)
            if v is not None:
                tag_t[i] = v
    has_tag_t = ~np.isnat(tag_t)

    first = pc.utf8_slice_codeunits(body, 0, 1)
    dollar = pc.equal(first, "$").to_numpy(zero_copy_only=False) & ~bad_tag
    bang = pc.equal(first, "!").to_numpy(zero_copy_only=False) & ~bad_tag
    pghp = dollar & pc.starts_with(body, "$PGHP,1,").to_numpy(zero_copy_only=False)
    junk = ~blank & ~standalone & ~dollar & ~bang  # includes unterminated tags
    ais = bang & pc.match_substring_regex(body, r"^!..VD[MO][^,]*,").to_numpy(zero_copy_only=False) & (
        pc.count_substring(body, ",").to_numpy(zero_copy_only=False) >= 6)
    other_bang = bang & ~ais

    # Time context: the latest context line after the latest resetting line.
    ctx = pghp | (standalone & has_tag_t)
    reset = bang | junk
    pos = np.arange(n)
    last_ctx = np.maximum.accumulate(np.where(ctx, pos, -1))
    last_reset = np.maximum.accumulate(np.where(reset, pos, -1))
    prev_ctx = np.concatenate([[-1], last_ctx[:-1]])
    prev_reset = np.concatenate([[-1], last_reset[:-1]])
    ctx_t = tag_t.copy()
    idx_p = np.flatnonzero(pghp)
    if len(idx_p):
        ctx_t[idx_p] = pghp_times(body.take(pa.array(idx_p)).to_pylist())
    use = (prev_ctx >= 0) & (prev_ctx > prev_reset)
    t_line = np.full(n, _NAT, dtype="datetime64[ns]")
    t_line[use] = ctx_t[prev_ctx[use]]
    if carry is not None:  # the context left by the chunk before
        t_line[(prev_ctx < 0) & (prev_reset < 0)] = carry.ctx_t
        if n and last_ctx[-1] > last_reset[-1]:
            carry.ctx_t = ctx_t[last_ctx[-1]]
        elif n and last_reset[-1] >= 0:
            carry.ctx_t = _NAT
    inline = matched & ~standalone & has_tag_t
    t_line[inline] = tag_t[inline]

    # Single-sentence AIS messages: vectorised. Everything else in line order with the loop's rules.
    idx_a = np.flatnonzero(ais)
    single = np.zeros(n, dtype=bool)
    payload_all = None
    if len(idx_a):
        parts = pc.split_pattern(body.take(pa.array(idx_a)), ",")
        f1 = pc.list_element(parts, 1).to_numpy(zero_copy_only=False)
        f2 = pc.list_element(parts, 2).to_numpy(zero_copy_only=False)
        sing = (f1 == "1") & (f2 == "1")
        single[idx_a[sing]] = True
        payload_all = pc.list_element(parts, 5)
        payload_single = payload_all.filter(pa.array(sing))
    idx_s = np.flatnonzero(single)
    irregular = np.flatnonzero(junk | other_bang | (ais & ~single))
    multi = _Multipart(items)
    if carry is not None:
        multi.buffers = carry.buffers
    if len(irregular):
        bodies = body.take(pa.array(irregular)).to_pylist()
        for i, b in zip(irregular, bodies):
            lineno = int(i) + 1 + base
            if junk[i]:
                items.add(lineno, b if not bad_tag[i] else b, BAD_SENTENCE)
                continue
            f = b.split(",")
            if other_bang[i]:
                if not _other_bang_ignored(b, f):
                    items.add(lineno, b, BAD_SENTENCE)
                continue
            multi.add(lineno, b, f, None if np.isnat(t_line[i]) else t_line[i])
    if carry is None or carry.last:
        multi.finish()
    ignored_other = int(np.sum(dollar & ~pghp)) + sum(
        1 for i in np.flatnonzero(other_bang) if _other_bang_ignored(*_split_once(body, i)))
    n_blank = int(blank.sum())

    # Merge the vectorised singles with the loop's items, in line order.
    k = len(idx_s)
    line = np.concatenate([idx_s + 1 + base, np.asarray(items.line, dtype=np.int64)])
    raw = body.take(pa.array(idx_s)).to_pylist() + items.raw if k else list(items.raw)
    perr = [None] * k + items.perr
    t = np.concatenate([t_line[idx_s], np.array([_NAT if x is None else x for x in items.t], dtype="datetime64[ns]")])
    payload = (payload_single.to_pylist() if k else []) + items.payload
    sentences = [None] * k + items.sentences
    single_flag = np.concatenate([np.ones(k, dtype=bool), np.asarray(items.single, dtype=bool)])
    order = np.argsort(line, kind="stable")
    # Items out of line order (a multipart group flushed after later lines) are reordered
    # whether or not vectorised singles were merged in.
    if len(order) and not np.all(order == np.arange(len(order))):
        raw = [raw[i] for i in order]
        perr = [perr[i] for i in order]
        payload = [payload[i] for i in order]
        sentences = [sentences[i] for i in order]
    stage, counts = _decode_columns(line[order], raw, perr, t[order], payload, sentences, single_flag[order],
                                    dedupe=carry is None)
    if carry is not None:
        carry.first_line += n
    meta = {"ignored": ignored_other + n_blank, "blank_lines": n_blank, "other_sentences": ignored_other, **counts}
    return stage, meta


def _decode_items(items: _Items) -> tuple[pd.DataFrame, dict]:
    n = len(items.line)
    t = np.array([_NAT if x is None else x for x in items.t], dtype="datetime64[ns]") if n else np.empty(0, "datetime64[ns]")
    return _decode_columns(np.asarray(items.line, dtype=np.int64), items.raw, items.perr, t, items.payload,
                           items.sentences, np.asarray(items.single, dtype=bool))


def duplicate_mask(payloads: list[str], t: np.ndarray) -> np.ndarray:
    """Which of the position payloads ``payloads`` (in line order, received at ``t``) are the
    same transmission heard twice: identical to the payload's previous occurrence, within
    :data:`DUPLICATE_WINDOW_S` of it or with either time unknown."""
    codes, _ = pd.factorize(np.asarray(payloads, dtype=object))
    order = np.lexsort((np.arange(len(payloads)), codes))
    same = np.zeros(len(payloads), dtype=bool)
    same[1:] = codes[order][1:] == codes[order][:-1]
    tc = np.asarray(t)[order]
    prev = np.concatenate([[_NAT], tc[:-1]]).astype(tc.dtype)
    gap = np.abs((tc - prev) / np.timedelta64(1, "s"))
    dup_sorted = same & (np.isnat(tc) | np.isnat(prev) | (gap <= DUPLICATE_WINDOW_S))
    dup = np.zeros(len(payloads), dtype=bool)
    dup[order] = dup_sorted
    return dup


def _decode_columns(line, raw, perr, t, payloads, sentences, single, dedupe: bool = True) -> tuple[pd.DataFrame, dict]:
    """Checksums of single sentences, message types, duplicates, decoding; the typed stage.
    Without ``dedupe`` no payload is marked a duplicate: the stage has a ``dup_payload`` column
    (each duplicate candidate's payload) for :func:`ais.io.nmea_chunks.mark_duplicates`."""
    # Long by design: the typed stage built column by column from the assembled messages (each
    # block fills one group of stage columns for the same rows).
    n = len(line)
    perr = np.asarray(perr, dtype=object) if n else np.empty(0, dtype=object)
    if single.any():
        idx = np.flatnonzero(single)
        bad = ~_checksums_ok([raw[i] for i in idx]) if len(idx) < n else ~_checksums_ok(raw)
        perr[idx[bad]] = BAD_CHECKSUM
    first = np.frombuffer("".join([p[:1] or "\x00" for p in payloads]).encode("latin-1", errors="replace"),
                          dtype=np.uint8).astype(np.int64) - 48
    mtype = np.where(first > 40, first - 8, first)
    mtype = np.where(np.equal(perr, None), mtype, -1)
    kind = np.full(n, KIND_POSITION, dtype=object)

    cols = {k: np.full(n, np.nan) for k in ("lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "nav_status",
                                            "length_m", "beam_m", "draught_m")}
    mmsi = np.full(n, -1, dtype=np.int64)
    statics = {k: np.full(n, None, dtype=object) for k in ("imo", "name", "callsign", "ship_type", "destination")}

    perr0 = perr.copy()
    open_ = np.equal(perr, None)
    lens = np.fromiter(map(len, payloads), dtype=np.int64, count=n)
    empty = open_ & (lens == 0)
    perr[empty] = BAD_PAYLOAD
    open_ &= ~empty

    # A position payload identical to its previous occurrence, heard within the window (or with
    # an unknown time): the same transmission received twice.
    cand = np.flatnonzero(open_ & np.isin(mtype, list(POSITION_TYPES)))
    dup_payload = None
    if not dedupe:  # left to the caller, which holds every row of the payloads' vessels
        dup_payload = np.full(n, None, dtype=object)
        dup_payload[cand] = [payloads[i] for i in cand]
    elif len(cand):
        dup = duplicate_mask([payloads[i] for i in cand], t[cand])
        perr[cand[dup]] = DUPLICATE_PAYLOAD
        open_[cand[dup]] = False

    other = open_ & ~np.isin(mtype, list(POSITION_TYPES | STATIC_TYPES))
    perr[other] = OTHER_MSG_TYPE
    open_ &= ~other

    no_parts = np.fromiter((x is None for x in sentences), dtype=bool, count=n)
    fast = open_ & np.isin(mtype, [1, 2, 3, 18]) & (lens == 28) & no_parts
    idx = np.flatnonzero(fast)
    if len(idx):
        dec = decode_positions_168([payloads[i] for i in idx], mtype[idx])
        good = dec["ok"]
        perr[idx[~good]] = BAD_PAYLOAD
        gi = idx[good]
        mmsi[gi] = dec["mmsi"][good]
        for k in ("lat_deg", "lon_deg", "sog_kn", "cog_deg", "heading_deg", "nav_status"):
            cols[k][gi] = dec[k][good]
    n_static = 0
    for i in np.flatnonzero(open_ & ~fast):
        sents = sentences[i] if sentences[i] is not None else [raw[i]]
        msg = _decode_with_pyais(sents)
        if msg is None:
            perr[i] = BAD_PAYLOAD
            continue
        if mtype[i] in STATIC_TYPES:
            st = _static_from_pyais(msg)
            kind[i] = KIND_STATIC
            n_static += 1
            mmsi[i] = st.pop("mmsi")
            for k, v in st.items():
                if k in cols:
                    cols[k][i] = v
                else:
                    statics[k][i] = v
        else:
            pos = _position_from_pyais(msg)
            if pos is None:
                perr[i] = BAD_PAYLOAD
                continue
            mmsi[i] = pos.pop("mmsi")
            for k, v in pos.items():
                cols[k][i] = v

    # Static messages whose payload failed to decode stay position-kind items (quarantined).
    df = pd.DataFrame({
        "line": np.asarray(line, dtype=np.int64),
        "raw": np.asarray(raw, dtype=object),
        "kind": kind,
        "parse_error": perr,
        "mmsi": pd.array(np.where(mmsi >= 0, mmsi, 0), dtype="Int64"),
        "time_utc": pd.DatetimeIndex(t).tz_localize("UTC"),
        **cols,
        **statics,
    })
    df.loc[mmsi < 0, "mmsi"] = pd.NA
    assembled = ~np.isin(perr0, [BAD_SENTENCE, BAD_CHECKSUM, INCOMPLETE_MULTIPART])
    types, freq = np.unique(mtype[assembled], return_counts=True)
    counts = {"messages": int(assembled.sum()),
              "position_messages": int(np.sum(assembled & np.isin(mtype, list(POSITION_TYPES)))),
              "msg_types": {int(k): int(v) for k, v in zip(types, freq)},
              "static": n_static}
    df = conform_stage(df)
    if dup_payload is not None:
        df["dup_payload"] = dup_payload
    return df, counts


def iter_lines(path) -> list[str]:
    """Physical lines of a (possibly gzipped) text file: split on ``\\n``, non-ASCII bytes
    replaced (NMEA is ASCII). A final newline does not add a line."""
    data = read_content(path)
    lines = data.decode("ascii", errors="replace").split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    return lines


def read_nmea(path, progress=None, fast: bool = True) -> tuple[pd.DataFrame, dict]:
    """Read an NMEA AIS file (gzip transparent) into a typed stage.

    Returns
    -------
    (pandas.DataFrame, dict)
        The typed stage and metadata: ``format``, ``path``, ``ignored`` (blank lines and
        non-AIS sentences), ``messages``, ``position_messages``, ``msg_types``, ``static``.
    """
    lines = iter_lines(path)
    stage, meta = parse_fast(lines) if fast else parse_lines(lines, progress=progress)
    if progress is not None and fast:
        progress(len(lines))
    stage, meta = orphan_statics(stage, meta)
    return stage, {"format": "nmea", "path": str(Path(path)), **meta}


def orphan_statics(stage: pd.DataFrame, meta: dict) -> tuple[pd.DataFrame, dict]:
    """A static message (5, 24) with no valid ship MMSI can be joined to no vessel: it is a
    message like any position report, quarantined as bad_mmsi, rather than lost."""
    orphan = (stage["kind"].to_numpy() == KIND_STATIC) & ~valid_mmsi(stage["mmsi"])
    if orphan.any():
        stage.loc[orphan, "kind"] = KIND_POSITION
        meta = {**meta, "static": int(meta["static"]) - int(orphan.sum())}
    return stage, meta
