"""Validation of the disturbance observer and the fault detector against known truth.

Observer: step, ramp and the slowly varying environment (current, wind, wave drift of
:func:`asvtwin.environment.default_environment`) on both vessel scales, with and without
sensor noise; per DOF the RMSE of d̂ − τ_d and the time to 90 % convergence (steps only).

Faults: the detector is calibrated on fault-free runs (their own seeds), then measured on
seeded runs with a 50 % loss of surge thrust (detection delay) and on long fault-free runs
(false alarms per hour), all under the default environment and sensor noise.

:func:`write_report` writes ``observer_report.md``, ``observer_report.json`` and
``observer_report.png`` (true vs estimated τ_d).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from asvtwin.observer.calibration import fit_residual_model
from asvtwin.observer.disturbance import DisturbanceObserver
from asvtwin.observer.faults import (
    DetectorConfig,
    FaultDetector,
    FaultEvent,
    ResidualModel,
)
from asvtwin.observer.runs import (
    InjectedFault,
    RunResult,
    SensorNoise,
    froude_ratio,
    simulate,
)
from asvtwin.vessel import VesselParams, vessel_by_name

__all__ = [
    "SCENARIOS",
    "FaultSuiteResult",
    "Scenario",
    "calibrate_detector",
    "fault_suite",
    "observer_metrics",
    "run_detector",
    "run_observer",
    "write_report",
]


def _scale_force(params: VesselParams) -> NDArray[np.float64]:
    """Force scale per DOF [N, N, Nm]: surge thrust range for surge and sway, yaw range."""
    a = params.actuators
    fx = a.tau_max[0] - a.tau_min[0]
    return np.array([fx, fx, a.tau_max[2] - a.tau_min[2]])


@dataclass(frozen=True, slots=True)
class Scenario:
    """A validation disturbance: ``kind`` "step", "ramp" or "environment"; amplitude as a
    fraction of the actuator range per DOF; ``t0`` onset and ``duration`` in model-scale
    seconds (Froude-scaled)."""

    name: str
    kind: str
    amplitude: tuple[float, float, float] = (0.1, 0.1, 0.1)
    t0: float = 20.0
    duration: float = 120.0


SCENARIOS = (
    Scenario("step", "step"),
    Scenario("ramp", "ramp", duration=120.0),
    Scenario("environment", "environment", duration=300.0),
)


def _profile(sc: Scenario, params: VesselParams):  # type: ignore[no-untyped-def]
    f = froude_ratio(params)
    A = np.asarray(sc.amplitude) * _scale_force(params)
    t0 = sc.t0 * f
    ramp_T = 60.0 * f
    if sc.kind == "step":
        return lambda t: A * (t >= t0)
    if sc.kind == "ramp":
        return lambda t: A * float(np.clip((t - t0) / ramp_T, 0.0, 1.0))
    return None


def run_observer(params: VesselParams, sc: Scenario, *, noise: bool, seed: int,
                 n_runs: int = 1) -> tuple[RunResult, NDArray[np.float64]]:
    """Simulate a scenario and run the observer on it; return the run and d̂ (T, r, 3)."""
    f = froude_ratio(params)
    env = "default" if sc.kind == "environment" else None
    res = simulate(params, n_runs, sc.duration * f, seed=seed, environment=env,
                   profile=_profile(sc, params),
                   noise=SensorNoise.for_vessel(params) if noise else None)
    obs = DisturbanceObserver(params, n_runs, dt_s=res.dt_s)
    d_hat = np.empty_like(res.tau_d)
    for k in range(res.t_s.shape[0]):
        d_hat[k] = obs.update(res.nu_meas[k], res.tau[k])
    return res, d_hat


def observer_metrics(params: VesselParams, sc: Scenario, res: RunResult,
                     d_hat: NDArray[np.float64]) -> dict[str, Any]:
    """RMSE per DOF over all runs after 3 T (past the onset for step and ramp) and, for a
    step, the time for the runs' mean estimate to reach 90 % of the step per DOF [s]."""
    f = froude_ratio(params)
    obs_T = np.array(DisturbanceObserver(params, 1, dt_s=res.dt_s).gains.time_constant_s)
    t = res.t_s
    err = d_hat - res.tau_d
    out: dict[str, Any] = {"vessel": params.name, "scenario": sc.name}
    rmse, t90 = [], []
    for j in range(3):
        # steady part: after 3 T (the step's transient is reported by t90 instead)
        start = (sc.t0 * f if sc.kind != "environment" else 0.0) + 3.0 * obs_T[j]
        sel = t >= start
        rmse.append(float(np.sqrt(np.mean(err[sel, :, j] ** 2))))
        if sc.kind == "step":
            step = float(res.tau_d[-1, 0, j])
            # ensemble mean over the runs, then the first time it reaches 90 % of the step
            frac = d_hat[:, :, j].mean(axis=1) / step if step else np.ones_like(t)
            hit = np.flatnonzero((frac >= 0.9) & (t >= sc.t0 * f))
            t90.append(float(t[hit[0]] - sc.t0 * f) if hit.size else math.nan)
        else:
            t90.append(math.nan)
    out["rmse"] = rmse
    out["rmse_rel"] = [r / s for r, s in zip(rmse, _scale_force(params))]
    out["t90_s"] = t90
    out["t90_theory_s"] = [math.log(10.0) * T for T in obs_T]
    return out


