"""``dopri5``: Dormand and Prince's explicit Runge–Kutta 5(4) pair (FSAL, 6 evaluations a
step) with its 4th-order dense output, in DOP853's loop; works for every model. For loose
tolerances (about 1e-4), where DOP853's 8th order over-delivers; ``auto`` never takes it."""

from __future__ import annotations

from typing import ClassVar

from mechsim.integrators.dop853 import DOP853
from mechsim.integrators.state import Pair


class DOPRI5(DOP853):
    """Dormand and Prince's 5(4) pair (``dopri5_tableau``) with its 4th-order dense output, in
    DOP853's loop: same events, projection, compensated summation, stiffness test, counters,
    error estimate and options. Its steps cost half of DOP853's, and it needs two to three
    times as many. Its local tolerance is ``LOCAL_FACTOR`` × the tolerance like DOP853's; on
    non-chaotic systems the end error over ten time scales stays within the tolerance, or
    close to it (``tests/test_dopri5.py``)."""

    method = "dopri5"
    PAIR: ClassVar[Pair] = Pair.DOPRI5
    N_STAGES: ClassVar[int] = 7  # 6 of the step and f at the new point; no more for its dense
    STIFF_EDGE: ClassVar[float] = 3.25
    LOCAL_FACTOR: ClassVar[float] = 1e-3
