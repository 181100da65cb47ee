"""Walk first, then hand over: the shortest walk (the two steps that close the feet from the
walking width to the home posture's), the rise, and a session target that takes over with its
own clock, on the simulated robot through the whole pipeline with the default balancer."""

import json

import numpy as np
import pytest

from hubo_cli.control.keys import STOP_MODE
from hubo_cli.control.pipeline import SafetyProfile
from hubo_cli.control.target import Target
from hubo_cli.model import load_model
from hubo_cli.posture import home_posture
from hubo_cli.session import RunSetup, run
from hubo_cli.walking.approach import PHASES, walk_first_setup

pytestmark = [pytest.mark.slow, pytest.mark.physical]


class Session(Target):
    """Holds the home posture for 0.3 s of its own clock and records what it saw, the soft
    stopper's mode among it (a key read through the walk-first target's store view)."""

    log_columns = ("session_t_s",)
    previous = (STOP_MODE,)

    def __init__(self, q_rad):
        self.q_rad = q_rad
        self.times_s = []
        self.attached = False
        self.modes = []

    def attach(self, world, modules, store):
        self.attached, self.store = True, store

    def __call__(self, t_s, state):
        self.times_s.append(t_s)
        self.modes.append(self.store.get(STOP_MODE, "release"))
        return self.q_rad, {"session_t_s": t_s, "done": t_s >= 0.3}


@pytest.fixture(scope="module")
def handed_over(tmp_path_factory):
    model = load_model()
    session = Session(home_posture(model))
    setup = RunSetup(command="walk-first", model=model, out=tmp_path_factory.mktemp("wf") / "run",
                     safety=SafetyProfile(), q_start_rad=home_posture(model), duration_s=30.0)
    target, setup = walk_first_setup(setup, session, (0.0, 0.0))
    done = run(setup, target)
    return target, session, done


def test_the_session_takes_over_on_its_own_clock(handed_over):
    target, session, done = handed_over
    assert done.loop.ended == "done"
    assert target.phase == "then" and session.attached
    assert set(session.modes) == {"release"}  # the stopper's mode, through the walk-first view
    assert session.times_s[0] == pytest.approx(0.0)
    phases = np.asarray(done.log["approach.phase_code"])
    phases = phases[np.isfinite(phases)]  # the loop's closing row has no target
    assert set(np.unique(phases)) == {float(i) for i in range(len(PHASES))}
    # walk, rise, then: in order, once each (on both code paths, AVX-512 / portable)
    assert np.all(np.diff(phases) >= 0)


def test_the_walk_closes_the_feet_without_a_stop(handed_over):
    target, _, done = handed_over
    summary = done.summary
    # the torso leans toward the stance foot while walking (lean_rad_per_m): measured 8.18 deg
    # on both code paths (AVX-512 / portable), bound 12.5 deg = 1.5x (a fall: 30 deg); the feet
    # end 0.3-0.4 mm from the 177 mm (bound 6 mm)
    assert summary["estop_events"] == [] and summary["max_torso_tilt_deg"] < 12.5
    assert summary["max_joint_velocity_ratio"] <= 1.0 + 1e-9
    walk = target.summary()
    assert walk["fell"] is False and walk["arrived"] is True
    assert walk["steps"] == 2  # only the closing pair: from 260 mm to 177 mm apart
    feet = [np.array(target.walk.final_feet[s][:2, 3]) for s in ("right", "left")]
    assert np.linalg.norm(feet[0] - feet[1]) == pytest.approx(0.177, abs=0.006)
    json.dumps(walk)  # the summary's walk field is plain JSON


def test_sim_step_stands_still_without_a_push(tmp_path):
    """``hubo sim --step`` without a push: no step (the capture point stays well inside), the
    summary says so and keeps ``fell``."""
    from click.testing import CliRunner

    from hubo_cli.cli.main import main

    result = CliRunner().invoke(main, ["sim", "--duration", "1", "--step", "--json",
                                       "--out", str(tmp_path / "run")])
    assert result.exit_code == 0, result.output
    fields = json.loads(result.stdout)
    assert fields["fell"] is False  # and no step, on both code paths (AVX-512 / portable)
    assert fields["capture_step"] == {"stepped": False, "trigger_s": None, "steps": 0,
                                      "start_feet": [], "stood_s": None, "stop_s": None,
                                      "stood_feet": [], "footsteps": []}
