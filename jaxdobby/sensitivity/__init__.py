"""Global sensitivity analysis (Sobol indices) of any model, batched over devices and processes.

The pipeline, each stage in its own module:

* ``space``: :class:`ParameterSpace` (names, bounds and units of the varied parameters, SALib's
  problem dict, the Saltelli/Sobol' design, the row → SI mapping);
* ``models``: :class:`ModelSpec`, how a model plugs in (a registry of its parameters and a
  ``build(space) -> model`` factory), with the Ishigami test model;
* ``dobby``: :data:`DOBBY`, the dobby's steady-state metrics as a Sobol model;
* ``batch``: :func:`evaluate`, fixed-size chunks sharded over the local devices
  (``jax.shard_map``) and over processes (``jax.distributed``);
* ``store``: the output directory, atomic chunk files and resume;
* ``failures``: failed samples and the policy for them;
* ``analysis``: :func:`analyze`, SALib's Sobol indices with intervals, per metric;
* ``plots``: bar and pie charts;
* ``command``: the ``jaxdobby sobol`` command (:func:`run_sobol`, :class:`ProgressBar`).

Example::

    import jax; jax.config.update("jax_enable_x64", True)
    from jaxdobby import sensitivity as sa
    space = sa.ParameterSpace.from_names(["x1", "x2", "x3"], sa.ISHIGAMI.parameters)
    x = space.sample(1024, second_order=False, seed=1)
    ev = sa.evaluate(sa.ISHIGAMI.build(space), x, chunk_size=1000)
    print(sa.analyze(space, ev.outputs, n=1024, second_order=False, seed=1).table())
"""

from .analysis import MetricIndices as MetricIndices
from .analysis import SobolResult as SobolResult
from .analysis import analyze as analyze
from .batch import Evaluation as Evaluation
from .batch import evaluate as evaluate
from .command import MODELS as MODELS
from .command import ProgressBar as ProgressBar
from .command import SobolConfig as SobolConfig
from .command import SobolRun as SobolRun
from .command import add_arguments as add_arguments
from .command import main as main
from .command import run_sobol as run_sobol
from .dobby import DOBBY as DOBBY
from .dobby import DOBBY_PARAMETERS as DOBBY_PARAMETERS
from .dobby import dobby_model as dobby_model
from .failures import FailedSamplesError as FailedSamplesError
from .failures import FailureReport as FailureReport
from .failures import SampleFailure as SampleFailure
from .models import ISHIGAMI as ISHIGAMI
from .models import ModelSpec as ModelSpec
from .models import ishigami as ishigami
from .plots import save_figures as save_figures
from .space import ParameterSpace as ParameterSpace
from .space import ParameterSpec as ParameterSpec
from .space import check_base_samples as check_base_samples
from .store import ChunkStore as ChunkStore
