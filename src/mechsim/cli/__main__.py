"""``python -m mechsim.cli``: the same as the ``mechsim`` command."""

from mechsim.cli import entry

entry()
