"""Stress and fatigue of the bending arm (DESIGN.md §7, "Stress in the arm").

* :mod:`~jaxdobby.stress.recovery` — edge stresses of a beam as a linear map of its nodal
  displacements (the element's own strain–displacement relations, the actual depth d(s)).
"""

from .recovery import EDGES as EDGES
from .recovery import StressOperator as StressOperator
from .recovery import edge_points as edge_points
from .recovery import stress_operator as stress_operator
