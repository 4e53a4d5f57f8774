"""jaxdobby: a differentiable JAX simulator of the rigid-flexible lifting mechanism of a rotary dobby.

float64 is required: switch it on with ``jax.config.update("jax_enable_x64", True)`` before use
(the ``jaxdobby`` command does it for you).

The main entry points::

    from jaxdobby import Machine, OperatingPoint, simulate
    run = simulate(Machine.default(), OperatingPoint.from_users_units(speed_rpm=800.0))

The layers, each usable on its own: :mod:`~jaxdobby.centreline`, :mod:`~jaxdobby.beam`,
:mod:`~jaxdobby.supports`, :mod:`~jaxdobby.loads`, :mod:`~jaxdobby.modal`,
:mod:`~jaxdobby.flexible_body`, :mod:`~jaxdobby.floating_frame`, :mod:`~jaxdobby.response`
(any planar curved beam in a moving frame); :mod:`~jaxdobby.kinematics`,
:mod:`~jaxdobby.rigid_motion`, :mod:`~jaxdobby.stroke` (the rigid mechanism);
:mod:`~jaxdobby.dobby`, :mod:`~jaxdobby.simulate` (the coupled model).
"""

from .machine import Machine as Machine
from .machine import OperatingPoint as OperatingPoint
from .parameters import Setup as Setup
from .simulate import Simulation as Simulation
from .simulate import simulate as simulate

__version__ = "0.1.0"
