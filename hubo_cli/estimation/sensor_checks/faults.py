"""What a sensor check raises: a device fault (exit 3: the loop stops as after Ctrl-C), or a
refusal when nothing moved yet (exit 4)."""

from __future__ import annotations

from hubo_cli.errors import DeviceError


class SensorFault(DeviceError):
    """A sensor reads values no working sensor reads (see
    :mod:`hubo_cli.estimation.plausibility`)."""

    def __init__(self, message: str, hint: str = "") -> None:
        super().__init__(message, hint=hint or "check the sensor (cable, power, hubo-daemon's "
                                                "reading of it), then start the run again")


class SensorRefusal(SensorFault):
    """A sensor reads what no working one does before anything moved: the run is refused
    (exit 4, as every refusal with nothing moved), not stopped."""

    exit_code = 4


def sensor_fault(message: str, hint: str = "", refuse: bool = False) -> SensorFault:
    """The fault (``refuse``: the refusal) a check raises."""
    return (SensorRefusal if refuse else SensorFault)(message, hint)
