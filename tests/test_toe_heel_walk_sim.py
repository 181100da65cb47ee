"""A short toe-heel walk on the simulated robot through the CLI (``hubo walk --toe-heel``):
it walks without falling, and the run folder holds Fig. 4 drawn from its own log, whose
estimated sole angles follow the planned heel strike."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from hubo_cli.cli.main import main

pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("walking-sim")]


@pytest.fixture(scope="module")
def toe_heel_walk(tmp_path_factory):
    """hubo walk --to 0.3 0 0 --toe-heel --corrections 0: four 75 mm steps, each rolling."""
    out = tmp_path_factory.mktemp("walk") / "run"
    result = CliRunner().invoke(main, ["walk", "--to", "0.3", "0", "0", "--toe-heel",
                                       "--corrections", "0", "--json", "--out", str(out)])
    return result, out


@pytest.mark.physical
def test_a_toe_heel_walk_draws_fig_4_from_its_log(toe_heel_walk):
    from hubo_cli.control.log import load_log

    result, out = toe_heel_walk
    assert result.exit_code == 0, result.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["fell"] is False and summary["ended"] == "done"
    assert "toe_heel.png" in summary["files"] and (out / "toe_heel.png").exists()
    log = load_log(out)
    for side in ("right", "left"):
        planned = np.asarray(log[f"walk.{side}_angle_ref_rad"], dtype=float)
        estimated = np.asarray(log[f"walk.{side}_angle_rad"], dtype=float)
        heel = planned < 0.8 * np.nanmin(planned)  # the heel strikes' deepest periods
        assert heel.sum() > 20
        # the estimated sole (the legs' kinematics and the attitude) turns with the plan:
        # 1.00-1.02 of the planned angle on average there, 0.90 at least (one run, AVX-512)
        assert np.mean(estimated[heel] / planned[heel]) > 0.6
