"""FASTRAK P&O data records: output-list layouts, vectorised decoding and encoding.

A data record is a 3-byte header (``'0'``, station ``'1'``-``'4'``, status character) followed by
the items of the station's output list (``O`` command) in order. In ASCII (``F``) numbers are
fixed-width text that may touch (``"  10.00-150.25"``); in binary (``f``) every number is a
little-endian float32. Items 0/50 (a space) and 1/51 (CR LF) are literal bytes in both formats and
serve as the record terminator that resynchronisation relies on.

Decoding works on a whole byte buffer at once: every offset whose header and literal bytes match is
a candidate, candidates are decoded and checked for plausibility with numpy, and the valid ones are
accepted greedily from the left (a record consumes its bytes; an invalid offset costs one byte).
This gives exactly the result of the "drop one byte and rescan" scanner, at numpy speed.

Orientation conventions (manual p.C-1): Euler angles are azimuth about Z, then elevation about
the new Y, then roll about the new X, so ``R = Rz(az) @ Ry(el) @ Rx(roll)``; quaternions are
scalar-first; the three direction-cosine items are the rows of ``R``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from hubo_cli.errors import InputError, quoted
from hubo_cli.geometry import (
    fastrak_euler_deg_to_quat_wxyz,
    matrix_to_fastrak_euler_deg,
    matrix_to_quat_wxyz,
    quat_wxyz_to_matrix,
)

FORMATS = ("ascii", "binary")
UNIT_SCALE_M = {"cm": 0.01, "in": 0.0254}
"""Metres per device position unit: ``u`` selects centimetres, ``U`` inches."""

STATUS_OK_CHARS = b" " + bytes(range(ord("a"), ord("z") + 1)) + bytes(range(ord("A"), ord("Z") + 1))
"""Status byte values a record may carry: a space when healthy, else a BIT error letter."""

SUSPECT_STATUS = frozenset("xyjk")
"""Status letters that make a pose suspect: outside the motion/angle envelope, signal trouble."""


@dataclass(frozen=True)
class Item:
    """One output-list item: what it holds and how it is written.

    Attributes:
        code: the item number of the ``O`` command.
        kind: ``space``, ``crlf``, ``position``, ``relative``, ``euler``, ``dcos_x``, ``dcos_y``,
            ``dcos_z``, ``quaternion`` or ``stylus``.
        count: numbers carried (0 for literals and the stylus flag).
        ascii_width: characters per number in ASCII (7 standard, 14 extended precision).
        decimals: digits after the point in the standard ASCII format.
    """

    code: int
    kind: str
    count: int = 0
    ascii_width: int = 7
    decimals: int = 2


_ITEMS: dict[int, Item] = {
    0: Item(0, "space"),
    1: Item(1, "crlf"),
    2: Item(2, "position", 3, 7, 2),
    3: Item(3, "relative", 3, 7, 2),
    4: Item(4, "euler", 3, 7, 2),
    5: Item(5, "dcos_x", 3, 7, 4),
    6: Item(6, "dcos_y", 3, 7, 4),
    7: Item(7, "dcos_z", 3, 7, 4),
    11: Item(11, "quaternion", 4, 7, 4),
    16: Item(16, "stylus"),
    50: Item(50, "space"),
    51: Item(51, "crlf"),
    52: Item(52, "position", 3, 14),
    53: Item(53, "relative", 3, 14),
    54: Item(54, "euler", 3, 14),
    55: Item(55, "dcos_x", 3, 14),
    56: Item(56, "dcos_y", 3, 14),
    57: Item(57, "dcos_z", 3, 14),
    61: Item(61, "quaternion", 4, 14),
}
SUPPORTED_ITEMS = tuple(sorted(_ITEMS))


@dataclass(frozen=True)
class Field:
    """One item placed in a record: ``offset`` bytes from the record start, ``size`` bytes long."""

    item: Item
    offset: int
    size: int


@dataclass(frozen=True)
class Plausibility:
    """Limits a decoded record must meet to be accepted (resynchronisation relies on them).

    Attributes:
        max_position_m: largest position component magnitude, metres (the default motion box is
            +-2 m; the long-range limit of the device is about 3 m).
        max_azimuth_deg, max_elevation_deg, max_roll_deg: Euler angle magnitudes, degrees.
        unit_norm_tol: allowed departure of a quaternion's (or direction-cosine row's) norm
            from 1 (ASCII keeps four decimals).
    """

    max_position_m: float = 3.0
    max_azimuth_deg: float = 180.5
    max_elevation_deg: float = 90.5
    max_roll_deg: float = 180.5
    unit_norm_tol: float = 0.02


DEFAULT_PLAUSIBILITY = Plausibility()


class RecordLayout:
    """The byte layout of one data record for an output list in ASCII or binary.

    Build with :func:`make_layout` (cached). ``length`` is the record size in bytes,
    ``literals`` the (offset, byte) pairs that must match (header ``'0'`` and the space/CR LF
    items), ``orientation`` the item kind the pose's rotation is taken from.
    """

    def __init__(self, fmt: str, output_list: tuple[int, ...]) -> None:
        self.fmt = fmt
        self.output_list = output_list
        fields: list[Field] = []
        offset = 3
        for code in output_list:
            item = _ITEMS[code]
            size = self._item_size(item)
            fields.append(Field(item, offset, size))
            offset += size
        self.fields = tuple(fields)
        self.length = offset
        kinds = {f.item.kind: f for f in fields}
        self.by_kind = kinds
        literals: list[tuple[int, int]] = [(0, 0x30)]
        for f in fields:
            if f.item.kind == "space":
                literals.append((f.offset, 0x20))
            elif f.item.kind == "crlf":
                literals += [(f.offset, 0x0D), (f.offset + 1, 0x0A)]
            elif f.item.kind == "stylus" and fmt == "binary":
                literals.append((f.offset, 0x20))
        self.literals = tuple(literals)
        if "quaternion" in kinds:
            self.orientation = "quaternion"
        elif all(k in kinds for k in ("dcos_x", "dcos_y", "dcos_z")):
            self.orientation = "dcos"
        else:
            self.orientation = "euler"
        self._ascii_allowed = self._ascii_table() if fmt == "ascii" else None
        # In ASCII ending in its only CR LF, no valid record can overlap another (CR and LF
        # never occur inside one), so the overlap tie-break of the scanner is not needed.
        crlf_count = sum(f.item.kind == "crlf" for f in fields)
        self.competitor_possible = not (fmt == "ascii" and fields[-1].item.kind == "crlf"
                                        and crlf_count == 1)

    def _item_size(self, item: Item) -> int:
        if item.kind == "space":
            return 1
        if item.kind == "crlf":
            return 2
        if item.kind == "stylus":
            return 1 if self.fmt == "ascii" else 2
        return item.count * (item.ascii_width if self.fmt == "ascii" else 4)

    def _ascii_table(self) -> np.ndarray:
        """(length, 256) bool: which byte values each column of an ASCII record may hold."""
        table = np.ones((self.length, 256), dtype=bool)
        number = np.zeros(256, dtype=bool)
        number[list(b" +-.0123456789")] = True
        extended = number.copy()
        extended[list(b"Ee")] = True
        for f in self.fields:
            kind = f.item.kind
            if kind == "stylus":
                table[f.offset] = False
                table[f.offset, list(b"01")] = True
            elif f.item.count:
                width = f.item.ascii_width
                allowed = extended if width == 14 else number
                table[f.offset:f.offset + f.size] = allowed
                if width == 7:
                    # Sxxx.xx has its point at column 4, Sx.xxxx at column 2
                    point = 7 - f.item.decimals - 1
                    for k in range(f.item.count):
                        col = f.offset + k * width + point
                        table[col] = False
                        table[col, ord(".")] = True
        return table

    @property
    def terminated(self) -> bool:
        """True if the record ends with a literal (space or CR LF) item."""
        return self.fields[-1].item.kind in ("space", "crlf")

    def describe(self) -> str:
        """Short text such as ``binary 2,11,1 (33 bytes)``."""
        return f"{self.fmt} {','.join(map(str, self.output_list))} ({self.length} bytes)"


def parse_output_list(text: str | tuple[int, ...] | list[int]) -> tuple[int, ...]:
    """Turn ``"2,11,1"`` (or a sequence of ints) into an output-list tuple, checking the items."""
    if isinstance(text, str):
        try:
            items = tuple(int(part) for part in text.replace(" ", "").split(",") if part != "")
        except ValueError:
            raise InputError(
                f"output list {quoted(text)} is not a comma-separated list of item numbers",
                hint="write it like the O command, e.g. 2,11,1",
            ) from None
    else:
        items = tuple(int(v) for v in text)
    return items


@functools.lru_cache(maxsize=64)
def _make_layout_cached(fmt: str, output_list: tuple[int, ...]) -> RecordLayout:
    return RecordLayout(fmt, output_list)


def make_layout(fmt: str, output_list) -> RecordLayout:
    """Return the :class:`RecordLayout` for ``fmt`` (``ascii``/``binary``) and an output list.

    Raises:
        InputError: unknown format or item, no position or orientation item, or no terminator.
    """
    if fmt not in FORMATS:
        raise InputError(f"unknown FASTRAK record format {quoted(fmt)}",
                         hint="use ascii or binary")
    items = parse_output_list(output_list)
    listed = quoted(",".join(map(str, items))) if items else "(empty)"
    unknown = sorted({c for c in items if c not in _ITEMS})
    if unknown:
        raise InputError(
            f"output list {listed} has unsupported item(s) {quoted(unknown)}",
            hint=f"supported items: {', '.join(map(str, SUPPORTED_ITEMS))}",
        )
    kinds = [_ITEMS[c].kind for c in items]
    if "position" not in kinds:
        raise InputError(f"output list {listed} has no position item",
                         hint="include 2 (or 52 for extended precision)")
    has_rotation = ("quaternion" in kinds or "euler" in kinds
                    or all(k in kinds for k in ("dcos_x", "dcos_y", "dcos_z")))
    if not has_rotation:
        raise InputError(f"output list {listed} has no orientation item",
                         hint="include 11 (quaternion), 4 (Euler) or 5,6,7 (direction cosines)")
    if kinds[-1] not in ("space", "crlf"):
        raise InputError(f"output list {listed} does not end with a terminator item",
                         hint="end the list with 1 (CR LF) or 0 (a space) so records can be "
                              "checked")
    return _make_layout_cached(fmt, items)


# ---------------------------------------------------------------------------------------------
# Decoded records


@dataclass
class RecordBatch:
    """Decoded data records, one row per record, in stream order.

    Attributes:
        station: (N,) station numbers 1..4.
        status: (N,) status bytes (``ord(" ")`` when healthy).
        position_m: (N,3) sensor position in the transmitter frame, metres.
        quat_wxyz: (N,4) sensor orientation, unit quaternion, scalar first.
        stylus: (N,) stylus switch 0/1, or -1 when the output list has no stylus item.
        offset: (N,) byte offset of each record's first byte in the stream.
        t_s: (N,) receive time of each record, seconds since the stream started.
    """

    station: np.ndarray
    status: np.ndarray
    position_m: np.ndarray
    quat_wxyz: np.ndarray
    stylus: np.ndarray
    offset: np.ndarray
    t_s: np.ndarray

    def __len__(self) -> int:
        return int(self.station.shape[0])

    @staticmethod
    def empty() -> RecordBatch:
        """A batch with no records."""
        return RecordBatch(np.zeros(0, np.int64), np.zeros(0, np.uint8), np.zeros((0, 3)),
                           np.zeros((0, 4)), np.zeros(0, np.int8), np.zeros(0, np.int64),
                           np.zeros(0))

    @staticmethod
    def concat(batches: list[RecordBatch]) -> RecordBatch:
        """Join batches in order."""
        batches = [b for b in batches if len(b)]
        if not batches:
            return RecordBatch.empty()
        if len(batches) == 1:
            return batches[0]
        return RecordBatch(*(np.concatenate([getattr(b, name) for b in batches])
                             for name in ("station", "status", "position_m", "quat_wxyz",
                                          "stylus", "offset", "t_s")))

    def select(self, mask: np.ndarray) -> RecordBatch:
        """The rows where ``mask`` (bool or index array) selects."""
        return RecordBatch(self.station[mask], self.status[mask], self.position_m[mask],
                           self.quat_wxyz[mask], self.stylus[mask], self.offset[mask],
                           self.t_s[mask])

    def transforms(self) -> np.ndarray:
        """(N,4,4) homogeneous transforms ``T_tracker_sensor``, metres."""
        T = np.zeros((len(self), 4, 4))
        T[:, :3, :3] = quat_wxyz_to_matrix(self.quat_wxyz) if len(self) else np.zeros((0, 3, 3))
        T[:, :3, 3] = self.position_m
        T[:, 3, 3] = 1.0
        return T

    def status_chars(self) -> list[str]:
        """The status characters as one-letter strings."""
        return [chr(c) for c in self.status.tolist()]


@dataclass
class ScanResult:
    """What one pass over a byte buffer found.

    Attributes:
        batch: the accepted records (``t_s`` left at zero; the caller stamps times).
        consumed: bytes at the front of the buffer that are decided (records or skipped bytes);
            the rest may still be the start of a record that is not complete yet.
        bad_bytes: bytes among ``consumed`` that belonged to no accepted record.
    """

    batch: RecordBatch
    consumed: int
    bad_bytes: int


_STATUS_OK = np.zeros(256, dtype=bool)
_STATUS_OK[list(STATUS_OK_CHARS)] = True


def station_table(stations=(1, 2, 3, 4)) -> np.ndarray:
    """256-entry bool table of the station bytes (``'1'``..``'4'``) that are accepted."""
    table = np.zeros(256, dtype=bool)
    for s in stations:
        if not 1 <= int(s) <= 4:
            raise InputError(f"station {s} is out of range", hint="FASTRAK stations are 1 to 4")
        table[0x30 + int(s)] = True
    return table


def _to_float(fields: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(K,n) fixed-width byte strings -> floats and a per-row ok mask (unparsable -> not ok)."""
    try:
        return fields.astype(np.float64), np.ones(fields.shape[0], dtype=bool)
    except ValueError:
        out = np.full(fields.shape, np.nan)
        ok = np.ones(fields.shape[0], dtype=bool)
        for i, row in enumerate(fields):
            for j, text in enumerate(row):
                try:
                    out[i, j] = float(text)
                except ValueError:
                    ok[i] = False
        return out, ok


