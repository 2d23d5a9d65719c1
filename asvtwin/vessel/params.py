"""Vessel parameter sets: the 3-DOF manoeuvring model's coefficients, validated.

A :class:`VesselParams` holds the rigid-body and hydrodynamic coefficients of the model

.. math::

    \\mathbf{M}\\dot{\\boldsymbol\\nu} + \\mathbf{C}(\\boldsymbol\\nu)\\boldsymbol\\nu
    + \\mathbf{D}(\\boldsymbol\\nu)\\boldsymbol\\nu = \\boldsymbol\\tau + \\boldsymbol\\tau_d

in SNAME notation (Fossen 2011, ch. 6-7): added mass ``X_udot`` ..., linear damping
``X_u`` ..., nonlinear damping ``X_uu`` (= X_|u|u), ``X_uuu``, ``Y_vv`` (= Y_|v|v),
``Y_rv`` (= Y_|r|v), ``Y_vr`` (= Y_|v|r), ``Y_rr`` (= Y_|r|r), and likewise for N.

Two parameter sets ship: :func:`cybership2` (the 1:70 model-scale supply ship the paper's
RL and safety filter use) and :func:`cybership2_full_scale` (the same hull Froude-scaled by
70, an 88 m supply vessel at home in the Trondheim Fjord). :func:`froude_scale` scales any
set.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from asvtwin.checks import check_finite
from asvtwin.errors import ParameterError

__all__ = [
    "PACKED_FIELDS",
    "RHO_FRESH",
    "RHO_SEA",
    "VESSELS",
    "ActuatorParams",
    "VesselParams",
    "cybership2",
    "cybership2_full_scale",
    "froude_scale",
    "vessel_by_name",
]

#: Density of sea water [kg/m^3] and of the fresh water of a model basin [kg/m^3].
RHO_SEA = 1025.0
RHO_FRESH = 1000.0

# Physical dimension of every coefficient as exponents of (mass kg, length m, time s).
# Angles (rad) are dimensionless. Used by froude_scale: one table, no per-field formulas.
_DIMENSIONS: dict[str, tuple[int, int, int]] = {
    "m": (1, 0, 0),
    "I_z": (1, 2, 0),
    "x_g": (0, 1, 0),
    "length": (0, 1, 0),
    "beam": (0, 1, 0),
    "draft": (0, 1, 0),
    "area_frontal": (0, 2, 0),
    "area_lateral": (0, 2, 0),
    "X_udot": (1, 0, 0),
    "Y_vdot": (1, 0, 0),
    "Y_rdot": (1, 1, 0),
    "N_vdot": (1, 1, 0),
    "N_rdot": (1, 2, 0),
    "X_u": (1, 0, -1),
    "Y_v": (1, 0, -1),
    "Y_r": (1, 1, -1),
    "N_v": (1, 1, -1),
    "N_r": (1, 2, -1),
    "X_uu": (1, -1, 0),
    "X_uuu": (1, -2, 1),
    "Y_vv": (1, -1, 0),
    "Y_rv": (1, 0, 0),
    "Y_vr": (1, 0, 0),
    "Y_rr": (1, 1, 0),
    "N_vv": (1, 0, 0),
    "N_rv": (1, 1, 0),
    "N_vr": (1, 1, 0),
    "N_rr": (1, 2, 0),
}


def _check_finite(name: str, value: float, source: str) -> None:
    check_finite(value, f"field {name!r}", where=source)


@dataclass(frozen=True, slots=True)
class VesselParams:
    """Coefficients of the 3-DOF model; SI units, body frame, SNAME notation.

    Parameters
    ----------
    name : str
        Identifier (``"cybership2"``).
    m : float
        Mass [kg].
    I_z : float
        Moment of inertia about the z axis through the origin of the body frame [kg m^2].
    x_g : float
        Longitudinal position of the centre of gravity [m].
    length, beam, draft : float
        Hull dimensions [m]; ``length`` and ``beam`` also give the hull outline.
    area_frontal, area_lateral : float
        Projected wind areas above the waterline [m^2], for the wind model.
    X_udot, Y_vdot, Y_rdot, N_vdot, N_rdot : float
        Added mass [kg, kg m, kg m^2].
    X_u, Y_v, Y_r, N_v, N_r : float
        Linear damping derivatives.
    X_uu, X_uuu, Y_vv, Y_rv, Y_vr, Y_rr, N_vv, N_rv, N_vr, N_rr : float
        Nonlinear damping derivatives (``X_uu`` is X_|u|u, ``Y_rv`` is Y_|r|v, ...).
    rho_water : float
        Density of the water the coefficients hold in [kg/m^3].
    actuators : ActuatorParams
        Thruster limits and dynamics.
    """

    name: str
    m: float
    I_z: float
    x_g: float
    length: float
    beam: float
    draft: float
    area_frontal: float
    area_lateral: float
    X_udot: float
    Y_vdot: float
    Y_rdot: float
    N_vdot: float
    N_rdot: float
    X_u: float
    Y_v: float
    Y_r: float
    N_v: float
    N_r: float
    X_uu: float
    X_uuu: float
    Y_vv: float
    Y_rv: float
    Y_vr: float
    Y_rr: float
    N_vv: float
    N_rv: float
    N_vr: float
    N_rr: float
    rho_water: float = RHO_FRESH
    actuators: ActuatorParams = field(default_factory=lambda: ActuatorParams())
    source: str = field(default="<code>", compare=False, repr=False)

    def __post_init__(self) -> None:
        src = self.source
        for name in _DIMENSIONS:
            _check_finite(name, float(getattr(self, name)), src)
        for name in ("m", "I_z", "length", "beam", "draft", "rho_water"):
            if getattr(self, name) <= 0:
                raise ParameterError(
                    f"{src}: field {name!r} must be > 0, actually: {getattr(self, name)}"
                )
        for name in ("area_frontal", "area_lateral"):
            if getattr(self, name) < 0:
                raise ParameterError(
                    f"{src}: field {name!r} must be >= 0, actually: {getattr(self, name)}"
                )
        M = self.M
        eig = np.linalg.eigvalsh(0.5 * (M + M.T))
        if eig.min() <= 0:
            raise ParameterError(
                f"{src}: mass matrix M (m - added mass) must be positive definite, "
                f"actually has eigenvalues {np.round(eig, 6).tolist()}"
            )
        # Damping must dissipate energy: linear part positive definite, and the principal
        # nonlinear terms in surge and sway must not feed energy in.
        for name in ("X_u", "Y_v", "N_r"):
            if getattr(self, name) >= 0:
                raise ParameterError(
                    f"{src}: field {name!r} (linear damping) must be < 0 "
                    f"(negative damping is refused), actually: {getattr(self, name)}"
                )
        for name in ("X_uu", "X_uuu", "Y_vv"):
            if getattr(self, name) > 0:
                raise ParameterError(
                    f"{src}: field {name!r} (nonlinear damping) must be <= 0, "
                    f"actually: {getattr(self, name)}"
                )
        D_L = self.D_linear
        eig_d = np.linalg.eigvalsh(0.5 * (D_L + D_L.T))
        if eig_d.min() <= 0:
            raise ParameterError(
                f"{src}: linear damping matrix D_L must be positive definite in its "
                f"symmetric part, actually has eigenvalues {np.round(eig_d, 6).tolist()}"
            )

    # ------------------------------------------------------------------ derived matrices
    @property
    def M(self) -> NDArray[np.float64]:
        """System inertia matrix M = M_RB + M_A (3, 3) [kg, kg m, kg m^2]."""
        m, xg = self.m, self.x_g
        return np.array(
            [
                [m - self.X_udot, 0.0, 0.0],
                [0.0, m - self.Y_vdot, m * xg - self.Y_rdot],
                [0.0, m * xg - self.N_vdot, self.I_z - self.N_rdot],
            ]
        )

    @property
    def D_linear(self) -> NDArray[np.float64]:
        """Linear damping matrix D_L (3, 3)."""
        return -np.array(
            [[self.X_u, 0.0, 0.0], [0.0, self.Y_v, self.Y_r], [0.0, self.N_v, self.N_r]]
        )

    def packed(self) -> NDArray[np.float64]:
        """The coefficients the kernels need, as one flat float64 vector.

        Layout: see :data:`PACKED_FIELDS`. ``M_inv`` is precomputed; ``M23s`` is the
        symmetrised off-diagonal inertia used in the skew-symmetric C(ν).
        """
        M = self.M
        Minv = np.linalg.inv(M)
        values = list(Minv.ravel()) + [M[0, 0], M[1, 1], 0.5 * (M[1, 2] + M[2, 1])]
        values += [getattr(self, f) for f in PACKED_FIELDS[12:]]
        return np.asarray(values, dtype=np.float64)

    # ----------------------------------------------------------------------- conversions
    def replace(self, **changes: Any) -> VesselParams:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """Plain-value dictionary (for TOML/JSON and the viewer)."""
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d.pop("source")
        d["actuators"] = self.actuators.to_dict()
        return d

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, source: str = "<dict>") -> VesselParams:
        """Build from a plain dictionary, naming ``source`` in any error."""
        known = {f.name for f in dataclasses.fields(cls)} - {"source"}
        unknown = set(data) - known
        if unknown:
            raise ParameterError(f"{source}: unknown field(s) {sorted(unknown)}")
        missing = [n for n in _DIMENSIONS if n not in data]
        if missing:
            raise ParameterError(f"{source}: missing field(s) {missing}")
        kw: dict[str, Any] = {}
        for k, v in data.items():
            if k == "actuators":
                kw[k] = ActuatorParams.from_dict(v, source=source)
            elif k == "name":
                kw[k] = str(v)
            else:
                try:
                    kw[k] = float(v)
                except (TypeError, ValueError) as exc:
                    raise ParameterError(
                        f"{source}: field {k!r} must be a number, actually: {v!r}"
                    ) from exc
        return cls(**kw, source=source)

    @classmethod
    def from_toml(cls, path: str | Path) -> VesselParams:
        """Load a parameter set from a TOML file (the fields of this class, flat; an
        optional ``[actuators]`` table)."""
        path = Path(path)
        try:
            data = tomllib.loads(path.read_text())
        except (OSError, tomllib.TOMLDecodeError) as exc:
            raise ParameterError(f"{path}: cannot read vessel parameters: {exc}") from exc
        return cls.from_dict(data, source=str(path))


@dataclass(frozen=True, slots=True)
class ActuatorParams:
    """Limits and dynamics of the generalised thrust τ = [τ_u, τ_v, τ_r].

    Each DOF's actual thrust follows its command through saturation to
    ``[tau_min, tau_max]``, a first-order lag with time constant ``time_constant_s``
    (0 means instantaneous) and a rate limit ``rate_limit`` [N/s or Nm/s] (inf: none).

    Parameters
    ----------
    tau_min, tau_max : tuple of 3 floats
        Bounds [N, N, Nm]; equal bounds make a DOF unactuated.
    time_constant_s : tuple of 3 floats
        First-order lag time constants [s], >= 0.
    rate_limit : tuple of 3 floats
        Largest rate of change [N/s, N/s, Nm/s], > 0 (``inf`` for none).
    """

    tau_min: tuple[float, float, float] = (-math.inf, -math.inf, -math.inf)
    tau_max: tuple[float, float, float] = (math.inf, math.inf, math.inf)
    time_constant_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rate_limit: tuple[float, float, float] = (math.inf, math.inf, math.inf)
    source: str = field(default="<code>", compare=False, repr=False)

    def __post_init__(self) -> None:
        src = self.source
        for name in ("tau_min", "tau_max", "time_constant_s", "rate_limit"):
            val = getattr(self, name)
            if len(val) != 3:
                raise ParameterError(
                    f"{src}: actuators.{name} must have 3 entries (surge, sway, yaw), "
                    f"actually: {len(val)}"
                )
            object.__setattr__(self, name, tuple(float(x) for x in val))
            if any(math.isnan(x) for x in getattr(self, name)):
                raise ParameterError(f"{src}: actuators.{name} must not be NaN: {val}")
        for i in range(3):
            if self.tau_min[i] > self.tau_max[i]:
                raise ParameterError(
                    f"{src}: actuators.tau_min[{i}] must be <= tau_max[{i}], actually: "
                    f"{self.tau_min[i]} > {self.tau_max[i]}"
                )
            if not (0.0 <= self.time_constant_s[i] < math.inf):
                raise ParameterError(
                    f"{src}: actuators.time_constant_s[{i}] must be in [0, inf), "
                    f"actually: {self.time_constant_s[i]}"
                )
            if not self.rate_limit[i] > 0:
                raise ParameterError(
                    f"{src}: actuators.rate_limit[{i}] must be > 0 (inf for none), "
                    f"actually: {self.rate_limit[i]}"
                )

    @property
    def is_ideal(self) -> bool:
        """True when thrust follows its (saturated) command at once."""
        return all(t == 0.0 for t in self.time_constant_s) and all(
            math.isinf(r) for r in self.rate_limit
        )

    def ideal(self) -> ActuatorParams:
        """The same limits with instantaneous response (as the RL predecessors used)."""
        return ActuatorParams(tau_min=self.tau_min, tau_max=self.tau_max)

    def packed(self) -> NDArray[np.float64]:
        """(4, 3) array: rows tau_min, tau_max, time constant, rate limit."""
        return np.array(
            [self.tau_min, self.tau_max, self.time_constant_s, self.rate_limit], dtype=float
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "tau_min": list(self.tau_min),
            "tau_max": list(self.tau_max),
            "time_constant_s": list(self.time_constant_s),
            "rate_limit": list(self.rate_limit),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, source: str = "<dict>") -> ActuatorParams:
        unknown = set(data) - {"tau_min", "tau_max", "time_constant_s", "rate_limit"}
        if unknown:
            raise ParameterError(f"{source}: unknown actuators field(s) {sorted(unknown)}")
        return cls(**{k: tuple(v) for k, v in data.items()}, source=source)


#: Order of the packed parameter vector used by the numba kernels.
PACKED_FIELDS: tuple[str, ...] = (
    "Minv00", "Minv01", "Minv02", "Minv10", "Minv11", "Minv12", "Minv20", "Minv21", "Minv22",
    "M11", "M22", "M23s",
    "X_u", "X_uu", "X_uuu",
    "Y_v", "Y_vv", "Y_rv", "Y_r", "Y_vr", "Y_rr",
    "N_v", "N_vv", "N_rv", "N_r", "N_vr", "N_rr",
)  # fmt: skip


def cybership2() -> VesselParams:
    """CyberShip II, the 1:70 model of a supply ship (Skjetne et al. 2004).

    The parameter set of the NTNU safety-filter and RL code the paper builds on.
    Actuation as in those RL studies: surge force F_u in [0, 2] N (forward only), no sway
    force, yaw moment F_r in [-0.15, 0.15] Nm; a 0.2 s thruster lag by default (use
    ``params.replace(actuators=params.actuators.ideal())`` for ideal actuators).
    Wind areas are estimates for a supply ship (frontal ~ beam x 3 m of freeboard and
    superstructure at full scale, lateral ~ length x 10 m), scaled to the model.
    """
    return VesselParams(
        name="cybership2",
        m=23.8,
        I_z=1.760,
        x_g=0.046,
        length=1.255,
        beam=0.29,
        draft=0.08,
        area_frontal=300.0 / 70.0**2,
        area_lateral=900.0 / 70.0**2,
        X_udot=-2.0,
        Y_vdot=-10.0,
        Y_rdot=0.0,
        N_vdot=0.0,
        N_rdot=-1.0,
        X_u=-0.7225,
        Y_v=-0.8612,
        Y_r=0.1079,
        N_v=0.1052,
        N_r=-0.5,
        X_uu=-1.3274,
        X_uuu=-5.8664,
        Y_vv=-36.2823,
        Y_rv=-0.01,
        Y_vr=-0.01,
        Y_rr=-0.02,
        N_vv=5.0437,
        N_rv=-0.001,
        N_vr=-0.001,
        N_rr=0.005,
        rho_water=RHO_FRESH,
        actuators=ActuatorParams(
            tau_min=(0.0, 0.0, -0.15),
            tau_max=(2.0, 0.0, 0.15),
            time_constant_s=(0.2, 0.2, 0.2),
        ),
    )


def froude_scale(params: VesselParams, scale: float, *, rho_water: float = RHO_SEA,
                 name: str | None = None) -> VesselParams:
    """Froude-scale a parameter set by the length ratio ``scale`` (full / model).

    Froude similarity keeps u / sqrt(g L) equal: lengths scale by λ, times and speeds by
    √λ, masses by λ³·ρ_full/ρ_model. Each coefficient scales by its dimension
    (mass^a length^b time^c → (λ³ρ_ratio)^a λ^b λ^(c/2)); the actuator limits scale as
    forces (λ³ρ_ratio) and moments (λ⁴ρ_ratio), time constants as times (√λ).

    Parameters
    ----------
    params : VesselParams
        The model-scale set.
    scale : float
        λ = L_full / L_model, > 0.
    rho_water : float
        Water density of the scaled vessel [kg/m^3].
    """
    if not (math.isfinite(scale) and scale > 0):
        raise ParameterError(f"froude_scale: scale must be finite and > 0, actually: {scale}")
    mass_ratio = scale**3 * rho_water / params.rho_water
    time_ratio = math.sqrt(scale)
    changes: dict[str, Any] = {}
    for fname, (a, b, c) in _DIMENSIONS.items():
        changes[fname] = getattr(params, fname) * mass_ratio**a * scale**b * time_ratio**c
    force = mass_ratio  # kg m s^-2: mass_ratio * λ / λ
    moment = mass_ratio * scale
    act = params.actuators
    per_dof = (force, force, moment)
    def triple(values: tuple[float, float, float], k: tuple[float, float, float]
               ) -> tuple[float, float, float]:
        return (values[0] * k[0], values[1] * k[1], values[2] * k[2])

    times = (time_ratio, time_ratio, time_ratio)
    changes["actuators"] = ActuatorParams(
        tau_min=triple(act.tau_min, per_dof),
        tau_max=triple(act.tau_max, per_dof),
        time_constant_s=triple(act.time_constant_s, times),
        rate_limit=triple(act.rate_limit, (force / time_ratio, force / time_ratio,
                                           moment / time_ratio)),
    )
    changes["rho_water"] = rho_water
    changes["name"] = name or f"{params.name}_x{scale:g}"
    return dataclasses.replace(params, **changes)


def cybership2_full_scale() -> VesselParams:
    """CyberShip II Froude-scaled ×70 in sea water: an 88 m × 20 m supply vessel.

    Why this vessel: it keeps the exact, published hydrodynamics of the paper's model
    while giving the fjord a ship to scale (top speed ≈ 0.57·√70 ≈ 4.8 m/s ≈ 9 kn,
    surge force up to ≈ 0.7 MN), and the Froude-similarity test ties the two together.
    """
    return froude_scale(cybership2(), 70.0, rho_water=RHO_SEA, name="cybership2_full_scale")


#: Registry of the shipped parameter sets, by name.
VESSELS = {
    "cybership2": cybership2,
    "cybership2_full_scale": cybership2_full_scale,
}

#: Former names still accepted by :func:`vessel_by_name`.
_ALIASES = {"cybership2_fullscale": "cybership2_full_scale"}


def vessel_by_name(name: str) -> VesselParams:
    """A shipped parameter set by name (see :data:`VESSELS`)."""
    try:
        return VESSELS[_ALIASES.get(name, name)]()
    except KeyError:
        raise ParameterError(
            f"unknown vessel {name!r}; expected one of {sorted(VESSELS)}"
        ) from None
