"""How well a run held the body: the balance figures of ``summary.json``, computed from the log.

Every figure comes from the run's per-period log (:class:`~hubo_cli.control.log.LogData`), so a
run folder can be reported again after the fact and the tests can feed synthetic logs:

* ``max_torso_tilt_deg``: the torso's largest tilt from upright (its logged world pose: the
  simulator's ground truth, the IMU on a real robot).
* ``min_support_margin_mm``: the capture point's smallest distance inside the support polygon of
  the soles on the ground (the capture-point monitor's ``cp_outside_m`` is measured against the
  polygon shrunk by ``CP_MARGIN_M``), with when and where (``min_support_margin_at``). Negative:
  the capture point was outside.
* ``contact_losses``: intervals longer than the robot file's ``contact_loss_min_s`` in which a
  foot that should stand on the ground (always while standing; where a walk's plan puts it
  down, its ``planned_{right,left}_foot_contact_flag`` columns) carried no load (its contact
  flag: F_z low-passed and thresholded as the robot file's ``[estimation]`` says, as the
  simulator and hrpsys decide it; recomputed from the logged F_z where a driver gives no
  flag), each with its start, length and foot.
* ``ankle_clamp_fraction``: the share of periods in which the soft error limiter clamped an
  ankle joint (``limiter_ankle_clamped_count``).
* ``cutting_fraction`` (runs with the drill and a wall): the share of the cut's time in which
  the bit's flutes were in the wall, the bit placed by the measured arm joints and the torso's
  world pose. The cut's time is where the task's plan cuts (its ``cutting`` column: the bit
  planned past the wall face), in a teleoperation the operating phase, otherwise from the
  first to the last period with the flutes in the wall.
"""

from __future__ import annotations

import math

import numpy as np

from hubo_cli.control.capture_point import CP_MARGIN_M
from hubo_cli.control.log import LogData
from hubo_cli.geometry import quat_wxyz_to_matrix
from hubo_cli.model import EstimationConfig

ESTIMATION = EstimationConfig()  # the robot file's [estimation] when no model is given
LISTED_LOSSES = 20            # contact losses listed one by one in the summary
FEET = ("right", "left")


def _period_s(log: LogData) -> float:
    t = log["t_s"]
    return float(np.median(np.diff(t))) if len(t) > 1 else 0.0


def tilt_deg_of_roll_pitch(roll_rad, pitch_rad) -> np.ndarray:
    """The tilt from upright (deg) of a frame logged as roll and pitch (the log's torso):
    the cosine of the tilt is the z of the frame's z axis in the world, cos roll cos pitch."""
    cos_tilt = np.cos(roll_rad) * np.cos(pitch_rad)
    return np.degrees(np.arccos(np.clip(cos_tilt, -1.0, 1.0)))


def max_tilt_deg(log: LogData) -> float | None:
    """The torso's largest tilt from upright over the run (deg), None without its pose."""
    if not log.has_pose("torso") or not len(log):
        return None
    tilt = tilt_deg_of_roll_pitch(log["torso_roll_rad"], log["torso_pitch_rad"])
    tilt = tilt[np.isfinite(tilt)]
    return float(tilt.max()) if len(tilt) else None


def support_margin(log: LogData) -> dict | None:
    """The worst period's support margin: ``{"mm", "t_s", "cp_x_mm", "cp_y_mm"}`` (the
    capture point's world x, y then), or None without a capture-point monitor in the run."""
    if "cp_outside_m" not in log.columns:
        return None
    margin = CP_MARGIN_M - log["cp_outside_m"]
    finite = np.flatnonzero(np.isfinite(margin))  # no foot on the ground: no polygon
    if not len(finite):
        return None
    k = int(finite[np.argmin(margin[finite])])
    return {"mm": float(margin[k] * 1000), "t_s": float(log["t_s"][k]),
            "cp_x_mm": float(log["cp_x_m"][k] * 1000), "cp_y_mm": float(log["cp_y_m"][k] * 1000)}


def contact_from_fz(fz_n: np.ndarray, period_s: float,
                    threshold_n: float = ESTIMATION.contact_threshold_n,
                    cutoff_hz: float = ESTIMATION.contact_cutoff_hz) -> np.ndarray:
    """Contact per period from a foot's F_z (N): first-order low-pass at ``cutoff_hz``, started
    at the first finite value, above ``threshold_n``; a period without a reading holds."""
    tau = 1.0 / (2.0 * math.pi * cutoff_hz)
    alpha = period_s / (period_s + tau)
    contact = np.zeros(len(fz_n), dtype=bool)
    filtered = None
    for k, fz in enumerate(fz_n):
        if math.isfinite(fz):
            filtered = fz if filtered is None else filtered + alpha * (fz - filtered)
        contact[k] = filtered is not None and filtered > threshold_n
    return contact


