"""``make bench``: performance figures, one module per area.

Each module in this package defines ``run(report)`` where ``report(name, value, unit, note="")``
records one figure. Benchmarks print numbers; they never fail on a slow machine.
"""
