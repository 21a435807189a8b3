"""New equations of motion, derived and compiled in a child process with a time limit.

A runtime change of a structural parameter (a formulation, the bead's ``shape`` or ``curve``, a
number of masses) needs new equations of motion: sympy derivation and numba compilation, seconds
of work that would otherwise run inside the node's executor with no bound. A parameter change
(``mechsim.runcore.change``) hands the candidate to :func:`prepare_model`, which builds it in
``python -m mechsim.runcore.equations``: the model is constructed (every check), its kernels
generated and compiled (numba's disk cache keeps them for the run, which then loads them in
milliseconds), and one tiny step taken with the requested method. A child that fails or
outlives ``timeout`` (then killed) turns into a MechsimError with one line, and the change is
rejected with that reason.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from typing import Any

from mechsim.errors import MechsimError

#: Seconds a structural change may take to derive and compile (a few on an idle machine).
PREPARE_TIMEOUT = 120.0


def prepare_model(system: str, values: dict[str, Any], method: str, tolerance: float,
                  timeout: float = PREPARE_TIMEOUT) -> None:
    """Build ``system`` with ``values`` and compile its kernels in a child process; return when
    done, or raise MechsimError with the reason (one line) on failure or after ``timeout``."""
    payload = json.dumps({"system": system, "values": values, "method": method,
                          "tolerance": tolerance, "parent": os.getpid()})
    try:
        r = subprocess.run([sys.executable, "-m", "mechsim.runcore.equations"], input=payload,
                           capture_output=True, text=True, timeout=timeout,
                           env=dict(os.environ))
    except subprocess.TimeoutExpired:
        raise MechsimError(f"building the equations of motion took longer than {timeout:g} s "
                           "(stopped; nothing changed)") from None
    except OSError as e:
        raise MechsimError(f"cannot start the build process ({e.strerror or e})") from None
    if r.returncode != 0:
        lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
        last = lines[-1] if lines else f"exit status {r.returncode}"
        raise MechsimError(last.removeprefix("mechsim: error: ")[:300])


def _build(request: dict[str, Any]) -> None:
    import numpy as np

    from mechsim.integrators import make_stepper
    from mechsim.simulate import OUTPUTS, evaluate
    from mechsim.systems import system_class

    model = system_class(request["system"])(**request["values"])
    stepper = make_stepper(model, request["method"], float(request["tolerance"]))
    y0 = stepper.y.copy()
    evaluate(model, np.zeros(1), y0[None, :], stepper.p, OUTPUTS)
    scale = model.time_scale()
    h = 1e-9 * scale if math.isfinite(scale) and scale > 0 else 1e-9
    stepper.advance(np.array([h]))  # compiles the stepping loop


def _main() -> int:
    """A child's whole life: a request on stdin, exit status 0 (built), 2 (refused with a
    one-line reason) or 3 (failed: the reason the change is rejected, never a traceback:
    the values come from a peer, so no traceback file is written either)."""
    from mechsim.runcore.stops import die_with_parent

    try:
        request = json.loads(sys.stdin.read())
        die_with_parent(int(request["parent"]))
        _build(request)
    except MechsimError as e:
        print(f"mechsim: error: {e}", file=sys.stderr)
        return 2
    except Exception as e:  # noqa: BLE001 - any failure is the reason the change is rejected
        first = (str(e).splitlines() or [""])[0][:200]
        print(f"mechsim: error: {type(e).__name__}: {first}", file=sys.stderr)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(_main())
