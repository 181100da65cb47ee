"""``hubo fk`` / ``hubo ik`` through click's CliRunner."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from hubo_cli.cli.main import main
from hubo_cli.kinematics import get_limb

PAPER_Q = ["-0.9914", "-0.3651", "-0.8339", "-1.1618", "-1.6542", "0.8894"]


def run(*args):
    return CliRunner().invoke(main, list(args), catch_exceptions=False)


def test_every_command_has_help():
    result = run("--help")
    assert result.exit_code == 0
    for name in ("fk", "ik"):
        assert name in result.output
        assert run(name, "--help").exit_code == 0


def test_fk_json_matches_library():
    result = run("fk", "right-arm", *PAPER_Q, "--tool", "drill", "--json")
    assert result.exit_code == 0
    data = json.loads(result.stdout)
    T = np.array(data["T"])
    assert np.allclose(T, get_limb("right-arm", "drill").fk(np.array(PAPER_Q, float)))
    assert data["position_mm"][0] == pytest.approx(484.0, abs=0.1)


def test_fk_text_shows_millimetres_and_degrees():
    result = run("fk", "left-leg", "0", "0", "-0.3", "0.6", "-0.3", "0")
    assert result.exit_code == 0
    assert "position (mm)" in result.output and "deg" in result.output


def test_fk_beyond_the_joint_limits_says_so():
    """The pose is computed all the same, with a note naming the joints past their limits
    (round 15: none was given)."""
    result = run("fk", "right-arm", "5", "5", "5", "5", "5", "5")
    assert result.exit_code == 0 and "position (mm)" in result.output
    assert "beyond the joint limits" in result.output and "RSR +5.000 rad" in result.output
    data = json.loads(run("fk", "right-arm", "5", "0", "0", "0", "0", "0", "--json").output)
    assert data["within_limits"] is False
    assert "beyond" not in run("fk", "right-arm", *PAPER_Q, "--tool", "drill").output


def test_ik_round_trip_and_all_candidates():
    result = run("ik", "right-arm", "--xyz", "484", "-170", "75", "--rpy", "0", "0", "0",
                 "--tool", "drill", "--all", "--json")
    assert result.exit_code == 0
    data = json.loads(result.stdout)
    assert data["status"] == "exact" and len(data["candidates"]) == 8
    T = get_limb("right-arm", "drill").fk(np.array(data["q_rad"]))
    assert np.allclose(T[:3, 3], [0.484, -0.170, 0.075], atol=1e-9)


def test_ik_matrix_and_prev():
    T = get_limb("right-arm", "hand").fk(np.array(PAPER_Q, float))
    result = run("ik", "right-arm", "--matrix", *map(str, T.ravel()), "--prev", *PAPER_Q,
                 "--json")
    data = json.loads(result.stdout)
    assert np.allclose(data["q_rad"], np.array(PAPER_Q, float), atol=1e-9)


def test_ik_unreachable_exits_5_without_traceback():
    result = run("ik", "right-arm", "--xyz", "2000", "0", "0")
    assert result.exit_code == 5
    assert "unreachable" in result.output


@pytest.mark.parametrize("args, needle", [
    (("ik", "right-arm"), "no goal given"),
    (("ik", "right-arm", "--matrix", *["1"] * 16), "not a rigid transform"),
    (("ik", "right-arm", "--xyz", "nan", "0", "0"), "NaN"),
    (("ik", "right-arm", "--batch", "/nonexistent.csv", "--out", "x.csv"), "cannot read"),
])
def test_bad_input_gives_one_line_error(args, needle):
    result = CliRunner().invoke(main, list(args))
    assert result.exit_code == 2
    assert needle in result.output
    assert "Traceback" not in result.output


def _write_batch(path, T, prev=None, extra_lines=()):
    cols = [f"T{i}{j}" for i in range(4) for j in range(4)]
    if prev is not None:
        cols += [f"qprev{k}" for k in range(1, 7)]
    lines = [",".join(cols)]
    for k, Tk in enumerate(T):
        values = list(Tk.ravel()) + ([] if prev is None else list(prev[k]))
        lines.append(",".join(repr(float(v)) for v in values))
    lines += list(extra_lines)
    path.write_text("\n".join(lines) + "\n")


def test_batch_solves_good_rows_and_reports_bad_ones(tmp_path, rng):
    limb = get_limb("right-arm", "hand")
    Q = limb.random_q(rng, 200)
    T = limb.fk_batch(Q)
    src, out = tmp_path / "in.csv", tmp_path / "out.csv"
    _write_batch(src, T, Q)
    lines = src.read_text().splitlines()
    lines[5] = lines[5].replace(lines[5].split(",")[3], "nan", 1)       # NaN
    lines[9] = ",".join(lines[9].split(",")[:-2])                        # missing fields
    lines[12] = lines[12].replace(lines[12].split(",")[0], "abc", 1)     # not a number
    src.write_text("\n".join(lines) + "\n")
    result = CliRunner().invoke(main, ["ik", "right-arm", "--batch", str(src), "--out", str(out),
                                       "--json"])
    assert result.exit_code == 2, result.output
    for line in (6, 10, 13):
        assert f"in.csv:{line}:" in result.output
    rows = out.read_text().splitlines()
    assert rows[0].startswith("line,q1") and len(rows) == 201
    solved = [r.split(",") for r in rows[1:] if "invalid" not in r]
    assert len(solved) == 197
    for r in solved:
        line = int(r[0])
        q = np.array(r[1:7], float)
        assert r[7] == "exact"
        assert np.allclose(limb.fk(q), T[line - 2], atol=1e-9)
    invalid = [int(r.split(",")[0]) for r in rows[1:] if "invalid" in r]
    assert invalid == [6, 10, 13]


@pytest.mark.parametrize("text", ["-", ".", "e5", "1e", "nan", "", "-.", "+", "1.5.2", "0x10"])
def test_batch_reports_a_field_that_is_not_a_complete_number(tmp_path, rng, text):
    limb = get_limb("right-arm", "hand")
    Q = limb.random_q(rng, 6)
    src, out = tmp_path / "in.csv", tmp_path / "out.csv"
    _write_batch(src, limb.fk_batch(Q))
    lines = src.read_text().splitlines()
    fields = lines[3].split(",")
    fields[7] = text  # T13, the pose's y
    lines[3] = ",".join(fields)
    src.write_text("\n".join(lines) + "\n")
    result = CliRunner().invoke(main, ["ik", "right-arm", "--batch", str(src), "--out",
                                       str(out), "--json"])
    assert result.exit_code == 2, result.output
    assert "in.csv:4:" in result.output and "T13" in result.output
    rows = [r.split(",") for r in out.read_text().splitlines()[1:]]
    assert [r[7] for r in rows] == ["exact"] * 2 + ["invalid"] + ["exact"] * 3
    assert rows[2][1:7] == [""] * 6  # nothing solved for it
    for r in rows[:2] + rows[3:]:
        assert np.allclose(limb.fk(np.array(r[1:7], float)), limb.fk(Q[int(r[0]) - 2]),
                           atol=1e-9)


def test_batch_reports_every_kind_of_bad_row_and_solves_the_rest(tmp_path, rng):
    limb = get_limb("right-arm", "hand")
    src, out = tmp_path / "in.csv", tmp_path / "out.csv"
    _write_batch(src, limb.fk_batch(limb.random_q(rng, 3)),
                 extra_lines=["", "1,2", ",".join(["1"] * 17), ",".join(["0.0"] * 16)])
    result = CliRunner().invoke(main, ["ik", "right-arm", "--batch", str(src), "--out",
                                       str(out)])
    assert result.exit_code == 2, result.output
    output = " ".join(result.output.split())
    for line, why in ((5, "found 1"), (6, "found 2"), (7, "found 17"), (8, "rigid")):
        assert f"in.csv:{line}:" in output and why in output
    assert len(out.read_text().splitlines()) == 1 + 7


def test_batch_refuses_to_write_over_its_input(tmp_path, rng):
    limb = get_limb("right-arm", "hand")
    src = tmp_path / "in.csv"
    _write_batch(src, limb.fk_batch(limb.random_q(rng, 3)))
    before = src.read_bytes()
    for out in (src, tmp_path / "." / "in.csv"):
        result = CliRunner().invoke(main, ["ik", "right-arm", "--batch", str(src), "--out",
                                           str(out)])
        assert result.exit_code == 2 and "input file" in result.output
    assert src.read_bytes() == before
