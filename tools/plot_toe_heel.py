"""Draw the multi-layer paper's Fig. 4 for the Hubo: a two-step toe-heel walk's (a) CoP
offsets, (b) ZMP and CoM, (c) foot angle offsets, into docs/toe-heel-fig4.png (deterministic).

    .venv/bin/python tools/plot_toe_heel.py

The phases, angles and soles are the robot file's ([toe_heel], [feet]); the double support and
the stance width are the walking's ([walking]); the CoM follows the ZMP by the walking's
preview control (hubo_cli/walking/preview.py) at the height of the CoM above the soles in the
home posture, lowered by the walking's crouch.
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from hubo_cli.kinematics.limb import Limb  # noqa: E402
from hubo_cli.model import load_model  # noqa: E402
from hubo_cli.posture import home_posture  # noqa: E402
from hubo_cli.walking.body import WalkingBody  # noqa: E402
from hubo_cli.walking.footsteps import Footstep  # noqa: E402
from hubo_cli.walking.params import walking_params  # noqa: E402
from hubo_cli.walking.preview import com_from_zmp, preview_gains  # noqa: E402
from hubo_cli.walking.toe_heel import ToeHeelParams, plan_toe_heel_walk  # noqa: E402

OUT = Path(__file__).resolve().parents[1] / "docs" / "toe-heel-fig4.png"
STEP_M = 0.2  # each step's length (the paper's Fig. 4 does not give its own)


def com_height_m(model) -> float:
    """The CoM's height above the soles in the home posture, less the walking's crouch."""
    q = home_posture(model)
    com_in_neck = WalkingBody(model, q, np.eye(4)).com_in_neck(q)
    sole_in_neck = Limb(model, "right-leg", tool="none").fk(q[model.limb_slice("right-leg")])
    return float(com_in_neck[2] - sole_in_neck[2, 3]) - walking_params(model).crouch_m


def main() -> None:
    model = load_model()
    params = ToeHeelParams.from_model(model)
    walking = walking_params(model)
    half_width = walking.step_width_m / 2
    right = Footstep("right", 0.0, -half_width, 0.0)
    left = Footstep("left", 0.0, half_width, 0.0)
    steps = [Footstep("left", STEP_M, half_width, 0.0),
             Footstep("right", STEP_M, -half_width, 0.0)]
    dt = model.control_period_s
    plan = plan_toe_heel_walk(right, left, steps, params, model.feet,
                              walking.double_support_s, dt, stand_s=1.0)
    z_c = com_height_m(model)
    com = com_from_zmp(plan.zmp_m, preview_gains(dt, z_c, walking.preview_s,
                                                 walking.zmp_weight, walking.jerk_weight)).com_m
    t = plan.t_s
    fig, axes = plt.subplots(3, 1, figsize=(7.5, 8.5), sharex=True)
    ax = axes[0]
    ax.plot(t, plan.cop_offset_m[:, 0], label="right foot")
    ax.plot(t, plan.cop_offset_m[:, 1], "--", label="left foot")
    ax.set_ylabel("CoP offset x (m)")
    ax.set_title("(a) CoP offsets along each sole (toe edge > 0, heel edge < 0)")
    ax.legend(loc="upper right")
    ax = axes[1]
    ax.plot(t, plan.zmp_m[:, 0], label="ZMP x")
    ax.plot(t, com[:, 0], "--", label="CoM x")
    ax.plot(t, plan.zmp_m[:, 1], label="ZMP y")
    ax.plot(t, com[:, 1], "--", label="CoM y")
    ax.set_ylabel("position (m)")
    ax.set_title(f"(b) ZMP (eq. 4) and CoM (preview control, z_c = {z_c:.2f} m)")
    ax.legend(loc="upper left", ncols=2)
    ax = axes[2]
    ax.plot(t, np.degrees(plan.foot_angle_rad[:, 0]), label="right foot")
    ax.plot(t, np.degrees(plan.foot_angle_rad[:, 1]), "--", label="left foot")
    ax.set_ylabel("foot angle (deg)")
    ax.set_xlabel("time (s)")
    ax.set_title("(c) foot angle offsets (> 0 on the toe, < 0 on the heel)")
    ax.legend(loc="upper right")
    phases = ", ".join(f"{p:g}" for p in params.phase_s)
    fig.suptitle(f"Hubo toe-heel walk, two {STEP_M:g} m steps; phases (i)-(v) {phases} s",
                 fontsize=10)
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(OUT, dpi=90)
    print(f"{OUT.name}: z_c {z_c:.3f} m, {len(t)} samples")


if __name__ == "__main__":
    main()
