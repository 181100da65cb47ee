"""``hubo ik --batch`` as a library: exact numbers out, every row accounted for."""

import csv

import numpy as np
import pytest

from hubo_cli.errors import InputError
from hubo_cli.kinematics import get_limb
from hubo_cli.kinematics.batch_csv import POSE_COLUMNS, PREV_COLUMNS, solve_csv


def test_written_joints_read_back_to_the_same_float64(tmp_path):
    limb = get_limb("left-arm", "hand")
    rng = np.random.default_rng(11)
    Q = limb.random_q(rng, 300)
    T = limb.fk_batch(Q).reshape(-1, 16)
    prev = np.clip(Q + rng.normal(0, 0.01, Q.shape), limb.lower_rad, limb.upper_rad)
    src, out = tmp_path / "in.csv", tmp_path / "out.csv"
    lines = [",".join(POSE_COLUMNS + PREV_COLUMNS)]
    lines += [",".join(repr(float(v)) for v in (*t, *p)) for t, p in zip(T, prev, strict=True)]
    src.write_text("\r\n".join(lines) + "\r\n")  # Windows line ends are read too
    report = solve_csv(limb, src, out)
    assert report.rows == report.solved == 300 and not report.bad_lines
    expected = limb.solve_batch(T.reshape(-1, 4, 4), prev)
    with out.open() as f:
        rows = list(csv.DictReader(f))
    q = np.array([[float(r[f"q{k}"]) for k in range(1, 7)] for r in rows])
    assert np.array_equal(q, expected.q_rad)  # shortest round-trip text: no digit lost
    assert [int(r["line"]) for r in rows] == list(range(2, 302))
    assert report.status_counts["exact"] + report.status_counts["capped"] == 300


def test_a_header_without_the_pose_columns_is_refused(tmp_path):
    src = tmp_path / "in.csv"
    src.write_text("a,b,c\n1,2,3\n")
    with pytest.raises(InputError, match="header lacks"):
        solve_csv(get_limb("right-arm", "hand"), src, tmp_path / "out.csv")


def test_a_header_only_file_gives_an_empty_result(tmp_path):
    src, out = tmp_path / "in.csv", tmp_path / "out.csv"
    src.write_text(",".join(POSE_COLUMNS) + "\n")
    report = solve_csv(get_limb("right-arm", "hand"), src, out)
    assert report.rows == 0 and out.read_text().startswith("line,q1")
