"""hubo sweep: the same rows sequentially and on a Dask cluster; the table, the plot, Ctrl-C."""

import csv
import json

import pytest
from click.testing import CliRunner

from hubo_cli.cli.main import main
from hubo_cli.errors import ConfigError, InputError
from hubo_cli.sweep import Job, check_jobs, make_jobs, parse_seeds, parse_sets, run_sweep

SHORT = {"duration": [0.6]}  # a short standing run per job: a few seconds of wall-clock


def test_seeds_and_values_make_every_combination():
    assert parse_seeds("1-3") == [1, 2, 3] and parse_seeds("4,2,4") == [4, 2]
    sets = parse_sets(["speed_mm_s=10,20", "wall_distance_mm=auto"])
    assert sets == {"speed_mm_s": [10, 20], "wall_distance_mm": ["auto"]}
    jobs = make_jobs("cut-slot", [1, 2], sets)
    assert len(jobs) == 4 and jobs[1] == Job("cut-slot", 1, (("speed_mm_s", 20),
                                                             ("wall_distance_mm", "auto")))
    assert len({job.name for job in jobs}) == 4


@pytest.mark.parametrize("text", ["", "a-b", "3-1", "-1", "1-"])
def test_bad_seeds_are_refused(text):
    with pytest.raises(InputError):
        parse_seeds(text)


def test_unknown_commands_and_parameters_are_refused_before_anything_runs():
    with pytest.raises(ConfigError):
        check_jobs(make_jobs("no-such-task", [1], {}))
    with pytest.raises(ConfigError):
        check_jobs(make_jobs("cut-slot", [1], {"no_such_parameter": [1]}))
    with pytest.raises(InputError):
        check_jobs(make_jobs("sim", [1], {"speed": [1]}))


@pytest.mark.physical
def test_a_local_cluster_of_two_workers_gives_the_sequential_rows(tmp_path):
    jobs = make_jobs("sim", [0, 2, 5], SHORT)
    sequential = run_sweep(jobs, tmp_path / "seq", workers=0)
    parallel = run_sweep(jobs, tmp_path / "par", workers=2)
    assert "2 worker processes" in parallel.where and not parallel.interrupted
    assert [r.outcome() for r in parallel.rows] == [r.outcome() for r in sequential.rows]
    assert [r.seed for r in sequential.rows] == [0, 2, 5]
    assert all(r.ended == "finished" and r.max_tilt_deg is not None for r in sequential.rows)
    # the seeds differ: 0.010, 0.155 and 0.459 deg on both code paths (AVX-512 / portable)
    assert len({r.max_tilt_deg for r in sequential.rows}) == 3
    with open(tmp_path / "par" / "sweep.csv") as f:
        table = list(csv.DictReader(f))
    assert [int(r["seed"]) for r in table] == [0, 2, 5] and table[0]["duration"] == "0.6"
    assert table[0]["hole_rms_mm"] == ""  # standing cuts no hole
    assert (tmp_path / "par" / "sweep.png").stat().st_size > 1000


def test_ctrl_c_keeps_the_finished_rows(tmp_path):
    def interrupt(row, done, total):
        if done == 1:
            raise KeyboardInterrupt

    result = run_sweep(make_jobs("sim", [1, 2], SHORT), tmp_path, workers=0, on_row=interrupt)
    assert result.interrupted and len(result.rows) == 1 and result.jobs == 2
    with open(tmp_path / "sweep.csv") as f:
        assert len(list(csv.DictReader(f))) == 1


def test_cli_sweep_writes_the_table(tmp_path):
    result = CliRunner().invoke(main, ["sweep", "sim", "--seeds", "3", "--set", "duration=0.4",
                                       "--workers", "0", "--out", str(tmp_path), "--json"])
    assert result.exit_code in (0, 1), result.output
    report = json.loads(result.output)
    assert report["jobs"] == 1 and report["rows"][0]["seed"] == 3
    assert (tmp_path / "sweep.csv").exists()
    refused = CliRunner().invoke(main, ["sweep", "no-such-task", "--out", str(tmp_path / "x")])
    assert refused.exit_code == 2 and not (tmp_path / "x").exists()