def _numbers(layout: RecordLayout, rec: np.ndarray, field: Field) -> tuple[np.ndarray, np.ndarray]:
    """Decode one numeric field of every candidate row: (K,count) values and an ok mask."""
    block = np.ascontiguousarray(rec[:, field.offset:field.offset + field.size])
    if layout.fmt == "binary":
        values = block.view("<f4").astype(np.float64)
        return values, np.ones(rec.shape[0], dtype=bool)
    texts = block.view(f"S{field.item.ascii_width}")
    return _to_float(texts)


def _unit_norm_ok(v: np.ndarray, tol: float) -> np.ndarray:
    return np.abs(np.sqrt(np.sum(v * v, axis=1)) - 1.0) <= tol


def decode_candidates(layout: RecordLayout, rec: np.ndarray, scale_m: float,
                      plaus: Plausibility = DEFAULT_PLAUSIBILITY):
    """Decode (K, length) candidate records; return (ok mask, position_m, quat_wxyz, stylus).

    Rows failing the character, range or norm checks are marked not ok (their values are
    meaningless). Header and literal bytes must already have been checked by the caller.
    """
    k = rec.shape[0]
    ok = np.ones(k, dtype=bool)
    if layout.fmt == "ascii":
        cols = np.arange(layout.length)
        ok &= layout._ascii_allowed[cols, rec].all(axis=1)
        if not ok.all():
            rec = rec[ok]
            keep = np.flatnonzero(ok)
        else:
            keep = None
    else:
        keep = None
    values: dict[str, np.ndarray] = {}
    sub_ok = np.ones(rec.shape[0], dtype=bool)
    with np.errstate(all="ignore"):
        for f in layout.fields:
            if not f.item.count:
                continue
            v, good = _numbers(layout, rec, f)
            sub_ok &= good & np.isfinite(v).all(axis=1)
            values[f.item.kind] = v
        max_units = plaus.max_position_m / scale_m
        sub_ok &= (np.abs(values["position"]) <= max_units).all(axis=1)
        if "relative" in values:
            sub_ok &= (np.abs(values["relative"]) <= max_units).all(axis=1)
        if "euler" in values:
            e = values["euler"]
            sub_ok &= ((np.abs(e[:, 0]) <= plaus.max_azimuth_deg)
                       & (np.abs(e[:, 1]) <= plaus.max_elevation_deg)
                       & (np.abs(e[:, 2]) <= plaus.max_roll_deg))
        if "quaternion" in values:
            sub_ok &= _unit_norm_ok(values["quaternion"], plaus.unit_norm_tol)
        for kind in ("dcos_x", "dcos_y", "dcos_z"):
            if kind in values:
                sub_ok &= _unit_norm_ok(values[kind], plaus.unit_norm_tol)
        stylus = np.full(rec.shape[0], -1, dtype=np.int8)
        if "stylus" in layout.by_kind:
            f = layout.by_kind["stylus"]
            col = rec[:, f.offset + (1 if layout.fmt == "binary" else 0)]
            sub_ok &= (col == 0x30) | (col == 0x31)
            stylus = (col == 0x31).astype(np.int8)
    position = values["position"] * scale_m
    if layout.orientation == "quaternion":
        q = values["quaternion"]
        with np.errstate(all="ignore"):
            q = q / np.linalg.norm(q, axis=1, keepdims=True)
    else:
        safe = np.where(sub_ok)[0]
        q = np.tile([1.0, 0.0, 0.0, 0.0], (rec.shape[0], 1))
        if safe.size:
            if layout.orientation == "dcos":
                R = np.stack([values["dcos_x"][safe], values["dcos_y"][safe],
                              values["dcos_z"][safe]], axis=1)
                q[safe] = matrix_to_quat_wxyz(R)
            else:
                q[safe] = fastrak_euler_deg_to_quat_wxyz(values["euler"][safe])
    if keep is not None:
        full_ok = np.zeros(k, dtype=bool)
        full_ok[keep] = sub_ok
        pos_full = np.zeros((k, 3))
        pos_full[keep] = position
        q_full = np.tile([1.0, 0.0, 0.0, 0.0], (k, 1))
        q_full[keep] = q
        st_full = np.full(k, -1, dtype=np.int8)
        st_full[keep] = stylus
        return full_ok, pos_full, q_full, st_full
    return sub_ok, position, q, stylus


