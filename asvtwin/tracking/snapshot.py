"""The tracker's output: a frozen snapshot of all tracks as plain arrays."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.checks import F8 as _F8

__all__ = ["TRACK_STATUS", "TrackSnapshot"]


#: Track statuses: tentative (not yet M of N), confirmed (updated this tick), coasting
#: (confirmed, predicted only this tick).
TRACK_STATUS = ("tentative", "confirmed", "coasting")
_STR = {str}


def _ro(a: ArrayLike, dtype: type) -> NDArray:  # type: ignore[type-arg]
    out: NDArray = np.array(a, dtype=dtype, copy=True)  # type: ignore[type-arg]
    out.flags.writeable = False
    return out


@dataclass(frozen=True, eq=False)
class TrackSnapshot:
    """All tracks at one tick (read-only arrays; row ``i`` is one track).

    Attributes
    ----------
    t_s : float
        Tick time [s].
    ids : ndarray of int64, shape (n,)
        Track ids (unique over the tracker's life).
    mmsi : tuple of (int or None)
        MMSI tied to each track, None when not identified by AIS.
    mean : ndarray, shape (n, 4)
        ``[north_m, east_m, v_north_m_s, v_east_m_s]``.
    cov : ndarray, shape (n, 4, 4)
        Covariances.
    status : tuple of str
        One of :data:`TRACK_STATUS` per track.
    semi_axes_m : ndarray, shape (n, 2)
        Smoothed semi-major/minor axes from good ellipse fits [m]; NaN when unknown.
    last_update_s : ndarray, shape (n,)
        Time of the last measurement [s].
    updated_lidar, updated_ais : ndarray of bool, shape (n,)
        Which sensors updated the track at this tick.
    lidar_only_mean, ais_only_mean : ndarray, shape (n, 4)
        The per-sensor filters' means (NaN when that sensor never saw the track).
    counters : Mapping[str, int]
        The tracker's counters at this tick.
    """

    t_s: float
    ids: NDArray[np.int64]
    mmsi: tuple[int | None, ...]
    mean: _F8
    cov: _F8
    status: tuple[str, ...]
    semi_axes_m: _F8
    last_update_s: _F8
    updated_lidar: NDArray[np.bool_]
    updated_ais: NDArray[np.bool_]
    lidar_only_mean: _F8
    ais_only_mean: _F8
    counters: Mapping[str, int]

    @classmethod
    def build(cls, *, t_s: float, ids: ArrayLike, mmsi: ArrayLike, mean: ArrayLike, cov: ArrayLike,
              status: ArrayLike, semi_axes_m: ArrayLike, last_update_s: ArrayLike,
              updated_lidar: ArrayLike, updated_ais: ArrayLike, lidar_only_mean: ArrayLike,
              ais_only_mean: ArrayLike, counters: Mapping[str, int]) -> TrackSnapshot:
        """Copy the arrays into a read-only snapshot (``mmsi < 0`` means none)."""
        # (a tuple of str is taken as it is: the tracker builds one per tick, 200 strings
        # through a numpy string array cost ~50 µs)
        st = status if isinstance(status, tuple) and set(map(type, status)) <= _STR else \
            tuple(np.asarray(status, dtype=str).reshape(-1).tolist())
        mm = np.asarray(mmsi, dtype=np.int64).reshape(-1).tolist()
        return cls(
            t_s=float(t_s), ids=_ro(ids, np.int64),
            mmsi=tuple(mm) if not mm or min(mm) >= 0 else tuple([m if m >= 0 else None for m in mm]),
            mean=_ro(mean, np.float64).reshape(-1, 4), cov=_ro(cov, np.float64).reshape(-1, 4, 4),
            status=st,
            semi_axes_m=_ro(semi_axes_m, np.float64).reshape(-1, 2),
            last_update_s=_ro(last_update_s, np.float64), updated_lidar=_ro(updated_lidar, np.bool_),
            updated_ais=_ro(updated_ais, np.bool_),
            lidar_only_mean=_ro(lidar_only_mean, np.float64).reshape(-1, 4),
            ais_only_mean=_ro(ais_only_mean, np.float64).reshape(-1, 4),
            counters=MappingProxyType(dict(counters)),
        )

    def __len__(self) -> int:
        return int(self.ids.shape[0])

    @property
    def is_confirmed(self) -> NDArray[np.bool_]:
        """Confirmed or coasting tracks."""
        return np.array([s != "tentative" for s in self.status], dtype=bool)

    def select(self, mask: ArrayLike) -> TrackSnapshot:
        """The tracks where ``mask`` is True (a new snapshot)."""
        m = np.asarray(mask, dtype=bool)
        idx = np.flatnonzero(m)
        return TrackSnapshot.build(
            t_s=self.t_s, ids=self.ids[m], mmsi=np.array([-1 if self.mmsi[i] is None else self.mmsi[i] for i in idx], np.int64),
            mean=self.mean[m], cov=self.cov[m], status=np.array(self.status, dtype=object)[m] if len(self) else [],
            semi_axes_m=self.semi_axes_m[m], last_update_s=self.last_update_s[m],
            updated_lidar=self.updated_lidar[m], updated_ais=self.updated_ais[m],
            lidar_only_mean=self.lidar_only_mean[m], ais_only_mean=self.ais_only_mean[m], counters=self.counters,
        )

    def confirmed(self) -> TrackSnapshot:
        """Only the confirmed (and coasting) tracks."""
        return self.select(self.is_confirmed)
