"""The reward kernel (rewards) against the documented numpy formula, bit for bit."""

import numpy as np
import pytest

from uavform_env.config import RewardConfig
from uavform_env.rewards import compute_rewards


def _numpy_rewards(cfg, prev_dist, dist, ferr, is_follower, crashed_now, was_active, actions, prev_actions, success):
    r = cfg.progress * (prev_dist - dist)
    r -= cfg.formation * ferr * is_follower
    r -= cfg.smoothness * np.sum((actions - prev_actions) ** 2, axis=1)
    r -= cfg.time
    r -= cfg.collision * crashed_now
    if success:
        r += cfg.success
    return np.where(was_active, r, 0.0)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_rewards_match_the_numpy_formula_bit_for_bit(dtype):
    rng = np.random.default_rng(2)
    names = ("progress", "formation", "collision", "smoothness", "success", "time")
    for _ in range(200):
        n = int(rng.integers(1, 12))
        cfg = RewardConfig(**{k: float(rng.choice([0.0, rng.uniform(0, 20)])) for k in names})
        args = (cfg, rng.uniform(0, 50, n), rng.uniform(0, 50, n), rng.uniform(0, 10, n), rng.random(n) < 0.7,
                (rng.random(n) < 0.2).astype(float), rng.random(n) < 0.9, rng.uniform(-1, 1, (n, 3)).astype(dtype),
                rng.uniform(-1, 1, (n, 3)).astype(dtype), bool(rng.random() < 0.3))
        assert compute_rewards(*args).tobytes() == _numpy_rewards(*args).tobytes()
