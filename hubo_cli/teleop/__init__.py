"""Teleoperation: operator poses -> hand goals -> the control pipeline."""