def feet_contact(log: LogData, config: EstimationConfig = ESTIMATION) -> np.ndarray | None:
    """(N, 2) contact of the right and left foot per period, None when the log has neither the
    contact flags nor ankle forces that ever carried the robot (a driver without force
    sensing, e.g. the ideal one, reads 0 N throughout: that says nothing about contact)."""
    columns = []
    period = _period_s(log)
    forces = [log[f"{foot}_foot_fz_n"] for foot in FEET if f"{foot}_foot_fz_n" in log.columns]
    sensed = len(forces) == 2 and max(np.nanmax(f, initial=-np.inf) for f in forces) > (
        config.contact_threshold_n)
    for foot in FEET:
        flag, fz = f"{foot}_foot_contact_flag", f"{foot}_foot_fz_n"
        if flag in log.columns and np.any(np.isfinite(log[flag])):
            columns.append(log[flag] > 0.5)
        elif sensed:
            columns.append(contact_from_fz(log[fz], period, config.contact_threshold_n,
                                          config.contact_cutoff_hz))
        else:
            return None
    return np.column_stack(columns)


def contact_losses(t_s: np.ndarray, contact: np.ndarray, period_s: float,
                   min_s: float = ESTIMATION.contact_loss_min_s) -> list[dict]:
    """The intervals in which a foot was unloaded for longer than ``min_s``.

    Args:
        t_s: period times (s).
        contact: (N, 2) right and left foot in contact.
        period_s: the control period (s); an interval of n periods lasts n * period_s.
        min_s: shorter losses are not counted.

    Returns:
        One ``{"t_s", "duration_s", "feet"}`` per interval, ``feet`` naming the unloaded foot
        (or both).
    """
    unloaded = ~np.asarray(contact, dtype=bool)
    lost = unloaded.any(axis=1)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], lost.astype(np.int8), [0]])))
    losses = []
    for start, end in zip(edges[::2], edges[1::2], strict=True):
        duration = (end - start) * period_s
        if duration > min_s + 1e-9:
            which = unloaded[start:end].any(axis=0)
            feet = [f for f, w in zip(FEET, which, strict=True) if w]
            losses.append({"t_s": float(t_s[start]), "duration_s": float(duration),
                           "feet": "both" if len(feet) == 2 else feet[0]})
    return losses


def ankle_clamp_fraction(log: LogData) -> float | None:
    """The share of periods in which the limiter clamped an ankle joint (0..1), None when the
    log has no such count."""
    column = "limiter_ankle_clamped_count"
    if column not in log.columns:
        return None
    count = log[column]
    count = count[np.isfinite(count)]  # the smooth stop's periods run without the pipeline
    return float(np.mean(count > 0)) if len(count) else None


# ------------------------------------------------------------------------------------ cutting
def bit_poses(log: LogData, model) -> np.ndarray:
    """World poses of the drill bit (N x 4 x 4, m): the measured right arm's forward kinematics
    to the bit through the torso's logged world pose (NaN where that is unknown)."""
    from hubo_cli.kinematics.limb import Limb

    limb = Limb(model, "right-arm", "drill")
    q_arm = np.column_stack([log[f"q_{j}_rad"] for j in model.limb("right-arm").joints])
    return log.poses("torso") @ limb.fk_batch(q_arm)


def flutes_in_wall(T_world_bit: np.ndarray, wall: dict, half_length_m: float) -> np.ndarray:
    """Per pose, whether the bit's flutes (``half_length_m`` either side of its middle, along
    its x axis) cross the wall box (as the simulator's cutting model decides: the bit meets
    the wall's mid-plane within the flutes' reach, inside the wall's face)."""
    R_world_wall = quat_wxyz_to_matrix(np.asarray(wall["quat_wxyz"], dtype=float))
    centre = np.asarray(wall["centre_world_m"], dtype=float)
    thickness, width, height = (float(v) for v in wall["size_m"])
    middle = (T_world_bit[:, :3, 3] - centre) @ R_world_wall  # in the wall's axes
    axis = T_world_bit[:, :3, 0] @ R_world_wall
    with np.errstate(divide="ignore", invalid="ignore"):
        s = -middle[:, 0] / axis[:, 0]
        reach = half_length_m + thickness / 2 / np.abs(axis[:, 0])
        point = middle + s[:, None] * axis
        inside = ((np.abs(axis[:, 0]) > 1e-6) & (np.abs(s) <= reach)
                  & (np.abs(point[:, 1]) <= width / 2) & (np.abs(point[:, 2]) <= height / 2))
    return inside & np.all(np.isfinite(middle), axis=1)


