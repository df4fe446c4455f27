"""Kinematic UAV model of spec (a): planar unicycle plus an independent vertical channel.

The same ``integrate`` kernel advances the simulator and the planners' rollouts (one source of
truth for the model). Commands pass through rate and acceleration limits first, so a planner that
samples inside the dynamic window reproduces the simulated motion exactly.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .config import UAVLimits

# Column indices of a state row (x, y, z, psi, v, w, vz).
X, Y, Z, PSI, V, W, VZ = range(7)
STATE_DIM = 7


@numba.njit(cache=True, inline="always")
def wrap(a):
    """Map an angle to (-pi, pi]."""
    two_pi = 2.0 * math.pi
    a = (a + math.pi) - two_pi * math.floor((a + math.pi) / two_pi)
    if a <= 0.0:
        a += two_pi
    return a - math.pi


@numba.njit(cache=True)
def wrap_all(a):
    """``wrap`` of every angle of the array ``a`` (a new float64 array of its shape)."""
    flat = np.ascontiguousarray(a).ravel()
    out = np.empty(flat.size)
    for i in range(flat.size):
        out[i] = wrap(flat[i])
    return out.reshape(a.shape)


@numba.njit(cache=True, inline="always")
def integrate(x, y, z, psi, v, w, vz, dt):
    """One 'yaw first' Euler step with the commands (v, w, vz) held constant (spec (a))."""
    psi_n = wrap(psi + w * dt)
    return x + v * math.cos(psi_n) * dt, y + v * math.sin(psi_n) * dt, z + vz * dt, psi_n


def actions_to_commands(actions: np.ndarray, limits: UAVLimits) -> np.ndarray:
    """Map actions in [-1, 1]^3 linearly to (v_c, w_c, vz_c) within the limits."""
    a = np.clip(np.asarray(actions, dtype=np.float64), -1.0, 1.0)
    cmd = np.empty_like(a)
    _commands(a.reshape(-1, a.shape[-1]), limits.v_min, limits.v_max - limits.v_min, limits.w_max, limits.vz_max,
              cmd.reshape(-1, a.shape[-1]))
    return cmd


@numba.njit(cache=True, inline="always")
def _command(a_v, a_w, a_vz, v_min, v_span, w_max, vz_max):
    """The commands (v_c, w_c, vz_c) of one action in [-1, 1]^3 (``actions_to_commands``)."""
    return v_min + 0.5 * (a_v + 1.0) * v_span, a_w * w_max, a_vz * vz_max


@numba.njit(cache=True)
def _commands(actions, v_min, v_span, w_max, vz_max, out):
    for i in range(actions.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = _command(actions[i, 0], actions[i, 1], actions[i, 2], v_min, v_span, w_max,
                                                   vz_max)


def commands_to_actions(commands: np.ndarray, limits: UAVLimits) -> np.ndarray:
    """Inverse of ``actions_to_commands`` (for scripted policies that plan in command space)."""
    c = np.asarray(commands, dtype=np.float64)
    a = np.empty_like(c)
    span = limits.v_max - limits.v_min
    a[..., 0] = 2.0 * (c[..., 0] - limits.v_min) / span - 1.0
    a[..., 1] = c[..., 1] / limits.w_max
    a[..., 2] = c[..., 2] / limits.vz_max if limits.vz_max > 0 else 0.0
    return np.clip(a, -1.0, 1.0).astype(np.float32)


@numba.njit(cache=True, inline="always")
def window(v_c, w_c, vz_c, v0, w0, vz0, dt, v_min, v_max, w_max, a_max, dw_max, vz_max, az_max):
    """The rates (v, w, vz) a UAV at (v0, w0, vz0) flies for one step on the commands (v_c, w_c, vz_c): each
    limited to the dynamic window (acceleration over dt) and to its bounds."""
    v = min(max(v_c, v0 - a_max * dt, v_min), v0 + a_max * dt, v_max)
    w = min(max(w_c, w0 - dw_max * dt, -w_max), w0 + dw_max * dt, w_max)
    vz = min(max(vz_c, vz0 - az_max * dt, -vz_max), vz0 + az_max * dt, vz_max)
    return v, w, vz


@numba.njit(cache=True, inline="always")
def _advance(states, i, v_c, w_c, vz_c, dt, v_min, v_max, w_max, a_max, dw_max, vz_max, az_max, z_min, z_max):
    """Advance UAV i one step with the commands (v_c, w_c, vz_c) (see ``step``)."""
    v, w, vz = window(v_c, w_c, vz_c, states[i, V], states[i, W], states[i, VZ], dt, v_min, v_max, w_max, a_max,
                      dw_max, vz_max, az_max)
    x, y, z, psi = integrate(states[i, X], states[i, Y], states[i, Z], states[i, PSI], v, w, vz, dt)
    if z < z_min or z > z_max:
        z = min(max(z, z_min), z_max)
        vz = 0.0
    states[i, X], states[i, Y], states[i, Z], states[i, PSI] = x, y, z, psi
    states[i, V], states[i, W], states[i, VZ] = v, w, vz


@numba.njit(cache=True)
def _step_kernel(states, commands, active, from_actions, dt, v_min, v_max, w_max, a_max, dw_max, vz_max, az_max, z_min,
                 z_max):
    for i in range(states.shape[0]):
        if not active[i]:
            states[i, V] = 0.0
            states[i, W] = 0.0
            states[i, VZ] = 0.0
            continue
        v_c, w_c, vz_c = commands[i, 0], commands[i, 1], commands[i, 2]
        if from_actions:  # rows of finite actions: clipped to [-1, 1] and mapped as actions_to_commands does
            v_c, w_c, vz_c = _command(min(max(v_c, -1.0), 1.0), min(max(w_c, -1.0), 1.0), min(max(vz_c, -1.0), 1.0),
                                      v_min, v_max - v_min, w_max, vz_max)
        _advance(states, i, v_c, w_c, vz_c, dt, v_min, v_max, w_max, a_max, dw_max, vz_max, az_max, z_min, z_max)


def step(states: np.ndarray, commands: np.ndarray, active: np.ndarray, limits: UAVLimits) -> None:
    """Advance all UAVs one step in place; inactive (crashed) UAVs stay frozen with zero rates.

    Commands are first limited to the dynamic window (acceleration) and to the velocity limits,
    then integrated; the altitude is kept inside [z_min, z_max].
    """
    _step_kernel(states, np.ascontiguousarray(commands, dtype=np.float64), active, False, limits.dt,
                 limits.v_min, limits.v_max, limits.w_max, limits.a_max, limits.dw_max,
                 limits.vz_max, limits.az_max, limits.z_min, limits.z_max)


def step_actions(states: np.ndarray, actions: np.ndarray, active: np.ndarray, limits: UAVLimits) -> None:
    """``step(states, actions_to_commands(actions, limits), active, limits)`` in one numba call, for finite
    ``actions`` (N, 3)."""
    _step_kernel(states, np.ascontiguousarray(actions, dtype=np.float64), active, True, limits.dt,
                 limits.v_min, limits.v_max, limits.w_max, limits.a_max, limits.dw_max,
                 limits.vz_max, limits.az_max, limits.z_min, limits.z_max)


def wind_drift(air: np.ndarray, lean: np.ndarray, active: np.ndarray, limits: UAVLimits) -> np.ndarray:
    """The velocity (N, 3) by which the wind ``air`` (N, 3, m/s) carries each UAV this step, and the autopilot's
    wind compensation ``lean`` (N, 3) updated in place for the ``active`` UAVs (README, "Disturbances").

    The commands are ground-velocity set-points of an autopilot that leans into its wind estimate: ``lean``
    follows ``air`` with time constant ``limits.wind_rejection_tau`` (lean += (air - lean) (1 - exp(-dt/tau))),
    then its horizontal part is scaled down to at most ``limits.wind_authority`` and its vertical part clipped
    to +/- the same; the UAV drifts with air - lean. Inactive rows of ``lean`` stay as they are (their drift is
    not applied by the caller). ``wind_authority = 0`` keeps ``lean`` at zero: the drift is the whole wind.
    """
    cap = limits.wind_authority
    if cap > 0.0:
        tau = limits.wind_rejection_tau
        gain = 1.0 if tau == 0.0 else -math.expm1(-limits.dt / tau)
        new = lean[active] + (air[active] - lean[active]) * gain
        horizontal = np.hypot(new[:, 0], new[:, 1])
        over = horizontal > cap
        new[over, :2] *= (cap / horizontal[over])[:, None]
        np.clip(new[:, 2], -cap, cap, out=new[:, 2])
        lean[active] = new
    return air - lean
