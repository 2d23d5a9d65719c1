"""Live AIS over the network: a TCP client for raw NMEA feeds and a UDP listener.

:class:`TcpAisSource` suits feeds such as the Norwegian Coastal Administration's open one
(raw NMEA with IEC 61162-450 tag blocks; talkers BS/AB/AI). It reconnects with exponential
backoff and jitter (:class:`Backoff`), treats a socket that stays silent for
``silence_timeout_s`` as dead, discards (and counts) a line cut off when the connection drops,
and never blocks the event loop: all waiting is ``await``-ed. :class:`UdpAisSource` receives
the datagrams many shipboard AIS receivers broadcast; a bounded queue decouples the socket
from the consumer, and what the queue or the kernel drops is counted.

Both are feature code for users: per the project's network rule, tests run them only against
servers on 127.0.0.1.
"""

from __future__ import annotations

import asyncio
import logging
import math
import os
import socket
import struct
from collections.abc import AsyncIterator, Callable

import numpy as np

from asvtwin.errors import ParameterError, SourceError
from asvtwin.sources.ais.counters import ErrorKind
from asvtwin.sources.ais.pipeline import AisPipeline
from asvtwin.sources.ais.reports import ReportBatch
from asvtwin.sources.ais.source import PipelineSource, SourceStatus

__all__ = ["Backoff", "TcpAisSource", "UdpAisSource"]

_MAX_LINE = 4096
_log = logging.getLogger("asvtwin.sources.ais")


class Backoff:
    """Exponential backoff with jitter: ``d_k = min(max_s, initial_s * factor**k)``, then a
    uniform draw in ``[d_k (1 - jitter), d_k]`` so many clients do not reconnect in step.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the jitter.
    initial_s, max_s : float
        First and largest delay [s].
    factor : float
        Growth per failed attempt (> 1).
    jitter : float
        Fraction of the delay drawn at random, in [0, 1].
    """

    def __init__(self, *, rng: np.random.Generator, initial_s: float = 1.0, max_s: float = 60.0,
                 factor: float = 2.0, jitter: float = 0.5) -> None:
        if not (0 < initial_s <= max_s and math.isfinite(max_s)):
            raise ParameterError(f"Backoff: 0 < initial_s <= max_s expected, actually: "
                                 f"{initial_s}, {max_s}")
        if not factor > 1.0 or not 0.0 <= jitter <= 1.0:
            raise ParameterError(f"Backoff: factor > 1 and jitter in [0, 1] expected, "
                                 f"actually: {factor}, {jitter}")
        self.rng = rng
        self.initial_s, self.max_s, self.factor, self.jitter = initial_s, max_s, factor, jitter
        self.attempt = 0

    def next_delay(self) -> float:
        """The delay before the next attempt [s]; each call counts one more failure."""
        d = min(self.max_s, self.initial_s * self.factor ** self.attempt)
        self.attempt += 1
        return d * (1.0 - self.jitter * float(self.rng.random()))

    def reset(self) -> None:
        """Back to the initial delay (after data arrived)."""
        self.attempt = 0


