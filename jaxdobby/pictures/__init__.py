"""Pictures of the mechanism: a drawing to scale, an animation of the flexible arm, and the
resonance map (Campbell diagram).

* :mod:`.pose` — joint positions of the rigid and the deformed mechanism (the geometry drawn);
* :mod:`.mechanism` — the labelled drawing (``jaxdobby simulate --out`` writes ``mechanism.png``);
* :mod:`.animation` — one steady cycle as a GIF/MP4 (``jaxdobby simulate --animate``);
* :mod:`.campbell` — coupled frequency bands, pick-rate harmonics, deviation against speed
  (``jaxdobby campbell``);
* :mod:`.command` — their command-line flags.

Nothing is imported here, so that the command line starts without matplotlib.
"""
