"""Vectorised decoding of the common single-sentence position reports (types 1, 2, 3, 18).

Most lines of a coastal AIS feed are one-sentence class A (types 1, 2, 3) or class B
(type 18) position reports. Decoding them one object at a time with pyais cost about half
of the pipeline's time; this module decodes a whole batch of them at once with numpy and is
checked field for field against pyais (``tests/sources/test_positions.py``: random payloads
of every used type, every field value at its limits). Everything else (other types,
multi-sentence messages, any sentence that is not exactly canonical) goes through pyais.

Which sentences qualify is decided by :data:`FAST_SENTENCE`, a regular expression that
matches only a sentence every one of the pipeline's sentence checks would accept apart from
the checksum (which the pipeline still checks for every line): ``!`` and a two-letter talker,
``VDM`` (``VDO`` is the own ship: counted apart), fragment 1 of 1, an optional one-digit
sequence id, channel ``A``/``B``/``1``/``2`` or empty, 28 to 82 characters of the AIS 6-bit
alphabet (ITU-R M.1371: ``0``..``W`` and `````..``w``; 28 characters are the 168 bits of a
position report), fill bits ``0``..``5`` and ``*hh``.

Field layout (ITU-R M.1371-5, Annex 8, tables 46 and 51; bit 0 is the first payload bit):

======  ======  ======  ======  =====  =====  =====  ======  =======
type    mmsi    status  turn    sog    lon    lat    cog     heading
======  ======  ======  ======  =====  =====  =====  ======  =======
1/2/3   8-37    38-41   42-49   50-59  61-88  89-115 116-127 128-136
18      8-37    --      --      46-55  57-84  85-111 112-123 124-132
======  ======  ======  ======  =====  =====  =====  ======  =======

The conversions are pyais's, to the bit: SOG and COG in tenths (``v / 10``), lon/lat in
1/10 000 min rounded to 1e-6 deg (``((10 v + 3) // 6) / 1e6``, exact in integers), the rate
of turn through pyais's own :func:`pyais.messages.to_turn` for each of its 256 values.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from pyais.messages import to_turn

from asvtwin.checks import F8

__all__ = ["FAST_SENTENCE", "FAST_TYPES", "FastLines", "PositionColumns", "decode_positions",
           "no_fast_lines", "scan_fast_lines"]

#: Message types decoded here (the rest goes through pyais).
FAST_TYPES = frozenset({1, 2, 3, 18})

#: A canonical single-sentence AIS VDM line whose payload may be a position report (group 1:
#: payload; group 2: ``*hh``). The type and length are checked by :func:`decode_positions`.
FAST_SENTENCE = re.compile(
    rb"![A-Z]{2}VDM,1,1,[0-9]?,[AB12]?,([0-W`-w]{28,82}),[0-5]\*([0-9A-Fa-f]{2})")

#: 6-bit value of each armouring character (ITU-R M.1371 / IEC 61162-1): c - 48, minus 8 more
#: above "W" ("`" is 40).
_SIXBIT = np.zeros(256, np.int64)
_SIXBIT[48:88] = np.arange(40)
_SIXBIT[96:120] = np.arange(40, 64)
#: Weights that pack 10 six-bit values into one 60-bit word (first character highest).
_PACK10 = (1 << (54 - 6 * np.arange(10))).astype(np.int64)
#: Payload character -> message type, for the characters of the four fast types.
_TYPE_OF_CHAR = {ord("1"): 1, ord("2"): 2, ord("3"): 3, ord("B"): 18}
#: Hexadecimal digit -> value (-1 for anything else), for the checksums of a batch at once.
_HEX = np.full(256, -1, np.int64)
_HEX[48:58] = np.arange(10)
_HEX[65:71] = np.arange(10, 16)
_HEX[97:103] = np.arange(10, 16)
#: pyais's rate-of-turn conversion of every raw 8-bit value, as floats (TurnRate 127/-128 as
#: their raw numbers, the pipeline maps them to "not available").
_TURN = np.array([float(to_turn(v)) for v in range(-128, 128)])


@dataclass(frozen=True, slots=True)
class PositionColumns:
    """Decoded position reports, one row per payload given to :func:`decode_positions`.

    Attributes
    ----------
    msg_type : ndarray of int64
        1, 2, 3 or 18.
    mmsi : ndarray of int64
        Maritime Mobile Service Identity as transmitted (0 .. 2**30 - 1; not yet validated).
    lat_deg, lon_deg : ndarray of float64
        As transmitted [deg] (91 / 181 = not available; not yet validated).
    sog_kn : ndarray of float64
        Speed over ground [kn] (102.3 = not available).
    cog_deg : ndarray of float64
        Course over ground [deg] (360 = not available).
    heading_deg : ndarray of float64
        True heading [deg] (511 = not available).
    rot_deg_min : ndarray of float64
        pyais's rate of turn [deg/min] (±127, -128: no value); NaN for type 18.
    nav_status : ndarray of int64
        Navigational status 0..15 (15 = not defined, also for type 18).
    """

    msg_type: NDArray[np.int64]
    mmsi: NDArray[np.int64]
    lat_deg: F8
    lon_deg: F8
    sog_kn: F8
    cog_deg: F8
    heading_deg: F8
    rot_deg_min: F8
    nav_status: NDArray[np.int64]


def decode_positions(payloads: list[bytes]) -> PositionColumns:
    """Decode position-report payloads (types 1, 2, 3, 18, each >= 28 characters) at once.

    Parameters
    ----------
    payloads : list of bytes
        Payloads in the AIS 6-bit alphabet whose first character is ``1``, ``2``, ``3`` or
        ``B`` and whose length is at least 28 characters (168 bits, without fill bits). Only
        the first 168 bits are read (what pyais reads of a longer payload).

    Returns
    -------
    PositionColumns
        One row per payload, the values pyais's ``decode()`` gives, as arrays.
    """
    n = len(payloads)
    buf = np.frombuffer(b"".join([p[:28] for p in payloads]), np.uint8)
    v = _SIXBIT[buf].reshape(n, 28)
    # three 60-bit words per payload: bit i of the payload is bit 59 - i % 60 of word i // 60
    w0 = v[:, 0:10] @ _PACK10
    w1 = v[:, 10:20] @ _PACK10
    w2 = v[:, 20:28] @ _PACK10[:8]
    msg_type = w0 >> 54
    b = msg_type == 18
    mmsi = (w0 >> 22) & 0x3FFFFFFF
    # class A (types 1-3) and class B (type 18) layouts, chosen per row
    speed = np.where(b, (w0 >> 4) & 1023, w0 & 1023)
    lon = np.where(b, ((w0 & 7) << 25) | (w1 >> 35), (w1 >> 31) & 0xFFFFFFF)
    lat = np.where(b, (w1 >> 8) & 0x7FFFFFF, (w1 >> 4) & 0x7FFFFFF)
    course = np.where(b, ((w1 & 255) << 4) | (w2 >> 56), ((w1 & 15) << 8) | (w2 >> 52))
    heading = np.where(b, (w2 >> 47) & 511, (w2 >> 43) & 511)
    lon = (lon ^ 0x8000000) - 0x8000000  # two's complement, 28 bits
    lat = (lat ^ 0x4000000) - 0x4000000  # 27 bits
    turn = (((w0 >> 10) & 255) ^ 0x80) - 0x80  # 8 bits, class A only
    return PositionColumns(
        msg_type=msg_type, mmsi=mmsi,
        lat_deg=((10 * lat + 3) // 6) / 1e6, lon_deg=((10 * lon + 3) // 6) / 1e6,
        sog_kn=speed / 10.0, cog_deg=course / 10.0, heading_deg=heading.astype(np.float64),
        rot_deg_min=np.where(b, np.nan, _TURN[turn + 128]),
        nav_status=np.where(b, 15, (w0 >> 18) & 15),
    )


@dataclass(frozen=True, slots=True)
class FastLines:
    """The canonical position-report lines of a batch, decoded (see :func:`scan_fast_lines`).

    Attributes
    ----------
    index : list of int
        Per input line: its row here, or -1 (the line goes through pyais).
    sentence_len : list of int
        Length of each row's sentence (from ``!`` to the end of the line): the pipeline uses
        a row only if its own framing found the same sentence.
    payload : list of bytes
        Each row's payload (the duplicate filter's key).
    checksum : list of tuple of int
        ``(computed, transmitted)`` sentence checksum of each row.
    msg_type, mmsi : list of int
    lat_deg, lon_deg : list of float
        What the per-line checks read, as Python numbers.
    columns : PositionColumns
        Every decoded field, as arrays (for the batch's output columns).
    """

    index: list[int]
    sentence_len: list[int]
    payload: list[bytes]
    checksum: list[tuple[int, int]]
    msg_type: list[int]
    mmsi: list[int]
    lat_deg: list[float]
    lon_deg: list[float]
    columns: PositionColumns


def scan_fast_lines(raws: list[bytes], P: bytes) -> FastLines:
    """Find and decode the lines of a batch whose sentence matches :data:`FAST_SENTENCE`
    with a position-report payload of at least 168 bits (after the fill bits).

    ``P`` is the prefix XOR of ``b"".join(raws)``
    (:func:`asvtwin.sources.ais.sentence.prefix_xor`): every row's checksum is computed from
    it at once (the pipeline still rejects a row whose checksum does not match).
    """
    index = [-1] * len(raws)
    lens: list[int] = []
    payloads: list[bytes] = []
    first: list[int] = []  # offset of "!" in the joined batch
    match = FAST_SENTENCE.fullmatch
    o = 0
    for i, raw in enumerate(raws):
        b0 = raw.rfind(b"\\") + 1  # after a tag block (a sentence holds no backslash)
        m = match(raw, b0)
        if m is not None:
            p = m.group(1)
            # 28 characters are exactly 168 bits: only with 0 fill bits ("...,0*hh")
            if p[0] in _TYPE_OF_CHAR and (len(p) > 28 or raw[-4] == 48):
                index[i] = len(payloads)
                payloads.append(p)
                lens.append(len(raw) - b0)
                first.append(o + b0)
        o += len(raw)
    if not payloads:
        return no_fast_lines(len(raws))
    start = np.array(first, np.int64)
    end = start + np.array(lens, np.int64)  # one past the last hex digit
    Pa = np.frombuffer(P, np.uint8)
    joined = np.frombuffer(b"".join(raws), np.uint8)
    computed = Pa[end - 4] ^ Pa[start]  # xor of the bytes between "!" and "*"
    sent = _HEX[joined[end - 2]] * 16 + _HEX[joined[end - 1]]
    cols = decode_positions(payloads)
    return FastLines(index, lens, payloads, list(zip(computed.tolist(), sent.tolist())),
                     cols.msg_type.tolist(), cols.mmsi.tolist(), cols.lat_deg.tolist(),
                     cols.lon_deg.tolist(), cols)


def no_fast_lines(n: int) -> FastLines:
    """A batch of ``n`` lines none of which is decoded here (all go through pyais)."""
    return FastLines([-1] * n, [], [], [], [], [], [], [], _EMPTY)


_EMPTY = decode_positions([])
