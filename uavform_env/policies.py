"""Resolving a policy from a string: a short name, ``module:attr`` or a checkpoint path.

The env package never imports ``baselines`` or ``training``: short names are Python entry points of
the group ``uavform.policies`` (third-party packages add their own the same way), and checkpoint files
are opened by loaders of the group ``uavform.policy_loaders``, keyed by file suffix.

A policy is any object with ``reset(env, seed)`` and ``act(observations, env) -> {agent: action}``.
"""

from __future__ import annotations

import importlib
from importlib.metadata import entry_points
from pathlib import Path
from typing import Protocol

POLICY_GROUP = "uavform.policies"
LOADER_GROUP = "uavform.policy_loaders"


class Policy(Protocol):
    def reset(self, env, seed: int | None) -> None: ...

    def act(self, observations: dict, env) -> dict: ...


def available_policies() -> list[str]:
    return sorted(ep.name for ep in entry_points(group=POLICY_GROUP))


def _import_attr(spec: str):
    module, _, attr = spec.partition(":")
    try:
        obj = importlib.import_module(module)
    except ImportError as e:
        raise ValueError(f"policy {spec!r}: cannot import module {module!r} ({e})") from e
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise ValueError(f"policy {spec!r}: module {module!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    return obj


def policy_factory(spec: str):
    """The zero-argument-callable (class or function) behind ``spec``; see the module docstring."""
    if not isinstance(spec, str) or not spec:
        raise ValueError(f"policy: expected a short name, 'module:attr' or a checkpoint path, got {spec!r}")
    named = {ep.name: ep for ep in entry_points(group=POLICY_GROUP)}
    if spec in named:
        return named[spec].load()
    path = Path(spec)
    if path.suffix and (path.exists() or path.suffix.lstrip(".") in {ep.name for ep in entry_points(group=LOADER_GROUP)}):
        loaders = {ep.name: ep for ep in entry_points(group=LOADER_GROUP)}
        key = path.suffix.lstrip(".")
        if key not in loaders:
            raise ValueError(f"policy {spec!r}: no loader for '.{key}' files; known: {sorted(loaders)}")
        if not path.exists():
            raise ValueError(f"policy {spec!r}: checkpoint file not found")
        loader = loaders[key].load()
        return lambda: loader(path)
    if ":" in spec:
        factory = _import_attr(spec)
        if not callable(factory):
            raise ValueError(f"policy {spec!r}: {spec.partition(':')[2]!r} is a {type(factory).__name__}, not a "
                             "class or function that makes a policy; give 'module:ClassName'")
        return factory
    raise ValueError(f"unknown policy {spec!r}; known short names: {available_policies()}, "
                     "or give 'module:attr' or a checkpoint path")


def load_policy(spec: str) -> Policy:
    policy = policy_factory(spec)()
    for method in ("reset", "act"):
        if not callable(getattr(policy, method, None)):
            raise ValueError(f"policy {spec!r}: the object has no {method}() method; a policy needs reset(env, seed) "
                             "and act(observations, env)")
    return policy
