"""The frame set's defaults of ``jaxdobby loom`` (a light module: the command line's parser reads
them without importing the solver)."""

DEFAULTS = dict(front_stroke=80.0, frame_pitch=12.0, fell_distance=250.0, frames=8)
"""Frame 1's stroke [mm], the frames' pitch [mm] and frame 1's distance from the cloth fell [mm]
(the clean-shed rule of :func:`jaxdobby.weave.loom.clean_shed_strokes`), and the frames of a
named weave."""
