"""Operator input devices, peers of the robot's drivers: each one delivers timed hand poses.

- :mod:`.device`: the contract (:class:`InputDevice`, :class:`HandPose`) every device keeps.
- :mod:`.fastrak`: a Polhemus FASTRAK, live on a serial port or replayed from a recording (raw
  capture or pose-log CSV); its stations and status letters stay inside it.
- :mod:`.generated`: seeded operator-like streams (:mod:`.operator_stream`) as a device.
- :mod:`.opener`: :func:`open_input`, which opens one of them from the command line's choice.

A new device (a SpaceMouse, a VR tracker) is one module with one :class:`InputDevice` subclass.
"""

from hubo_cli.input.device import ARM_OF_HAND, HAND_OF_ARM, HANDS, HandPose, InputDevice

__all__ = ["ARM_OF_HAND", "HAND_OF_ARM", "HANDS", "HandPose", "InputDevice"]
