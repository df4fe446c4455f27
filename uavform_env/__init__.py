"""uavform_env: a PettingZoo ParallelEnv of N UAVs flying in formation through 3D obstacle fields.

    from uavform_env import parallel_env
    penv = parallel_env(scenario="forest", n_uavs=5, formation="wedge")
"""

from . import formation_v0
from .config import EnvConfig
from .env import FormationEnv
from .formation_v0 import env, parallel_env, raw_env

__version__ = "0.1.0"
__all__ = ["EnvConfig", "FormationEnv", "env", "formation_v0", "parallel_env", "raw_env"]


def _register() -> None:
    """Register ``uavform/formation-v0`` where PettingZoo has a registry (1.27+); 1.24.3 has none."""
    import pettingzoo

    register = getattr(pettingzoo, "register", None)
    if register is None:
        return
    for kind, entry in (("parallel", "parallel_env"), ("aec", "env")):
        registry = getattr(pettingzoo, f"{kind}_registry", {})
        if "uavform/formation-v0" not in registry:
            register(kind, id="uavform/formation-v0", entry_point=f"uavform_env.formation_v0:{entry}")


_register()
