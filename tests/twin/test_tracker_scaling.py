"""The twin's tracker settings follow the own ship's scale (Froude similarity)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from asvtwin.tracking import TrackerConfig
from asvtwin.tracking.prediction import predict_tracks
from asvtwin.twin.components import tracker_config
from asvtwin.twin.world import FULL_SCALE_REFERENCE_M

FULL = FULL_SCALE_REFERENCE_M


def test_full_scale_keeps_the_tracker_defaults():
    # but for the AIS dimensions, which only keep new tracks off a known hull in the twin
    twin_default = TrackerConfig(measure_with_dimensions=False)
    assert tracker_config(FULL, FULL) == twin_default
    assert tracker_config(300.0, FULL) == twin_default  # larger hulls: at most 1
    assert not tracker_config(1.255, FULL).measure_with_dimensions


def test_model_scale_scales_motion_and_lengths_not_sensors():
    s = 1.255 / FULL
    cfg, d = tracker_config(1.255, FULL), TrackerConfig()
    assert cfg.q == pytest.approx(d.q * math.sqrt(s))
    assert cfg.init_velocity_std_m_s == pytest.approx(d.init_velocity_std_m_s * math.sqrt(s))
    assert cfg.confirm_velocity_std_m_s == pytest.approx(d.confirm_velocity_std_m_s * math.sqrt(s))
    assert cfg.min_separation_m == pytest.approx(d.min_separation_m * s)
    assert cfg.ais.position_std_m == pytest.approx(d.ais.position_std_m * s)
    # sensor models and the chart's error are the scenario's / the chart's
    assert cfg.cluster == d.cluster and cfg.lidar == d.lidar
    assert cfg.chart_error_m == d.chart_error_m and cfg.max_coast_s == d.max_coast_s


@pytest.mark.parametrize("length", [1.255, 10.0])
def test_prediction_growth_is_froude_similar(length):
    """Over Froude-similar horizons (times × √s) the CV prediction's σ, in ship lengths,
    is the same at both scales: the filter's clearance circles scale with the hull."""
    s = length / FULL

    def sigma_end(cfg: TrackerConfig, scale: float, L: float) -> float:
        v0 = 0.3 * math.sqrt(scale)  # a track with a settled velocity σ, Froude-scaled
        cov = np.diag([(0.05 * L) ** 2] * 2 + [v0 ** 2] * 2)[None]
        mean = np.array([[0.0, 0.0, 2.0 * math.sqrt(scale), 0.0]])
        t_end = 209.0 * math.sqrt(scale)  # the full-scale filter horizon, scaled
        p = predict_tracks(mean, cov, 0.0, np.array([0.0, t_end]), cfg.q)
        return float(p.position_std_max()[0, -1]) / L

    full = sigma_end(tracker_config(FULL, FULL), 1.0, FULL)
    model = sigma_end(tracker_config(length, FULL), s, length)
    assert model == pytest.approx(full, rel=1e-9)
    unscaled = sigma_end(TrackerConfig(), s, length)
    assert unscaled > 1.5 * full  # what the model-scale twin used before
