"""``mechsim stress``: numerical stress tests, each with a pass criterion, run against every
system it applies to, reported as JSON + Markdown + PNG plots (drift against time, ...).

The catalogue (``mechsim.stress.cases``):

- ``long_horizon``: 10⁶ steps and more with ``auto``; symplectic compositions must keep the
  energy error bounded (no secular growth), DOP853 may let it grow at most ~linearly in t;
- ``chaos``: double pendulum, CR3BP: finite-time Lyapunov exponent from two nearby initial
  conditions, the time at which two tolerances part ways, a conservation law holding while
  the trajectories diverge;
- ``stiffness``: huge damping / spring constants: ``auto`` must stop with a clear
  StiffnessError, or finish with its laws kept, instead of crawling or blowing up;
- ``singular``: inverted pendulum, Kepler e = 0.99/0.999 pericentre passages and the radial
  fall to the centre, the heavy top near θ = 0, the twisted cubic's RIC frame at the origin,
  a bead on a steep wire: graceful, explained outcomes;
- ``sweeps``: tolerance and step-size sweeps against a reference, with the diagnostics node's
  own logic: WARN/ERROR must come before the numbers become garbage;
- ``hamilton``: Hamilton's principle for every Lagrangian system: fixed-endpoint variations
  of a computed trajectory change the action by O(ε²), not O(ε) (and a non-solution by O(ε)).

``--quick`` runs a reduced catalogue in about a minute (what ``tests/test_stress.py`` runs).
"""

from __future__ import annotations

