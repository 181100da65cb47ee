"""What a phase of a run (a walk, a rise, a capture step and its catch) tells the pipeline:
store keys its target writes every period and the modules follow (``follows``: a run without
such a phase writes none of them, and the modules then do as when standing).

A target switches the modules through these keys, never through their attributes or by
resetting them: the capture-point monitor judges the capture point against the support the
phase plans (:data:`SUPPORT_PLAN`), the standing balancers rest while a phase moves the centre
of mass itself (:data:`BALANCERS_REST`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hubo_cli.dataflow import Key


@dataclass(frozen=True)
class SupportPlan:
    """The support a phase plans for this period.

    Attributes:
        T_world_soles: (2, 4, 4) the right and left sole poses the robot stands on in this
            phase of the step (a swing foot at its landing place), on the floor.
        margin_m: the capture-point monitor shrinks their hull by this much (m; None: by
            its own margin).
    """

    T_world_soles: np.ndarray
    margin_m: float | None = None


SUPPORT_PLAN = Key("support_plan", object,
                   "SupportPlan of this period, or None: the estimate's soles in contact, "
                   "shrunk by the monitor's own margin")
BALANCERS_REST = Key("standing_balancers_rest", bool,
                     "True while a phase moves the centre of mass itself: the standing "
                     "balancers send no correction and start afresh when it ends")

PHASE_KEYS = (SUPPORT_PLAN, BALANCERS_REST)
