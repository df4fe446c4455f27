"""Slot geometry (formation): slots and slot/target distances against the numpy formulas, bit for bit."""

import numpy as np

from uavform_env.formation import slot_distances, slot_offsets, slot_positions


def test_slots_and_slot_distances_match_numpy_bit_for_bit():
    rng = np.random.default_rng(1)
    for shape, n in (("wedge", 7), ("line", 4), ("column", 3), ("diamond", 4), ("triangle", 3), ("wedge", 1)):
        offsets = slot_offsets(shape, n, float(rng.uniform(1, 4)))
        offsets[:, 2] = rng.normal(size=n)
        lead, yaw, z_ref = rng.uniform(-20, 20, 3), float(rng.uniform(-4, 4)), float(rng.uniform(1, 5))
        c, s = np.cos(yaw), np.sin(yaw)
        want = np.column_stack([lead[0] + c * offsets[:, 0] - s * offsets[:, 1],
                                lead[1] + s * offsets[:, 0] + c * offsets[:, 1], z_ref + offsets[:, 2]])
        slots = slot_positions(lead[:2], yaw, offsets, z_ref)
        assert slots.tobytes() == want.tobytes()
        pos, goal = rng.uniform(-20, 20, (n, 3)), rng.uniform(-20, 20, 3)
        targets = slots.copy()
        targets[0] = goal
        ferr, dist = slot_distances(pos, slots, goal)
        assert ferr.tobytes() == np.linalg.norm(pos - slots, axis=1).tobytes()
        assert dist.tobytes() == np.linalg.norm(pos - targets, axis=1).tobytes()
