"""sympy, imported on its first use: what the system modules write equations with.

A Lagrangian model whose kernels are already in the cache is set up from its recalled summary
(``LagrangianModel``), without its declaration: a process running it never needs sympy,
whose import costs 0.3–0.5 s of CPU (a third of a warm ``mechsim run``). The modules therefore
bind ``sp`` to this stand-in, which imports sympy when an attribute is first read (deriving a
model, parsing a curve), then holds sympy's namespace itself. Nothing may read an attribute of
``sp`` when a module is imported (``tests/test_recall.py`` checks that none does).
"""

from __future__ import annotations

import importlib
import threading
import types
from typing import Any

__all__ = ["sympy"]


class _Deferred(types.ModuleType):
    """A module imported when one of its attributes is first read (thread-safe)."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        object.__setattr__(self, "_deferred_lock", threading.Lock())

    def __getattr__(self, attr: str) -> Any:  # only for names not (yet) in this namespace
        with object.__getattribute__(self, "_deferred_lock"):
            module = importlib.import_module(self.__name__)
            for key, value in vars(module).items():
                self.__dict__.setdefault(key, value)
        return getattr(module, attr)


sympy: Any = _Deferred("sympy")
