"""The targets' route following compiled (TargetPilots._route_course) against its NumPy
reference (_route_course_numpy): the same legs exactly and the same courses to 1e-12 rad,
over routes that loop, end, and have legs short enough to switch several times in one step.

Not to the bit: NumPy's vectorised sin/cos/arctan (SIMD, chosen by the CPU) and the libm
calls of the compiled kernel differ by an ulp on some processors (on a Xeon with AVX-512, 6
of 60 courses differed by 4.4e-16 rad)."""

from __future__ import annotations

import copy

import numpy as np

from asvtwin.geo import default_scene
from asvtwin.scenarios import TargetSpec
from asvtwin.twin.pilots import TargetPilots
from asvtwin.twin.world import target_params

#: the courses agree to a picoradian (the ulp-level differences of sin/cos/atan pass
#: through the line-of-sight arithmetic: up to 4e-15 rad seen)
COURSE_TOL_RAD = 1e-12


def _fleet(rng: np.random.Generator, n: int) -> tuple[TargetPilots, np.ndarray]:
    p = TargetPilots(default_scene().frame)
    xs = []
    for i in range(n):
        L = float(rng.uniform(25.0, 150.0))
        x0 = np.array([*rng.uniform(-2000, 2000, 2), rng.uniform(-np.pi, np.pi), 3.0, 0.0, 0.0])
        spec: dict = {"name": f"T{i}", "ais_class": None, "length_m": round(L, 1), "beam_m": round(L / 6, 1),
                      "start": {"north_m": float(x0[0]), "east_m": float(x0[1])},
                      "heading_deg": float(np.degrees(x0[2]) % 360.0), "speed_kn": 4.0}
        kind = i % 4
        if kind:  # waypoints: long legs, short legs (several switches a step), looping
            scale = 40.0 if kind == 2 else 900.0
            wps = x0[:2] + np.cumsum(rng.uniform(-scale, scale, (int(rng.integers(1, 6)), 2)), 0)
            spec["behaviour"] = {"kind": "waypoints", "loop": kind == 3, "route": [
                {"north_m": float(w[0]), "east_m": float(w[1])} for w in wps]}
        p.add(TargetSpec.model_validate(spec), target_params(L), x0)
        xs.append(x0)
    return p, np.array(xs)


def test_compiled_route_course_equals_the_numpy_reference() -> None:
    rng = np.random.default_rng(5)
    p, x = _fleet(rng, 60)
    q = copy.deepcopy(p)
    switched = ended = 0
    for _ in range(400):
        k0 = p.k.copy()
        a, ha = p._route_course(x)
        b, hb = q._route_course_numpy(x)
        np.testing.assert_allclose(a, b, rtol=0, atol=COURSE_TOL_RAD)
        np.testing.assert_array_equal(ha, hb)
        np.testing.assert_array_equal(p.k, q.k)
        np.testing.assert_allclose(p.course, q.course, rtol=0, atol=COURSE_TOL_RAD)
        switched += int((p.k != k0).sum())
        ended += int((~ha & (p.n_wp >= 2)).sum())
        # sail along the commanded course, with some scatter
        x[:, 0] += 25.0 * np.cos(a) + rng.normal(0, 3.0, len(x))
        x[:, 1] += 25.0 * np.sin(a) + rng.normal(0, 3.0, len(x))
    assert switched > 50 and ended > 0  # legs switched and routes ended: both paths ran
