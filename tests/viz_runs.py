"""A short recorded simulation run for the viewer tests: the drill arm sways in front of a wall."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hubo_cli.control.log import set_log_metadata
from hubo_cli.control.loop import ControlLoop
from hubo_cli.control.pipeline import DEFAULT_ORDER, build_pipeline
from hubo_cli.drivers.base import make_driver
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture


def record_sway_run(run_dir: Path, duration_s: float = 2.0) -> Path:
    """Run the sim for ``duration_s``: the right (drill) arm raised and swaying sideways with
    the bit through a wall; write the log with its scene metadata into ``run_dir``."""
    model = load_model()
    run_dir.mkdir(parents=True, exist_ok=True)
    q0 = home_posture(model)
    arm = model.limb_slice("right-arm")
    with make_driver("sim", model, drill=True) as robot:
        robot.start(q0)
        raised = q0.copy()
        raised[arm] = [-0.9, 0.0, 0.0, -0.9, 0.0, -0.3]  # bit forward at chest height
        bit_x = None

        def target(t_s: float, state):
            nonlocal bit_x
            ramp = min(t_s / 0.8, 1.0)
            q = q0 + (raised - q0) * (0.5 - 0.5 * np.cos(np.pi * ramp))
            if t_s >= 0.8:
                if bit_x is None:  # the wall through the bit, once the arm is up
                    bit_x = robot.frame_pose("right_drill_bit")[0, 3]
                    robot.add_wall(bit_x - 0.005, 1.4, 1.2, 0.01)
                q[arm.start + 2] = 0.25 * np.sin(2 * np.pi * 0.8 * (t_s - 0.8))
            return q, {}

        loop = ControlLoop(robot, build_pipeline(model, DEFAULT_ORDER), target,
                           log_path=run_dir)
        loop.run(duration_s)
        set_log_metadata(run_dir, "scene", robot.scene())
    return run_dir
