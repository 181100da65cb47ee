"""The store keys pipeline modules write for later modules: one home for each (the estimate's
own keys live in :mod:`hubo_cli.estimation.keys`)."""

from __future__ import annotations

import numpy as np

from hubo_cli.dataflow import Key

SUPPORT_BOX_WORLD = Key(
    "support_box_world_m", np.ndarray,
    "(min x, max x, min y, max y) of the soles in contact laid flat on the floor, shrunk by "
    "the capture-point monitor's margin (world, m); written by the capture-point monitor")
