"""Seeing a run: kinematic replay in PyBullet, videos, Rerun recordings and Foxglove MCAP files.

Everything here works from a run folder's log (``log.csv``/``log.parquet`` and ``log.json``), so
any run can be looked at again, sim or hardware. The video encoder, Rerun and MCAP writers are in
the optional extra ``hubo-cli[viz]`` (see :mod:`hubo_cli.viz.deps`).
"""
