"""The estimation layer: what the robot's sensors say, turned once per period into one typed
estimate (contact, compensated wrenches, attitude, floating base and soles, CoM and capture
point) that every module, target and planner reads from the per-period store.

It runs in the control loop after the driver's read and before the target and the modules
(:class:`~hubo_cli.estimation.estimator.Estimator`). It imports nothing from control, walking,
tasks or teleop: the estimate flows down, nothing climbs back. The simulator's truth never
enters it.
"""
