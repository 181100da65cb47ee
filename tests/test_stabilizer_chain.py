"""The three layers chained as the wiring will chain them, on a planned toe-heel walk: the
planner's ZMP and CoPs, the CoM by preview control, the LIP feedback's ZMP command for a
disturbed state, its split between the feet in contact."""

import numpy as np
import pytest

from hubo_cli.control.lip_feedback import LipFeedback, lip_ground_force
from hubo_cli.control.wrench_distribution import Contact, WrenchDistributor
from hubo_cli.walking.footsteps import Footstep
from hubo_cli.walking.preview import com_from_zmp, preview_gains
from hubo_cli.walking.toe_heel import ToeHeelParams, plan_toe_heel_walk

MASS_KG = 38.7  # the model's (the URDF's links)
COM_HEIGHT_M = 0.58


@pytest.mark.parametrize("com_error_m", [(0.0, 0.0), (0.015, -0.01), (-0.03, 0.02)])
def test_a_walk_through_feedback_and_distribution(model, com_error_m):
    """Every period of a three-step walk: a distribution is found, the feet's forces sum to
    the pendulum's demand at the (possibly clipped) ZMP command, and only feet on the ground
    carry load; a rolling sole touches along its edge. Undisturbed, the command is the planned
    ZMP and is never moved."""
    dt = model.control_period_s
    half = 0.12
    steps = [Footstep("left", 0.15, half, 0.0), Footstep("right", 0.3, -half, 0.0),
             Footstep("left", 0.3, half, 0.0)]
    plan = plan_toe_heel_walk(Footstep("right", 0.0, -half, 0.0),
                              Footstep("left", 0.0, half, 0.0), steps,
                              ToeHeelParams.from_model(model), model.feet, 0.3, dt)
    path = com_from_zmp(plan.zmp_m, preview_gains(dt, COM_HEIGHT_M))
    feedback = LipFeedback.from_model(model, COM_HEIGHT_M)
    distributor = WrenchDistributor.from_model(model)
    moved_m = []
    for k in range(len(plan.t_s)):
        com = path.com_m[k] + com_error_m
        u = feedback.zmp_command(path.com_m[k], path.com_velocity_m_s[k], plan.zmp_m[k], com,
                                 path.com_velocity_m_s[k], plan.zmp_m[k])
        contacts = [Contact(tuple(plan.foot_pose[k, i, :2]), plan.foot_pose[k, i, 2],
                            tuple(plan.cop_m[k, i]),
                            plan.pivot_m[k, i] if plan.foot_angle_rad[k, i] != 0 else None)
                    for i in (0, 1)]  # a rolling sole touches along its edge
        if plan.ratio[k] == 0.0:
            contacts[1] = None
        elif plan.ratio[k] == 1.0:
            contacts[0] = None
        force = lip_ground_force(com, u, MASS_KG, feedback.omega_1_s)
        split = distributor.distribute(force, u, *contacts)
        assert split.found, (k, split.reason)
        np.testing.assert_allclose(split.force_n.sum(axis=0), split.total_force_n, atol=1e-6)
        for i in (0, 1):
            if contacts[i] is None:
                assert np.all(split.force_n[i] == 0)
        moved_m.append(float(np.linalg.norm(split.zmp_m - u)))
    if com_error_m == (0.0, 0.0):
        # the planned ZMP is inside the support polygon in every period, although a rolling
        # sole's CoP sits on its physical edge, just outside the margined one: in double
        # support that sole carries at most half
        assert max(moved_m) == 0.0
