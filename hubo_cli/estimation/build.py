"""The one place a run's estimator is assembled: which observers, in which order."""

from __future__ import annotations

from collections.abc import Mapping

from hubo_cli.estimation.base import FloatingBase
from hubo_cli.estimation.centre_of_mass import CentreOfMass
from hubo_cli.estimation.contact import ContactObserver
from hubo_cli.estimation.estimator import Estimator
from hubo_cli.estimation.reported_attitude import ReportedAttitude
from hubo_cli.estimation.wrenches import RemoveForceOffset
from hubo_cli.model import RobotModel


def build_estimator(model: RobotModel, tools: Mapping[str, str] | None = None,
                    period_s: float | None = None) -> Estimator:
    """The estimation layer of a run: attitude, compensated wrenches, contact, floating base
    and soles, centre of mass with the capture point and the ZMP.

    Args:
        model: the robot model.
        tools: arm -> tool held (``drill`` in the right hand adds its mass beyond the wrist
            sensor and to the CoM).
        period_s: the control period (s; default the model's).
    """
    # The attitude is the driver's (ReportedAttitude) until the Kalman filter of gyro and
    # accelerometer (estimation/attitude.py, AttitudeObserver) holds up under the estimate's
    # users. Measured with it here (est-attitude up to 215c1dc, nominal robot): pushed 60 N
    # for 0.1 s the torso 3.2 mm and the capture point 10 mm off the truth's (0.07 and 0.08 mm
    # with the driver's attitude); `hubo walk --to 0.3 0 0` stopped on the capture point at
    # 0.015 s (the estimate 35 mm off at the start) and did not walk.
    tools = tools or {}
    drill = tools.get("right-arm") == "drill"
    dt_s = model.control_period_s if period_s is None else float(period_s)
    return Estimator([
        ReportedAttitude(),
        RemoveForceOffset(model, drill=drill),
        ContactObserver(model.estimation, dt_s),
        FloatingBase(model),
        CentreOfMass(model, dt_s, drill=drill),
    ])
