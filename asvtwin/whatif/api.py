"""``POST /api/whatif`` on the viewer's server: ask the live (or replayed) twin "what if?".

The request (JSON, validated, unknown fields refused)::

    {"alternatives": ["route", "route+filter_off", "starboard:30"],
     "rollouts": 100, "horizon_s": 120, "seed": 0, "ghosts": 10}

(imported by :mod:`asvtwin.server` only, so FastAPI is there) forks the snapshot the
server is showing, rolls the alternatives out in a worker thread
and answers with :meth:`asvtwin.whatif.WhatIfAnswer.to_dict` plus up to ``ghosts``
futures per alternative (positions every 5 s, NED metres) for the viewer's ghost tracks.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from typing import Annotated, Any

import orjson
from fastapi import Request, Response
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from asvtwin.errors import AsvTwinError

__all__ = ["WhatIfRequest", "add_whatif_route"]


class WhatIfRequest(BaseModel):
    """A what-if question (see the module docstring)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    alternatives: Annotated[list[Annotated[str, Field(max_length=64)]],
                            Field(min_length=1, max_length=8)] = [
        "route", "route+filter_off", "keep_course", "starboard:30"]
    rollouts: Annotated[int, Field(ge=1, le=500)] = 100
    horizon_s: Annotated[float, Field(gt=0.0, le=900.0, allow_inf_nan=False)] = 120.0
    seed: Annotated[int, Field(ge=0, le=2**31 - 1)] = 0
    ghosts: Annotated[int, Field(ge=0, le=50)] = 10


def answer_bytes(snapshot_bytes: bytes, req: WhatIfRequest, *, land: Any = None,
                 params: Any = None) -> bytes:
    """The JSON answer to ``req`` about an encoded snapshot (raises AsvTwinError for a
    bad alternative or a snapshot that cannot be forked)."""
    from asvtwin.whatif import RolloutConfig, ask, fork, parse_alternative

    alts = [parse_alternative(s) for s in req.alternatives]
    ans = ask(fork(snapshot_bytes), alts, rollouts=req.rollouts, seed=req.seed,
              config=RolloutConfig(horizon_s=req.horizon_s), land=land, params=params)
    return orjson.dumps(ans.to_dict(ghosts=req.ghosts),
                        option=orjson.OPT_SERIALIZE_NUMPY)


def add_whatif_route(app: Any, feed: Any, refuse: Callable[[int, str], Any]) -> None:
    """Add ``POST /api/whatif`` to the FastAPI ``app`` serving ``feed``; ``refuse(status,
    reason)`` is the server's refusal (counted)."""
    lock = asyncio.Lock()  # one question at a time: each takes the CPU for seconds

    @app.post("/api/whatif")
    async def whatif(request: Request) -> Response:
        body = await request.body()
        try:
            raw = orjson.loads(body) if body.strip() else {}
            req = WhatIfRequest.model_validate(raw)
        except orjson.JSONDecodeError as exc:
            return refuse(400, f"malformed JSON: {exc}")  # type: ignore[no-any-return]
        except ValidationError as exc:
            errs = "; ".join(f"{'.'.join(str(p) for p in e['loc']) or 'body'}: {e['msg']}"
                             for e in exc.errors()[:5])
            return refuse(422, f"invalid whatif request: {errs}")  # type: ignore[no-any-return]
        fr = feed.frame()
        if fr is None:
            return refuse(409, "no snapshot yet (the twin has not ticked)")  # type: ignore[no-any-return]
        land = getattr(feed.scene(), "land", None)
        params = getattr(getattr(feed, "twin", None), "params", None)
        if lock.locked():
            return refuse(429, "a what-if question is being answered; ask again when it is done")  # type: ignore[no-any-return]
        async with lock:
            try:
                data = await asyncio.to_thread(answer_bytes, fr.data, req, land=land,
                                               params=params)
            except AsvTwinError as exc:
                return refuse(422, str(exc))  # type: ignore[no-any-return]
        return Response(data, media_type="application/json")
