"""Gradient-based design of the bending arm: ``jaxdobby optimize``.

* :mod:`~jaxdobby.optimize.design` — design variables ↔ Setup, bounds, constraints;
* :mod:`~jaxdobby.optimize.objective` — the steady-state objective over a batch of speeds and
  its exact gradient (forward or reverse mode), each design on its own modes (differentiated
  as the subspace they span) or on a fixed reduction basis;
* :mod:`~jaxdobby.optimize.feasible` — the box of the bounds cut by the mass budget, held
  exactly by projection;
* :mod:`~jaxdobby.optimize.loop` — projected Adam / L-BFGS (optax), with an augmented
  Lagrangian for the nonlinear constraint (the first coupled frequency);
* :mod:`~jaxdobby.optimize.output` — history, optimised design (TOML), figures;
* :mod:`~jaxdobby.optimize.command` — the command line.

Example::

    import jax; jax.config.update("jax_enable_x64", True)
    from jaxdobby import Setup
    from jaxdobby.optimize import Constraints, DesignSpace, Evaluator, Objective, Settings, optimize
    space = DesignSpace.create(Setup(), ["thickness"])
    evaluator = Evaluator(space, Objective())
    limits = Constraints(mass_budget=0.5)
    result = optimize(evaluator.value_and_grad, lambda u: constraint_jacobian(space, limits, u),
                      space.initial, Settings(optimizer="lbfgs", steps=10))
"""

from .design import Constraints as Constraints
from .design import DesignSpace as DesignSpace
from .design import constraint_jacobian as constraint_jacobian
from .design import constraints as constraints
from .loop import Settings as Settings
from .loop import optimize as optimize
from .objective import Evaluator as Evaluator
from .objective import Objective as Objective