class TcpAisSource(PipelineSource):
    """A raw NMEA feed over TCP, reconnected forever (or ``max_reconnects`` times).

    Parameters
    ----------
    host : str
        Feed host.
    port : int
        Feed port.
    pipeline : AisPipeline, optional
        Decoding pipeline (default scene when omitted).
    clock : callable, optional
        Current UNIX time [s]: receive time of untagged lines and of ``last_data_unix_s``.
    rng : numpy.random.Generator, optional
        Jitter of the reconnection delays; ``default_rng(0)`` when omitted.
    backoff : Backoff, optional
        Reconnection policy (1 s doubling up to 60 s, 50 % jitter by default).
    silence_timeout_s : float
        No byte for this long means the feed stalled: reconnect [s].
    connect_timeout_s : float
        Give up one connection attempt after this long [s].
    max_reconnects : int or None
        Stop after this many reconnections (None: never stop).
    """

    def __init__(self, host: str, port: int, *, pipeline: AisPipeline | None = None,
                 clock: Callable[[], float] | None = None, rng: np.random.Generator | None = None,
                 backoff: Backoff | None = None, silence_timeout_s: float = 60.0,
                 connect_timeout_s: float = 10.0, max_reconnects: int | None = None) -> None:
        super().__init__(pipeline=pipeline, clock=clock)
        if not 0 < port < 65536:
            raise ParameterError(f"TcpAisSource: port in 1..65535 expected, actually: {port}")
        if not (silence_timeout_s > 0 and connect_timeout_s > 0):
            raise ParameterError("TcpAisSource: timeouts must be > 0, actually: "
                                 f"{silence_timeout_s}, {connect_timeout_s}")
        self.host, self.port = host, int(port)
        self.backoff = backoff or Backoff(rng=rng if rng is not None else np.random.default_rng(0))
        self.silence_timeout_s = float(silence_timeout_s)
        self.connect_timeout_s = float(connect_timeout_s)
        self.max_reconnects = max_reconnects

    async def batches(self) -> AsyncIterator[ReportBatch]:
        count = self.pipeline.counters.count
        while True:
            try:
                reader, writer = await asyncio.wait_for(
                    asyncio.open_connection(self.host, self.port), self.connect_timeout_s)
            except (TimeoutError, OSError) as exc:
                count(ErrorKind.CONNECT_FAILED, f"{self.host}:{self.port}", str(exc) or "timeout")
                if not await self._retry():
                    return
                continue
            self._connected = True
            buf = b""
            discarding = False  # inside a line that is already too long: skip to its end
            try:
                while True:
                    try:
                        chunk = await asyncio.wait_for(reader.read(65536), self.silence_timeout_s)
                    except TimeoutError:
                        count(ErrorKind.SILENT_FEED, f"{self.host}:{self.port}",
                              f"no data for {self.silence_timeout_s} s")
                        break
                    except (ConnectionError, OSError) as exc:
                        count(ErrorKind.DISCONNECTED, f"{self.host}:{self.port}", str(exc))
                        break
                    if not chunk:
                        count(ErrorKind.DISCONNECTED, f"{self.host}:{self.port}", "closed by peer")
                        break
                    self.backoff.reset()
                    self._last_data = self._now()
                    if discarding:
                        nl = chunk.find(b"\n")
                        if nl < 0:
                            continue
                        chunk = chunk[nl + 1:]
                        discarding = False
                    buf += chunk
                    *lines, buf = buf.split(b"\n")
                    if len(buf) > _MAX_LINE:
                        count(ErrorKind.LINE_TOO_LONG, buf[:80],
                              f"line longer than {_MAX_LINE} bytes: skipped to its end")
                        buf = b""
                        discarding = True
                    if lines and max(map(len, lines)) > _MAX_LINE:
                        for long_line in (x for x in lines if len(x) > _MAX_LINE):
                            count(ErrorKind.LINE_TOO_LONG, long_line[:80],
                                  f"line longer than {_MAX_LINE} bytes")
                        lines = [x for x in lines if len(x) <= _MAX_LINE]
                    if lines:
                        batch = self.pipeline.feed_batch(lines, recv_time_s=self._last_data)
                        if len(batch) or batch.static:
                            yield batch
            finally:
                self._connected = False
                if buf.strip():
                    count(ErrorKind.TRUNCATED, buf, "connection lost in the middle of a line")
                writer.close()
                try:
                    await writer.wait_closed()
                except (ConnectionError, OSError):
                    pass
            if not await self._retry():
                return

    async def _retry(self) -> bool:
        """Wait before the next attempt; False once ``max_reconnects`` is used up."""
        self._reconnects += 1
        if self.max_reconnects is not None and self._reconnects > self.max_reconnects:
            return False
        await asyncio.sleep(self.backoff.next_delay())
        return True


#: Linux: ask the kernel to attach its drop counter to every datagram (socket(7)).
SO_RXQ_OVFL = getattr(socket, "SO_RXQ_OVFL", 40)


