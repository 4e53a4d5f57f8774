"""Identification of a machine's parameters from its measured heald-frame motion
(``jaxdobby identify``): least squares through the periodic steady state.

* :mod:`~jaxdobby.identify.measurement` — the measured trace (CSV) and its checks;
* :mod:`~jaxdobby.identify.model` — fitted parameters → the model at the measured times;
* :mod:`~jaxdobby.identify.fit` — Levenberg–Marquardt from several starts (:func:`identify`);
* :mod:`~jaxdobby.identify.inner` — each outer step's linearised problem (compressed residuals,
  Gauss–Newton);
* :mod:`~jaxdobby.identify.uncertainty` — standard errors, correlations, identifiability;
* :mod:`~jaxdobby.identify.twin` — synthetic traces for twin experiments;
* :mod:`~jaxdobby.identify.report` and :mod:`~jaxdobby.identify.command` — output and CLI.
"""

from .fit import Identified as Identified
from .fit import identify as identify
from .measurement import Measurement as Measurement
from .measurement import read_csv as read_csv
from .twin import synthetic as synthetic
