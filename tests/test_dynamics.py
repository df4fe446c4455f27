"""Actions to motion (dynamics): step_actions is step of the commands, the commands the documented map, bit for bit."""

import numpy as np

from uavform_env import dynamics
from uavform_env.config import UAVLimits


def test_step_actions_is_step_of_the_commands_bit_for_bit():
    rng = np.random.default_rng(3)
    limits = UAVLimits()
    states = np.column_stack([rng.uniform(-10, 10, (9, 3)), rng.uniform(-3, 3, 9), rng.uniform(0, 2, (9, 3))])
    states[:, 2] = rng.uniform(limits.z_min - 1, limits.z_max + 1, 9)
    active = rng.random(9) < 0.8
    for _ in range(20):
        acts = rng.uniform(-1.2, 1.2, (9, 3)).astype(np.float32)
        a, b = states.copy(), states.copy()
        dynamics.step(a, dynamics.actions_to_commands(acts, limits), active, limits)
        dynamics.step_actions(b, acts, active, limits)
        assert a.tobytes() == b.tobytes()
        states = a
    cmd = dynamics.actions_to_commands(acts, limits)
    a = np.clip(acts.astype(np.float64), -1, 1)
    want = np.column_stack([limits.v_min + 0.5 * (a[:, 0] + 1.0) * (limits.v_max - limits.v_min),
                            a[:, 1] * limits.w_max, a[:, 2] * limits.vz_max])
    assert cmd.tobytes() == want.tobytes()
    assert dynamics.actions_to_commands(acts[0], limits).tobytes() == want[0].tobytes()
