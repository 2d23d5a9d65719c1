"""Stage 1 of the AIS pipeline: a received line -> a checked NMEA sentence.

The checks of this stage, in order (each failure has its own
:class:`~asvtwin.sources.ais.counters.ErrorKind`):

- **framing**: 7-bit ASCII; a garbage prefix is skipped up to the next ``\\`` or ``!``
  (:func:`resync`);
- **tag block** (IEC 61162-450, :mod:`~asvtwin.sources.ais.tagblock`): ``\\s:station,
  c:time*hh\\``, checksum over the whole tag or, the national feed's group convention, over
  ``c:`` alone; parsed once per distinct tag (:class:`TagCache`: a feed repeats each tag for
  every line of the same second and station);
- **sentence checksum**: ``*hh``, the XOR of the characters between ``!``/``$`` and ``*``.
  Every checksum of a batch comes from one prefix XOR over the joined batch
  (:func:`prefix_xor`), so a checksum is two index reads, not a loop over the line;
- **fields**: parsed by :class:`pyais.messages.NMEASentenceFactory`, then (:func:`check_ais`)
  VDM rather than VDO (the own ship), fill bits one digit 0..5 (pyais reads ``x`` as 0) and
  every payload character in the AIS 6-bit alphabet (ITU-R M.1371; a character outside it
  would decode to a wrong position).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pyais.exceptions import AISBaseException
from pyais.messages import AISSentence, NMEASentenceFactory

from asvtwin.sources.ais.counters import ErrorKind
from asvtwin.sources.ais.tagblock import TagBlockError, parse_tag_block_time

__all__ = ["ARMOUR", "TagCache", "as_bytes", "check_ais", "prefix_xor", "resync"]

#: The AIS 6-bit armouring alphabet (ITU-R M.1371 / IEC 61162-1): "0".."W" and "`".."w".
ARMOUR = bytes(range(48, 88)) + bytes(range(96, 120))
#: First characters of an AIS line: tag block, encapsulated sentence, parametric sentence.
STARTS = b"\\!$"

_produce = NMEASentenceFactory.produce


def as_bytes(line: object) -> bytes:
    """A line as bytes (text encoded as UTF-8, undecodable characters kept as escapes)."""
    if isinstance(line, str):
        return line.encode("utf-8", "surrogateescape")
    return bytes(line)  # type: ignore[call-overload]


def resync(raw: bytes) -> int:
    """Where a sentence starts after a garbage prefix, or -1: the first ``\\`` or ``!`` (AIS
    lines start so), else the first ``$``. Only the part after the last non-ASCII byte is
    searched (the sentence must be clean ASCII)."""
    start = 0
    if not raw.isascii():
        start = max(i for i, b in enumerate(raw) if b > 127) + 1
    found = [k for k in (raw.find(b"\\", start), raw.find(b"!", start)) if k >= 0]
    if not found:
        return raw.find(b"$", start)
    k = min(found)
    # a backslash right before "!" closes a tag block the garbage cut: keep the sentence
    return k + 1 if raw[k] == 92 and raw[k + 1:k + 2] == b"!" else k


def prefix_xor(joined: bytes) -> bytes:
    """Running XOR of ``joined``: ``xor(joined[a:b]) == P[b - 1] ^ P[a - 1]`` (``P[-1]`` = 0)."""
    if not joined:
        return b""
    return np.bitwise_xor.accumulate(np.frombuffer(joined, np.uint8)).tobytes()


class TagCache:
    """Tag blocks parsed and checked once per distinct text (per time offset).

    ``get(tag)`` returns ``(t_unix_s + offset, station, c_only)`` for a good tag,
    ``(ErrorKind, detail)`` for a rejected one, None for a tag not seen yet (then
    :meth:`parse`). At most ``size`` tags of each kind are kept.
    """

    def __init__(self, size: int = 1024) -> None:
        self.size = size
        self.offset = 0.0
        self._good: dict[bytes, tuple[Any, ...]] = {}
        self._bad: dict[bytes, tuple[Any, ...]] = {}

    def get(self, tag: bytes) -> tuple[Any, ...] | None:
        got = self._good.get(tag)
        return got if got is not None else self._bad.get(tag)

    def set_offset(self, offset_s: float) -> None:
        """Times are cached with the offset added: a new offset forgets them."""
        if offset_s != self.offset:
            self._good.clear()
            self.offset = offset_s

    def parse(self, tag: bytes, P: bytes, o: int) -> tuple[Any, ...]:
        """Parse, check and cache ``tag`` (``raw[1:end]`` of the line at offset ``o`` of the
        batch whose prefix XOR is ``P``)."""
        parsed = _parse_tag(tag, P, o, self.offset)
        cache = self._bad if len(parsed) == 2 else self._good
        if len(cache) > self.size:
            cache.clear()
        cache[tag] = parsed
        return parsed


def _parse_tag(tag: bytes, P: bytes, o: int, offset: float) -> tuple[Any, ...]:
    star = tag.rfind(b"*")
    whole = (P[o + star] ^ P[o]) if star > 0 else None  # xor(raw[1:1 + star])
    if whole is not None and len(tag) - star == 3:
        # the common form "s:station,c:digits" with the standard checksum, parsed here
        # (this path runs for a third of a feed's lines: each new second and station)
        fields = tag[:star].split(b",")
        if len(fields) == 2 and fields[0][:2] == b"s:" and fields[1][:2] == b"c:":
            c = fields[1][2:]
            try:
                ok = c.isdigit() and len(c) <= 16 and int(tag[star + 1:], 16) == whole
            except ValueError:
                ok = False
            if ok:
                secs = float(c)
                return ((secs / 1000.0 if secs > 1e11 else secs) + offset,
                        fields[0][2:].decode("ascii", "backslashreplace"), False)
    try:
        t, station, c_only = parse_tag_block_time(tag, whole)
    except TagBlockError as exc:
        return (ErrorKind.BAD_TAG_CHECKSUM if exc.checksum else ErrorKind.BAD_TAG_BLOCK,
                str(exc))
    return (None if t is None else t + offset, station, c_only)


def check_ais(body: bytes, star: int) -> AISSentence | tuple[ErrorKind, str]:
    """The field checks of a sentence whose checksum passed: a pyais
    :class:`~pyais.messages.AISSentence`, or ``(kind, detail)`` for a rejection.

    ``star`` is the index of ``*`` in ``body``."""
    try:
        msg: Any = _produce(body)
    except AISBaseException as exc:
        kind = ErrorKind.NOT_AIS if type(exc).__name__ == "UnknownMessageException" \
            else ErrorKind.MALFORMED
        return kind, str(exc)[:80]
    if msg.TYPE != "AIS":
        return ErrorKind.NOT_AIS, ""
    if body[5] == 79:  # "!xxVDO": the own ship's transponder
        return ErrorKind.OWN_SHIP, "VDO is the own ship's report, not a target"
    if body[star - 2] != 44 or not 48 <= body[star - 1] <= 53:  # pyais reads "x" as 0
        return ErrorKind.MALFORMED, "fill bits must be one digit 0..5"
    bad = msg.payload.translate(None, ARMOUR)
    if bad:
        char = bad[:1].decode("ascii", "replace")
        return ErrorKind.DECODE_ERROR, f"payload character {char!r} is outside the AIS 6-bit alphabet"
    return msg  # type: ignore[no-any-return]
