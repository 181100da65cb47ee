"""The Stabilizer's LIP state feedback (eq. 7-8): gains against hand computations and an
independent pole placement, the closed loop converging, and bad parameters."""

import math

import numpy as np
import pytest
import scipy.linalg
from robot_file_support import robot_file_with
from scipy.signal import place_poles

from hubo_cli.control.lip_feedback import (
    LipFeedback,
    LipFeedbackParams,
    lip_gains,
    lip_ground_force,
    lip_matrices,
)
from hubo_cli.errors import ConfigError
from hubo_cli.model import load_model
from hubo_cli.state import GRAVITY_M_S2


def test_gains_by_hand():
    """w^2 = 10 1/s^2, T_p = 0.1 s, poles -10, -5, -2: (s+10)(s+5)(s+2) = s^3 + 17 s^2 +
    80 s + 100, so k3 = 0.1 * 17 - 1 = 0.7, k2 = -0.1 (1 + 80/10) = -0.9,
    k1 = -0.1 (17 + 100/10) = -2.7."""
    np.testing.assert_allclose(lip_gains(math.sqrt(10.0), 0.1, [-10, -5, -2]),
                               [-2.7, -0.9, 0.7], atol=1e-12)


def test_hrpsys_default_gains_from_their_poles():
    """hrpsys's eefm_k1..k3 defaults (-1.41429, -0.404082, -0.18 with T_p = 0.055 s) place the
    poles at -0.99703 w and -(1.63063 +- 0.66061 j) w for a 0.8 m CoM (eigenvalues of A - B K,
    computed once); placing those poles gives the defaults back, to their printed digits."""
    w = math.sqrt(GRAVITY_M_S2 / 0.8)
    poles = np.array([-0.99703168, -1.63063202 + 0.66060661j, -1.63063202 - 0.66060661j]) * w
    np.testing.assert_allclose(lip_gains(w, 0.055, poles), [-1.41429, -0.404082, -0.18],
                               atol=2e-6)


@pytest.mark.parametrize("com_height_m", [0.5, 0.7, 0.9])
def test_gains_place_the_model_poles(model, com_height_m):
    """The robot file's poles, checked against scipy's pole placement (another algorithm) and
    the eigenvalues of the closed loop."""
    feedback = LipFeedback.from_model(model, com_height_m)
    w = feedback.omega_1_s
    assert w == pytest.approx(math.sqrt(GRAVITY_M_S2 / com_height_m))
    A, B = lip_matrices(w, feedback.params.zmp_time_constant_s)
    poles = np.asarray(feedback.params.poles_per_omega) * w
    reference = place_poles(A, B[:, None], poles).gain_matrix[0]
    np.testing.assert_allclose(feedback.gains, reference, rtol=1e-9)
    eig = np.sort(np.linalg.eigvals(A - np.outer(B, feedback.gains)).real)
    np.testing.assert_allclose(eig, np.sort(poles), rtol=1e-9)
    assert feedback.gains[0] < 0 and feedback.gains[1] < 0  # the ZMP moves toward the error


def _simulate(feedback, x0, duration_s, dt_s=0.005, true_lag_s=None, reference=None,
              lead=False):
    """The LIP of eq. 7 (exactly discretised, u held over the period) under eq. 8 at
    ``dt_s``; ``true_lag_s`` lets the plant's ZMP lag differ from the controller's model;
    ``reference(t)`` gives [CoM, velocity, ZMP, ZMP velocity]."""
    A, B = lip_matrices(feedback.omega_1_s, true_lag_s or feedback.params.zmp_time_constant_s)
    big = np.zeros((4, 4))
    big[:3, :3], big[:3, 3] = A, B
    E = scipy.linalg.expm(big * dt_s)
    Ad, Bd = E[:3, :3], E[:3, 3]
    x = np.array(x0, dtype=float)  # one axis: [CoM, velocity, ZMP]
    states = [x.copy()]
    for k in range(int(round(duration_s / dt_s))):
        ref = reference(k * dt_s) if reference else np.zeros(4)
        u = feedback.zmp_command([ref[0], 0], [ref[1], 0], [ref[2], 0], [x[0], 0], [x[1], 0],
                                 [x[2], 0], [ref[3] if lead else 0.0, 0])[0]
        x = Ad @ x + Bd * u
        states.append(x.copy())
    return np.array(states)


