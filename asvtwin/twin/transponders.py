"""The simulated targets' AIS transponders: ground truth in, tagged NMEA lines out.

Each target with an AIS class broadcasts what its transponder would: a position report
(class A: type 1, every fourth a type 3; class B: type 18) at the ITU-R M.1371-5 nominal
interval for its speed (:func:`asvtwin.sources.ais.nominal_report_interval_s`: 10 s under
14 kn, 6 s to 23 kn, 2 s above for class A; 30 s for class B), and its static data every
6 minutes (type 5, or type 24 parts A and B), each line behind an IEC 61162-450 tag block
as the Norwegian Coastal Administration's feed sends them. The lines are the *only* way the
twin learns about these targets from AIS: they go through the real
:class:`~asvtwin.sources.ais.AisPipeline` like a live feed.

Which transponders are due is decided for all targets at once (arrays); only the due
ones are encoded (pyais), a handful per second even with fifty targets.

**GNSS error.** A real transponder reports its own GNSS fix, not the true position: the
reported position and velocity carry the receiver's error. Each report draws it anew
(white, seeded): per axis σ = :data:`GNSS_POSITION_STD_M` (4 m; a horizontal 95 % radius
of 2.45 σ ≈ 10 m, the limit of ITU-R M.1371-5's "high" position accuracy flag, which
typical class A receivers with SBAS/DGNSS meet) and :data:`GNSS_VELOCITY_STD_M_S`
(0.05 m/s per axis, a GNSS Doppler velocity; SOG and COG follow from the noisy velocity, so
COG is noisy at low speed as real AIS COG is). Heading and rate of turn come from the gyro
and are sent as they are. The errors are independent between reports; real GNSS error is
correlated over minutes (multipath, atmosphere), which this model leaves out on purpose
so that the tracker's AIS model (the same σ, white) is the correct one and the twin's NEES
measures the tracker's consistency, not a model mismatch.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.geo import LocalFrame
from asvtwin.sources.ais import (
    AisReport,
    AisStatic,
    encode_report,
    encode_static,
    nominal_report_interval_s,
    tag_block,
)
from asvtwin.units import wrap_angle

__all__ = ["GNSS_POSITION_STD_M", "GNSS_VELOCITY_STD_M_S", "STATIC_INTERVAL_S",
           "Transponders"]

#: Static and voyage data interval [s] (ITU-R M.1371-5: every 6 min).
STATIC_INTERVAL_S = 360.0
#: GNSS position error of a transponder's fix, per axis (north, east), 1 σ [m].
GNSS_POSITION_STD_M = 4.0
#: GNSS velocity error of a transponder's fix, per axis (north, east), 1 σ [m/s].
GNSS_VELOCITY_STD_M_S = 0.05


class Transponders:
    """AIS transponders of n simulated vessels.

    Parameters
    ----------
    mmsi : sequence of int
        MMSI per vessel; a vessel with class None sends nothing.
    ais_class : sequence of {"A", "B", None}
        Transponder class per vessel.
    names, ship_types, length_m, beam_m : sequences
        Static data per vessel.
    frame : LocalFrame
        The scene's tangent plane (NED -> WGS84).
    epoch_unix_s : float
        UNIX time of simulation time 0 [s].
    rng : numpy.random.Generator
        Reporting phases and radio channels.
    station : str
        Receiving base station of the tag blocks.
    position_std_m : float
        GNSS position error per axis, 1 σ [m] (0: exact positions).
    velocity_std_m_s : float
        GNSS velocity error per axis, 1 σ [m/s] (0: exact SOG and COG).
    """

    def __init__(self, mmsi: Sequence[int | None], ais_class: Sequence[str | None],
                 names: Sequence[str], ship_types: Sequence[int], length_m: ArrayLike,
                 beam_m: ArrayLike, *, frame: LocalFrame, epoch_unix_s: float,
                 rng: np.random.Generator, station: str = "2579999",
                 position_std_m: float = GNSS_POSITION_STD_M,
                 velocity_std_m_s: float = GNSS_VELOCITY_STD_M_S) -> None:
        from asvtwin.errors import ParameterError

        for name, v in (("position_std_m", position_std_m),
                        ("velocity_std_m_s", velocity_std_m_s)):
            if not (math.isfinite(v) and v >= 0.0):
                raise ParameterError(f"Transponders {name} must be finite and >= 0, "
                                     f"actually: {v!r}")
        self.position_std_m = float(position_std_m)
        self.velocity_std_m_s = float(velocity_std_m_s)
        self.frame = frame
        self.epoch_unix_s = float(epoch_unix_s)
        self.rng = rng
        self.station = station
        self.alive = True
        self._mmsi: list[int] = []
        self._class_b = np.zeros(0, bool)
        self._sends = np.zeros(0, bool)
        self._names: list[str] = []
        self._types: list[int] = []
        self._dims: list[tuple[float, float]] = []
        self._next = np.zeros(0)
        self._next_static = np.zeros(0)
        self._count = np.zeros(0, np.int64)
        self._seq = 0
        self.add(mmsi, ais_class, names, ship_types, length_m, beam_m, t_s=0.0)

    def add(self, mmsi: Sequence[int | None], ais_class: Sequence[str | None],
            names: Sequence[str], ship_types: Sequence[int], length_m: ArrayLike,
            beam_m: ArrayLike, *, t_s: float) -> None:
        """Append vessels (their first report falls within one interval of ``t_s``)."""
        k = len(mmsi)
        self._mmsi += [int(m) if m is not None else -1 for m in mmsi]
        self._class_b = np.concatenate([self._class_b, [c == "B" for c in ais_class]])
        self._sends = np.concatenate([self._sends, [c is not None and m is not None
                                                    for c, m in zip(ais_class, mmsi, strict=True)]])
        self._names += list(names)
        self._types += [int(t) for t in ship_types]
        self._dims += [(float(a), float(b)) for a, b in zip(np.asarray(length_m, float).reshape(-1), np.asarray(beam_m, float).reshape(-1), strict=True)]
        self._next = np.concatenate([self._next, t_s + np.floor(self.rng.uniform(0.0, 10.0, k))])
        self._next_static = np.concatenate(
            [self._next_static, t_s + np.floor(self.rng.uniform(0.0, 30.0, k))])
        self._count = np.concatenate([self._count, np.zeros(k, np.int64)])
        self._update_due()

    def _update_due(self) -> None:
        """The earliest time any transponder is due (a tick before it has nothing to do:
        most ticks, at 20 Hz against report intervals of seconds)."""
        s = self._sends
        self._due_at = (float(min(self._next[s].min(), self._next_static[s].min()))
                        if s.any() else math.inf)

    def _tagged(self, t_unix: float, sentences: list[str]) -> list[str]:
        tag = tag_block(station=self.station, t_unix_s=t_unix)
        return [tag + s for s in sentences]

    def step(self, t_s: float, states: NDArray[np.float64]) -> list[str]:
        """The lines broadcast at ``t_s`` by the vessels in ``states`` (n, 6) (truth)."""
        if not self.alive or t_s + 1e-9 < self._due_at:
            return []
        due = np.flatnonzero(self._sends & (self._next <= t_s + 1e-9))
        due_static = np.flatnonzero(self._sends & (self._next_static <= t_s + 1e-9))
        if not (due.size or due_static.size):
            return []
        t_unix = math.floor(self.epoch_unix_s + t_s)
        lines: list[str] = []
        if due.size:
            x = states[due].copy()
            c, s = np.cos(x[:, 2]), np.sin(x[:, 2])
            vn = c * x[:, 3] - s * x[:, 4]   # eq. η̇ = R(ψ) ν: velocity over ground
            ve = s * x[:, 3] + c * x[:, 4]
            # the transponder's GNSS fix: truth + white error (see the module docstring)
            e = self.rng.standard_normal((due.size, 4))
            x[:, :2] += self.position_std_m * e[:, :2]
            vn = vn + self.velocity_std_m_s * e[:, 2]
            ve = ve + self.velocity_std_m_s * e[:, 3]
            sog = np.hypot(vn, ve)
            cog = np.where(sog > 1e-3, np.arctan2(ve, vn), x[:, 2])
            lat, lon = self.frame.to_wgs84(x[:, 0], x[:, 1])
            nav = np.zeros(due.size, np.int64)
            interval = nominal_report_interval_s(sog, self._class_b[due], nav)
            for j, i in enumerate(due.tolist()):
                b = bool(self._class_b[i])
                msg_type = 18 if b else (3 if self._count[i] % 4 == 3 else 1)
                rep = AisReport(
                    mmsi=self._mmsi[i], t_unix_s=float(t_unix), msg_type=msg_type,
                    north_m=float(x[j, 0]), east_m=float(x[j, 1]), lat_deg=float(lat[j]),
                    lon_deg=float(lon[j]), sog_m_s=float(sog[j]),
                    cog_rad=float(wrap_angle(cog[j])), heading_rad=float(x[j, 2] % (2 * math.pi)),
                    rot_rad_s=None if b else float(x[j, 5]), nav_status=None if b else 0)
                ch = "AB"[int(self.rng.integers(2))]
                lines += self._tagged(t_unix, [encode_report(rep, channel=ch)])
                self._count[i] += 1
                self._next[i] = t_s + float(interval[j])
        for i in due_static.tolist():
            L, B = self._dims[i]
            st = AisStatic(
                mmsi=self._mmsi[i], t_unix_s=float(t_unix), msg_type=24 if self._class_b[i] else 5,
                name=self._names[i][:20].upper(), callsign=None, ship_type=self._types[i],
                # the halves sum to the rounded whole (round(2.5) is 2: halves of a 5 m
                # beam rounded each came to 4 m)
                to_bow_m=round(0.5 * L), to_stern_m=round(L) - round(0.5 * L),
                to_port_m=round(0.5 * B), to_starboard_m=round(B) - round(0.5 * B))
            for msg in encode_static(st, seq_id=self._seq % 10,
                                     channel="AB"[int(self.rng.integers(2))]):
                lines += self._tagged(t_unix, msg)
            self._seq += 1
            self._next_static[i] = t_s + STATIC_INTERVAL_S
        self._update_due()
        return lines
