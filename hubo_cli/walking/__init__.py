"""Walking: footsteps to a goal stance, ZMP preview control of the CoM, swing feet, and the
legs' closed-form IK turning them into joint targets."""
