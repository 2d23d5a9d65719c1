"""The manoeuvre figure: numbers in words with units, the thrust that reached the hull,
and the coast around the track."""

from __future__ import annotations

import math

import numpy as np

from asvtwin.geo import default_scene
from asvtwin.plots import manoeuvre_figure, metric_text
from asvtwin.vessel import cybership2, cybership2_full_scale
from asvtwin.vessel.manoeuvres import METRICS, thrust_step, turning_circle, zigzag


def _texts(fig) -> str:
    out = [t.get_text() for ax in fig.axes for t in ax.texts]
    out += [ax.get_ylabel() for ax in fig.axes] + [ax.get_title() for ax in fig.axes]
    return "\n".join(out)


def test_every_metric_has_words_and_a_unit():
    for result in (turning_circle(cybership2()), zigzag(cybership2(), surge_fraction=0.2),
                   thrust_step(cybership2())):
        for key in result.metrics:
            words, unit = METRICS[key]
            assert words and unit and "_" not in words


def test_metric_text_is_words_with_units_and_criteria():
    r = turning_circle(cybership2_full_scale())
    text = metric_text(r)
    assert "tactical diameter (transfer at 180°) = 104 m" in text
    assert "steady turning diameter 2U/r = 112 m" in text
    assert "IMO tactical diameter: 1.18 ≤ 5 L: pass" in text
    assert "tactical_diameter_m" not in text  # no snake_case keys


def test_undefined_metrics_are_labelled_with_the_reason():
    r = zigzag(cybership2(), surge_fraction=1.0)
    assert math.isnan(r.metrics["second_overshoot_deg"])
    fig = manoeuvre_figure(r, length_m=1.255)
    text = _texts(fig)
    assert "second overshoot = undefined (see notes)" in text
    assert "course-unstable" in text


def test_thrust_is_shown_in_readable_units():
    fig = manoeuvre_figure(thrust_step(cybership2_full_scale()), length_m=88.0)
    labels = _texts(fig)
    assert "surge τ_u [kN]" in labels  # 703 kN, not 7.03e5 N
    (line,) = next(ax for ax in fig.axes if ax.get_ylabel() == "surge τ_u [kN]").lines
    # 2 N at model scale × 70³ × 1025/1000 = 703.2 kN
    assert abs(np.nanmax(line.get_ydata()) - 703.2) < 0.1


def test_the_coast_frames_the_turning_circle():
    r = turning_circle(cybership2_full_scale())
    fig = manoeuvre_figure(r, length_m=88.0, scene=default_scene())
    track_ax = fig.axes[0]
    x0, x1 = track_ax.get_xlim()
    y0, y1 = track_ax.get_ylim()
    span = np.ptp(r.x[:, :2], axis=0).max()
    # three times the track's extent (at least 8 L and 600 m) of margin each side
    pad = max(3 * span, 8 * 88.0, 600.0)
    assert x0 <= r.x[:, 1].min() - pad + 1e-6 and x1 >= r.x[:, 1].max() + pad - 1e-6
    assert y0 <= r.x[:, 0].min() - pad + 1e-6 and y1 >= r.x[:, 0].max() + pad - 1e-6
    assert len(track_ax.patches) >= 1  # land drawn
