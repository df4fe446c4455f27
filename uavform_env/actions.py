"""Checking a step's {agent: action} dict, shared by the env and the wrappers that change the action space."""

from __future__ import annotations

import numpy as np


def check_actions(actions, possible_agents: list[str], live_agents: list[str], size: int,
                  meaning: str) -> dict[str, np.ndarray]:
    """{agent: float64 action clipped to [-1, 1]} for the live agents, or a ValueError naming the agent.

    ``meaning`` describes the ``size`` action components for the error messages.
    """
    return dict(zip(actions, action_rows(actions, possible_agents, live_agents, size, meaning)))


def action_rows(actions, possible_agents: list[str], live_agents: list[str], size: int, meaning: str) -> np.ndarray:
    """``check_actions`` as one float64 array (len(actions), size), rows in the dict's order."""
    if not isinstance(actions, dict):
        raise ValueError(f"actions: expected a dict {{agent: array of shape ({size},)}}, got {type(actions).__name__}")
    if actions.keys() != set(live_agents):
        unknown = [a for a in actions if a not in possible_agents]
        if unknown:
            raise ValueError(f"actions for unknown agent(s) {unknown}; agents are {possible_agents}")
        finished = [a for a in actions if a not in live_agents]
        if finished:
            raise ValueError(f"actions for agent(s) {finished} that are no longer live; live agents are {live_agents}")
        missing = [a for a in live_agents if a not in actions]
        raise ValueError(f"missing actions: no action for live agent(s) {missing}")
    try:  # all at once; a ragged or non-numeric dict is checked agent by agent below, for the message
        rows = np.asarray(list(actions.values()), dtype=np.float64)
    except (TypeError, ValueError):
        rows = None
    if rows is not None and rows.shape == (len(actions), size) and np.isfinite(rows).all():
        return np.minimum(np.maximum(rows, -1.0, out=rows), 1.0, out=rows)  # np.clip without its wrapper's cost
    for a, act in actions.items():
        arr = np.asarray(act, dtype=np.float64)
        if arr.shape != (size,):
            raise ValueError(f"action of {a}: expected shape ({size},) ({meaning} in [-1, 1]), got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"action of {a}: expected finite values in [-1, 1], got {arr.tolist()}")
    raise ValueError(f"actions: expected one array of shape ({size},) per agent, got {actions!r}")
