"""Motion primitives below the pipeline and the drivers: the joint limits
(:mod:`~hubo_cli.motion.limits`) and the jerk-limited joint tracker
(:mod:`~hubo_cli.motion.tracker`)."""
