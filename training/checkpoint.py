"""Residual-policy checkpoints: an SB3 PPO zip with the uavform metadata inside, and the policy object.

The metadata member (``uavform.json``) holds what is needed to fly the policy again and to refuse a
mismatch: the env version, the observation layout, the expert's configuration, the weight bound and
the observation normalisation statistics. SB3's loader ignores the extra member, so the file is also a
plain SB3 model. Writes are atomic: a crash never leaves a torn checkpoint.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import zipfile
from pathlib import Path

import numpy as np

from baselines.expert import WEIGHT_NAMES, ExpertConfig, FusionExpert
from baselines.policy import check_flyable
from uavform_env import __version__ as UAVFORM_VERSION
from uavform_env.actions import check_actions
from uavform_env.files import atomic_write_bytes

from .residual import ResidualConfig, WeightAdjuster

META_MEMBER = "uavform.json"
FORMAT = "uavform-residual/1"
ENV_NAME = "formation_v0"


def layout_signature(env) -> dict:
    """What a policy's input depends on: the env version and the observation layout (fields, sizes, meanings)."""
    base = getattr(env, "unwrapped", env)
    layout = base.layout
    return {"env": base.metadata["name"], "observation_fields": [[f.name, f.size] for f in layout.fields],
            "layout_hash": hashlib.sha256(layout.table().encode()).hexdigest()[:16]}


def save_checkpoint(model, path: str | os.PathLike, meta: dict) -> None:
    """Write ``model`` with ``meta`` (see ``checkpoint_meta``) to ``path`` atomically."""
    buf = io.BytesIO()
    model.save(buf)
    with zipfile.ZipFile(buf, "a") as archive:
        archive.writestr(META_MEMBER, json.dumps(meta, sort_keys=True))
    atomic_write_bytes(path, buf.getvalue())


def checkpoint_meta(env, expert_config: ExpertConfig, residual: ResidualConfig, obs_rms, clip_obs: float,
                    epsilon: float, extra: dict) -> dict:
    return {"format": FORMAT, "uavform_version": UAVFORM_VERSION, **layout_signature(env),
            "weight_names": list(WEIGHT_NAMES), "expert_config": expert_config.to_dict(),
            "residual": residual.to_dict(),
            "obs_norm": {"mean": obs_rms.mean.tolist(), "var": obs_rms.var.tolist(), "count": float(obs_rms.count),
                         "clip": float(clip_obs), "epsilon": float(epsilon)}, **extra}


def read_meta(path: str | os.PathLike) -> dict:
    """The uavform metadata of a checkpoint, after checking it is one this version can fly."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"checkpoint {str(path)!r}: file not found")
    try:
        with zipfile.ZipFile(path) as archive:
            if META_MEMBER not in archive.namelist():
                raise ValueError(f"checkpoint {str(path)!r}: no {META_MEMBER} inside; not a uavform residual policy "
                                 "(train one with `uavform train`)")
            meta = json.loads(archive.read(META_MEMBER))
    except zipfile.BadZipFile as e:
        raise ValueError(f"checkpoint {str(path)!r}: not a readable zip file ({e})") from e
    if meta.get("format") != FORMAT:
        raise ValueError(f"checkpoint {str(path)!r}: format {meta.get('format')!r}, this version reads {FORMAT!r}")
    if meta.get("env") != ENV_NAME:
        raise ValueError(f"checkpoint {str(path)!r}: trained on env version {meta.get('env')!r}, this library "
                         f"provides {ENV_NAME!r}")
    if meta.get("weight_names") != list(WEIGHT_NAMES):
        raise ValueError(f"checkpoint {str(path)!r}: adjusts weights {meta.get('weight_names')}, the expert's "
                         f"weights are {list(WEIGHT_NAMES)}")
    return meta


class ResidualPolicy:
    """A trained residual policy as a plain policy: ``reset(env, seed)`` and ``act(observations, env)``.

    Each step it observes like ``ResidualWeightEnv``, normalises with the saved statistics, asks the
    network (deterministic) for the weight adjustments and lets the expert fly with those weights.
    """

    def __init__(self, model, meta: dict, name: str = "residual"):
        self.model, self.meta, self.name = model, meta, name
        self.expert_config = ExpertConfig.from_dict(meta["expert_config"])
        self.adjuster = WeightAdjuster(self.expert_config, ResidualConfig.from_dict(meta["residual"]))
        norm = meta["obs_norm"]
        self._mean, self._std = np.asarray(norm["mean"]), np.sqrt(np.asarray(norm["var"]) + norm["epsilon"])
        self._clip = norm["clip"]
        self.expert = FusionExpert(self.expert_config)

    @classmethod
    def load(cls, path: str | os.PathLike) -> "ResidualPolicy":
        from stable_baselines3 import PPO

        meta = read_meta(path)
        try:
            model = PPO.load(path, device="cpu")
        except Exception as e:
            raise ValueError(f"checkpoint {str(path)!r}: SB3 could not load the model ({e})") from e
        return cls(model, meta, name=str(path))

    def reset(self, env, seed: int | None = None) -> None:
        check_flyable(env)
        have, want = layout_signature(env), {k: self.meta[k] for k in ("env", "observation_fields", "layout_hash")}
        if have != want:
            diff = [k for k in want if have[k] != want[k]]
            raise ValueError(f"policy {self.name}: trained for {', '.join(f'{k}={want[k]}' for k in diff)}, "
                             f"but the env has {', '.join(f'{k}={have[k]}' for k in diff)}")
        self.expert.reset(env, seed)
        self._in_use = {a: np.zeros(len(WEIGHT_NAMES)) for a in getattr(env, "unwrapped", env).possible_agents}

    def act(self, observations: dict, env) -> dict:
        agents = list(getattr(env, "unwrapped", env).agents)
        rows = np.stack([self.adjuster.observe(observations[a], self._in_use[a]) for a in agents])
        rows = np.clip((rows - self._mean) / self._std, -self._clip, self._clip).astype(np.float32)
        actions, _ = self.model.predict(rows, deterministic=True)
        self._in_use.update(check_actions(dict(zip(agents, actions)), agents, agents, len(WEIGHT_NAMES),
                                          "the network's weight adjustments"))
        weights = {a: self.adjuster.weights(self._in_use[a]) for a in agents}
        return self.expert.act(observations, env, weights=weights)


def load_residual_policy(path: str | os.PathLike) -> ResidualPolicy:
    """The ``uavform.policy_loaders`` entry for ``.zip`` files."""
    return ResidualPolicy.load(path)
