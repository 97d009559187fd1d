"""Spectra and tests for chaos on a time series (jaxclear.chaos.signals) and period detection on
Poincare sections (jaxclear.analysis.sections), against closed forms: a sine's spectral line,
the logistic map's known periodic windows and chaotic parameters."""

from __future__ import annotations

import math

import numpy as np
import pytest

import jaxclear as jc
from jaxclear.analysis.sections import detect_period, period_name, section_indices
from jaxclear.chaos.signals import psd, zero_one_test


def logistic(r, n, x0=0.3, transient=1000):
    """x_{k+1} = r x_k (1 - x_k) after ``transient`` iterations."""
    x = x0
    for _ in range(transient):
        x = r * x * (1 - x)
    out = np.empty(n)
    for k in range(n):
        x = r * x * (1 - x)
        out[k] = x
    return out


def test_psd_of_a_sine_peaks_at_its_frequency():
    """A 7 Hz sine of amplitude 2 sampled at 200 Hz for 20 s: Welch's density peaks at the
    frequency bin nearest 7 Hz (resolution fs/nperseg = 0.5 Hz) and integrates to the mean
    square a^2/2 = 2 (Parseval; to 2 %, the Hann window's leakage into the bins kept)."""
    dt, f0 = 1 / 200, 7.0
    t = np.arange(0, 20, dt)
    f, p = psd(2.0 * np.sin(2 * math.pi * f0 * t), dt, nperseg=400)
    assert abs(f[np.argmax(p)] - f0) <= 0.25
    assert np.trapezoid(p, f) == pytest.approx(2.0, rel=0.02)


def test_zero_one_test_on_the_logistic_map():
    """Gottwald and Melbourne (2009, fig. 2): the logistic map at r = 3.55 (period 8) gives
    K near 0, at r = 3.97 (chaotic) near 1; with N = 2000 iterates and 100 values of c their
    figure shows |K| < 0.1 and K > 0.9. Same bounds here."""
    k_regular, _, _ = zero_one_test(logistic(3.55, 2000))
    k_chaotic, _, _ = zero_one_test(logistic(3.97, 2000))
    assert abs(k_regular) < 0.1
    assert k_chaotic > 0.9


@pytest.mark.parametrize("r, period", [(2.8, 1), (3.2, 2), (3.5, 4), (3.55, 8), (3.9, 0)])
def test_period_detection_names_the_logistic_maps_orbits(r, period):
    """The logistic map's period-doubling cascade (May, Nature 261 (1976) 459): a fixed point
    at r = 2.8, period 2 at 3.2, 4 at 3.5, 8 at 3.55, chaos at 3.9 (no period up to 16)."""
    assert detect_period(logistic(r, 200)) == period
    assert period_name(period) == (f"period-{period}" if period else "not periodic (n > 16)")


def test_bad_input_is_named():
    with pytest.raises(jc.ParameterError, match=r"zero_one_test: expected at least 100 finite samples"):
        zero_one_test(np.ones(50))
    with pytest.raises(jc.ParameterError, match=r"psd: sample step dt = 0.0 s .*\(0, inf\)"):
        psd(np.ones(100), 0.0)
    with pytest.raises(jc.ParameterError, match=r"stride = 0 samples per period .*\[1, inf\)"):
        section_indices(100, 0)


def test_period_of_a_section_near_zero_is_measured_against_the_channel():
    """A period-1 section lying near zero (a slider's velocity at a dead centre, 5e-3 m/s, with
    the integration's noise 3e-4 m/s) of a channel whose run reaches 0.5 m/s: period-1 against
    the channel's size (noise 6e-4 of it, tolerance 1e-2), none against the section's own."""
    rng = np.random.default_rng(0)
    points = -5e-3 + 3e-4 * rng.uniform(-0.5, 0.5, 60)
    assert detect_period(points, rtol=1e-2, scale=0.5) == 1
    assert detect_period(points, rtol=1e-2) == 0