# --------------------------------------------------------------------------- faults
def calibrate_detector(params: VesselParams, *, seed: int = 10_000, n_runs: int = 4,
                       duration_s: float | None = None) -> ResidualModel:
    """Fit the residual model on fault-free runs (default environment, sensor noise;
    1 h of full-scale time per run, Froude-scaled)."""
    f = froude_ratio(params)
    noise = SensorNoise.for_vessel(params)
    dur = duration_s if duration_s is not None else 3600.0 * f / math.sqrt(70.0)
    cal = simulate(params, n_runs, dur, seed=seed, noise=noise)
    return fit_residual_model(params, cal.nu_meas, cal.tau, cal.dt_s, noise.sigma_nu)


def run_detector(params: VesselParams, model: ResidualModel, res: RunResult,
                 config: DetectorConfig | None = None) -> list[FaultEvent]:
    """All fault events the detector raises over the runs of ``res``."""
    det = FaultDetector(params, res.x.shape[1], model, config)
    events: list[FaultEvent] = []
    for k in range(res.t_s.shape[0]):
        events.extend(det.update(float(res.t_s[k]), res.nu_meas[k], res.tau[k]))
    return events


@dataclass(frozen=True, slots=True)
class FaultSuiteResult:
    """Outcome of the injected-fault suite: per-run detection delays [s] (NaN: missed),
    wrong alarms in the fault runs (other DOF, or before the fault), false alarms in the
    fault-free runs and their total length [h]."""

    delays_s: tuple[float, ...]
    wrong_alarms: int
    false_alarms: int
    fault_free_hours: float
    threshold: float

    @property
    def median_delay_s(self) -> float:
        d = np.asarray(self.delays_s)
        return float(np.median(d)) if np.all(np.isfinite(d)) else float(np.nanmedian(
            np.where(np.isfinite(d), d, np.inf)))

    @property
    def detected_fraction(self) -> float:
        return float(np.mean(np.isfinite(np.asarray(self.delays_s))))

    @property
    def false_alarms_per_hour(self) -> float:
        return self.false_alarms / self.fault_free_hours if self.fault_free_hours else 0.0


def fault_suite(params: VesselParams, model: ResidualModel, *, n_runs: int = 20,
                seed: int = 20_000, fault_free_hours: float = 10.0, dof: int = 0,
                gain: float = 0.5, bias: float = 0.0) -> FaultSuiteResult:
    """Seeded fault runs (fault at 600 s, then 300 s; Froude-scaled from full scale) and
    fault-free runs of the same length, environment and noise, ``fault_free_hours`` of
    the vessel's own time in total."""
    f = froude_ratio(params) / math.sqrt(70.0)  # 1 at full scale
    noise = SensorNoise.for_vessel(params)
    tf, after = 600.0 * f, 300.0 * f
    faults = [InjectedFault(tf, i, dof, gain=gain, bias=bias) for i in range(n_runs)]
    res = simulate(params, n_runs, tf + after, seed=seed, noise=noise, faults=faults)
    ev = run_detector(params, model, res)
    delays = [math.nan] * n_runs
    wrong = 0
    for e in ev:
        if e.dof == dof and e.t_s >= tf and math.isnan(delays[e.vessel]):
            delays[e.vessel] = e.t_s - tf
        else:
            wrong += 1
    per_run = tf + after
    n_ff = max(1, math.ceil(fault_free_hours * 3600.0 / per_run))
    ff = simulate(params, n_ff, per_run, seed=seed + 1, noise=noise)
    n_false = len(run_detector(params, model, ff))
    det = FaultDetector(params, 1, model)
    return FaultSuiteResult(tuple(delays), wrong, n_false, n_ff * per_run / 3600.0,
                            det.threshold)


