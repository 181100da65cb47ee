"""The summary's reach report with the followed orientation: what the replay's verdict judges.

The teleop target records, per hand and per operating period, the position and orientation
error, whether the goal was reachable and whether the hand was meant to follow it (input live,
not held for a re-centre, clutch released); its reach report gives the position RMS over the
followed time (``followed_position_rms_mm``). This adds the orientation RMS over the same
periods (``followed_orientation_rms_deg``), so the verdict judges a hand that follows the
operator's position but not the turn of the tool.
"""

from __future__ import annotations

import numpy as np


def followed_orientation_rms_deg(target, arm: str) -> float | None:
    """RMS of the hand's orientation error (deg) over the periods its goal was reachable and
    it was meant to follow; None when there were none."""
    rot = np.asarray(target.rotation_errors_rad[arm])
    followed = (np.asarray(target.reachable[arm], dtype=bool)
                & np.asarray(target.meant_to_follow[arm], dtype=bool))
    if not followed.any():
        return None
    return float(np.degrees(np.sqrt(np.mean(rot[followed] ** 2))))


def reach_summary(target) -> dict[str, dict]:
    """``target.reach_report()`` with ``followed_orientation_rms_deg`` per hand."""
    report = target.reach_report()
    for arm, figures in report.items():
        figures["followed_orientation_rms_deg"] = followed_orientation_rms_deg(target, arm)
    return report
