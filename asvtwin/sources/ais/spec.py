"""Open an AIS source from a short text spec (the CLI's argument).

``tcp://HOST:PORT``, ``udp://:PORT`` (or ``udp://HOST:PORT``), ``synthetic`` (or
``synthetic:SEED``), or the path of an NMEA log file.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from urllib.parse import urlsplit

import numpy as np

from asvtwin.errors import ConfigError
from asvtwin.geo import Scene, default_scene
from asvtwin.sources.ais.network import TcpAisSource, UdpAisSource
from asvtwin.sources.ais.pipeline import AisPipeline
from asvtwin.sources.ais.replay import FileReplaySource, SyntheticAisSource
from asvtwin.sources.ais.source import PipelineSource
from asvtwin.sources.ais.synthetic import SyntheticTraffic

__all__ = ["open_ais_source"]


def open_ais_source(spec: str, *, clock: Callable[[], float], scene: Scene | None = None,
                    speed: float | None = 1.0, loop: bool = False, seed: int = 0,
                    silence_timeout_s: float = 60.0) -> PipelineSource:
    """Build the source a spec names.

    Parameters
    ----------
    spec : str
        ``tcp://HOST:PORT``, ``udp://[HOST]:PORT``, ``synthetic[:SEED]`` or a file path.
    clock : callable
        Current UNIX time [s] (live receive times; the synthetic traffic's start time).
    scene : Scene, optional
        Frame and bounds (the default scene when omitted).
    speed : float or None
        Replay / synthetic pacing factor (None: as fast as possible).
    loop : bool
        Loop a file replay.
    seed : int
        Seed of the reconnection jitter and of the synthetic traffic.
    silence_timeout_s : float
        TCP: reconnect after this long without data [s].

    Raises
    ------
    ConfigError
        If the spec is malformed or the file does not exist.
    """
    scene = scene if scene is not None else default_scene()
    rng = np.random.default_rng(seed)
    if spec.startswith(("tcp://", "udp://")):
        u = urlsplit(spec)
        try:
            port = u.port
        except ValueError as exc:
            raise ConfigError(f"AIS source {spec!r}: port must be 0..65535") from exc
        if port is None:
            raise ConfigError(f"AIS source {spec!r}: a port is required, e.g. tcp://host:5631")
        pipeline = AisPipeline(scene, clock=clock)
        if u.scheme == "tcp":
            if not u.hostname:
                raise ConfigError(f"AIS source {spec!r}: a host is required, e.g. tcp://host:5631")
            return TcpAisSource(u.hostname, port, pipeline=pipeline, clock=clock, rng=rng,
                                silence_timeout_s=silence_timeout_s)
        return UdpAisSource(port, host=u.hostname or "0.0.0.0", pipeline=pipeline, clock=clock)
    if spec == "synthetic" or spec.startswith("synthetic:"):
        if ":" in spec:
            try:
                rng = np.random.default_rng(int(spec.split(":", 1)[1]))
            except ValueError as exc:
                raise ConfigError(f"AIS source {spec!r}: synthetic:SEED needs an integer") from exc
        traffic = SyntheticTraffic(rng=rng, start_unix_s=clock(), scene=scene)
        return SyntheticAisSource(traffic, speed=speed, pipeline=AisPipeline(scene))
    if not Path(spec).is_file():
        raise ConfigError(f"AIS source {spec!r} is neither tcp://HOST:PORT, udp://:PORT, "
                          "synthetic nor an existing file")
    # untagged lines of a log are stamped with the receive clock (counted as a notice)
    return FileReplaySource(spec, speed=speed, loop=loop, pipeline=AisPipeline(scene),
                            clock=clock)
