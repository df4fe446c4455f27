"""The expert's per-step shortcuts give what the per-UAV computations they replace gave, bit for bit."""

import numpy as np

from baselines.expert import ExpertConfig, FusionExpert
from baselines.fusion.controller import _column_offsets, _rotated


def test_column_offsets_are_single_file_behind_the_leader_at_each_slots_height():
    offsets = np.array([[0.0, 0.0, 0.0], [-2.0, 2.0, 0.5], [-2.0, -2.0, -0.5], [-4.0, 0.0, 1.0]])
    column = _column_offsets(offsets, 1.5)
    expected = np.array([[0.0, 0.0, 0.0], [-1.5, 0.0, 0.5], [-3.0, 0.0, -0.5], [-4.5, 0.0, 1.0]])
    assert np.array_equal(column, expected)
    assert not np.shares_memory(column, offsets)


def test_rotating_every_offset_at_once_equals_rotating_each_alone_bit_for_bit():
    rng = np.random.default_rng(7)
    offsets = rng.uniform(-6.0, 6.0, (9, 3))
    for psi in (0.0, 0.3, -2.9, np.pi, 1e-12):
        together = _rotated(psi, offsets)
        for i in range(len(offsets)):
            assert np.array_equal(together[i], _rotated(psi, offsets[i][None])[0])


def test_the_final_approach_config_is_made_once_per_dwa_config():
    expert = FusionExpert(ExpertConfig())
    dwa = expert.config.dwa
    free = expert._without_clearance_weight(dwa)
    assert free.beta == 0.0 and free.alpha0 == dwa.alpha0 and free.gamma == dwa.gamma
    assert expert._without_clearance_weight(dwa) is free              # the same object while the config is
    other = ExpertConfig(dwa=type(dwa)(beta=0.3)).dwa
    assert expert._without_clearance_weight(other).beta == 0.0 and expert._without_clearance_weight(other) is not free
