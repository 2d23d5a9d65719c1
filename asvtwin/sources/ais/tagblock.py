"""IEC 61162-450 tag blocks: ``\\s:station,c:unix_time*hh\\`` in front of an NMEA sentence.

A tag block is a comma-separated list of ``key:value`` fields between two backslashes, closed
by ``*hh``, the hexadecimal XOR of the characters between the opening backslash and ``*``.
The fields the twin reads:

- ``c:`` receive time, UNIX seconds (or milliseconds when above 1e11), digits only;
- ``s:`` source (the receiving base station);
- ``g:`` sentence group ``n-m-id`` (sentence n of m of group id), on multi-sentence messages.

**The national feed's group convention.** The Norwegian Coastal Administration's open feed
writes group tag blocks like ``\\g:1-2-9999,c:1565218798*53\\``, whose checksum covers only
the ``c:`` field (the XOR of ``c:1565218798`` is 0x53), not the whole tag. A strict parser
drops every multi-sentence message of that feed (all type 5 static and voyage data).
:func:`parse_tag_block` accepts a tag whose checksum matches either the whole tag or, failing
that, the ``c:`` field alone, and says which (:attr:`TagBlock.checksum_over`), so the pipeline
can count the second convention; a tag matching neither is rejected, and the error says what
was computed.
"""

from __future__ import annotations

from dataclasses import dataclass

from asvtwin.errors import SourceError

__all__ = [
    "TagBlock",
    "TagBlockError",
    "parse_tag_block",
    "parse_tag_block_time",
    "parse_tag_fields",
    "xor_checksum",
]

#: c: above this is in milliseconds (1e11 s is the year 5138).
_MS_THRESHOLD = 1e11


class TagBlockError(SourceError, ValueError):
    """A tag block is malformed or its checksum matches neither convention.

    Attributes
    ----------
    checksum : bool
        True when the fields parse but the checksum is wrong (the pipeline counts it as
        ``bad_tag_checksum``), False for a malformed field (``bad_tag_block``).
    """

    def __init__(self, message: str, *, checksum: bool = False) -> None:
        super().__init__(message)
        self.checksum = checksum


@dataclass(frozen=True, slots=True)
class TagBlock:
    """The fields of one tag block the twin uses.

    Attributes
    ----------
    t_unix_s : float or None
        ``c:`` receive time [UNIX s] (milliseconds converted), None when absent.
    station : str or None
        ``s:`` source / base station.
    group : tuple of int or None
        ``g:`` as (sentence number, sentence count, group id).
    checksum_over : str
        ``"tag"`` (the standard: the whole tag) or ``"c"`` (the ``c:`` field alone, the
        national feed's group convention).
    """

    t_unix_s: float | None
    station: str | None
    group: tuple[int, int, int] | None = None
    checksum_over: str = "tag"


def xor_checksum(data: bytes) -> int:
    """NMEA checksum: the XOR of all bytes of ``data``."""
    cs = 0
    for b in data:
        cs ^= b
    return cs


def _digits_time(value: bytes) -> float:
    """``c:`` value: digits, optionally one decimal point; seconds or milliseconds."""
    whole, dot, frac = value.partition(b".")
    if not whole.isdigit() or (dot and not frac.isdigit()) or len(whole) > 16:
        raise TagBlockError(f"tag block c: must be digits (UNIX s or ms), actually: "
                            f"{value.decode('ascii', 'backslashreplace')!r}")
    c = float(value)
    return c / 1000.0 if c > _MS_THRESHOLD else c


def parse_tag_block(tag: bytes, *, whole_xor: int | None = None) -> TagBlock:
    """Parse and check the text between the two backslashes of a tag block.

    Parameters
    ----------
    tag : bytes
        E.g. ``b"s:2573555,c:1707873398*05"`` (without the backslashes).
    whole_xor : int, optional
        The XOR of the text before ``*`` when the caller has it already (the pipeline
        computes all checksums of a batch at once).

    Returns
    -------
    TagBlock

    Raises
    ------
    TagBlockError
        No ``*hh``, a checksum matching neither the whole tag nor the ``c:`` field, or a
        malformed ``c:``/``g:`` field; the message says which check failed.
    """
    return TagBlock(*parse_tag_fields(tag, whole_xor))


def parse_tag_block_time(tag: bytes, whole_xor: int | None = None
                         ) -> tuple[float | None, str | None, bool]:
    """The hot path's form of :func:`parse_tag_block`: ``(t_unix_s, station, c_only)``."""
    t, station, _, over = parse_tag_fields(tag, whole_xor)
    return t, station, over == "c"


def parse_tag_fields(tag: bytes, whole_xor: int | None = None
                     ) -> tuple[float | None, str | None, tuple[int, int, int] | None, str]:
    """:func:`parse_tag_block` as a plain tuple ``(t, station, group, checksum_over)``."""
    star = tag.rfind(b"*")
    if star < 0 or len(tag) - star != 3:
        raise TagBlockError("tag block does not end in *hh")
    try:
        expected = int(tag[star + 1:], 16)
    except ValueError:
        raise TagBlockError(f"tag block checksum {tag[star + 1:]!r} is not hexadecimal") from None
    body = tag[:star]
    if not body:
        raise TagBlockError("tag block has no fields")
    t = None
    station = None
    group = None
    c_field = None
    for fld in body.split(b","):
        key = fld[:2]
        if key == b"c:":
            if c_field is not None:
                raise TagBlockError("tag block has two c: fields")
            c_field = fld
            value = fld[2:]
            if value.isdigit() and len(value) <= 16:  # the usual case: whole seconds or ms
                t = float(value)
                if t > _MS_THRESHOLD:
                    t /= 1000.0
            else:
                t = _digits_time(value)
        elif key == b"s:":
            station = fld[2:].decode("ascii", "backslashreplace")
        elif key == b"g:":
            group = _group(fld[2:])
        elif len(fld) < 2 or fld[1:2] != b":":
            raise TagBlockError(f"tag block field {fld.decode('ascii', 'backslashreplace')!r} "
                                "is not key:value")
    whole = xor_checksum(body) if whole_xor is None else whole_xor
    if whole == expected:
        return t, station, group, "tag"
    if c_field is not None and xor_checksum(c_field) == expected:
        return t, station, group, "c"
    over_c = f", 0x{xor_checksum(c_field):02X} over c: alone" if c_field is not None else \
        " (no c: field for the c:-only convention)"
    raise TagBlockError(f"tag block checksum 0x{expected:02X} in the tag, 0x{whole:02X} computed "
                        f"over the whole tag{over_c}", checksum=True)


def _group(value: bytes) -> tuple[int, int, int]:
    parts = value.split(b"-")
    if len(parts) != 3 or not all(p.isdigit() and len(p) <= 9 for p in parts):
        raise TagBlockError(f"tag block g: must be n-m-id digits, actually: "
                            f"{value.decode('ascii', 'backslashreplace')!r}")
    n, m, gid = (int(p) for p in parts)
    if not 1 <= n <= m:
        raise TagBlockError(f"tag block g: sentence 1..{m} expected, actually {n}")
    return n, m, gid
