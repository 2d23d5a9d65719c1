"""Explanations of the safety filter's answers, in words a navigator reads.

An explanation names the *cause* (the obstacle the learner's input would have come
within d_safe of, by its identity, bearing from the bow, range and, for a vessel, CPA and
TCPA at present velocities), the *change* to the input ("reducing to 47 % thrust and
turning to starboard") and what the applied plan *keeps* ("the plan keeps ≥ 1.3 m").
Bearings use the bridge's sectors: ahead (±11.25°), bow, beam (90 ± 22.5°), quarter,
astern (beyond ±168.75°).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from asvtwin.checks import F8 as _F8
from asvtwin.control.colreg import cpa_tcpa

__all__ = ["bearing_words", "describe_cause", "describe_change", "describe_obstacle"]



def bearing_words(rel_bearing_rad: float) -> str:
    """"ahead", "on the starboard bow", "on the port beam", "on the port quarter",
    "astern" for a bearing relative to the bow (clockwise, starboard > 0) [rad]."""
    b = math.degrees((rel_bearing_rad + math.pi) % (2 * math.pi) - math.pi)
    a = abs(b)
    side = "starboard" if b > 0 else "port"
    if a <= 11.25:
        return "ahead"
    if a >= 168.75:
        return "astern"
    part = "bow" if a < 67.5 else ("beam" if a <= 112.5 else "quarter")
    return f"on the {side} {part}"


def describe_change(u_L: _F8, u0: _F8, lb: _F8, ub: _F8) -> str:
    """The change from ``u_L`` to ``u0`` in words (surge thrust and yaw moment)."""
    words: list[str] = []
    rng = ub - lb
    if rng[0] > 0 and abs(u0[0] - u_L[0]) > 0.01 * rng[0]:
        if u0[0] < 0:
            words.append(f"going astern at {100 * u0[0] / lb[0]:.0f} % of astern thrust")
        elif u0[0] < u_L[0]:
            words.append(f"reducing to {100 * u0[0] / ub[0]:.0f} % thrust")
        else:
            words.append(f"increasing to {100 * u0[0] / ub[0]:.0f} % thrust")
    if rng[2] > 0 and abs(u0[2] - u_L[2]) > 0.01 * rng[2]:
        cap = max(abs(lb[2]), abs(ub[2]))
        pct = 100 * abs(u0[2]) / cap
        if abs(u0[2]) <= 0.01 * rng[2]:
            words.append("holding the rudder amidships")
        else:
            side = "starboard" if u0[2] > 0 else "port"
            verb = "turning" if np.sign(u0[2]) != np.sign(u_L[2]) or abs(u0[2]) > abs(
                u_L[2]) else "easing the turn"
            words.append(f"{verb} to {side} ({pct:.0f} % yaw moment)")
    return " and ".join(words) if words else "keeping the input"


def describe_obstacle(j: int, x: _F8, labels: list[str], moving: NDArray[np.bool_],
                      centres: _F8, radii: _F8, segs: _F8, dt_s: float) -> str:
    """One obstacle (circle ``j`` < m, else segment ``j - m``) seen from own state ``x``."""
    m = centres.shape[1]
    psi = float(x[2])
    if j < m:
        c0 = centres[0, j]
        rel = c0 - x[:2]
        rng = max(0.0, float(np.hypot(*rel)) - float(radii[0, j]))
        b = math.atan2(rel[1], rel[0]) - psi
        text = f"{labels[j]} {bearing_words(b)}, {rng:.1f} m"
        if moving[j] and centres.shape[0] > 1:
            v_t = (centres[1, j] - centres[0, j]) / dt_s
            c, s = math.cos(psi), math.sin(psi)
            v_o = np.array([c * x[3] - s * x[4], s * x[3] + c * x[4]])
            cpa, tcpa = cpa_tcpa(rel, v_t - v_o)
            if tcpa[0] > 0:
                text += f", CPA {max(0.0, cpa[0] - radii[0, j]):.1f} m in {tcpa[0]:.0f} s"
            else:
                text += ", opening"
        return text
    a, bb = segs[j - m, 0:2], segs[j - m, 2:4]
    e = bb - a
    t = float(np.clip(np.dot(x[:2] - a, e) / max(float(np.dot(e, e)), 1e-12), 0.0, 1.0))
    q = a + t * e - x[:2]
    b = math.atan2(q[1], q[0]) - psi
    return f"the coast {bearing_words(b)}, {float(np.hypot(*q)):.1f} m"


def describe_cause(x: _F8, margins_L: _F8, term_L: float, labels: list[str],
                   moving: NDArray[np.bool_], centres: _F8, radii: _F8, segs: _F8,
                   dt_s: float, d_safe_m: float, d_f_m: float, term_tol: float,
                   end_clear_m: float) -> str:
    """Why u_L was not kept: the binding constraint of the plan that starts with it
    (margins ``margins_L`` (N+1, m + k) [m], terminal margin ``term_L``).
    ``end_clear_m``: what that plan's end must keep from a static obstacle at its end
    speed (d_safe + d_f √V_N with the braking credit)."""
    N = margins_L.shape[0] - 1
    if margins_L.shape[1] and float(margins_L[1:].min()) < 0:
        k_c, j_c = np.unravel_index(int(np.argmin(margins_L[1:])), margins_L[1:].shape)
        cause = describe_obstacle(int(j_c), x, labels, moving, centres, radii, segs, dt_s)
        if k_c + 1 == N and margins_L[N, j_c] + d_f_m >= 0:
            return (f"{cause}; u_L leaves no room to stop: at its end speed the plan must "
                    f"end ≥ {end_clear_m:.1f} m clear (d_safe {d_safe_m:.1f} m + braking)")
        return f"{cause}; u_L comes within d_safe in {(k_c + 1) * dt_s:.0f} s"
    if term_L < -term_tol:
        return "u_L leaves no room to stop within d_f by the horizon's end"
    return "u_L unsafe"