# --------------------------------------------------------------------------- report
def _fmt(v: float) -> str:
    return "—" if not math.isfinite(v) else f"{v:.3g}"


def write_report(out_dir: str | Path, vessels: Sequence[str] = ("cybership2",
                                                                 "cybership2_full_scale"),
                 *, seed: int = 1, faults: bool = True, fault_runs: int = 20,
                 fault_free_hours: float = 10.0, runs: int = 8) -> dict[str, Path]:
    """Run the validation and write the table (Markdown, JSON) and the plot.

    ``runs`` seeded runs per observer scenario; the plot shows the first.
    Returns the paths written, by kind (``"md"``, ``"json"``, ``"png"``).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, Any]] = []
    panels = []
    fault_rows: list[dict[str, Any]] = []
    for name in vessels:
        p = vessel_by_name(name)
        for sc in SCENARIOS:
            for noise in (False, True):
                res, dh = run_observer(p, sc, noise=noise, seed=seed, n_runs=runs)
                m = observer_metrics(p, sc, res, dh)
                m["noise"] = noise
                rows.append(m)
                if noise and sc.kind in ("step", "environment"):
                    panels.append((f"{p.name} {sc.name}", p, res, dh))
        if faults:
            model = calibrate_detector(p)
            fs = fault_suite(p, model, n_runs=fault_runs, fault_free_hours=fault_free_hours)
            fault_rows.append({
                "vessel": p.name, "fault": "50 % surge thrust loss",
                "median_delay_s": fs.median_delay_s, "detected": fs.detected_fraction,
                "wrong_alarms": fs.wrong_alarms, "false_alarms": fs.false_alarms,
                "fault_free_hours": fs.fault_free_hours,
                "false_alarms_per_hour": fs.false_alarms_per_hour,
                "threshold": fs.threshold, "kappa": list(model.kappa)})
    lines = ["# Disturbance observer validation", "",
             (f"RMSE of d̂ − τ_d per DOF over {runs} seeded runs after 3 T (absolute [N, N, "
              "Nm], and relative to the actuator range) and time for the mean estimate to "
              "reach 90 % of a step (theory: ln 10 · T)."), "",
             ("| vessel | scenario | noise | RMSE surge | RMSE sway | RMSE yaw | "
              "rel. surge | rel. sway | rel. yaw | t90 surge [s] | t90 sway [s] | "
              "t90 yaw [s] | t90 theory [s] |"),
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for m in rows:
        lines.append(
            f"| {m['vessel']} | {m['scenario']} | {'yes' if m['noise'] else 'no'} | "
            + " | ".join(_fmt(v) for v in m["rmse"]) + " | "
            + " | ".join(f"{100 * v:.2f} %" for v in m["rmse_rel"]) + " | "
            + " | ".join(_fmt(v) for v in m["t90_s"]) + " | "
            + "/".join(f"{v:.0f}" for v in m["t90_theory_s"]) + " |")
    if fault_rows:
        lines += ["", "# Fault detection (default environment, sensor noise)", "",
                  ("| vessel | fault | detected | median delay [s] | wrong alarms | "
                   "false alarms | fault-free hours | false alarms / h | threshold |"),
                  "|---|---|---|---|---|---|---|---|---|"]
        for fr in fault_rows:
            lines.append(
                f"| {fr['vessel']} | {fr['fault']} | {100 * fr['detected']:.0f} % | "
                f"{fr['median_delay_s']:.1f} | {fr['wrong_alarms']} | {fr['false_alarms']} | "
                f"{fr['fault_free_hours']:.1f} | {fr['false_alarms_per_hour']:.2f} | "
                f"{fr['threshold']:.1f} |")
    paths = {"md": out / "observer_report.md", "json": out / "observer_report.json",
             "png": out / "observer_report.png"}
    paths["md"].write_text("\n".join(lines) + "\n")
    paths["json"].write_text(json.dumps({"seed": seed, "observer": rows,
                                         "faults": fault_rows}, indent=2, default=float))
    from asvtwin.plots import save
    from asvtwin.plots.observer import observer_figure

    save(observer_figure(panels), paths["png"], dpi=110)
    return paths
