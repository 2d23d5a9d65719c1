"""A vessel replayed from an AIS log: the ``ais_replay`` target behaviour.

A scenario target with ``behaviour: {kind: ais_replay, file: LOG, mmsi: M}`` moves as
vessel ``M`` moved in the log. The log is read through the real AIS pipeline
(:class:`~asvtwin.sources.ais.AisPipeline`: tag-block times, checksums, validation;
malformed lines are counted and skipped, as from a live feed) and the vessel's position
reports become a track in the scene's NED frame.

**Time.** Simulation time 0 is the time of the first accepted report in the log (of any
vessel, so two vessels replayed from one log keep their relative timing), like ``ais.mode:
file``. Report times come from the IEC 61162-450 tag block (``c:``); a log without tag
blocks has no usable times and is refused.

**State between reports.** The position is interpolated linearly between consecutive
reports (AIS positions are GNSS fixes, already noisy by a few metres); heading is the
reported true heading (COG when the heading is not available, 511), surge speed the
reported SOG, sway 0, yaw rate the reported rate of turn (0 when not available). Before
the first report the vessel waits at its first reported position; after the last it is
dead-reckoned along its last COG at its last SOG (the twin has nothing better; so does a
real receiver). The replayed vessel is kinematic ground truth: it is not pushed by the
physics or by any autopilot, and it does not react to the own ship.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from asvtwin.checks import F8 as _F8
from asvtwin.errors import ScenarioError
from asvtwin.geo import Scene
from asvtwin.sources.ais import AisPipeline, ReportBatch
from asvtwin.units import wrap_angle

__all__ = ["AisTrack", "read_ais_log"]


def read_ais_log(path: str | Path, scene: Scene) -> ReportBatch:
    """Every accepted dynamic report of an NMEA log (tag-block times), in file order.

    Raises
    ------
    ScenarioError
        The file cannot be read.
    """
    p = Path(path)
    try:
        raw = p.read_bytes().splitlines()
    except OSError as exc:
        raise ScenarioError(f"ais_replay file {p}: cannot read the AIS log: {exc}") from exc
    return AisPipeline(scene).feed_batch(raw)


class AisTrack:
    """The track of one MMSI in an AIS log, as a state at any simulation time.

    Parameters
    ----------
    reports : ReportBatch
        The log's accepted reports (:func:`read_ais_log`), NED in the scene's frame.
    mmsi : int
        The vessel to replay.
    source : str
        Where the reports came from (for error messages).

    Raises
    ------
    ScenarioError
        The MMSI has fewer than one position report in the log.
    """

    def __init__(self, reports: ReportBatch, mmsi: int, *, source: str = "AIS log") -> None:
        if len(reports) == 0:
            raise ScenarioError(f"ais_replay {source}: no valid position report with a "
                                "tag-block time in the log")
        t0 = float(np.min(reports.t_unix_s))
        sel = np.flatnonzero(reports.mmsi == int(mmsi))
        if sel.size == 0:
            found = sorted(set(reports.mmsi.tolist()))
            raise ScenarioError(
                f"ais_replay {source}: MMSI {mmsi} has no position report in the log "
                f"(MMSIs found: {found[:10]}{' ...' if len(found) > 10 else ''})")
        order = sel[np.argsort(reports.t_unix_s[sel], kind="stable")]
        t = reports.t_unix_s[order] - t0
        keep = np.concatenate([[True], np.diff(t) > 0.0])  # one report per time stamp
        order, t = order[keep], t[keep]
        self.mmsi = int(mmsi)
        self.epoch_unix_s = t0
        self.t_s = t
        self.north_m = reports.north_m[order]
        self.east_m = reports.east_m[order]
        sog = np.nan_to_num(reports.sog_m_s[order], nan=0.0)
        cog = reports.cog_rad[order]
        hdg = reports.heading_rad[order]
        # heading: the gyro's when sent, else COG, else the direction of travel, else 0
        travel = np.zeros_like(t)
        if t.size > 1:
            d = np.arctan2(np.diff(self.east_m), np.diff(self.north_m))
            travel = np.concatenate([d, d[-1:]])
        self.heading_rad = np.where(np.isfinite(hdg), hdg, np.where(np.isfinite(cog), cog, travel))
        self.cog_rad = np.where(np.isfinite(cog), cog, self.heading_rad)
        self.sog_m_s = sog
        self.rot_rad_s = np.nan_to_num(reports.rot_rad_s[order], nan=0.0)

    def __len__(self) -> int:
        return int(self.t_s.size)

    def state_at(self, t_s: float) -> _F8:
        """The vessel's state ``[x, y, ψ, u, v, r]`` at simulation time ``t_s`` [s]."""
        t = self.t_s
        if t_s < t[0]:  # not heard yet: waiting at its first reported position
            return np.array([self.north_m[0], self.east_m[0],
                             self.heading_rad[0] % (2 * math.pi), 0.0, 0.0, 0.0])
        if t_s >= t[-1]:  # dead reckoning along the last COG
            dt = t_s - t[-1]
            c, s = math.cos(self.cog_rad[-1]), math.sin(self.cog_rad[-1])
            return np.array([self.north_m[-1] + self.sog_m_s[-1] * c * dt,
                             self.east_m[-1] + self.sog_m_s[-1] * s * dt,
                             self.heading_rad[-1] % (2 * math.pi), self.sog_m_s[-1], 0.0, 0.0])
        k = int(np.searchsorted(t, t_s, side="right")) - 1
        a = (t_s - t[k]) / (t[k + 1] - t[k])
        dpsi = float(wrap_angle(self.heading_rad[k + 1] - self.heading_rad[k]))
        return np.array([self.north_m[k] + a * (self.north_m[k + 1] - self.north_m[k]),
                         self.east_m[k] + a * (self.east_m[k + 1] - self.east_m[k]),
                         (self.heading_rad[k] + a * dpsi) % (2 * math.pi),
                         self.sog_m_s[k] + a * (self.sog_m_s[k + 1] - self.sog_m_s[k]), 0.0,
                         self.rot_rad_s[k]])
