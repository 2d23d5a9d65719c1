"""The local server: the viewer's files, the scene, snapshots on ``/ws``, controls over REST.

Endpoints (all JSON unless said otherwise):

``GET /``                        the viewer (``asvtwin/web/index.html``)
``GET /static/...``              the viewer's files, vendored JavaScript included
``GET /api/info``                feed kind (live / replay / synthetic), actions, schema id
``GET /api/scene``               land as GeoJSON (lon/lat) and NED, the relief grid (once)
``GET /api/snapshot``            the newest snapshot (the same bytes as on ``/ws``)
``GET /api/schema``              the snapshot's JSON Schema
``GET /api/stats``               clients, frames sent/replaced, refused requests by reason
``POST /api/control/{action}``   pause, resume, speed, step, filter, route, inject, wind, seek
``WS /ws?rate_hz=10&format=json&ack=0``  snapshots at the client's rate (json or msgpack;
                                 with ``ack=1`` the next one waits for ``{"ack": seq}``)

Security: the server binds 127.0.0.1 unless told otherwise. A request from any other
address needs the access token (``Authorization: Bearer T``, header ``X-Asvtwin-Token`` or
``?token=T``); without a configured token such requests are refused. The ``Host`` header
must name this server and a WebSocket's ``Origin``, when sent, must be this server (a web
page elsewhere cannot drive the twin through the user's browser), and control requests
must be ``application/json`` (so a cross-site form cannot post one). Bodies over
:data:`~asvtwin.server.api.MAX_BODY_BYTES` get 413. Every refusal is a 4xx with a JSON
``{"error": reason}`` and is counted in ``/api/stats``. No endpoint reads or writes a path
given in a request: the only files served are the package's own viewer files.
"""

from __future__ import annotations

import asyncio
import contextlib
import hmac
import ipaddress
import logging
import secrets
import threading
import time
from collections.abc import AsyncIterator, Awaitable, Callable, MutableMapping
from importlib import resources
from pathlib import Path
from typing import Any, Self
from urllib.parse import parse_qs, urlsplit

import numpy as np
import orjson
from fastapi import FastAPI, Request, WebSocket, WebSocketDisconnect
from fastapi.responses import FileResponse, Response
from fastapi.staticfiles import StaticFiles
from pydantic import ValidationError

from asvtwin.geo import Scene
from asvtwin.server.api import CONTROL_MODELS, MAX_BODY_BYTES, ClientOptions
from asvtwin.server.feed import ControlError, SnapshotFeed, as_feed
from asvtwin.server.hub import Hub
from asvtwin.twin.snapshot import SCHEMA_ID, json_schema

__all__ = ["ServerThread", "create_app", "scene_document", "serve"]

log = logging.getLogger(__name__)

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]

#: Cells of the relief grid along north and east (the 3-D view's terrain).
RELIEF_SHAPE = (150, 225)


def web_dir() -> Path:
    """The folder of the viewer's static files inside the package."""
    return Path(str(resources.files("asvtwin").joinpath("web")))


def _loopback(host: str | None) -> bool:
    if not host:
        return False
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return host == "localhost"


def _error(status: int, reason: str) -> Response:
    return Response(orjson.dumps({"error": reason}), status_code=status,
                    media_type="application/json")