def cut_periods(log: LogData, inside: np.ndarray) -> tuple[np.ndarray, str]:
    """The cut's periods and how they were chosen: where the task's plan cuts (its ``cutting``
    column, ``plan``); in a teleoperation, while the operator drives the tool (its
    ``phase_code`` is ``operate``); otherwise from the first to the last period with the
    flutes in the wall (``inside``)."""
    if "cutting" in log.columns:
        return log["cutting"] > 0.5, "plan"
    if log.metadata.get("command") == "teleop" and "phase_code" in log.columns:
        from hubo_cli.teleop.phases import PHASES

        return log["phase_code"] == PHASES.index("operate"), "operating"
    window = np.zeros(len(log), dtype=bool)
    hits = np.flatnonzero(inside)
    if len(hits):
        window[hits[0]:hits[-1] + 1] = True
    return window, "first to last contact"


def cutting_report(log: LogData, T_world_bit: np.ndarray, half_length_m: float) -> dict | None:
    """``cutting_fraction`` and how it was measured, or None for a run without a wall.

    Returns:
        ``{"cutting_fraction", "cut_s", "cut_window", "bit_depth_mm"}``: the share (0..1) of
        the cut's periods with the flutes in a wall, the cut's length (s), how the cut's
        periods were chosen (see :func:`cut_periods`), and the bit's middle past the first
        wall's face during the cut (median, min, max; mm).
    """
    walls = log.metadata.get("scene", {}).get("walls", [])
    if not walls or not len(log):
        return None
    inside = np.zeros(len(log), dtype=bool)
    for wall in walls:
        inside |= flutes_in_wall(T_world_bit, wall, half_length_m)
    window, how = cut_periods(log, inside)
    periods = int(window.sum())
    wall = walls[0]
    R_world_wall = quat_wxyz_to_matrix(np.asarray(wall["quat_wxyz"], dtype=float))
    face = np.asarray(wall["centre_world_m"], dtype=float)
    depth = ((T_world_bit[window, :3, 3] - face) @ R_world_wall)[:, 0] + wall["size_m"][0] / 2
    depth = depth[np.isfinite(depth)] * 1000
    return {"cutting_fraction": float(inside[window].mean()) if periods else None,
            "cut_s": periods * _period_s(log), "cut_window": how,
            "bit_depth_mm": ({"median": float(np.median(depth)), "min": float(depth.min()),
                              "max": float(depth.max())} if len(depth) else None)}


# ------------------------------------------------------------------------------------ summary
def balance_report(log: LogData, model=None, drill: bool = False) -> dict:
    """The balance fields of ``summary.json`` (see the module docstring); a figure the log
    cannot give is None. ``model`` and ``drill`` (the right hand holds the drill) are needed
    for ``cutting_fraction``."""
    margin = support_margin(log)
    config = ESTIMATION if model is None else model.estimation
    contact = feet_contact(log, config)
    if contact is not None and all(f"planned_{foot}_foot_contact_flag" in log.columns
                                   for foot in FEET):
        planned = np.column_stack([log[f"planned_{foot}_foot_contact_flag"] > 0.5
                                   for foot in FEET])
        contact = contact | ~planned  # a foot in the air by plan is not a lost contact
    losses = (None if contact is None
              else contact_losses(log["t_s"], contact, _period_s(log), config.contact_loss_min_s))
    report = {
        "max_torso_tilt_deg": max_tilt_deg(log),
        "min_support_margin_mm": None if margin is None else margin["mm"],
        "min_support_margin_at": None if margin is None else
        {k: v for k, v in margin.items() if k != "mm"},
        "contact_losses": None if losses is None else len(losses),
        "contact_loss_intervals": None if losses is None else losses[:LISTED_LOSSES],
        "ankle_clamp_fraction": ankle_clamp_fraction(log),
    }
    if drill and model is not None:
        cut = cutting_report(log, bit_poses(log, model), model.drill.bit_half_length_m)
        if cut is not None:
            report["cutting_fraction"] = cut.pop("cutting_fraction")
            report["cutting"] = cut
    return report
