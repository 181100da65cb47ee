"""Plots users would rather look at than read (matplotlib, Agg backend)."""