def scene_document(scene: Scene, *, shape: tuple[int, int] = RELIEF_SHAPE) -> dict[str, Any]:
    """The scene as the viewer needs it, computed once per server.

    ``land`` is a GeoJSON FeatureCollection in ``(lon, lat)`` [deg]; ``land_ned`` the same
    polygons as rings of ``[north_m, east_m]``; ``relief`` a grid of terrain heights [m]
    derived from the coastline only (:meth:`asvtwin.geo.LandMask.terrain_height_m`: no
    elevation model is bundled), rows north, columns east.
    """
    from shapely.geometry import mapping

    polys_ll = [mapping(p) for p in scene.land_lonlat.geoms]
    land = {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"kind": "land"}, "geometry": g} for g in polys_ll]}
    rings = [[np.round(np.asarray(p.exterior.coords), 1).tolist()]
             + [np.round(np.asarray(r.coords), 1).tolist() for r in p.interiors]
             for p in scene.land.polygons.geoms]
    n0, n1, e0, e1 = scene.bounds_ned
    rows, cols = shape
    nn, ee = np.meshgrid(np.linspace(n0, n1, rows), np.linspace(e0, e1, cols), indexing="ij")
    peak, scale = 400.0, 1500.0
    h = scene.land.terrain_height_m(np.column_stack([nn.ravel(), ee.ravel()]),
                                    peak_m=peak, scale_m=scale)
    b = scene.bounds
    return {
        "name": scene.name,
        "origin": {"lat_deg": scene.frame.lat0_deg, "lon_deg": scene.frame.lon0_deg},
        "bounds": {"lat_min_deg": b.lat_min_deg, "lat_max_deg": b.lat_max_deg,
                   "lon_min_deg": b.lon_min_deg, "lon_max_deg": b.lon_max_deg},
        "bounds_ned": {"north_min_m": n0, "north_max_m": n1, "east_min_m": e0, "east_max_m": e1},
        "attribution": scene.attribution,
        "licence": scene.licence,
        "land": land,
        "land_ned": rings,
        "relief": {"rows": rows, "cols": cols, "north_m": [n0, n1], "east_m": [e0, e1],
                   "heights_m": np.round(h, 1).tolist(), "peak_m": peak, "scale_m": scale,
                   "note": "relief derived from the coastline (height grows with distance "
                           "inland); no elevation model is bundled"},
    }


class _Guard:
    """ASGI middleware: token for non-local clients, Host/Origin checks, body size limit."""

    def __init__(self, app: Any, *, token: str | None, counters: Any,
                 max_body: int = MAX_BODY_BYTES) -> None:
        self.app = app
        self.token = token
        self.counters = counters
        self.max_body = max_body

    def _refuse_reason(self, scope: Scope) -> tuple[int, str] | None:
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope["headers"]}
        client = (scope.get("client") or ("", 0))[0]
        if not _loopback(client):
            given = headers.get("x-asvtwin-token", "")
            auth = headers.get("authorization", "")
            if auth.lower().startswith("bearer "):
                given = auth[7:].strip()
            if not given:
                q = parse_qs(scope.get("query_string", b"").decode("latin-1"))
                given = (q.get("token") or [""])[0]
            if self.token is None:
                return 403, (f"requests from {client or 'an unknown address'} are refused: "
                             "this server is local-only (bound to 127.0.0.1, no access token)")
            if not given or not hmac.compare_digest(given.encode(), self.token.encode()):
                return 403, f"requests from {client} need the access token (missing or wrong)"
        elif self.token is None:
            host = headers.get("host", "").rsplit(":", 1)[0].strip("[]")
            if host and not _loopback(host):
                return 403, (f"Host {host!r} is not this local server (DNS rebinding guard); "
                             "use http://127.0.0.1")
        origin = headers.get("origin")
        if scope["type"] == "websocket" and origin:
            o = urlsplit(origin)
            if o.netloc != headers.get("host", ""):
                return 403, f"WebSocket from origin {origin!r} refused (not this server)"
        if scope["type"] == "http" and scope["method"] == "POST":
            ctype = headers.get("content-type", "").split(";")[0].strip()
            if ctype != "application/json":
                return 415, f"control requests must be application/json, got {ctype or 'none'!r}"
            length = headers.get("content-length")
            if length is not None and (not length.isdigit() or int(length) > self.max_body):
                return 413, f"request body of {length} bytes exceeds {self.max_body} bytes"
        return None

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        refused = self._refuse_reason(scope)
        if refused is not None:
            status, reason = refused
            self.counters[f"refused_{status}"] += 1
            self.counters["refused"] += 1
            log.info("refused %s %s: %s", scope["type"], scope.get("path"), reason)
            if scope["type"] == "websocket":
                await send({"type": "websocket.close", "code": 1008, "reason": reason[:120]})
                return
            await _error(status, reason)(scope, receive, send)
            return
        if scope["type"] == "http" and scope["method"] == "POST":
            receive = self._limited(receive)
        await self.app(scope, receive, send)

    def _limited(self, receive: Receive) -> Receive:
        seen = 0
        limit = self.max_body

        async def wrapped() -> Message:
            nonlocal seen
            msg = await receive()
            if msg["type"] == "http.request":
                seen += len(msg.get("body", b""))
                if seen > limit:
                    raise _TooLarge(seen)
            return msg

        return wrapped


