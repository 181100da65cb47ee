"""The store keys pipeline modules write for later modules: one home for each (the estimate's
own keys live in :mod:`hubo_cli.estimation.keys`)."""

from __future__ import annotations

import numpy as np

from hubo_cli.dataflow import Key

SUPPORT_BOX_WORLD = Key(
    "support_box_world_m", np.ndarray,
    "(min x, max x, min y, max y) of the soles in contact laid flat on the floor, shrunk by "
    "the capture-point monitor's margin (world, m); written by the capture-point monitor")

STOP_MODE = Key(
    "stop_mode", str,
    "the soft emergency stopper's mode after its update (one of control.estop.MODES); "
    "written by the stopper named estop, read by targets as the previous period's (previous)")
WRIST_RELIEF = Key(
    "wrist_relief", object,
    "function: the braked joint command (rad) -> the postures (m x joints, rad) that relieve "
    "the tool after a wrist-torque stop, or None to hold where braked; written by the task "
    "target, followed by the soft stopper")
IMPEDANCE_ON = Key(
    "impedance_on", bool,
    "True: the ImpedanceController runs eq. 3; False: it blends its offset back to zero and "
    "passes through; written by a target whose phase presses with a force, followed by the "
    "controller (not written: as it was built)")
ARM_SYNC = Key(
    "arm_synchronization", dict,
    "arm -> 'phase' or 'none': how the trajectory generator's tracker of that arm times its "
    "joints from this period on; written by the teleoperation target, followed by otg "
    "(groups limbs)")
TRACKER_STATES = Key(
    "tracker_states", dict,
    "group -> TrackerState (limits, q_rad, v_rad_s, a_rad_s2) of the trajectory generator's "
    "trackers after its update (groups limbs); read by the teleoperation target as the "
    "previous period's (previous)")
ARM_TARGET_VELOCITY = Key(
    "arm_target_velocity", dict,
    "arm -> the velocity (rad/s, its joints) the trajectory generator's tracker of that arm "
    "arrives at its target with this period (the goal's own or its prediction's, feed-forward; "
    "absent: zero); "
    "written by the teleoperation target, followed by otg (groups limbs)")
