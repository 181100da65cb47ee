"""The sensor plausibility checks, one module each, run by one observer
(:class:`~hubo_cli.estimation.plausibility.SensorPlausibility`, which says what they share):
a reading that is not a finite number (:mod:`.non_finite`),
an ankle sensor or the accelerometer reading exactly 0 (:mod:`.dead_channels`), the IMU
frozen (:mod:`.imu_frozen`), the IMU's vertical against the legs' at the start and while
standing still (:mod:`.imu_tilt`, over :mod:`.still_window`), the soles' load over the robot's
weight (:mod:`.soles_overload`), the wrist sensors dead or off their load (:mod:`.wrists`) and
the ankle sensors wired wrong (:mod:`.ankle_wiring`); what several read of the legs is
:mod:`.legs`'s.
"""
