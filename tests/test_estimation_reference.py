"""The estimation layer gives, to 1e-9, the estimate it gave when the reference was written, on
a recorded walk with bad readings put in (tests/estimation_reference.py): its per-period speed
work (compiled kernels, fewer copies and checks) cannot change its numbers unnoticed."""

from __future__ import annotations

import numpy as np
from estimation_reference import DATA, WIDTHS, estimate_rows, states


def test_the_estimate_matches_the_recorded_reference(model):
    with np.load(DATA) as data:
        expected = data["expected"]
        rows = estimate_rows(states(data), model)
    assert rows.shape == expected.shape
    # NaN where the reference had NaN (the ZMP without a loaded sole), equal elsewhere
    assert np.array_equal(np.isnan(rows), np.isnan(expected))
    error = np.abs(np.nan_to_num(rows) - np.nan_to_num(expected))
    if error.max() > 1e-9:
        period, column = np.unravel_index(np.argmax(error), error.shape)
        bounds = np.cumsum(list(WIDTHS.values()))
        key = list(WIDTHS)[int(np.searchsorted(bounds, column, side="right"))]
        raise AssertionError(f"{key.name} differs by {error.max():.3g} in period {period} "
                             f"(first at period {np.argmax(error.max(axis=1) > 1e-9)})")


def test_the_reference_covers_the_paths():
    """The sequence is one that exercises what the layer decides: both soles take the anchor,
    single supports on either sole, the IMU's rejections, the ZMP without a loaded sole."""
    with np.load(DATA) as data:
        expected = data["expected"]
    names = [key.name for key in WIDTHS for _ in range(WIDTHS[key])]
    contact = expected[:, names.index("contact_feet"):][:, :2]
    rejected = expected[:, names.index("imu_rejected"):][:, :2]
    assert {tuple(row) for row in contact} >= {(1.0, 1.0), (1.0, 0.0), (0.0, 1.0)}
    assert rejected[:, 0].any() and rejected[:, 1].any()
