"""Fast batched steady-state evaluation of the dobby for parameter studies (Sobol, sweeps).

:func:`steady_state_metrics` maps one :class:`~jaxdobby.parameters.Setup` to the heald frame's
steady-state metrics with static sizes, so it jits once and vmaps over thousands of samples; the
same equations as :func:`jaxdobby.simulate.simulate`, solved by Gauss collocation on a
phase-normalised grid with the chain in closed form (modules ``chain``, ``collocation``,
``cycle``, ``stepper``, ``steady``; ``rows`` for rows of users'-unit parameters).
"""

from .steady import DEFAULT_STEPS as DEFAULT_STEPS
from .steady import METRICS as METRICS
from .steady import steady_state_metrics as steady_state_metrics
