"""Gusts as a field in space and time: nearby UAVs feel nearly the same gust, far ones different gusts.

The gust velocity at a point x is a sum of ``n_modes`` random Fourier modes,

    u(x, t) = (1 / sqrt(M)) * sum_m [cos(k_m . x) a_m(t) + sin(k_m . x) b_m(t)],

with wavevectors k_m drawn once per episode from N(0, I / L^2) and amplitudes a_m, b_m (one per axis) that are
independent Ornstein-Uhlenbeck processes of standard deviation ``std`` and correlation time ``tau``, started from
their stationary law. Every point then sees gusts of exactly ``std`` per axis, and two points d apart see gusts
whose expected correlation is exp(-|d|^2 / (2 L^2)) (Gaussian spatial covariance, correlation length L = ``length``),
the random-Fourier-feature construction of a stationary Gaussian field. The vertical axis is scaled by
``vertical_scale`` (near the ground gusts are mostly horizontal).

Why a field: per-UAV independent gusts push two UAVs 2 m apart against each other at up to twice the gust speed,
which air does not do; the Dryden model's low-altitude length scale (MIL-F-8785C) is about 23 m at 3 m altitude.
"""

from __future__ import annotations

import math

import numpy as np

# Fourier modes per field: within 10 m one episode's correlation is within about 0.02 of exp(-d^2 / 2L^2)
GUST_MODES = 64


class GustField:
    """One episode's gust field; ``advance`` moves it one step in time, ``at`` reads it at given positions."""

    def __init__(self, rng: np.random.Generator, std: float, tau: float, length: float, n_modes: int,
                 vertical_scale: float):
        self.std, self.tau = std, tau
        self._rng = rng
        self._k = rng.standard_normal((n_modes, 3)) / length                  # wavevectors (1/m)
        self._amp = rng.standard_normal((2 * n_modes, 3)) * std                # [a; b] per axis, stationary start
        self._scale = np.array([1.0, 1.0, vertical_scale]) / math.sqrt(n_modes)

    def advance(self, dt: float) -> None:
        """One exact Ornstein-Uhlenbeck step of every mode amplitude."""
        decay = math.exp(-dt / self.tau)
        self._amp *= decay
        self._amp += self._rng.standard_normal(self._amp.shape) * (self.std * math.sqrt(1.0 - decay * decay))

    def at(self, positions: np.ndarray) -> np.ndarray:
        """Gust velocity (m/s) at each of ``positions`` (n, 3), shape (n, 3)."""
        phase = positions @ self._k.T                                          # (n, M)
        basis = np.concatenate((np.cos(phase), np.sin(phase)), axis=1)         # (n, 2M)
        return (basis @ self._amp) * self._scale
