"""The safety filter's optimal control problem, written once in CasADi for every backend.

The OCP of the paper's "Predictive Safety Filter" section,

.. math::

    \\min_{u, x, s} \\; \\|u_0 - u_L\\|^2_W + \\epsilon \\sum_{k=1}^{N-1}\\|u_k - u_L\\|^2_W
        + \\rho \\sum_k \\mathbf{1}^\\top s_k

    \\text{s.t.}\\; (a)\\; x_{k+1} = F(x_k, u_k, \\hat d), \\quad (b)\\; x_0 = x(t),
    \\quad (c)\\; |\\nu_k| \\le \\nu_{max} + s, \\quad (d)\\; u_{lb} \\le u_k \\le u_{ub},

    (e)\\; d(p_k, O_{i,k}) \\ge d_{safe} - s, \\quad (f)\\; d(p_N, O_{i,N}) \\ge d_{safe} + d_f - s,
    \\quad (g)\\; \\nu_N^\\top P_f \\nu_N \\le 1 + s,

is described here by stage functions a backend assembles: the discrete dynamics ``F``
(classic RK4 of the vessel model, |·| smoothed as sqrt(z² + 1e-6): with the plain
absolute value IPOPT hit its iteration limit near zero speed), the soft path constraints ``h(x, p) >= 0`` and the terminal constraints
``h_N(x, p) >= 0``. Every soft constraint has an L1-penalised slack (weight ``rho``),
counted in model-scale units at every hull size (:func:`margin_scale`,
:func:`velocity_slack_scale`); the inputs are hard.

Stage parameters ``p_k`` (one vector per stage, ``(N+1, n_p)``) carry everything that
changes between calls, so a solver is built once: ``[d̂ (3), clearance (1), circles
(3 m: north, east, radius), segments (4 s: n0, e0, n1, e1), a (1), static (m)]``. The last
two are read at stage N only. There eq. (f) has the braking credit of
:mod:`asvtwin.control.certification`: a plan ending at V_N = ν_Nᵀ P_f ν_N ≤ 1 needs
d_safe + d_f (1 − c) + c d_f √V_N of room from static obstacles and the coast. The OCP
asks its tangent at the warm start's V_N = s² (an upper bound, exact there): stage N's
clearance holds d_safe + d_f (1 − c) + c d_f s / 2 and the constraint subtracts a·V_N,
a = c d_f / (2 s), from a static obstacle's margin (``static`` is 1 or 0 per circle slot).
So the solver trades ending farther away against ending slower as its plan is judged (a
requirement fixed from the warm start's end speed let it end moving beside a shore and
fail certification on every call); the tangent, not √V_N itself, because the RTI
backend's single linearisation of √V_N overshot and oscillated between calls.
Unused obstacle slots hold far-away dummies (:func:`dummy_parameters`), never ±inf or 1e9
(an acados pitfall).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.vessel.params import VesselParams

__all__ = [
    "DUMMY_DISTANCE_FACTOR",
    "SMOOTH_ABS_EPS",
    "OcpSpec",
    "cache_dir",
    "continuous_dynamics",
    "discrete_dynamics",
    "discrete_lagged_dynamics",
    "lag_states",
    "path_constraints",
    "terminal_constraints",
    "velocity_slack_scale",
]

#: ε of the smoothed absolute value sqrt(z² + ε) in the damping.
SMOOTH_ABS_EPS = 1e-6
#: Unused obstacle slots sit this many ship lengths away from the own ship.
DUMMY_DISTANCE_FACTOR = 200.0
#: What changes the generated code beyond the spec: part of every cache key.
FORMULATION = ("stage N: braking credit tangent a V_N with static flags; Froude margins; "
               "Froude velocity slacks")
#: The hull length whose metres the solver's obstacle margins are counted in (CyberShip
#: II's): see :func:`margin_scale`.
MARGIN_REFERENCE_LENGTH_M = 1.255


@dataclass(frozen=True)
class OcpSpec:
    """Everything that fixes the structure and constants of the OCP (hashed for caches).

    Attributes
    ----------
    params : dict
        The vessel's coefficients (``VesselParams.to_dict()``).
    N : int
        Number of stages.
    dt_s : float
        Stage length [s].
    n_circles, n_segments : int
        Obstacle slots per stage.
    u_lb, u_ub : tuple of 3 floats
        Hard input bounds [N, N, Nm].
    nu_max : tuple of 3 floats
        Soft velocity bounds |u|, |v| [m/s], |r| [rad/s].
    W : tuple of 3 floats
        Diagonal of the input weight (paper's W, normalised by the input range).
    later_weight : float
        ε: weight of stages 1..N-1 relative to stage 0.
    slack_l1, slack_l2 : float
        Slack penalties ρ (L1) and a small quadratic term for conditioning.
    yaw_slack_weight : float
        What the yaw-rate bound's slack costs relative to the other slacks (1: the
        same ρ per model-scale unit; see :func:`velocity_slack_scale`).
    clearance_slack_weight : float
        What a model-scale metre of the obstacle margins' slack (eq. (e), (f)) costs
        relative to the other slacks (its L1 price ρ is multiplied by it).
    P_f : tuple of 9 floats
        Terminal ellipsoid matrix (row-major 3x3).
    rk4_substeps : int
        RK4 steps per stage.
    actuator_tc : tuple of 3 floats
        The thrusters' first-order time constants [s] (``ActuatorParams.time_constant_s``)
        when the plan models them, else zeros. With all three > 0 the solver's state is
        ``[x (6), τ_s (3)]``, τ_s = τ / S the thrust the vessel produces (in the scaled
        inputs' units, :func:`input_scale`), τ̇_s = (u_s − τ_s) / T: a commanded reversal
        of the yaw moment takes effect over T, not at once.
    """

    params: tuple[tuple[str, float], ...]
    N: int
    dt_s: float
    n_circles: int
    n_segments: int
    u_lb: tuple[float, float, float]
    u_ub: tuple[float, float, float]
    nu_max: tuple[float, float, float]
    W: tuple[float, float, float]
    later_weight: float
    slack_l1: float
    slack_l2: float
    P_f: tuple[float, ...]
    rk4_substeps: int = 1
    yaw_slack_weight: float = 1.0
    actuator_tc: tuple[float, float, float] = (0.0, 0.0, 0.0)
    clearance_slack_weight: float = 1.0

    @property
    def lag(self) -> bool:
        """Whether the plan models the thrusters' lag (every time constant > 0)."""
        return min(self.actuator_tc) > 0.0

    @property
    def nx(self) -> int:
        """Number of solver states: 6, or 9 with the thrust states of a lagged plan."""
        return 9 if self.lag else 6

    @property
    def n_p(self) -> int:
        """Length of one stage's parameter vector."""
        return self.credit_index + 1 + self.n_circles

    @property
    def credit_index(self) -> int:
        """Index in a stage's parameters of stage N's credit slope a; the circle slots'
        static flags follow it."""
        return 4 + 3 * self.n_circles + 4 * self.n_segments

    @property
    def n_h(self) -> int:
        """Number of soft path constraints per stage (obstacles only)."""
        return self.n_circles + self.n_segments

    @property
    def vessel(self) -> VesselParams:
        return VesselParams.from_dict(
            {k: v for k, v in self.params if k not in ("actuators",)}
        )

    @property
    def P_f_matrix(self) -> NDArray[np.float64]:
        return np.asarray(self.P_f, dtype=float).reshape(3, 3)

    def key(self) -> str:
        """Stable hash of the spec and of the formulation (cache key for generated
        code)."""
        d = asdict(self)
        if d["yaw_slack_weight"] == 1.0:  # (the default leaves the older keys as they were)
            d.pop("yaw_slack_weight")
        if not self.lag:
            d.pop("actuator_tc")
        if d["clearance_slack_weight"] == 1.0:
            d.pop("clearance_slack_weight")
        blob = json.dumps(d, sort_keys=True, default=float).encode()
        blob += FORMULATION.encode()
        blob += ca.CasadiMeta.version().encode()
        return hashlib.sha256(blob).hexdigest()[:16]


def cache_dir() -> Path:
    """Where generated solver code lives: ``$ASVTWIN_CACHE`` or ``~/.cache/asvtwin``."""
    root = os.environ.get("ASVTWIN_CACHE") or os.path.join(
        os.path.expanduser("~"), ".cache", "asvtwin"
    )
    path = Path(root)
    path.mkdir(parents=True, exist_ok=True)
    return path


def _sabs(z: ca.SX) -> ca.SX:
    return ca.sqrt(z * z + SMOOTH_ABS_EPS)


def continuous_dynamics(p: VesselParams) -> ca.Function:
    """ẋ = f(x, τ, d̂) of the vessel model as a CasADi SX function ``f(x, u, d)``.

    eq. (a) / (state_space_model): η̇ = R(ψ)ν, M ν̇ = τ + τ_d − C(ν)ν − D(ν)ν, the same
    coefficients as :func:`asvtwin.vessel.model.rhs` with |·| smoothed.
    """
    x = ca.SX.sym("x", 6)
    u = ca.SX.sym("u", 3)
    d = ca.SX.sym("d", 3)
    psi, su, sv, sr = x[2], x[3], x[4], x[5]
    M = p.M
    Minv = np.linalg.inv(M)
    M23 = 0.5 * (M[1, 2] + M[2, 1])
    au, av, ar = _sabs(su), _sabs(sv), _sabs(sr)
    # D(ν) entries of CyberShip II (Skjetne et al. 2004; Fossen 2011, ch. 6-7)
    d11 = -p.X_u - p.X_uu * au - p.X_uuu * su * su
    d22 = -p.Y_v - p.Y_vv * av - p.Y_rv * ar
    d23 = -p.Y_r - p.Y_vr * av - p.Y_rr * ar
    d32 = -p.N_v - p.N_vv * av - p.N_rv * ar
    d33 = -p.N_r - p.N_vr * av - p.N_rr * ar
    # C(ν) skew-symmetric: c13 = -(M22 v + M23 r), c23 = M11 u
    c13 = -(M[1, 1] * sv + M23 * sr)
    c23 = M[0, 0] * su
    Cnu = ca.vertcat(c13 * sr, c23 * sr, -c13 * su - c23 * sv)
    Dnu = ca.vertcat(d11 * su, d22 * sv + d23 * sr, d32 * sv + d33 * sr)
    rhs = u + d - Cnu - Dnu
    nu_dot = ca.mtimes(ca.DM(Minv), rhs)
    eta_dot = ca.vertcat(ca.cos(psi) * su - ca.sin(psi) * sv,
                         ca.sin(psi) * su + ca.cos(psi) * sv, sr)
    return ca.Function("f_vessel", [x, u, d], [ca.vertcat(eta_dot, nu_dot)],
                       ["x", "u", "d"], ["xdot"])


def discrete_dynamics(p: VesselParams, dt_s: float, substeps: int = 1) -> ca.Function:
    """x_{k+1} = F(x_k, u_k, d̂): ``substeps`` classic RK4 steps over one stage."""
    f = continuous_dynamics(p)
    x = ca.SX.sym("x", 6)
    u = ca.SX.sym("u", 3)
    d = ca.SX.sym("d", 3)
    h = dt_s / substeps
    xk = x
    for _ in range(substeps):
        k1 = f(xk, u, d)
        k2 = f(xk + 0.5 * h * k1, u, d)
        k3 = f(xk + 0.5 * h * k2, u, d)
        k4 = f(xk + h * k3, u, d)
        xk = xk + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("F_stage", [x, u, d], [xk], ["x", "u", "d"], ["x_next"])


def discrete_lagged_dynamics(p: VesselParams, dt_s: float, substeps: int, S: ArrayLike,
                             tc: ArrayLike) -> ca.Function:
    """x_{k+1} = F(x_k, u_s,k, d̂) of the plan with the thrusters' first-order lag.

    x = [η, ν, τ_s] (9): τ_s, the thrust the vessel produces divided by ``S``, follows
    the held command u_s as τ_s(t) = u_s + (τ_s,k − u_s) e^{−t/T}, integrated exactly
    (the lag is faster than a stage, Δt/T = 2.5 for CyberShip II, where classic RK4 of
    τ̇ would be wrong by half the step); η, ν by classic RK4 (``substeps`` per stage)
    under τ = S τ_s(t) + d̂ taken at each RK4 node's time.
    """
    f = continuous_dynamics(p)
    x = ca.SX.sym("x", 9)
    u = ca.SX.sym("u", 3)
    d = ca.SX.sym("d", 3)
    Sd = ca.DM(np.asarray(S, dtype=float))
    T = np.asarray(tc, dtype=float)
    h = dt_s / substeps
    e_half, e_full = ca.DM(np.exp(-0.5 * h / T)), ca.DM(np.exp(-h / T))
    xk, tk = x[0:6], x[6:9]
    for _ in range(substeps):
        t_mid = u + (tk - u) * e_half
        t_end = u + (tk - u) * e_full
        k1 = f(xk, Sd * tk, d)
        k2 = f(xk + 0.5 * h * k1, Sd * t_mid, d)
        k3 = f(xk + 0.5 * h * k2, Sd * t_mid, d)
        k4 = f(xk + h * k3, Sd * t_end, d)
        xk = xk + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        tk = t_end
    return ca.Function("F_lagged", [x, u, d], [ca.vertcat(xk, tk)], ["x", "u", "d"],
                       ["x_next"])


def lag_states(tau0: ArrayLike, U: ArrayLike, dt_s: float, tc: ArrayLike
               ) -> NDArray[np.float64]:
    """The produced thrust at every stage (N+1, 3) of a plan ``U`` (N, 3) held stage by
    stage from ``tau0`` (3,): τ_{k+1} = u_k + (τ_k − u_k) e^{−Δt/T} (exact for a
    first-order lag; any units, the same for both)."""
    U = np.asarray(U, dtype=float)
    a = np.exp(-dt_s / np.asarray(tc, dtype=float))
    out = np.empty((U.shape[0] + 1, 3))
    out[0] = tau0
    for k in range(U.shape[0]):
        out[k + 1] = U[k] + (out[k] - U[k]) * a
    return out


def _obstacle_margins(x: ca.SX, pk: ca.SX, n_circles: int, n_segments: int) -> ca.SX:
    """Distance margins [m] of position (x[0], x[1]) to every obstacle slot, minus the
    stage's clearance (eq. (e)/(f)); >= 0 is safe."""
    clearance = pk[3]
    out = []
    base = 4
    for i in range(n_circles):
        cx, cy, r = pk[base + 3 * i], pk[base + 3 * i + 1], pk[base + 3 * i + 2]
        dist = ca.sqrt((x[0] - cx) ** 2 + (x[1] - cy) ** 2 + SMOOTH_ABS_EPS)
        out.append(dist - r - clearance)
    base += 3 * n_circles
    for j in range(n_segments):
        ax, ay, bx, by = (pk[base + 4 * j + i] for i in range(4))
        ex, ey = bx - ax, by - ay
        L2 = ex * ex + ey * ey + SMOOTH_ABS_EPS
        t = ca.fmin(1.0, ca.fmax(0.0, ((x[0] - ax) * ex + (x[1] - ay) * ey) / L2))
        qx, qy = ax + t * ex - x[0], ay + t * ey - x[1]
        out.append(ca.sqrt(qx * qx + qy * qy + SMOOTH_ABS_EPS) - clearance)
    return ca.vertcat(*out) if out else ca.SX(0, 1)


def margin_scale(spec: OcpSpec) -> float:
    """What the solver's obstacle margins are divided by: the hull's Froude scale
    λ = L / 1.255 m, so that they count model-scale metres at every hull size.

    In metres, an 88 m hull's margins are ~70 times the model's while its cost is the
    same (inputs scaled to O(1)): the QP's L1 slack penalty ρ per metre was then as
    strong against a metre of a 175 m clearance as against a metre of a 2.5 m one, and
    HPIPM stopped at its iteration limit on 36 % of the twin's solves among 50 vessels
    (900 s); with the margins in model-scale metres 3 %. At model scale nothing
    changes."""
    return max(spec.vessel.length / MARGIN_REFERENCE_LENGTH_M, 1e-9)


def velocity_slack_scale(spec: OcpSpec) -> NDArray[np.float64]:
    """What the velocity bounds' slacks (eq. (c): surge, sway, yaw rate) are multiplied
    by before the L1/L2 penalty: (1/√λ, 1/√λ, √λ) with λ = :func:`margin_scale`, so that
    they count model-scale units at every hull size, as the obstacle margins do.

    By Froude similarity speeds grow with √λ and yaw rates shrink with it. Priced in its
    own units, a yaw rate 45 % above the 88 m hull's comfort bound (0.0179 rad/s) cost
    ρ · 0.008 = 0.8, against 6.8 for the same relative excess of the model (0.15 rad/s):
    the full-scale solver turned past its comfort bound at a fraction of the price the
    model's paid. At model scale (λ = 1) nothing changes.

    The yaw rate's factor is further multiplied by ``spec.yaw_slack_weight``."""
    r = math.sqrt(margin_scale(spec))
    return np.array([1.0 / r, 1.0 / r, r * spec.yaw_slack_weight])


def path_constraints(spec: OcpSpec) -> ca.Function:
    """``h(x, p) >= 0`` (soft): obstacle margins, eq. (e), for stages 1..N-1."""
    x = ca.SX.sym("x", 6)
    pk = ca.SX.sym("p", spec.n_p)
    h = _obstacle_margins(x, pk, spec.n_circles, spec.n_segments) / margin_scale(spec)
    return ca.Function("h_path", [x, pk], [h], ["x", "p"], ["h"])


def terminal_constraints(spec: OcpSpec) -> ca.Function:
    """``h_N(x, p) >= 0`` (soft): obstacle margins at stage N, eq. (f) with the braking
    credit (static obstacles and the coast ask a·V_N more than the stage's clearance,
    see the module docstring), and the terminal ellipsoid 1 − V_N, eq. (g)."""
    x = ca.SX.sym("x", 6)
    pk = ca.SX.sym("p", spec.n_p)
    h = _obstacle_margins(x, pk, spec.n_circles, spec.n_segments)
    nu = x[3:6]
    V = ca.mtimes([nu.T, ca.DM(spec.P_f_matrix), nu])
    k0 = spec.credit_index
    if spec.n_circles + spec.n_segments:
        static = ca.vertcat(*[pk[k0 + 1 + i] for i in range(spec.n_circles)],
                            ca.DM.ones(spec.n_segments))
        h = h - pk[k0] * V * static
    h = h / margin_scale(spec)
    # eq. (OCP)(g): terminal ellipsoid ν_Nᵀ P_f ν_N ≤ 1
    return ca.Function("h_term", [x, pk], [ca.vertcat(h, 1.0 - V)], ["x", "p"], ["h"])


def input_scale(u_lb: ArrayLike, u_ub: ArrayLike) -> NDArray[np.float64]:
    """Per-DOF scale of the solver's inputs: the larger actuator bound in magnitude (1
    for a DOF without actuation)."""
    S = np.maximum(np.abs(np.asarray(u_lb, dtype=float)), np.abs(np.asarray(u_ub, dtype=float)))
    return np.where(S > 0, S, 1.0)
