"""The one place a run's estimator is assembled: which observers, in which order."""

from __future__ import annotations

from collections.abc import Mapping

from hubo_cli.estimation.attitude import AttitudeObserver, attitude_params
from hubo_cli.estimation.base import FloatingBase
from hubo_cli.estimation.centre_of_mass import CentreOfMass
from hubo_cli.estimation.contact import ContactObserver
from hubo_cli.estimation.estimator import Estimator
from hubo_cli.estimation.plausibility import SensorPlausibility
from hubo_cli.estimation.wrenches import RemoveForceOffset
from hubo_cli.model import RobotModel


def build_estimator(model: RobotModel, tools: Mapping[str, str] | None = None,
                    period_s: float | None = None, accel_measured: bool = True,
                    sensors_measured: bool = False,
                    tool_mass_kg: float | None = None) -> Estimator:
    """The estimation layer of a run: attitude (gyro, accelerometer and the legs' tilt),
    compensated wrenches (weight, and the hands' inertia), contact, floating base
    and soles, centre of mass with the capture point and the ZMP, then the sensors'
    plausibility checks (:mod:`hubo_cli.estimation.plausibility`).

    Args:
        model: the robot model.
        tools: arm -> tool held (``drill`` in the right hand adds its mass beyond the wrist
            sensor and to the CoM).
        period_s: the control period (s; default the model's).
        accel_measured: the driver measures the accelerometer (``Driver.accel_measured``);
            else the wrists' compensation removes the hands' weight alone.
        sensors_measured: the driver's sensors are measured (``Driver.sensors_measured``,
            which a run passes); else (made-up states: a bench, a test) their plausibility
            is not checked.
    """
    tools = tools or {}
    drill = tools.get("right-arm") == "drill"
    drill_kg = model.drill.mass_kg if tool_mass_kg is None else float(tool_mass_kg)
    dt_s = model.control_period_s if period_s is None else float(period_s)
    attitude = attitude_params(model)
    com = CentreOfMass(model, dt_s, drill=drill)
    weight_n = com.robot.weight_n
    return Estimator([
        AttitudeObserver(attitude, dt_s, model),
        RemoveForceOffset(model, attitude.accel_reject_m_s2, drill=drill, period_s=dt_s,
                          accel_measured=accel_measured, drill_kg=drill_kg),
        ContactObserver(model.estimation, dt_s),
        FloatingBase(model),
        com,
        SensorPlausibility(model, weight_n, dt_s, measured=sensors_measured,
                           drill_kg=drill_kg if drill else None),
    ])
