"""The paper's 3-DOF vessel model, vectorised over vessels with numpy.

.. math::

    \\dot{\\boldsymbol\\eta} = \\mathbf{R}(\\psi)\\boldsymbol\\nu, \\qquad
    \\mathbf{M}\\dot{\\boldsymbol\\nu} + \\mathbf{C}(\\boldsymbol\\nu)\\boldsymbol\\nu
    + \\mathbf{D}(\\boldsymbol\\nu)\\boldsymbol\\nu = \\boldsymbol\\tau + \\boldsymbol\\tau_d

State ``x = [x, y, ψ, u, v, r]`` (NED position [m], heading [rad] from north clockwise,
surge and sway [m/s], yaw rate [rad/s]); shape (6,) for one vessel, (n, 6) for many.
Input ``tau = [τ_u, τ_v, τ_r]`` [N, N, Nm] and disturbance ``d = τ_d`` likewise, (n, 3).

These functions are the readable reference; :mod:`asvtwin.vessel.kernels` holds the
compiled versions the simulator uses, tested against these.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.checks import check_rows
from asvtwin.vessel.params import VesselParams

__all__ = [
    "coriolis",
    "damping",
    "dissipation_margin",
    "kinetic_energy",
    "rhs",
    "rotation",
    "state_space",
    "validate_array",
]

_FIELDS_STATE = ("x", "y", "psi", "u", "v", "r")
_FIELDS_INPUT = ("tau_u", "tau_v", "tau_r")


def validate_array(a: ArrayLike, width: int, what: str,
                   fields: tuple[str, ...] | None = None) -> NDArray[np.float64]:
    """Return ``a`` as a float (n, width) array; raise StateError naming the vessel index
    and field of the first NaN/inf, or the expected shape (:func:`asvtwin.checks.check_rows`)."""
    return check_rows(a, width, what, fields)


def rotation(psi: ArrayLike) -> NDArray[np.float64]:
    """R(ψ), shape (..., 3, 3): body velocities to NED rates (paper's R_rot)."""
    psi = np.asarray(psi, dtype=float)
    c, s = np.cos(psi), np.sin(psi)
    R = np.zeros(psi.shape + (3, 3))
    R[..., 0, 0], R[..., 0, 1] = c, -s
    R[..., 1, 0], R[..., 1, 1] = s, c
    R[..., 2, 2] = 1.0
    return R


def coriolis(p: VesselParams, nu: ArrayLike) -> NDArray[np.float64]:
    """C(ν) = C_RB(ν) + C_A(ν), shape (n, 3, 3), skew-symmetric.

    c13 = -(M22 v + M23 r), c23 = M11 u, c31 = -c13, c32 = -c23 (Fossen 2011, eq. 6.43
    with the added-mass terms; M23 symmetrised).
    """
    nu = np.atleast_2d(np.asarray(nu, dtype=float))
    M = p.M
    M23 = 0.5 * (M[1, 2] + M[2, 1])
    u, v, r = nu[:, 0], nu[:, 1], nu[:, 2]
    C = np.zeros((nu.shape[0], 3, 3))
    c13 = -(M[1, 1] * v + M23 * r)
    c23 = M[0, 0] * u
    C[:, 0, 2], C[:, 2, 0] = c13, -c13
    C[:, 1, 2], C[:, 2, 1] = c23, -c23
    return C


def damping(p: VesselParams, nu: ArrayLike) -> NDArray[np.float64]:
    """D(ν) = D_L + D_NL(ν), shape (n, 3, 3) (d11 ... d33 of Skjetne, Smogeli and Fossen 2004, CyberShip II)."""
    nu = np.atleast_2d(np.asarray(nu, dtype=float))
    u, v, r = nu[:, 0], nu[:, 1], nu[:, 2]
    au, av, ar = np.abs(u), np.abs(v), np.abs(r)
    D = np.zeros((nu.shape[0], 3, 3))
    D[:, 0, 0] = -p.X_u - p.X_uu * au - p.X_uuu * u * u
    D[:, 1, 1] = -p.Y_v - p.Y_vv * av - p.Y_rv * ar
    D[:, 1, 2] = -p.Y_r - p.Y_vr * av - p.Y_rr * ar
    D[:, 2, 1] = -p.N_v - p.N_vv * av - p.N_rv * ar
    D[:, 2, 2] = -p.N_r - p.N_vr * av - p.N_rr * ar
    return D


def rhs(p: VesselParams, x: ArrayLike, tau: ArrayLike, d: ArrayLike | None = None
        ) -> NDArray[np.float64]:
    """ẋ = f(x, τ, τ_d) for many vessels, shape (n, 6).

    .. math:: \\dot\\eta = R(\\psi)\\nu, \\quad
              \\dot\\nu = M^{-1}(\\tau + \\tau_d - C(\\nu)\\nu - D(\\nu)\\nu)
    """
    x = validate_array(x, 6, "state", _FIELDS_STATE)
    tau = validate_array(tau, 3, "input", _FIELDS_INPUT)
    d = np.zeros_like(tau) if d is None else validate_array(d, 3, "disturbance",
                                                            _FIELDS_INPUT)
    nu = x[:, 3:6]
    R = rotation(x[:, 2])
    eta_dot = np.einsum("nij,nj->ni", R, nu)
    # eq. (dynamics): M ν̇ = τ + τ_d − C(ν)ν − D(ν)ν
    Cnu = np.einsum("nij,nj->ni", coriolis(p, nu), nu)
    Dnu = np.einsum("nij,nj->ni", damping(p, nu), nu)
    nu_dot = np.linalg.solve(p.M, (tau + d - Cnu - Dnu).T).T
    return np.concatenate([eta_dot, nu_dot], axis=1)


def state_space(p: VesselParams, x: ArrayLike) -> tuple[NDArray[np.float64],
                                                        NDArray[np.float64]]:
    """The paper's state-space form ẋ = A(x) x + B u + B d, eq. (state_space_model).

    Returns ``A`` of shape (n, 6, 6) = [[0, R(ψ)], [0, M⁻¹(−C(ν) − D(ν))]] and ``B``
    of shape (6, 3) = [[0], [M⁻¹]].
    """
    x = validate_array(x, 6, "state", _FIELDS_STATE)
    n = x.shape[0]
    Minv = np.linalg.inv(p.M)
    A = np.zeros((n, 6, 6))
    A[:, 0:3, 3:6] = rotation(x[:, 2])
    A[:, 3:6, 3:6] = -Minv @ (coriolis(p, x[:, 3:6]) + damping(p, x[:, 3:6]))
    B = np.zeros((6, 3))
    B[3:6, :] = Minv
    return A, B


def kinetic_energy(p: VesselParams, nu: ArrayLike) -> NDArray[np.float64]:
    """½ νᵀ M ν for each vessel, shape (n,) [J]."""
    nu = np.atleast_2d(np.asarray(nu, dtype=float))
    return 0.5 * np.einsum("ni,ij,nj->n", nu, p.M, nu)


def dissipation_margin(p: VesselParams, nu: ArrayLike) -> NDArray[np.floating]:
    """Smallest eigenvalue of the symmetric part of D(ν), shape (n,).

    Positive means the damping dissipates energy at that velocity. The published
    CyberShip II coefficients (N_|v|v = +5.04) make D(ν) lose this property at large
    sway speeds (|v| ≳ 2.8 m/s at model scale), far outside the vessel's envelope.
    """
    D = damping(p, nu)
    eig: NDArray[np.floating] = np.linalg.eigvalsh(0.5 * (D + np.swapaxes(D, 1, 2)))[:, 0]
    return eig
