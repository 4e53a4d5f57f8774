"""The periodic steady-state solver: Gauss collocation on a phase-normalised grid.

The default integrator of :func:`jaxdobby.simulate.simulate` (``dense.steady_cycle``: the
steady cycle with its time series) and of every batched study (sweep, sobol, optimize).
:func:`steady_state_metrics` maps one :class:`~jaxdobby.parameters.Setup` to the heald frame's
steady-state metrics with static sizes, so it jits once and vmaps over thousands of samples; the
same equations as :func:`jaxdobby.simulate.simulate`, solved by Gauss collocation on a
phase-normalised grid with the chain in closed form (modules ``chain``, ``collocation``,
``cycle``, ``stepper``, ``linear``, ``steady``, ``dense``).
"""

from .steady import DEFAULT_STEPS as DEFAULT_STEPS
from .steady import METRICS as METRICS
from .steady import steady_state_metrics as steady_state_metrics
