"""``python -m mechsim.cli``: the same as the ``mechsim`` command."""

import sys

from mechsim.cli import main

sys.exit(main())
