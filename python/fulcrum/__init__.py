"""fulcrum from Python: tool worlds, exact object empowerment, gymnasium environments.

The Rust core (the same crates as the ``fulcrum`` command line) does the work; this
package gives it the shapes Python researchers use:

- :class:`World`: a tool world from a built-in name or a file, or a layout of a world
  family (``World.layout("toolbox", seed)``; :func:`builtin_families`) (map, tools, objects,
  actions, states as text or as 38 packed bytes);
- :func:`make_vec` / :class:`FulcrumVectorEnv`: a ``gymnasium.vector.VectorEnv`` whose
  steps run in Rust with the GIL released, writing numpy arrays in place;
  :class:`FulcrumEnv` and the registered ids ``fulcrum/<world>-v0`` for single envs; on
  a world family a layout per episode (``make_vec("toolbox", 8, layouts=16)``: the
  layouts 0..15; ``"all"``; held-out ``"test:K"``);
- :mod:`fulcrum.empowerment`: the matrix, landscapes, traces and values, datasets of exact E
  for learned estimators and their scoring, as the CLI's
  ``fulcrum empowerment`` computes them;
- :class:`fulcrum.wrappers.EmpowermentReward`: R + beta * E (the paper's equation (1))
  and the project's other intrinsic forms, from the exact table;
- :class:`ServiceClient`: lookups from a running ``fulcrum serve`` over shared memory.

Bad input raises ``ValueError`` with the command line's sentence.
"""

from fulcrum._native import (
    STATE_BYTES,
    NoService,
    Refused,
    ServiceClient,
    ServiceError,
    ServiceFull,
    ServiceGone,
    ServiceTimeout,
    TransportError,
    World,
    WrongWorld,
    __version__,
    builtin_families,
    builtin_worlds,
)
from fulcrum import empowerment, wrappers
from fulcrum.envs import FulcrumEnv, FulcrumVectorEnv, make_vec, register_envs

register_envs()

__all__ = [
    "STATE_BYTES",
    "FulcrumEnv",
    "FulcrumVectorEnv",
    "NoService",
    "Refused",
    "ServiceClient",
    "ServiceError",
    "ServiceFull",
    "ServiceGone",
    "ServiceTimeout",
    "TransportError",
    "World",
    "WrongWorld",
    "__version__",
    "builtin_families",
    "builtin_worlds",
    "empowerment",
    "make_vec",
    "wrappers",
]
