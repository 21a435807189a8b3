"""``mechsim bench``: work-precision benchmark against peers, and the cost of a scene's outputs.

- ``mechsim bench [SYSTEM ...] [--quick] --out DIR``: see :mod:`mechsim.bench.run` (JSON schema
  in its docstring), problems in :mod:`mechsim.bench.problems`, peers in
  :mod:`mechsim.bench.peers`.
- ``mechsim bench --scene SCENE --out DIR``: see :mod:`mechsim.bench.scene_cost`.
- ``mechsim bench --streaming [SYSTEM ...] --out DIR``: see :mod:`mechsim.bench.streaming`.

This module only registers the subcommand; everything heavy is imported when it runs.
"""

from __future__ import annotations

