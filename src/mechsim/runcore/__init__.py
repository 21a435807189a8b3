"""The run core: one system instance run sample by sample, without ROS.

Between the API (``mechsim.simulate``: integrators and the one output evaluation) and the
outputs (wire encoding, bag, Rerun): what every node process, the in-process scene runner and
the benchmarks drive. Its rooms:

- ``run``: :class:`~mechsim.runcore.run.SystemRun`, the model, its stepper and the samples it
  releases to an observer, in blocks;
- ``guards``: what stops a system cleanly (non-finite state, constraint hard limit);
- ``effort``: the zero-order hold of a controller's generalized forces;
- ``change``: parameter changes as transactions (validate completely, then commit), and the
  run settings;
- ``equations``: new equations of motion built in a child process with a time limit;
- ``pacing``: how simulated time follows the wall clock, and samples computed ahead;
- ``stops``: Ctrl-C and SIGTERM, one clean path that never splits a sample.

Importing this package imports none of them (a command's start stays quick).
"""
