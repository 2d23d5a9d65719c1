"""A fork of the twin: what the own ship knows at one instant, as plain arrays.

A :class:`Fork` is taken from a :class:`~asvtwin.twin.snapshot.Snapshot` (the live twin's
``latest()``), from its encoded bytes or from a decoded message (a recording's
``message_at(t)``): the own ship's navigation state and route, the tracked targets with
their estimated states ``[x, y, v_x, v_y]`` and covariances, the disturbance estimate d̂
and the weather. It never reads the ground truth: a what-if question is asked of the
twin's picture, as a navigator would ask it of the radar.

Frames and units as in the snapshot: NED metres in the scene's tangent plane, radians
clockwise from north, m/s, N and Nm (d̂ in the body frame).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.errors import StateError
from asvtwin.twin.snapshot import Snapshot, decode, encode
from asvtwin.vessel import VesselParams, vessel_by_name

__all__ = ["Fork", "fork", "fork_scenario"]

#: Track statuses a fork takes (tentative tracks are not yet believed by the twin).
_BELIEVED = ("confirmed", "coasting")


@dataclass(frozen=True, eq=False)
class Fork:
    """The twin's picture at ``t_s``, ready to roll out.

    Attributes
    ----------
    t_s : float
        Simulation time of the fork [s].
    vessel : str
        Own ship's parameter set (``cybership2`` or ``cybership2_full_scale``).
    own_state : ndarray (6,)
        ``[x, y, ψ, u, v, r]`` [m, m, rad, m/s, m/s, rad/s].
    route : ndarray (k, 2)
        Remaining waypoints [m] (from the active one on).
    cruise_speed_m_s : float
        Speed the own ship follows its route at [m/s].
    d_hat : ndarray (3,)
        Disturbance estimate τ̂_d [N, N, Nm], body frame.
    track_ids, track_mmsi : ndarray (n,) int
        Track numbers and MMSI (−1 without AIS).
    track_mean : ndarray (n, 4)
        ``[x, y, v_x, v_y]`` [m, m/s].
    track_cov : ndarray (n, 4, 4)
        Covariance of ``track_mean`` [m², m²/s, m²/s²].
    track_length_m : ndarray (n,)
        Hull length per track [m]: from AIS static data when tied to AIS, else the own
        ship's length (an unknown hull is assumed as large as ours).
    track_names : tuple of str
        Name a navigator reads ("COASTER", or "track 3").
    wind_speed_m_s, wind_from_rad : float
        Wind at the own ship (NaN when unknown).
    filter_enabled : bool
        Whether the safety filter is in the loop at the fork.
    filter_period_s : float
        Time between the twin's filter calls [s] (``1 / rates.filter_hz``): the rollouts'
        filter period unless :class:`~asvtwin.whatif.RolloutConfig` sets one (NaN:
        unknown, the rollouts' default).
    scenario : str
        Scenario name of the snapshot.
    """

    t_s: float
    vessel: str
    own_state: _F8
    route: _F8
    cruise_speed_m_s: float
    d_hat: _F8 = field(default_factory=lambda: np.zeros(3))
    track_ids: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    track_mmsi: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    track_mean: _F8 = field(default_factory=lambda: np.zeros((0, 4)))
    track_cov: _F8 = field(default_factory=lambda: np.zeros((0, 4, 4)))
    track_length_m: _F8 = field(default_factory=lambda: np.zeros(0))
    track_names: tuple[str, ...] = ()
    wind_speed_m_s: float = float("nan")
    wind_from_rad: float = float("nan")
    filter_enabled: bool = True
    scenario: str = ""
    filter_period_s: float = float("nan")

    @property
    def params(self) -> VesselParams:
        """The own ship's vessel parameters."""
        return vessel_by_name(self.vessel)

    @property
    def n_tracks(self) -> int:
        return int(self.track_mean.shape[0])


def _arr(msg: dict[str, Any], path: str, shape: tuple[int, ...]) -> _F8:
    node: Any = msg
    for key in path.split("."):
        node = node.get(key) if isinstance(node, dict) else None
    a = np.array([] if node is None else node, dtype=float)  # None inside lists -> nan
    try:
        return a.reshape(shape)
    except ValueError as exc:
        raise StateError(f"snapshot field {path} must have shape {shape}, actually: "
                         f"{a.shape}") from exc


def fork(snapshot: Snapshot | bytes | str | dict[str, Any], *,
         cruise_speed_m_s: float | None = None) -> Fork:
    """Take a :class:`Fork` from a snapshot (object, encoded JSON or decoded message).

    Parameters
    ----------
    snapshot : Snapshot, bytes, str or dict
        The twin's snapshot at the instant to fork.
    cruise_speed_m_s : float, optional
        Route speed [m/s]; default the own ship's present speed over ground.

    Raises
    ------
    StateError
        A message that is not a snapshot, a non-finite own state, a track covariance that
        is not symmetric positive semi-definite.

    Examples
    --------
    >>> from asvtwin.twin.snapshot import empty_snapshot, OwnShip, ro
    >>> s = empty_snapshot(t_s=4.0, own=OwnShip(state=ro([0, 0, 0, 3.0, 0, 0]),
    ...                                         route=ro([[1000.0, 0.0]])))
    >>> f = fork(s)
    >>> f.t_s, f.n_tracks, f.cruise_speed_m_s
    (4.0, 0, 3.0)
    """
    if isinstance(snapshot, Snapshot):
        msg = decode(encode(snapshot))
    elif isinstance(snapshot, bytes | str):
        msg = decode(snapshot)
    else:
        msg = snapshot
    if not isinstance(msg, dict) or not str(msg.get("schema", "")).startswith("asvtwin.snapshot/"):
        raise StateError(f"not a twin snapshot (schema {msg.get('schema')!r} where "
                         "'asvtwin.snapshot/1' was expected)" if isinstance(msg, dict)
                         else f"not a twin snapshot: {type(msg).__name__}")
    own = msg["own"]
    x = _arr(msg, "own.state", (6,))
    if not np.isfinite(x).all():
        raise StateError(f"the own ship's state at t = {msg.get('t_s')} s is not finite: "
                         f"{x.tolist()}; nothing to fork from")
    route = _arr(msg, "own.route", (-1, 2))
    k = int(own.get("waypoint_index", 0))
    route = route[min(max(k, 0), max(len(route) - 1, 0)):] if len(route) else route
    vessel = str(own.get("vessel", "cybership2_full_scale"))
    own_len = float(own.get("length_m") or vessel_by_name(vessel).length)
    d_hat = _arr(msg, "observer.d_hat", (3,))
    if not np.isfinite(d_hat).all():
        d_hat = np.zeros(3)
    tr = msg.get("tracks", {})
    status = list(tr.get("status", []))
    mean = _arr(msg, "tracks.mean", (-1, 4))
    cov = _arr(msg, "tracks.cov", (-1, 4, 4))
    ids = np.asarray(tr.get("ids", []), np.int64)
    mmsi = np.asarray(tr.get("mmsi", []), np.int64)
    keep = np.array([s in _BELIEVED for s in status], bool) & np.isfinite(mean).all(axis=1)
    mean, cov, ids, mmsi = mean[keep], cov[keep], ids[keep], mmsi[keep]
    for i in range(len(cov)):
        c = cov[i]
        if not (np.isfinite(c).all() and np.allclose(c, c.T, atol=1e-6 * (1 + np.abs(c).max()))
                and np.linalg.eigvalsh(0.5 * (c + c.T))[0] > -1e-6 * (1 + np.abs(c).max())):
            raise StateError(f"track {int(ids[i])}: covariance is not symmetric positive "
                             f"semi-definite: {c.tolist()}")
    ais = msg.get("ais", {})
    ais_mmsi = list(ais.get("mmsi", []))
    ais_len = list(ais.get("length_m", []))
    ais_names = list(ais.get("names", []))
    length = np.full(len(ids), own_len)
    names: list[str] = []
    for i, m in enumerate(mmsi.tolist()):
        name = f"track {int(ids[i])}"
        if m >= 0 and m in ais_mmsi:
            j = ais_mmsi.index(m)
            if j < len(ais_len) and ais_len[j] is not None and math.isfinite(ais_len[j]):
                length[i] = float(ais_len[j])
            if j < len(ais_names) and ais_names[j]:
                name = f"{ais_names[j]} (track {int(ids[i])})"
        names.append(name)
    w = msg.get("weather", {})
    sog = float(np.hypot(x[3], x[4]))
    flt = msg.get("filter", {})
    return Fork(
        t_s=float(msg.get("t_s", 0.0)), vessel=vessel, own_state=x, route=route,
        cruise_speed_m_s=float(sog if cruise_speed_m_s is None else cruise_speed_m_s),
        d_hat=d_hat, track_ids=ids, track_mmsi=mmsi, track_mean=mean, track_cov=cov,
        track_length_m=length, track_names=tuple(names),
        wind_speed_m_s=float(w.get("wind_speed_m_s") or math.nan),
        wind_from_rad=float(w.get("wind_from_rad") or math.nan),
        filter_enabled=bool(flt.get("enabled", True)), scenario=str(msg.get("scenario", "")),
        filter_period_s=float(flt.get("period_s") or math.nan))


def fork_scenario(scenario: Any, *, at_s: float = 0.0, position_std_m: float | None = None,
                  velocity_std_m_s: float | None = None) -> Fork:
    """A fork of a scenario's *plan*: every vessel as written in the file, moved at its
    start velocity for ``at_s`` seconds, the targets believed with the given standard
    deviations (default 0.5 ship lengths
    in position and 0.05 m/s·√(L/1.255 m) in velocity). For studies of the scenario
    library without running the tracker; the live twin forks with :func:`fork`.
    """
    from asvtwin.scenarios import resolve_scene
    from asvtwin.units import KNOT_M_S

    scene = resolve_scene(scenario)
    frame = scene.frame
    params = vessel_by_name(scenario.own_ship.vessel)
    L = params.length
    sp = 0.5 * L if position_std_m is None else float(position_std_m)
    sv = 0.05 * math.sqrt(L / 1.255) if velocity_std_m_s is None else float(velocity_std_m_s)
    if not (math.isfinite(at_s) and at_s >= 0 and sp >= 0 and sv >= 0):
        raise StateError(f"at_s, position_std_m, velocity_std_m_s must be finite and >= 0, "
                         f"actually: {at_s}, {sp}, {sv}")
    o = scenario.own_ship
    psi = math.radians(o.heading_deg)
    u = o.speed_kn * KNOT_M_S
    p0 = o.start.to_ned(frame) + at_s * u * np.array([math.cos(psi), math.sin(psi)])
    route = np.array([w.to_ned(frame) for w in o.route], dtype=float).reshape(-1, 2)
    mean, names, lengths, mmsi = [], [], [], []
    for i, t in enumerate(scenario.targets):
        h = math.radians(t.heading_deg)
        v = t.speed_kn * KNOT_M_S * np.array([math.cos(h), math.sin(h)])
        mean.append([*(t.start.to_ned(frame) + at_s * v), *v])
        names.append(f"{t.name} (track {i})")
        lengths.append(t.length_m)
        mmsi.append(-1 if t.mmsi is None else int(t.mmsi))
    n = len(mean)
    cov = np.tile(np.diag([sp**2, sp**2, sv**2, sv**2]), (n, 1, 1))
    return Fork(t_s=float(at_s), vessel=o.vessel,
                own_state=np.array([p0[0], p0[1], psi, u, 0.0, 0.0]), route=route,
                cruise_speed_m_s=o.cruise_speed_kn * KNOT_M_S,
                track_ids=np.arange(n, dtype=np.int64), track_mmsi=np.array(mmsi, np.int64),
                track_mean=np.array(mean, dtype=float).reshape(-1, 4), track_cov=cov,
                track_length_m=np.array(lengths, dtype=float), track_names=tuple(names),
                filter_enabled=o.controller.endswith("_psf"), scenario=scenario.name,
                filter_period_s=1.0 / scenario.rates.filter_hz)