def _select(valid: np.ndarray, length: int, size: int, final: bool,
            header: np.ndarray | None) -> tuple[np.ndarray, int | None]:
    """Choose records among sorted valid starts, as the one-byte-at-a-time scanner would.

    A valid start is taken unless it lies inside the record taken before it. When another valid
    start ``w`` lies inside its span (binary layouts only: a record cut short followed by the
    next record's header can pass every check), the start whose following bytes begin a record
    header wins, i.e. the one that keeps the stream in step. Deciding that needs the bytes up to
    two records ahead, so a non-final scan stops there and waits for them.

    Args:
        valid: sorted offsets of valid records.
        length: record length, bytes.
        size: bytes in the buffer.
        final: no more bytes will come.
        header: per offset, whether 3 header-like bytes start there (None: no competition
            possible for this layout).

    Returns:
        (keep mask over ``valid``, offset to resume from when waiting, else None).
    """
    keep = np.ones(valid.size, dtype=bool)
    inside = None
    if header is not None and valid.size:
        m = header.size
        counts = np.concatenate([[0], np.cumsum(header)])
        inside = counts[np.minimum(valid + length, m)] - counts[np.minimum(valid + 1, m)]
        if not inside.any():
            inside = None
    if inside is None and (valid.size < 2 or (np.diff(valid) >= length).all()):
        return keep, None
    if inside is not None:
        m = header.size
        after = valid + length
        confirmed = (after < m) & header[np.minimum(after, m - 1)]
        confirmed_starts = valid[confirmed]
    nxt = -1
    for i, v in enumerate(valid.tolist()):
        if v < nxt:
            keep[i] = False
            continue
        if inside is not None and inside[i] > 0:
            if not final and v + 2 * length + 2 > size:
                keep[i:] = False
                return keep, v
            if not confirmed[i]:
                j = int(np.searchsorted(confirmed_starts, v, side="right"))
                if j < confirmed_starts.size and confirmed_starts[j] < v + length:
                    keep[i] = False
                    continue
        nxt = v + length
    return keep, None


