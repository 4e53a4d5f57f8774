"""A weave's lift plan from a WIF file (the weavers' interchange format, WIF 1.1).

Read with the maintained ``dtx-to-wif`` package (PyPI; Russell Owen's reader/writer of WIF,
FiberWorks .dtx and WeavePoint files): its ``read_wif`` parses the file into a
``PatternData`` and its ``make_liftplan`` gives each pick's raised shafts from ``[LIFTPLAN]``
or, without one, from ``[TIEUP]`` + ``[TREADLING]``. Here, on top of it:

* ``Rising Shed = no`` in ``[WEAVING]`` (a sinking/counter-marched shed): the listed shafts
  go down, so a frame is up where it is *not* listed;
* the number of frames is the highest shaft the plan uses (the header's ``Shafts`` can
  disagree with the data: the data win), the picks the highest pick listed (or ``[WEFT]
  Threads`` if larger: picks with no shaft raised);
* a file without ``[COLOR PALETTE]`` or ``[COLOR TABLE]`` gets WIF's default range and a
  one-colour table before parsing (dtx-to-wif 4.7.1 fails on such a file, though both
  sections are optional and colours do not matter to a lift plan); the reader needs a
  ``[THREADING]``, as every weaving program writes;
* a file with neither a lift plan nor a tie-up with a treadling, or that the reader cannot
  parse, is an :class:`~jaxdobby.errors.InputError` of one line.
"""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import numpy as np

from ..errors import InputError


def read_wif(path: str | Path) -> np.ndarray:
    """The lift plan (picks, frames) of the WIF file at ``path``, 1 = the frame is up."""
    from dtx_to_wif import make_liftplan
    from dtx_to_wif.wif_reader import read_wif as parse

    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except FileNotFoundError:
        raise InputError(f"WIF file {path} does not exist") from None
    except OSError as err:
        raise InputError(f"cannot read WIF file {path}: {err}") from None
    # dtx-to-wif 4.7 fails on a file without a colour palette and table (optional sections,
    # irrelevant to a lift plan): give it WIF's default range and one colour
    if "[color palette]" not in text.lower():
        text += "\n[COLOR PALETTE]\nRange=0,255\nEntries=1\n"
    if "[color table]" not in text.lower():
        text += "\n[COLOR TABLE]\n1=0,0,0\n"
    try:
        with warnings.catch_warnings():  # the reader's notes on colours and spacing
            warnings.simplefilter("ignore")
            pattern = parse(io.StringIO(text), filename=path.name)
    except Exception as err:  # the reader raises RuntimeError, ValueError, configparser errors
        text = str(err).splitlines()[0] if str(err) else ""
        if "liftplan" in text.lower():
            raise InputError(f"{path.name} has no [LIFTPLAN] and no [TIEUP] with a "
                             "[TREADLING]: no lift plan to weave") from None
        raise InputError(f"{path.name} is not a WIF file dtx-to-wif can read "
                         f"({type(err).__name__}: {text})") from None
    if not pattern.liftplan and not (pattern.tieup and pattern.treadling):
        raise InputError(f"{path.name} has no [LIFTPLAN] and no [TIEUP] with a [TREADLING]: "
                         "no lift plan to weave")
    lifts = make_liftplan(pattern)
    if not lifts:
        raise InputError(f"{path.name}: its lift plan raises no shaft in any pick")
    picks = max(max(lifts), pattern.weft.threads or 0)
    frames = max(max(s) for s in lifts.values())
    plan = np.zeros((picks, frames))
    for pick, shafts in lifts.items():
        plan[pick - 1, [s - 1 for s in shafts]] = 1.0
    if not pattern.is_rising_shed:
        plan = 1.0 - plan
    if picks < 2:
        raise InputError(f"{path.name}: its lift plan has {picks} pick: a repeat needs at "
                         "least 2")
    return plan
