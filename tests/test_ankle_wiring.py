"""Ankle force-torque sensors wired wrong on the simulated robot (round 20, review 19's
``sensor_lies19.py``): the estimation layer's wiring checks
(:mod:`hubo_cli.estimation.sensor_checks.ankle_wiring`) end the run with the sensor named.
Physical tests: the sim driver's readings rewired as :mod:`tools.ankle_wiring` does."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner
from tool_support import load_tool

from hubo_cli.cli.main import main
from hubo_cli.drivers.sim import SimDriver

rewired = load_tool("ankle_wiring").rewired


def _wired(monkeypatch, kind: str) -> None:
    monkeypatch.setattr(SimDriver, "_measure", rewired(SimDriver._measure, kind))


@pytest.mark.physical
def test_a_walk_on_an_ankle_sensor_turned_180_deg_stops_with_the_sensor_named(monkeypatch,
                                                                              tmp_path):
    """The right ankle's sensor turned 180 deg about its z: main's walk fell at 0.86 s, the
    capture point's stop unable to stand it (exit 1), the sensor unnamed. Its sole's centre of
    pressure reads behind the heel as the first weight shift loads the toe: a device fault at
    0.12 s, the walk ending standing (nothing stepped yet)."""
    _wired(monkeypatch, "rot180-right")
    result = CliRunner().invoke(main, ["walk", "--to", "0.6", "0", "0",
                                       "--out", str(tmp_path / "w")])
    assert result.exit_code == 3, result.output
    assert "the right-ankle force-torque sensor reads its sole's centre of pressure at x" \
        in result.output and "turned about its z" in result.output
    summary = json.loads((tmp_path / "w" / "summary.json").read_text())
    assert summary["fell"] is False and summary["steps"] == 0, summary


@pytest.mark.physical
def test_a_stand_on_an_ankle_sensor_reading_fz_flipped_is_refused(monkeypatch, tmp_path):
    """The right ankle's F_z with its sign flipped: main's stand ran its 1 s and exited 0
    (a walk stopped after 1 s, 'the ankle force sensors read -136 N together', the sensor
    unnamed). Refused before anything moved, exit 4."""
    _wired(monkeypatch, "flip-fz-right")
    result = CliRunner().invoke(main, ["sim", "--duration", "1", "--out", str(tmp_path / "s")])
    assert result.exit_code == 4, result.output
    assert "the right-ankle force-torque sensor reads F_z -1" in result.output
    assert "refused before anything moved" in result.output and "sign" in result.output


@pytest.mark.physical
def test_a_walk_on_swapped_ankle_sensors_stops_before_a_foot_lifts(monkeypatch, tmp_path):
    """The two ankle sensors swapped, perturbation seed 1: main's walk fell (round 20's check
    named the swap at 1.41 s, once a foot had lifted). The walk's first weight shift rocks the
    robot from sole to sole, and the estimate, standing it on the sole its sensor loads, sinks
    a sole that stays down: round 21 saw both soles under the floor (0.61 s); with the ankle
    sensors reading the period's mean (round 23) the robot rocks less, both soles pass 2 mm
    under only at 0.88-0.90 s, but both loaded, the left sinks 1.5 mm under the right since
    the start by 0.335 s (both code paths): a device fault before the first lift-off (0.9 s),
    the robot standing."""
    _wired(monkeypatch, "swap")
    result = CliRunner().invoke(main, ["walk", "--to", "0.6", "0", "0", "--perturb", "1",
                                       "--out", str(tmp_path / "w")])
    assert result.exit_code == 3, result.output
    assert "under the right one since the start, before a step" in result.output
    assert "swapped between the feet" in result.output
    summary = json.loads((tmp_path / "w" / "summary.json").read_text())
    assert summary["steps"] == 0 and summary["stood"] is True, summary
    assert summary["fell"] is False and summary["fell_truth"] is False, summary
    assert summary["stopped_s"] < 0.85, summary


@pytest.mark.physical
def test_a_perturbed_stand_rocking_after_a_push_is_no_swapped_sensors(tmp_path):
    """A healthy robot (perturbation seed 28) pushed 90 N backward rocks on its heels (the
    soles tilted up to 4.8 deg in the estimate) and back, and the estimate, taking the rolled
    soles flat, sinks both soles 2.9-3.2 mm under the floor it started on at 2.34 s. Judged at
    round 21's 2 mm throughout, the check named swapped ankle sensors and ended the run (exit
    3). Once a sole has tilted past 2 deg the depth judged is 5 mm: stands pushed 90 N on seeds
    11-40 in four directions held at most 2.25 mm after such a tilt, 0.23 mm before one (round
    35, docs/history/safety.md). The run stands its 4 s."""
    result = CliRunner().invoke(main, ["sim", "--push", "90", "--push-direction", "backward",
                                       "--perturb", "28", "--duration", "4", "--json",
                                       "--out", str(tmp_path / "s")])
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "s" / "summary.json").read_text())
    assert summary["ended"] == "finished" and summary["fell"] is False, summary
    assert "swapped" not in result.output