class UdpAisSource(PipelineSource):
    """NMEA datagrams received on a UDP port (one or more sentences per datagram).

    Nothing is lost silently. The socket's receive buffer is enlarged (``rcvbuf_bytes``, as
    far as the kernel allows: :attr:`rcvbuf_bytes_granted`); datagrams the kernel still drops
    because the buffer was full are counted as ``kernel_drop`` from the drop counter Linux
    attaches to each datagram (``SO_RXQ_OVFL``) and from ``/proc/net/udp`` (which also
    tells the drops after the last datagram received); datagrams a slow consumer leaves in a full
    queue are counted as ``queue_overflow``. The socket is read by the event loop's reader
    callback, so a consumer that blocks the loop makes the kernel drop (and count).

    Parameters
    ----------
    port : int
        Port to listen on (0: any free port, see :attr:`bound_port`).
    host : str
        Address to bind ("0.0.0.0" for all interfaces, "127.0.0.1" for this machine only).
    pipeline, clock
        As for :class:`TcpAisSource`.
    queue_size : int
        Datagrams buffered for a slow consumer (beyond: dropped and counted).
    silence_timeout_s : float or None
        Count a ``silent_feed`` whenever nothing arrives for this long [s].
    rcvbuf_bytes : int
        Receive buffer requested from the kernel [bytes] (capped by ``net.core.rmem_max``).
    """

    def __init__(self, port: int, *, host: str = "0.0.0.0", pipeline: AisPipeline | None = None,
                 clock: Callable[[], float] | None = None, queue_size: int = 1024,
                 silence_timeout_s: float | None = None, rcvbuf_bytes: int = 4 << 20) -> None:
        super().__init__(pipeline=pipeline, clock=clock)
        if not 0 <= port < 65536:
            raise ParameterError(f"UdpAisSource: port in 0..65535 expected, actually: {port}")
        if queue_size < 1 or rcvbuf_bytes < 1:
            raise ParameterError(f"UdpAisSource: queue_size and rcvbuf_bytes must be >= 1, "
                                 f"actually: {queue_size}, {rcvbuf_bytes}")
        self.host, self.port = host, int(port)
        self.queue_size = int(queue_size)
        self.silence_timeout_s = silence_timeout_s
        self.rcvbuf_bytes = int(rcvbuf_bytes)
        self.rcvbuf_bytes_granted: int | None = None
        self.drop_counter_available = False
        self.bound_port: int | None = None
        self.datagrams = 0  #: datagrams received from the kernel
        self._kernel_drops = 0
        self._inode: str | None = None
        self.ready = asyncio.Event()

    def _open(self) -> socket.socket:
        sock = socket.socket(socket.AF_INET6 if ":" in self.host else socket.AF_INET,
                             socket.SOCK_DGRAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, self.rcvbuf_bytes)
            self.rcvbuf_bytes_granted = sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
            try:
                sock.setsockopt(socket.SOL_SOCKET, SO_RXQ_OVFL, 1)
                self.drop_counter_available = True
            except OSError:  # not Linux: kernel drops cannot be counted
                _log.warning("UDP: the kernel's drop counter (SO_RXQ_OVFL) is not available "
                             "here; datagrams the kernel drops cannot be counted")
            sock.bind((self.host, self.port))
            sock.setblocking(False)
        except OSError as exc:
            sock.close()
            raise SourceError(f"cannot listen on udp://{self.host}:{self.port}: {exc}") from exc
        return sock

    def _read_all(self, sock: socket.socket, queue: asyncio.Queue[bytes]) -> None:
        """Reader callback: drain the socket into the queue, counting every loss."""
        count = self.pipeline.counters.count
        anc_size = socket.CMSG_SPACE(4)
        while True:
            try:
                data, anc, _, _ = sock.recvmsg(65535, anc_size)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:
                count(ErrorKind.DISCONNECTED, f"udp:{self.bound_port}", str(exc))
                return
            self.datagrams += 1
            for level, kind, cdata in anc:
                if level == socket.SOL_SOCKET and kind == SO_RXQ_OVFL and len(cdata) >= 4:
                    self._count_drops(struct.unpack("=I", cdata[:4])[0])
            try:
                queue.put_nowait(data)
            except asyncio.QueueFull:
                count(ErrorKind.QUEUE_OVERFLOW, data[:80], "consumer too slow")

    def _count_drops(self, total: int) -> None:
        """Count the kernel's cumulative drop counter's increase as ``kernel_drop``."""
        if total > self._kernel_drops:
            self.pipeline.counters.count(
                ErrorKind.KERNEL_DROP, f"udp:{self.bound_port}",
                "the socket's receive buffer was full (consumer too slow, or a burst; buffer "
                f"{self.rcvbuf_bytes_granted} bytes)", n=total - self._kernel_drops)
            self._kernel_drops = total

    def _sync_drops(self) -> None:
        """Read the socket's drop counter from /proc/net/udp (Linux): the per-datagram
        counter only arrives with the next datagram, this one also after the last."""
        if self._inode is None:
            return
        for table in ("/proc/net/udp", "/proc/net/udp6"):
            try:
                with open(table, encoding="ascii") as fh:
                    next(fh)
                    for row in fh:
                        f = row.split()
                        if len(f) >= 13 and f[9] == self._inode:
                            self._count_drops(int(f[12]))
                            return
            except (OSError, ValueError, StopIteration):
                continue

    def status(self) -> SourceStatus:
        """Current health and counts (kernel drops brought up to date first)."""
        self._sync_drops()
        return super().status()

    async def batches(self) -> AsyncIterator[ReportBatch]:
        loop = asyncio.get_running_loop()
        queue: asyncio.Queue[bytes] = asyncio.Queue(self.queue_size)
        sock = self._open()
        self._inode = str(os.fstat(sock.fileno()).st_ino)
        self.bound_port = int(sock.getsockname()[1])
        loop.add_reader(sock.fileno(), self._read_all, sock, queue)
        self._connected = True
        self.ready.set()
        try:
            while True:
                try:
                    data = await asyncio.wait_for(queue.get(), self.silence_timeout_s)
                except TimeoutError:
                    self._sync_drops()
                    self.pipeline.counters.count(ErrorKind.SILENT_FEED, f"udp:{self.bound_port}",
                                                 f"no datagram for {self.silence_timeout_s} s")
                    continue
                if queue.empty():
                    self._sync_drops()
                self._last_data = self._now()
                batch = self.pipeline.feed_batch(data.split(b"\n"), recv_time_s=self._last_data)
                if len(batch) or batch.static:
                    yield batch
        finally:
            self._sync_drops()
            self._connected = False
            self._inode = None
            loop.remove_reader(sock.fileno())
            sock.close()
