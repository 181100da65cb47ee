"""Scripted tasks: the task file format, pre-flight planning and the runner."""