class _TooLarge(Exception):
    def __init__(self, n: int) -> None:
        super().__init__(f"request body exceeds {MAX_BODY_BYTES} bytes (chunked, {n}+ read)")


def create_app(feed: Any, *, token: str | None = None, send_timeout_s: float = 2.0) -> Any:
    """The ASGI application serving ``feed`` (a feed, a ``Twin`` or a ``Recording``).

    Parameters
    ----------
    feed : SnapshotFeed or Twin or Recording
        What to serve (wrapped by :func:`asvtwin.server.feed.as_feed`).
    token : str, optional
        Access token that requests from outside 127.0.0.1 must present; None refuses them.
    send_timeout_s : float
        A WebSocket send blocked longer than this [s] drops that client.

    Returns
    -------
    ASGI app
        A FastAPI app wrapped in the guard middleware; ``app.state.hub`` (on the inner
        FastAPI app, also reachable as ``.hub`` on the returned object) holds the counters.
    """
    feed_ = as_feed(feed)
    hub = Hub(feed_, send_timeout_s=send_timeout_s)
    scene_cache: dict[str, bytes] = {}
    scene_lock = threading.Lock()

    @contextlib.asynccontextmanager
    async def lifespan(_app: FastAPI) -> AsyncIterator[None]:
        feed_.start()
        hub.start()
        try:
            yield
        finally:
            await hub.stop()
            feed_.stop()

    app = FastAPI(title="asvtwin", lifespan=lifespan, docs_url=None, redoc_url=None,
                  openapi_url=None)
    app.state.hub = hub
    app.state.feed = feed_
    web = web_dir()
    app.mount("/static", StaticFiles(directory=web), name="static")

    @app.exception_handler(_TooLarge)
    async def _too_large(_req: Request, exc: _TooLarge) -> Response:
        hub.counters["refused_413"] += 1
        hub.counters["refused"] += 1
        return _error(413, str(exc))

    @app.get("/", include_in_schema=False)
    async def index() -> Response:
        return FileResponse(web / "index.html", headers={"Cache-Control": "no-cache"})

    @app.get("/api/info")
    async def info() -> Response:
        return Response(orjson.dumps({**feed_.info(), "schema": SCHEMA_ID}),
                        media_type="application/json")

    @app.get("/api/scene")
    async def scene() -> Response:
        def build() -> bytes:
            with scene_lock:
                if "doc" not in scene_cache:
                    scene_cache["doc"] = orjson.dumps(scene_document(feed_.scene()),
                                                      option=orjson.OPT_SERIALIZE_NUMPY)
                return scene_cache["doc"]
        data = await asyncio.to_thread(build)
        return Response(data, media_type="application/json",
                        headers={"Cache-Control": "max-age=3600"})

    @app.get("/api/snapshot")
    async def snapshot() -> Response:
        fr = hub.last_frame or feed_.frame()
        if fr is None:
            return _error(404, "no snapshot yet (the twin has not ticked)")
        return Response(fr.data, media_type="application/json")

    @app.get("/api/schema")
    async def schema() -> Response:
        return Response(orjson.dumps(json_schema()), media_type="application/json")

    @app.get("/api/stats")
    async def stats() -> Response:
        return Response(orjson.dumps(hub.stats()), media_type="application/json")

    @app.post("/api/control/{action}")
    async def control(action: str, request: Request) -> Response:
        model = CONTROL_MODELS.get(action)
        if model is None:
            return _refuse(404, f"unknown action {action!r}; known: {', '.join(CONTROL_MODELS)}")
        if action not in feed_.actions:
            return _refuse(409, f"action {action!r} is not available on a {feed_.kind} feed; "
                                f"available: {', '.join(feed_.actions)}")
        body = await request.body()
        try:
            raw = orjson.loads(body) if body.strip() else {}
        except orjson.JSONDecodeError as exc:
            return _refuse(400, f"malformed JSON: {exc}")
        if not isinstance(raw, dict):
            return _refuse(400, f"the body must be a JSON object, got {type(raw).__name__}")
        try:
            req = model.model_validate(raw)
        except ValidationError as exc:
            errs = "; ".join(f"{'.'.join(str(p) for p in e['loc']) or 'body'}: {e['msg']}"
                             for e in exc.errors()[:5])
            return _refuse(422, f"invalid {action} request: {errs}")
        payload = req.model_dump()
        if action == "inject":
            payload = {"spec": req.spec.to_target_spec()}  # type: ignore[attr-defined]
        try:
            answer = await asyncio.to_thread(feed_.control, action, payload)
        except ControlError as exc:
            return _refuse(409, str(exc))
        hub.counters[f"control_{action}"] += 1
        return Response(orjson.dumps(answer), media_type="application/json")

    def _refuse(status: int, reason: str) -> Response:
        hub.counters[f"refused_{status}"] += 1
        hub.counters["refused"] += 1
        return _error(status, reason)

    from asvtwin.whatif.api import add_whatif_route

    add_whatif_route(app, feed_, _refuse)  # POST /api/whatif

    @app.websocket("/ws")
    async def ws_endpoint(ws: WebSocket) -> None:
        q: dict[str, Any] = {k: v for k, v in ws.query_params.items()
                             if k in ("rate_hz", "format", "ack")}
        unknown = set(ws.query_params) - {"rate_hz", "format", "ack", "token"}
        try:
            if unknown:
                raise ValueError(f"unknown query parameter(s) {sorted(unknown)}")
            opts = ClientOptions.model_validate(
                {**q, **({"rate_hz": float(q["rate_hz"])} if "rate_hz" in q else {})})
        except (ValueError, ValidationError) as exc:
            hub.counters["refused_ws_options"] += 1
            hub.counters["refused"] += 1
            await ws.close(code=1008, reason=f"bad options: {exc}"[:120])
            return
        await ws.accept()
        client = hub.add(opts)
        await ws.send_text(orjson.dumps({"type": "hello", "schema": SCHEMA_ID, "client": client.id,
                                         "rate_hz": opts.rate_hz, "format": opts.format,
                                         **feed_.info()}).decode())
        sender = asyncio.ensure_future(hub.send_loop(ws, client))
        receiver = asyncio.ensure_future(_receive(ws, client))
        try:
            await asyncio.wait({sender, receiver}, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for t in (sender, receiver):
                t.cancel()  # never await close() on a stalled socket: it blocks too
                t.add_done_callback(_ended)
            hub.remove(client)

    def _ended(t: asyncio.Future[Any]) -> None:
        """A client's task ended: a client gone mid-send (dropped, send timeout; a send
        being cancelled can end with the transport's error) is counted, not logged as an
        unretrieved task exception."""
        if not t.cancelled() and t.exception() is not None:
            hub.counters[f"ws_ended_{type(t.exception()).__name__}"] += 1

    async def _receive(ws: WebSocket, client: Any) -> None:
        """Options changes from the client, ``{"rate_hz": 5}``; ends on disconnect."""
        while True:
            try:
                text = await ws.receive_text()
            except (WebSocketDisconnect, RuntimeError, KeyError):
                return
            try:
                raw = orjson.loads(text)
                if isinstance(raw, dict) and set(raw) == {"ack"}:
                    client.credit.set()  # the client took the last snapshot
                    continue
                client.options = ClientOptions.model_validate({**client.options.model_dump(), **raw})
            except (orjson.JSONDecodeError, ValidationError, TypeError) as exc:
                hub.counters["refused_ws_message"] += 1
                hub.counters["refused"] += 1
                client.events.append({"type": "error", "error": f"bad message: {exc}"[:300]})
                client.wake.set()

    guarded = _Guard(app, token=token, counters=hub.counters)
    guarded.hub = hub  # type: ignore[attr-defined]
    guarded.fastapi = app  # type: ignore[attr-defined]
    return guarded


def _make_server(feed: Any, host: str, port: int, token: str | None, log_level: str,
                 send_timeout_s: float = 2.0) -> Any:
    import uvicorn

    if not _loopback(host) and not token:
        token = secrets.token_urlsafe(18)
    app = create_app(feed, token=token, send_timeout_s=send_timeout_s)
    config = uvicorn.Config(app, host=host, port=port, log_level=log_level, lifespan="on",
                            ws_max_size=MAX_BODY_BYTES, ws_per_message_deflate=False,
                            proxy_headers=False, server_header=False)
    server = uvicorn.Server(config)
    server.asvtwin_token = token  # type: ignore[attr-defined]
    server.asvtwin_app = app  # type: ignore[attr-defined]
    return server


def _bound_url(server: Any, host: str) -> str:
    port = server.servers[0].sockets[0].getsockname()[1]
    shown = "127.0.0.1" if host in ("", "0.0.0.0", "::") else host
    if ":" in shown:
        shown = f"[{shown}]"
    token = server.asvtwin_token
    return f"http://{shown}:{port}/" + (f"?token={token}" if token else "")


def serve(feed_or_twin: Any, *, host: str = "127.0.0.1", port: int = 8765,
          token: str | None = None, log_level: str = "warning",
          on_ready: Callable[[str], None] | None = None) -> None:
    """Serve a twin, a recording or a feed until interrupted (blocking, uvicorn).

    Prints ``viewer: http://127.0.0.1:PORT/`` once listening (with ``?token=...`` when bound
    to another address: a token is generated when none is given). The feed's loop is
    started at startup and stopped at shutdown (Ctrl-C).
    """
    server = _make_server(feed_or_twin, host, port, token, log_level)
    orig = server.startup

    async def startup(sockets: Any = None) -> None:
        await orig(sockets=sockets)
        if server.started:
            url = _bound_url(server, host)
            print(f"viewer: {url}  (snapshots on WebSocket /ws; Ctrl-C stops)", flush=True)
            if on_ready is not None:
                on_ready(url)

    server.startup = startup
    server.run()


class ServerThread:
    """Run the server in a background thread (tests, benchmark): ``url``, ``stop()``.

    >>> # with ServerThread(SyntheticFeed(5)) as srv: httpx.get(srv.url + "api/info")
    """

    def __init__(self, feed: Any, *, host: str = "127.0.0.1", port: int = 0,
                 token: str | None = None, log_level: str = "error",
                 send_timeout_s: float = 2.0) -> None:
        self.server = _make_server(feed, host, port, token, log_level, send_timeout_s)
        self.app = self.server.asvtwin_app
        self.hub: Hub = self.app.hub
        self.feed: SnapshotFeed = self.app.fastapi.state.feed
        self._thread = threading.Thread(target=self.server.run, name="asvtwin-server", daemon=True)
        self._thread.start()
        deadline = time.monotonic() + 20.0
        while not self.server.started:
            if not self._thread.is_alive() or time.monotonic() > deadline:
                raise RuntimeError("the server did not start")
            time.sleep(0.02)
        self.url = _bound_url(self.server, host).split("?")[0]
        self.port = int(self.url.rsplit(":", 1)[1].strip("/"))

    def stop(self) -> None:
        self.server.should_exit = True
        self._thread.join(timeout=10.0)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
