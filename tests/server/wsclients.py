"""Load for the server's reliability tests and the viewer benchmark, run in its own process
(so the clients do not share the server's interpreter): ``n`` WebSocket clients at
``rate_hz`` for ``hold_s`` seconds, ``cycles`` times, dropping abruptly (transport closed
without a closing handshake) after each hold. Prints one JSON line per cycle: messages and
bytes received per client.

    python tests/server/wsclients.py URL N RATE_HZ HOLD_S CYCLES
"""

from __future__ import annotations

import asyncio
import json
import sys
import time

import websockets


async def one(url: str, rate_hz: float, hold_s: float) -> tuple[int, int]:
    n = nbytes = 0
    async with websockets.connect(f"{url}?rate_hz={rate_hz}", max_size=None,
                                  open_timeout=30) as ws:
        end = time.monotonic() + hold_s
        while (left := end - time.monotonic()) > 0:
            try:
                msg = await asyncio.wait_for(ws.recv(), left)
            except TimeoutError:
                break
            if isinstance(msg, bytes):
                n += 1
                nbytes += len(msg)
        ws.transport.abort()  # drop, no closing handshake
    return n, nbytes


async def main(url: str, n: int, rate_hz: float, hold_s: float, cycles: int) -> None:
    for _ in range(cycles):
        t0 = time.monotonic()
        res = await asyncio.gather(*(one(url, rate_hz, hold_s) for _ in range(n)),
                                   return_exceptions=True)
        ok = [r for r in res if isinstance(r, tuple)]
        print(json.dumps({"clients": n, "ok": len(ok), "errors": [repr(r) for r in res
                                                               if not isinstance(r, tuple)][:3],
                          "messages": [r[0] for r in ok], "bytes": [r[1] for r in ok],
                          "wall_s": time.monotonic() - t0}), flush=True)


if __name__ == "__main__":
    u, k, r, h, c = sys.argv[1:6]
    asyncio.run(main(u, int(k), float(r), float(h), int(c)))
