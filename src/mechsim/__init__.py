"""mechsim: simulated classical mechanics streamed as ROS 2 topics.

Pure-Python API (no ROS needed)::

    import mechsim
    model = mechsim.load_system("pendulum", **{"initial.angle": 1.0})
    run = mechsim.simulate(model, t_end=10.0, output_dt=0.01)
    run.total, run.invariants, run.observables["tension"]
"""

from mechsim.ensemble import EnsembleResult, simulate_many
from mechsim.errors import IntegrationError, MechsimError, ParameterError, UnknownSystemError
from mechsim.simulate import SimulationResult, load_system, simulate
from mechsim.systems import system_ids

__version__ = "0.1.0"
__all__ = ["EnsembleResult", "IntegrationError", "MechsimError", "ParameterError",
           "SimulationResult", "UnknownSystemError", "load_system", "simulate",
           "simulate_many", "system_ids", "__version__"]
