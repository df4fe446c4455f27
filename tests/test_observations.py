"""The batched observation kernel equals a plain numpy reference of every own-state field, bit for bit."""

import numpy as np
import pytest

from uavform_env.config import EnvConfig, ObservationConfig
from uavform_env.dynamics import PSI, VZ, W, V, Z
from uavform_env.observations import ObservationLayout, build_observations
from uavform_env.occupancy import MapStore
from uavform_env.scenarios import GRID_RESOLUTION


def body(dxy, psi):
    c, s = np.cos(psi), np.sin(psi)
    return np.stack([c * dxy[..., 0] + s * dxy[..., 1], -s * dxy[..., 0] + c * dxy[..., 1]], axis=-1)


def reference(layout, cfg, states, targets, leader, broadcast, ok):
    """The ego, target, role and neighbour fields, vectorised over UAVs (neighbours sorted with a stable argsort)."""
    u, oc = cfg.uav, cfg.observation
    n = len(states)
    out = np.zeros((n, layout.size), np.float32)
    psi = states[:, PSI]
    ego = out[:, layout.slice("ego")]
    ego[:, 0], ego[:, 1], ego[:, 2] = states[:, V] / u.v_max, states[:, W] / u.w_max, states[:, VZ] / u.vz_max
    ego[:, 3], ego[:, 4] = np.sin(psi), np.cos(psi)
    ego[:, 5] = 2.0 * (states[:, Z] - u.z_min) / (u.z_max - u.z_min) - 1.0
    rel = targets - states[:, :3]
    tgt = out[:, layout.slice("target")]
    tgt[:, :2] = body(rel[:, :2], psi) / oc.target_clip
    tgt[:, 2] = rel[:, 2] / oc.target_clip
    tgt[:, 3] = np.linalg.norm(rel, axis=1) / oc.target_clip
    role = out[:, layout.slice("role")]
    role[leader, 0] = 1.0
    role[:, 1], role[:, 2] = np.sin(broadcast[leader, PSI] - psi), np.cos(broadcast[leader, PSI] - psi)
    k, rng_max = oc.k_neighbours, oc.neighbour_range
    vel = np.stack([broadcast[:, V] * np.cos(broadcast[:, PSI]), broadcast[:, V] * np.sin(broadcast[:, PSI]),
                    broadcast[:, VZ]], axis=1)
    own = np.stack([states[:, V] * np.cos(psi), states[:, V] * np.sin(psi), states[:, VZ]], axis=1)
    rel = broadcast[None, :, :3] - states[:, None, :3]
    dist = np.linalg.norm(rel, axis=2)
    dist[np.arange(n), np.arange(n)] = np.inf
    dist[:, ~ok] = np.inf
    dist[dist > rng_max] = np.inf
    order = np.argsort(dist, axis=1, kind="stable")[:, :k]
    feats = out[:, layout.slice("neighbours")].reshape(n, k, 7)
    for slot in range(min(k, n - 1)):
        j = order[:, slot]
        r, dv = rel[np.arange(n), j], vel[j] - own
        feats[:, slot, :2] = body(r[:, :2], psi) / rng_max
        feats[:, slot, 2] = r[:, 2] / rng_max
        feats[:, slot, 3:5] = body(dv[:, :2], psi) / (2.0 * u.v_max)
        feats[:, slot, 5] = dv[:, 2] / (2.0 * u.v_max)
        feats[:, slot, 6] = 1.0
        feats[~np.isfinite(dist[np.arange(n), j]), slot, :] = 0.0
    out[:, layout.slice("neighbours")] = feats.reshape(n, -1)
    return np.clip(out, layout.low, layout.high)


@pytest.mark.parametrize("n, k", [(1, 3), (3, 4), (9, 4), (12, 2)])
def test_own_fields_equal_the_numpy_reference(n, k):
    rng = np.random.default_rng(n * 10 + k)
    cfg = EnvConfig(observation=ObservationConfig(k_neighbours=k, include_histogram=False))
    layout = ObservationLayout(cfg)
    states = np.column_stack([rng.uniform(0, 8, (n, 2)), rng.uniform(1, 4, n), rng.uniform(-4, 4, n),
                              rng.uniform(0, 1, n), rng.uniform(-0.5, 0.5, n), rng.uniform(-0.3, 0.3, n)])
    states[n // 2:, :3] = states[0, :3] + np.array([3.0, 0.0, 0.0])   # equal distances: ties keep index order
    broadcast = states + rng.normal(0, 0.1, states.shape)
    broadcast[n // 2:, :3] = states[0, :3] + np.array([3.0, 0.0, 0.0])
    targets = rng.uniform(0, 10, (n, 3))
    ok = rng.random(n) < 0.8
    maps = MapStore((0.0, 0.0, 0.0), (8, 8, 8), GRID_RESOLUTION, cfg.map, n)
    got = build_observations(layout, cfg, states, targets, 0, broadcast, maps, ok)
    np.testing.assert_array_equal(got, reference(layout, cfg, states, targets, 0, broadcast, ok))