@pytest.mark.parametrize("true_lag_s", [None, 0.03, 0.08])
def test_the_closed_loop_returns_to_the_reference(model, true_lag_s):
    """A 20 mm CoM error with 0.1 m/s toward it: back within 0.1 mm in 3 s, also when the
    real ZMP lags 0.03 s or 0.08 s instead of the 0.055 s the gains assume (0.1 mm is over
    10x the residues computed: 1e-4 mm nominal, 0.007 mm with the other lags)."""
    feedback = LipFeedback.from_model(model, 0.7)
    states = _simulate(feedback, [0.02, 0.1, 0.0], 3.0, true_lag_s=true_lag_s)
    assert np.abs(states[-1]).max() < 1e-4
    # the ZMP the command asks for stays within a sole's length of the CoM (no wild swing)
    assert np.abs(states[:, 2]).max() < 0.1


def test_a_moving_reference_with_and_without_the_lag_feedforward(model):
    """The CoM at 0.2 m/s above its ZMP, started 10 mm off. Eq. 8 as printed settles at the
    offset -(A - B K)^-1 [0, 0, -v] (hand-derived: the ZMP's lag leaves the reference
    inconsistent; within 0.2 mm of it after 3 s when the command is held over 0.5 ms periods,
    0.08 mm computed: the hold lags the continuous law by half a period); with T_p p_ref'
    added the CoM is on the reference within the same 0.2 mm (0.08 mm computed, the hold)."""
    feedback = LipFeedback.from_model(model, 0.7)
    speed = 0.2

    def reference(t):
        return np.array([speed * t, speed, speed * t, speed])

    A, B = lip_matrices(feedback.omega_1_s, feedback.params.zmp_time_constant_s)
    offset = -np.linalg.solve(A - np.outer(B, feedback.gains), [0.0, 0.0, -speed])
    assert abs(offset[0]) > 0.005  # a real offset, so the feedforward's test means something
    plain = _simulate(feedback, [0.01, 0.0, 0.0], 3.0, dt_s=0.0005, reference=reference)
    assert plain[-1][0] - reference(3.0)[0] == pytest.approx(offset[0], abs=2e-4)
    lead = _simulate(feedback, [0.01, 0.0, 0.0], 3.0, dt_s=0.0005, reference=reference,
                     lead=True)
    assert abs(lead[-1][0] - reference(3.0)[0]) < 2e-4


def test_the_open_loop_falls(model):
    """Without feedback (the ZMP held at the reference) the same error grows: the test's
    plant is unstable, so convergence above is the feedback's."""
    feedback = LipFeedback.from_model(model, 0.7)
    feedback.gains = np.zeros(3)
    states = _simulate(feedback, [0.02, 0.1, 0.0], 1.0)
    assert abs(states[-1][0]) > 0.2


def test_non_finite_estimates_leave_their_term_out(model):
    feedback = LipFeedback.from_model(model, 0.7)
    u = feedback.zmp_command([0.01, 0.0], [0.0, 0.0], [0.02, 0.0], [float("nan"), 0.0],
                             [0.0, 0.0], [0.02, float("inf")])
    assert np.all(np.isfinite(u))
    assert u[0] == pytest.approx(0.02) and u[1] == pytest.approx(0.0)


def test_ground_force_of_the_pendulum():
    w = math.sqrt(GRAVITY_M_S2 / 0.7)
    force = lip_ground_force([0.05, -0.02, 0.7], [0.0, 0.0], 40.0, w)
    np.testing.assert_allclose(force, [40 * w * w * 0.05, -40 * w * w * 0.02,
                                       40 * GRAVITY_M_S2])


@pytest.mark.parametrize("key,value,match", [
    ("zmp_time_constant_s", "0", "zmp_time_constant_s"),
    ("zmp_time_constant_s", '"x"', "zmp_time_constant_s"),
    ("poles_per_omega", "[-1.0, -1.5]", "poles_per_omega"),
    ("poles_per_omega", "[-1.0, 0.5, -2.0]", "poles_per_omega"),
    ("poles_per_omega", "[-1.0, nan, -2.0]", "poles_per_omega"),
    ("poles_per_omega", "3", "poles_per_omega")])
def test_bad_parameters_are_refused(model, tmp_path, key, value, match):
    bad = load_model(path=robot_file_with(model, tmp_path, "lip_feedback", key, value))
    with pytest.raises(ConfigError, match=match):
        LipFeedbackParams.from_model(bad)


@pytest.mark.parametrize("height", [0.0, -0.7, float("nan")])
def test_a_bad_com_height_is_refused(model, height):
    with pytest.raises(ConfigError, match="CoM height"):
        LipFeedback.from_model(model, height)
