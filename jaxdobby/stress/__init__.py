"""Stress and fatigue of the bending arm (DESIGN.md §7, "Stress in the arm").

* :mod:`~jaxdobby.stress.recovery` — edge stresses of a beam as a linear map of its nodal
  displacements (the element's own strain–displacement relations, the actual depth d(s));
* :mod:`~jaxdobby.stress.correction` — the arm's stress over a cycle with static correction of
  the truncated modes (mode acceleration);
* :mod:`~jaxdobby.stress.truncation` — mode displacement vs mode acceleration vs the unreduced
  arm as the modes kept go 1…8;
* :mod:`~jaxdobby.stress.fatigue` — Goodman safety factor and smooth surrogates;
* :mod:`~jaxdobby.stress.cycle` — a run's stresses and metrics; :mod:`~jaxdobby.stress.summary`
  — its summary keys and warnings; :mod:`~jaxdobby.stress.plots` — the envelope figure.
"""

from .correction import arm_stress as arm_stress
from .correction import cycle_stress as cycle_stress
from .cycle import CycleStress as CycleStress
from .cycle import run_stress as run_stress
from .fatigue import goodman_factor as goodman_factor
from .recovery import EDGES as EDGES
from .recovery import StressOperator as StressOperator
from .recovery import edge_points as edge_points
from .recovery import stress_operator as stress_operator
