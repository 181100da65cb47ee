"""Opening the operator's input device from the command line's choice."""

from __future__ import annotations

from pathlib import Path

from hubo_cli.errors import InputError
from hubo_cli.input.device import HAND_OF_ARM, InputDevice
from hubo_cli.input.operator_stream import StreamSettings


def open_input(replay: str | Path | None = None, port: str | None = None,
               generate_seed: int | None = None, stream: StreamSettings | None = None,
               station_arm: dict[int, str] | None = None, **options) -> InputDevice:
    """Open exactly one input: a FASTRAK recording (``replay``), a live FASTRAK (``port``,
    ``options`` are its reader's) or the generated stream of ``generate_seed``.

    Args:
        station_arm: FASTRAK station -> arm (None: 1 -> right-arm, 2 -> left-arm); for a
            generated stream, the arms it names are the hands it generates.

    Raises:
        InputError: not exactly one input, a bad recording or stream setting.
        DeviceError: the port is absent or the tracker does not answer.
    """
    if sum(x is not None for x in (replay, port, generate_seed)) != 1:
        raise InputError("give exactly one operator input: a recording, a serial port or a "
                         "generated stream", hint="use --replay FILE, --port DEV or "
                                                  "--generate SEED")
    if generate_seed is not None:
        from hubo_cli.input.generated import generated_input

        arms = (station_arm or {1: "right-arm", 2: "left-arm"}).values()
        return generated_input(generate_seed, stream,
                               hands=tuple(HAND_OF_ARM[arm] for arm in arms))
    from hubo_cli.input.fastrak import open_fastrak

    return open_fastrak(replay=replay, port=port, station_arm=station_arm, **options)
