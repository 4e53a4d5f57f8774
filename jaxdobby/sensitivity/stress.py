"""The dobby with the arm's stress as a Sobol model (``jaxdobby sobol --model dobby-stress``).

Like :data:`jaxdobby.sensitivity.dobby.DOBBY` (same parameters, problems and base machine), but
each sample row runs the full steady-state cycle of :func:`jaxdobby.simulate.simulate`
(collocation, dense output) and recovers the arm's stress over it
(:func:`jaxdobby.stress.cycle.run_stress`, mode acceleration), so its outputs add

``stress_max_mpa`` (largest |σ| over the arm and the cycle) and ``fatigue_safety_factor``
(Goodman, smallest over the arm)

to ``deviation_pp_mm`` and ``acceleration_amp_m_s2``. It is slower than the reduced-in-solve
batch evaluator of the default model (a dense cycle and 1729 × 100 stresses per sample, ~1.5 MB
of intermediate arrays per row: ``--chunk-size 128`` keeps a chunk under 0.2 GB).

The samples of a chunk run one after another (``jax.custom_batching.sequential_vmap``), not
vectorised: a sample's whole computation (assembly, ``eigh``, the collocation cycle, the dense
output) holds LAPACK calls, and jaxlib splits a batched LAPACK call over the CPU's intra-op
threads and blocks one of them, so two of them side by side can wait on each other for ever on
2 cores (see :func:`jaxdobby.periodic.steady.model_terms`), and ``jaxdobby sobol`` runs one device
per core side by side. (Measured on the slow test's 48 samples, 1 device: 19 s cold either way.)
"""

from __future__ import annotations

import jax

from ..periodic import DEFAULT_STEPS
from ..parameters import Setup
from .dobby import DEFAULT_PROBLEM, DOBBY_PARAMETERS, check_strokes, setup_of_row
from .models import ModelSpec


def dobby_stress_model(base: Setup | None = None, *, steps: int = DEFAULT_STEPS,
                       tolerance: float = 1e-6):
    """``build(space)`` of the stress model (arguments as :func:`~.dobby.dobby_model`)."""
    def build(space):
        from ..simulate import _simulate
        from ..stress.cycle import run_stress

        names, scales = space.names, space.si_scales
        start = Setup() if base is None else base
        check_strokes(space, start)

        @jax.custom_batching.sequential_vmap
        def model(x):
            setup, ok = setup_of_row(start, names, scales, x)
            run = _simulate(setup.machine, setup.operating, None, method="collocation",
                            steps=steps, n_out=3001, rtol=1e-8, atol=1e-12,
                            tolerance=tolerance, forward_mode=False)
            m = run_stress(run).metrics
            return {"deviation_pp_mm": run.metrics["deviation_pp"] * 1e3,
                    "acceleration_amp_m_s2": run.metrics["acceleration_amp"],
                    "stress_max_mpa": m["stress_max"] * 1e-6,
                    "fatigue_safety_factor": m["fatigue_safety_factor"],
                    "ok": run.converged & ok}

        return model

    return build


DOBBY_STRESS = ModelSpec("dobby-stress", DOBBY_PARAMETERS, DEFAULT_PROBLEM, dobby_stress_model(),
                         lambda steps: dobby_stress_model(steps=steps), DEFAULT_STEPS)
"""The dobby with the arm's stress metrics as a Sobol model."""