def scan(data, layout: RecordLayout, units: str, stations=(1, 2, 3, 4), *, final: bool = False,
         plaus: Plausibility = DEFAULT_PLAUSIBILITY,
         station_ok: np.ndarray | None = None) -> ScanResult:
    """Find every valid record in ``data`` (bytes-like), resynchronising one byte at a time.

    Args:
        data: the bytes to scan (a stream prefix; may start or end inside a record).
        layout: the record layout the device was configured with.
        units: ``cm`` or ``in`` (positions are returned in metres).
        stations: station numbers whose records are accepted.
        final: the stream ends here, so a trailing partial record counts as skipped bytes.
        plaus: plausibility limits.
        station_ok: precomputed :func:`station_table` (overrides ``stations``).

    Returns:
        A :class:`ScanResult`; records carry byte offsets relative to ``data``.
    """
    buf = np.frombuffer(data, dtype=np.uint8) if not isinstance(data, np.ndarray) else data
    size = buf.shape[0]
    length = layout.length
    n = size - length + 1
    if n <= 0:
        consumed = size if final else 0
        return ScanResult(RecordBatch.empty(), consumed, consumed)
    table = station_table(stations) if station_ok is None else station_ok
    m = size - 2
    header = (buf[:m] == 0x30) & table[buf[1:m + 1]] & _STATUS_OK[buf[2:m + 2]]
    mask = header[:n].copy()
    for off, byte in layout.literals[1:]:
        mask &= buf[off:off + n] == byte
    cand = np.flatnonzero(mask)
    stop = None
    if cand.size:
        rec = buf[cand[:, None] + np.arange(length)]
        ok, pos, q, stylus = decode_candidates(layout, rec, UNIT_SCALE_M[units], plaus)
        valid = cand[ok]
        keep, stop = _select(valid, length, size, final,
                             header if layout.competitor_possible else None)
        starts = valid[keep]
        idx = np.flatnonzero(ok)[keep]
        batch = RecordBatch(
            station=(buf[starts + 1].astype(np.int64) - 0x30), status=buf[starts + 2].copy(),
            position_m=pos[idx], quat_wxyz=q[idx], stylus=stylus[idx],
            offset=starts.astype(np.int64), t_s=np.zeros(starts.shape[0]))
    else:
        batch = RecordBatch.empty()
    end_last = int(batch.offset[-1]) + length if len(batch) else 0
    if final:
        consumed = size
    elif stop is not None:
        consumed = stop
    else:
        consumed = max(end_last, n)
    return ScanResult(batch, consumed, consumed - len(batch) * length)


