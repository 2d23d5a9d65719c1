from __future__ import annotations

import math

import numpy as np
import pytest

from asvtwin.errors import ParameterError
from asvtwin.vessel import (
    VesselParams,
    cybership2,
    cybership2_full_scale,
    froude_scale,
    vessel_by_name,
)


def test_cybership2_mass_matrix_matches_reference():
    # Skjetne, Smogeli and Fossen (2004), CyberShip II: M = [[25.8, 0, 0], [0, 33.8, 1.0948], [0, 1.0948, 2.76]]
    M = cybership2().M
    np.testing.assert_allclose(
        M, [[25.8, 0, 0], [0, 33.8, 1.0948], [0, 1.0948, 2.76]], atol=1e-12
    )


@pytest.mark.parametrize(
    "field,value,match",
    [
        ("m", -1.0, "'m' must be > 0"),
        ("X_udot", 30.0, "positive definite"),
        ("X_u", 0.5, "negative damping"),
        ("Y_vv", 3.0, "'Y_vv'"),
        ("I_z", float("nan"), "'I_z' must be finite"),
        ("N_v", -50.0, "D_L must be positive definite"),
    ],
)
def test_bad_parameters_are_refused_with_field_and_range(field, value, match):
    with pytest.raises(ParameterError, match=match):
        cybership2().replace(**{field: value})


def test_toml_errors_name_the_file(tmp_path):
    d = cybership2().to_dict()
    d["m"] = -3.0
    lines = [f"{k} = {v!r}" if isinstance(v, str) else f"{k} = {v}"
             for k, v in d.items() if k != "actuators"]
    path = tmp_path / "bad.toml"
    path.write_text("\n".join(lines).replace("'", '"'))
    with pytest.raises(ParameterError, match=r"bad\.toml: field 'm' must be > 0"):
        VesselParams.from_toml(path)
    path.write_text("m = 1.0\n")
    with pytest.raises(ParameterError, match=r"bad\.toml: missing field"):
        VesselParams.from_toml(path)


def test_toml_round_trip(tmp_path):
    p = cybership2()
    d = p.to_dict()
    act = d.pop("actuators")
    text = "\n".join(f'{k} = "{v}"' if isinstance(v, str) else f"{k} = {v!r}"
                     for k, v in d.items())
    text += "\n[actuators]\n" + "\n".join(
        f"{k} = [{', '.join(repr(float(x)).replace('inf', 'inf') for x in v)}]"
        for k, v in act.items())
    path = tmp_path / "cs2.toml"
    path.write_text(text)
    assert VesselParams.from_toml(path) == p


def test_actuator_limits_validated():
    p = cybership2()
    with pytest.raises(ParameterError, match=r"tau_min\[2\] must be <= tau_max\[2\]"):
        p.replace(actuators=type(p.actuators)(tau_min=(0, 0, 1), tau_max=(1, 1, 0)))
    with pytest.raises(ParameterError, match="time_constant_s"):
        p.replace(actuators=type(p.actuators)(time_constant_s=(-1, 0, 0)))


def test_froude_scaling_of_coefficients():
    lam = 70.0
    p, f = cybership2(), cybership2_full_scale()
    rho = 1025.0 / 1000.0
    assert f.length == pytest.approx(lam * p.length)
    assert f.m == pytest.approx(p.m * lam**3 * rho)
    assert f.I_z == pytest.approx(p.I_z * lam**5 * rho)
    assert f.X_u == pytest.approx(p.X_u * lam**2.5 * rho)          # N/(m/s)
    assert f.X_uuu == pytest.approx(p.X_uuu * lam**1.5 * rho)      # N/(m/s)^3
    assert f.N_r == pytest.approx(p.N_r * lam**4.5 * rho)          # Nm/(rad/s)
    assert f.N_rr == pytest.approx(p.N_rr * lam**5 * rho)          # Nm/(rad/s)^2
    assert f.actuators.tau_max[0] == pytest.approx(2.0 * lam**3 * rho)
    assert f.actuators.tau_max[2] == pytest.approx(0.15 * lam**4 * rho)
    assert f.actuators.time_constant_s[0] == pytest.approx(0.2 * math.sqrt(lam))
    # scaling back recovers the model (fresh water)
    back = froude_scale(f, 1 / lam, rho_water=1000.0)
    for name in ("m", "I_z", "X_u", "Y_vv", "N_rr", "Y_r"):
        assert getattr(back, name) == pytest.approx(getattr(p, name), rel=1e-12)


def test_froude_scale_rejects_bad_scale():
    with pytest.raises(ParameterError, match="scale must be finite and > 0"):
        froude_scale(cybership2(), 0.0)


def test_vessel_by_name():
    assert vessel_by_name("cybership2").name == "cybership2"
    with pytest.raises(ParameterError, match="unknown vessel"):
        vessel_by_name("titanic")