# ---------------------------------------------------------------------------------------------
# Encoding (the emulator and the sample writers use this, so recordings are the real format)


def _record_numbers(layout: RecordLayout, position_m: np.ndarray, quat_wxyz: np.ndarray,
                    units: str, relative_m: np.ndarray | None) -> dict[str, np.ndarray]:
    """Every number kind the layout needs, in device units, for (N,) records."""
    scale = UNIT_SCALE_M[units]
    q = quat_wxyz / np.linalg.norm(quat_wxyz, axis=1, keepdims=True)
    numbers = {"position": position_m / scale, "quaternion": q,
               "relative": (np.zeros_like(position_m) if relative_m is None
                            else np.asarray(relative_m, dtype=np.float64).reshape(-1, 3) / scale)}
    kinds = {f.item.kind for f in layout.fields}
    if kinds & {"euler", "dcos_x", "dcos_y", "dcos_z"}:
        R = quat_wxyz_to_matrix(q)
        numbers["euler"] = matrix_to_fastrak_euler_deg(R)
        numbers["dcos_x"], numbers["dcos_y"], numbers["dcos_z"] = R[:, 0], R[:, 1], R[:, 2]
    return numbers


def encode_records(layout: RecordLayout, stations, position_m, quat_wxyz, units: str,
                   status: str = " ", stylus=None, relative_m=None) -> list[bytes]:
    """Encode N data records exactly as the device writes them.

    Args:
        layout: record layout (format and output list).
        stations: (N,) station numbers 1..4.
        position_m: (N,3) sensor positions in the transmitter frame, metres.
        quat_wxyz: (N,4) sensor orientations, scalar-first quaternions.
        units: ``cm`` or ``in``.
        status: status character of every record (a space when healthy).
        stylus: (N,) stylus switch states for item 16 (default all 0).
        relative_m: (N,3) relative movement for item 3, metres (default zero).

    Raises:
        InputError: a value does not fit its ASCII field (e.g. a position beyond 999.99 units).
    """
    stations = np.asarray(stations, dtype=np.int64).reshape(-1)
    n = stations.shape[0]
    position_m = np.asarray(position_m, dtype=np.float64).reshape(n, 3)
    quat_wxyz = np.asarray(quat_wxyz, dtype=np.float64).reshape(n, 4)
    stylus = np.zeros(n, dtype=np.int64) if stylus is None else np.asarray(stylus).reshape(n)
    numbers = _record_numbers(layout, position_m, quat_wxyz, units, relative_m)
    status_byte = status.encode("latin-1")
    if len(status_byte) != 1:
        raise InputError(f"status {quoted(status)} must be one character",
                         hint="use a space or a letter")
    if layout.fmt == "binary":
        rec = np.zeros((n, layout.length), dtype=np.uint8)
        rec[:, 0] = 0x30
        rec[:, 1] = 0x30 + stations
        rec[:, 2] = status_byte[0]
        for f in layout.fields:
            kind = f.item.kind
            if kind == "space":
                rec[:, f.offset] = 0x20
            elif kind == "crlf":
                rec[:, f.offset], rec[:, f.offset + 1] = 0x0D, 0x0A
            elif kind == "stylus":
                rec[:, f.offset] = 0x20
                rec[:, f.offset + 1] = np.where(stylus != 0, 0x31, 0x30)
            else:
                values = np.ascontiguousarray(numbers[kind], dtype="<f4")
                rec[:, f.offset:f.offset + f.size] = values.view(np.uint8).reshape(n, f.size)
        blob = rec.tobytes()
        L = layout.length
        return [blob[i * L:(i + 1) * L] for i in range(n)]
    parts: list[str] = []
    columns: list[np.ndarray] = []
    for f in layout.fields:
        kind = f.item.kind
        if kind == "space":
            parts.append(" ")
        elif kind == "crlf":
            parts.append("\r\n")
        elif kind == "stylus":
            parts.append("%d")
            columns.append((stylus != 0).astype(np.int64)[:, None])
        else:
            values = numbers[kind]
            if f.item.ascii_width == 14:
                values = np.where(np.abs(values) < 1e-30, 0.0, values)
                parts.append("% .6E " * f.item.count)
            else:
                parts.append(f"%7.{f.item.decimals}f" * f.item.count)
            columns.append(values)
    template = "".join(parts)
    table = np.concatenate(columns, axis=1).astype(object) if columns else np.zeros((n, 0))
    head = [f"0{s}".encode() + status_byte for s in stations.tolist()]
    out = []
    for i, row in enumerate(table.tolist()):
        rec = head[i] + (template % tuple(row)).encode()
        if len(rec) != layout.length:
            raise InputError(f"a value of record {i} does not fit its ASCII field "
                             f"({len(rec)} bytes instead of {layout.length})",
                             hint="positions must stay within +-999.99 device units")
        out.append(rec)
    return out


def encode_record(layout: RecordLayout, station: int, position_m, quat_wxyz, units: str,
                  status: str = " ", stylus: int = 0, relative_m=(0.0, 0.0, 0.0)) -> bytes:
    """Encode one data record exactly as the device writes it (see :func:`encode_records`)."""
    return encode_records(layout, [station], [position_m], [quat_wxyz], units, status,
                          [stylus], [relative_m])[0]
