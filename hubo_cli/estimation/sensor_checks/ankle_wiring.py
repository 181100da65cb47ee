"""An ankle force-torque sensor wired wrong (round 20, docs/history/safety.md):

- its F_z, the foot's weight removed, below -:data:`SOLE_PULL_MAX_WEIGHTS` of the robot's
  weight (the floor pushes a sole, it cannot pull it: the sign of F_z flipped);
- the centre of pressure it gives its sole more than :data:`COP_OFF_SOLE_M` outside the sole's
  outline while it carries :data:`~.legs.SOLE_LOADED_WEIGHTS` of the robot's weight (no force
  on a sole acts outside it: the sensor turned about its z, a moment's sign flipped);
- a sole read carrying :data:`SOLE_CARRIES_WEIGHTS` of the weight more than
  :data:`SOLE_UNDER_M` above one read in the air (the estimate stands the robot on the sole its
  sensor loads; on a flat floor the other cannot lie under it: the sensors swapped between the
  feet, seen once a foot lifts);

at the start (refused) or for longer than :data:`SOLE_WIRING_OVER_S` later
(:data:`SOLE_SWAPPED_OVER_S` for a sole under the other: a healthy robot rocking on a sole's
edge reads so for a moment, as the estimate takes that sole flat); or, before a step or a
bounce, both soles more than :data:`SOLES_SUNK_M` under the floor the robot started on
(:data:`SOLES_SUNK_ROCKED_M` once a sole has rolled onto an edge: the estimate's height drifts
then; round 35) for longer than :data:`SOLE_WIRING_OVER_S` (the sensors swapped before a foot
lifts: a walk's first weight shift rocks the robot from sole to sole, and standing it on the
sole its sensor loads, the rising one, each rock carries the estimate down; round 21), or one
sunk more than :data:`SOLE_SUNK_UNDER_OTHER_M` under the other since the start while both carry
weight (the same, the estimate carrying down only the sole that stays on the floor; round 23);
or, in the first swing (until its landing), a sole read in the air more than
:data:`AIR_SOLE_UNDER_M` under the flat one read loaded for longer than
:data:`SOLE_WIRING_OVER_S` (a swapped walk that does not rock before its lift-off; round 23,
third pass). The swap rules read the soles' heights through the estimated attitude: when the
sole carrying more lies flat yet tilted more than :data:`SOLE_FLAT_TILT_MAX_DEG` in the
estimate, the fault names the IMU's attitude instead of a swap (round 22: a gyro frozen
mid-walk read as swapped sensors). A moment flipped or a sensor turned while the centre of
pressure stays near the ankle, and swapped sensors on a robot that stands without rocking, read
as a working pair does (docs/history/safety.md, rounds 20 and 21).
"""

from __future__ import annotations

import math

import numpy as np

from hubo_cli.dataflow import Store
from hubo_cli.estimation.keys import SOLES_FLAT, T_WORLD_SOLES, WRENCHES
from hubo_cli.estimation.sensor_checks.faults import sensor_fault
from hubo_cli.estimation.sensor_checks.legs import SOLE_LOADED_WEIGHTS
from hubo_cli.model import FootShape
from hubo_cli.state import ANKLE_SENSORS, RobotState

# Healthy walks, stands, pushes, the push-wall and the tasks, nominal and perturbed, both code
# paths (round 20). The floor's push on a sole, its foot's weight removed, read at least -29 N
# (a foot landing after a side push); F_z's sign flipped reads minus the sole's load, -140 N or
# less on a standing robot:
SOLE_PULL_MAX_WEIGHTS = 0.25
# A sole's centre of pressure from its sensor read at most 15.4 mm outside the sole for a
# period while it carried SOLE_LOADED_WEIGHTS (a 100 N push mid-walk), 0.6 mm held over 0.055
# s (20.5 mm for a period with 50 N: a lighter sole is not judged); a sensor turned 180 deg
# about its z puts a toe-loaded sole's 40 mm beyond its heel, turned 90 deg 65 mm beside it
COP_OFF_SOLE_M = 0.02
# A sole read carrying SOLE_CARRIES_WEIGHTS of the weight lay at most 5.0 mm above one read as
# in the air (below SOLE_IN_AIR_WEIGHTS) in the estimate (the floor flat; its tilt on a
# perturbed robot, 0.5 deg at most, is 2 mm over the 0.24 m between the soles); swapped
# sensors, the estimate stands the robot on its lifted foot: up to 50-90 mm
SOLE_UNDER_M = 0.02
SOLE_CARRIES_WEIGHTS = 0.5
SOLE_IN_AIR_WEIGHTS = 0.1
SOLE_WIRING_OVER_S = 0.05  # either for longer than this (s) after the start
# ... and a sole under the other for longer than this (s): rocking from sole to sole after a
# backward capture step (sim --step pushed 90 or 105 N backward, round 20's audit), healthy
# robots read the loaded sole, rolled on its edge and taken flat by the estimate, 21-43 mm
# above the other for up to 0.105 s in a row (11 of 22 runs stopped on SOLE_WIRING_OVER_S);
# swapped sensors on walks read so for 0.245 s (seed 1) to 0.76-0.83 s (nominal) in a row
SOLE_SWAPPED_OVER_S = 0.15
# Before a step (each sole within SOLE_STEPPED_M of where the estimate put it at the start: the
# floor under both is the one the robot started on) and before a bounce (the soles together
# carrying less than SOLE_IN_AIR_WEIGHTS of the weight: the estimate then holds no sole to the
# floor, and takes the anchor up where its sole comes down), both soles estimated more than
# SOLES_SUNK_M under that floor (round 21, docs/history/safety.md), or SOLES_SUNK_ROCKED_M once
# a sole has tilted more than SOLES_ROCKED_DEG in the estimate since the start. Healthy walks,
# pushes and tasks on seeds 1-10, both code paths, read 0.61 mm at most (a door pushed on seed
# 55, the wrist overloaded, bounced and sank 2.9 mm after its first bounce, which is not
# judged). Swapped sensors, the estimate stands the robot on the foot that rises as the walk's
# first weight shift rocks it from sole to sole, and each rock carries the estimate down: past
# 2 mm by 0.47-0.68 s (the first lift-off at 0.9 s; the fast gait's at 0.55 s, seen at 0.51 s),
# 5-40 mm later
SOLES_SUNK_M = 0.002
# Stands pushed 90 N on perturbation seeds 11-40 rock on their soles' edges, and the estimate,
# taking the rolled soles flat, drifts: both soles held up to 2.25 mm under the floor over
# 0.055 s once a sole had tilted past 2 deg (3.9 mm at an instant; seeds 23 forward and 28
# backward ended in a false swapped-sensors fault at 2 mm), 0.23 mm at most before any had (120
# runs, four directions; round 35, docs/history/safety.md). Swapped walks tilted a sole 0.8-1.65
# deg before this rule named them (nominal, seeds 5 and 2 fast), 2.63 deg on seed 41 (its first
# step); at 5 mm they pass it at 0.86-1.11 s, before or in the first step: 2.2x the healthy 2.25
SOLES_ROCKED_DEG = 2.0
SOLES_SUNK_ROCKED_M = 0.005
_ROCKED_COS = math.cos(math.radians(SOLES_ROCKED_DEG))
SOLE_STEPPED_M = 0.03
# ... and, before a step, both soles carrying at least SOLE_IN_AIR_WEIGHTS of the weight (both
# on the floor the robot started on) yet one sunk more than this under the other since the start
# (round 23, docs/history/walking.md: the ankle sensors reading the period's mean, the swapped
# walks rock less and the estimate sinks the sole that stays down, not both: seed 1's soles 0.3
# and 3.5 mm under at 0.6 s, past 2 mm together only at 0.83-0.85 s, after its first weight came
# off a foot). Healthy runs (walks normal and fast on nominal and seeds 1-10, stands pushed 90 N
# forward, backward, left and right, pushed walks, tasks; 52 a path), both code paths, held at
# most 0.50 mm for 0.055 s (a stand pushed 90 N forward, seed 4, portable; 3.0x); swapped, seed
# 1 passed 1.5 mm at 0.335 s on both paths
SOLE_SUNK_UNDER_OTHER_M = 0.0015
# In the first swing (once both soles have carried SOLE_IN_AIR_WEIGHTS at once, until the first
# landing), a sole read in the air (below SOLE_IN_AIR_WEIGHTS) more than this under the one read
# carrying SOLE_CARRIES_WEIGHTS while that one lies flat (SOLES_FLAT: its centre of pressure
# inside it) (round 23, third pass, docs/history/walking.md: with the ankle sensors reading the
# period's mean, a swapped fast-gait walk does not rock before its lift-off, and the rules above
# see nothing before a step; in the swing the estimate, standing the robot on the rising foot,
# carries the true stance, read in the air, under it). Healthy first swings, whole (the fast
# and normal walks on seeds 1-10 and nominal, the 0.6 m walk, walks pushed 100 N in the lead-in
# and in the first swing forward, backward, left and right at 0.58-1.4 s, toe-heel walks, a
# task walking to its stance, stands pushed 90-120 N, sim --step), both code paths, held at most
# 0.74 mm (the 1 m walk on seed 9, portable; 4.1x). Not flat, the loaded sole rolls on its toe
# or heel as a push in the swing tips the robot, and the estimate, taking it flat, put the
# healthy swing foot up to 12.8 mm under it before its landing; swapped, the fast gait held 3 mm
# at 0.69 s (AVX-512; portable, its loaded sole read on its edge, not)
AIR_SOLE_UNDER_M = 0.003
# ... a sole read in the air longer than this (s), then loaded again, is the first landing and
# closes that window: a walk's lead-in reads a sole in the air for a few periods as its weight
# shifts (healthy walks up to 0.075 s in a row), a step's swing for 0.55-0.65 s (0.22 s pushed)
FIRST_SWING_MIN_S = 0.2
# The swap rules above read the soles' heights through the estimated attitude: the sole carrying
# more, flat on the floor (SOLES_FLAT: its centre of pressure inside it), tilted more than this
# (deg) in the estimate says the attitude is off the legs, and the fault names the IMU (round 22,
# docs/history/safety.md). Healthy walks and pushes, both code paths, tilted a flat loaded sole
# 0.71 deg at most (a gyro biased 0.2 rad/s included), swapped sensors' walks 0.74 before their
# fault; the gyro frozen from 1 s of a 0.6 m walk tilted it 13.4-13.7 deg when the swap rule
# fired (a sole 56 mm under the other). An attitude off by less than 6 deg cannot put a sole
# 20 mm under the other 0.18 m beside it
SOLE_FLAT_TILT_MAX_DEG = 5.0


class AnkleWiring:
    """Judges every period, fresh or repeated (module docstring).

    Args:
        weight_n: the robot's weight (N), its tools included.
        period_s: the control period (s).
        feet: the soles' outline (:class:`~hubo_cli.model.FootShape`).
    """

    def __init__(self, weight_n: float, period_s: float, feet: FootShape) -> None:
        self.weight_n, self.period_s = weight_n, period_s
        corners = feet.sole_corners_m()
        self._sole_lo, self._sole_hi = corners[:, :2].min(axis=0), corners[:, :2].max(axis=0)
        self._wiring_over = 0  # periods in a row an ankle sensor read as wired wrong
        self._swapped_over = 0  # ... the two read as swapped
        self._sunk_over = 0  # ... both soles under the floor before a step
        self._soles_start = None  # where the estimate put the soles at the start (x, y, z m) ...
        self._judge_sunk = True  # ... until one leaves it (a step) or both bounce
        self._rocked = False  # ... a sole tilted past SOLES_ROCKED_DEG since the start
        self._air_under_over = 0  # ... the sole read in the air under the loaded one
        self._stood = False  # both soles have carried SOLE_IN_AIR_WEIGHTS at once
        self._air_s = [0.0, 0.0]  # each sole read in the air so long in a row (s)
        self._judge_air = True  # ... until the first landing or a bounce

    def update(self, state: RobotState, store: Store, start: bool = False) -> None:
        """An ankle sensor whose F_z pulls its sole or whose centre of pressure lies off its
        sole, or the two swapped: refused at the ``start``, a fault once it lasts longer than
        SOLE_WIRING_OVER_S (swapped: SOLE_SWAPPED_OVER_S)."""
        wrenches = store.get(WRENCHES)
        if wrenches is None:
            return
        wrong = None
        for sensor in ANKLE_SENSORS:
            w = np.asarray(wrenches[sensor], dtype=float)
            fz_n = float(w[2])
            if fz_n < -SOLE_PULL_MAX_WEIGHTS * self.weight_n:
                wrong = (sensor, f"F_z {fz_n:.0f} N, its foot's weight removed (the floor "
                                 "pushes a sole, it cannot pull it: at least "
                                 f"{-SOLE_PULL_MAX_WEIGHTS * self.weight_n:.0f} N)",
                         "its F_z's sign is flipped")
                break
            if not fz_n >= SOLE_LOADED_WEIGHTS * self.weight_n:
                continue
            cop_m = np.array([-w[4], w[3]]) / fz_n
            off_m = float(np.max(np.maximum(self._sole_lo - cop_m, cop_m - self._sole_hi)))
            if off_m > COP_OFF_SOLE_M:
                (x0, y0), (x1, y1) = self._sole_lo * 1000, self._sole_hi * 1000
                wrong = (sensor, f"its sole's centre of pressure at x {round(cop_m[0] * 1000)}, y "
                                 f"{round(cop_m[1] * 1000)} mm while the sole carries {fz_n:.0f} "
                                 f"N: {off_m * 1000:.0f} mm outside the sole (x {x0:.0f} to "
                                 f"{x1:.0f}, y {y0:.0f} to {y1:.0f} mm; at most "
                                 f"{COP_OFF_SOLE_M * 1000:.0f} mm: no force on a sole acts "
                                 "outside it)",
                         "it is turned about its z (mounted 90 or 180 deg off) or the sign of "
                         "its m_x or m_y is flipped")
                break
        swapped = self._swapped(store, wrenches)
        sunk = self._soles_sunk(store, wrenches)
        air_under = self._air_sole_under(store, wrenches)
        self._wiring_over = self._wiring_over + 1 if wrong else 0
        self._swapped_over = self._swapped_over + 1 if swapped else 0
        self._sunk_over = self._sunk_over + 1 if sunk else 0
        self._air_under_over = self._air_under_over + 1 if air_under else 0
        for found, over, over_s in ((wrong, self._wiring_over, SOLE_WIRING_OVER_S),
                                    (swapped, self._swapped_over, SOLE_SWAPPED_OVER_S),
                                    (sunk, self._sunk_over, SOLE_WIRING_OVER_S),
                                    (air_under, self._air_under_over, SOLE_WIRING_OVER_S)):
            if found is not None and (start or over * self.period_s > over_s + 1e-9):
                break
        else:
            return
        sensor, reading, cause = found
        when = ", at the start: refused before anything moved" if start else (
            f" for {over * self.period_s:.3f} s at t = {state.time_s:.2f} s")
        # (the swap rules read the soles' heights through the attitude; the others do not)
        tilted = None if found is wrong else self._flat_sole_tilted(store, wrenches)
        if tilted is not None:
            raise sensor_fault(
                f"the {sensor} force-torque sensor reads {reading}{when}; but the estimate "
                f"tilts the {tilted[0]} sole {tilted[1]:.1f} deg while its centre of pressure "
                "says it lies flat on the floor (at most "
                f"{SOLE_FLAT_TILT_MAX_DEG:g} deg): the IMU's attitude disagrees with the legs, "
                "so the soles' heights do not show the ankle sensors swapped",
                hint="the IMU reads wrong (its gyro frozen or biased), or the ankle sensors are "
                     "swapped between the feet: check the IMU's reading in hubo-daemon first, "
                     "then the ankle sensors' cables and channels, then start the run again",
                refuse=start)
        raise sensor_fault(f"the {sensor} force-torque sensor reads {reading}{when}",
                           hint=f"{cause}, or the ankle sensors are wired to the wrong channels: "
                                f"check the {sensor} sensor's mounting, its cable and "
                                "hubo-daemon's channel and sign settings for it, then start the "
                                "run again", refuse=start)

    def _flat_sole_tilted(self, store: Store, wrenches: dict) -> tuple[str, float] | None:
        """The sole carrying more (compensated F_z) that lies flat (SOLES_FLAT) yet is tilted
        more than SOLE_FLAT_TILT_MAX_DEG in the estimate: ("right"/"left", its tilt in deg),
        else None."""
        k = int(float(wrenches[ANKLE_SENSORS[1]][2]) > float(wrenches[ANKLE_SENSORS[0]][2]))
        if not store.get(SOLES_FLAT, (False, False))[k]:
            return None
        up = float(np.asarray(store[T_WORLD_SOLES], dtype=float)[k, 2, 2])
        tilt_deg = math.degrees(math.acos(max(-1.0, min(1.0, up))))
        return (("right", "left")[k], tilt_deg) if tilt_deg > SOLE_FLAT_TILT_MAX_DEG else None

    def _swapped(self, store: Store, wrenches: dict) -> tuple[str, str, str] | None:
        """A sole read carrying SOLE_CARRIES_WEIGHTS of the robot more than SOLE_UNDER_M above
        one read as in the air (below SOLE_IN_AIR_WEIGHTS): the estimate stands the robot on the
        sole its sensor loads, so the other one is under the floor."""
        T_world_soles = store.get(T_WORLD_SOLES)
        if T_world_soles is None:
            return None
        z_m = np.asarray(T_world_soles, dtype=float)[:, 2, 3]
        fz_n = [float(wrenches[sensor][2]) for sensor in ANKLE_SENSORS]
        for k, other in ((0, 1), (1, 0)):
            below_m = z_m[k] - z_m[other]
            if fz_n[k] > SOLE_CARRIES_WEIGHTS * self.weight_n and \
                    fz_n[other] < SOLE_IN_AIR_WEIGHTS * self.weight_n and below_m > SOLE_UNDER_M:
                return (ANKLE_SENSORS[k], f"F_z {fz_n[k]:.0f} N while the {ANKLE_SENSORS[other]} "
                                          f"sensor reads {fz_n[other]:.0f} N, its sole "
                                          f"{below_m * 1000:.0f} mm lower (at most "
                                          f"{SOLE_UNDER_M * 1000:.0f} mm: the sole carrying the "
                                          "robot is on the floor, the other cannot be under it)",
                        "the two ankle sensors are swapped between the feet")
        return None

    def _soles_sunk(self, store: Store, wrenches: dict) -> tuple[str, str, str] | None:
        """Before a step (each sole within SOLE_STEPPED_M of its place at the start) or a bounce
        (the soles together under SOLE_IN_AIR_WEIGHTS), both soles more than SOLES_SUNK_M under
        the floor (SOLES_SUNK_ROCKED_M once a sole has tilted past SOLES_ROCKED_DEG): the
        estimate stood the robot on a rising foot (module docstring). After
        either, never again judged (the floor there may lie elsewhere; a bounce lets the
        estimate's height float). (Scalar arithmetic: it runs every period while the robot
        stands.)"""
        T_world_soles = store.get(T_WORLD_SOLES)
        if T_world_soles is None or not self._judge_sunk:
            return None
        fz_n = [float(wrenches[sensor][2]) for sensor in ANKLE_SENSORS]
        if not fz_n[0] + fz_n[1] >= SOLE_IN_AIR_WEIGHTS * self.weight_n:
            self._judge_sunk = False
            return None
        soles = np.asarray(T_world_soles)
        (rx, ry, rz), (lx, ly, lz) = soles[:, :3, 3].tolist()
        r_up, l_up = soles[:, 2, 2].tolist()  # each sole's z axis, its world z component
        if self._soles_start is None:
            self._soles_start = (rx, ry, rz, lx, ly, lz)
        rx0, ry0, rz0, lx0, ly0, lz0 = self._soles_start
        if not (math.hypot(rx - rx0, ry - ry0) <= SOLE_STEPPED_M
                and math.hypot(lx - lx0, ly - ly0) <= SOLE_STEPPED_M):
            self._judge_sunk = False  # (or not finite)
            return None
        # a sole rolled on its edge (the z axis's tilt past SOLES_ROCKED_DEG): the estimate's
        # height has drifted since, the depth judged is SOLES_SUNK_ROCKED_M from then on
        self._rocked = self._rocked or not (r_up >= _ROCKED_COS and l_up >= _ROCKED_COS)
        sunk_m = SOLES_SUNK_ROCKED_M if self._rocked else SOLES_SUNK_M
        if not (rz < -sunk_m and lz < -sunk_m):
            return self._sole_under_other(fz_n, rz - rz0, lz - lz0)
        return ("right-ankle", f"F_z {fz_n[0]:.0f} N and the left-ankle sensor {fz_n[1]:.0f} N, "
                               "which stand the robot on soles "
                               f"{-rz * 1000:.1f} mm (right) and {-lz * 1000:.1f} mm (left) "
                               "under the floor it started on, before a step (at most "
                               f"{sunk_m * 1000:.0f} mm: the estimate stands the robot on "
                               "the sole its sensor loads, and a foot that rises as the robot "
                               "rocks carries it down)",
                "the two ankle sensors are swapped between the feet")

    def _sole_under_other(self, fz_n: list[float], right_sunk_m: float,
                          left_sunk_m: float) -> tuple[str, str, str] | None:
        """Before a step (called by :meth:`_soles_sunk`), both soles carrying at least
        SOLE_IN_AIR_WEIGHTS of the robot (on the floor the robot started on) and one sunk more
        than SOLE_SUNK_UNDER_OTHER_M under the other since the start (``right_sunk_m``,
        ``left_sunk_m``: each sole's height change in the estimate, m): the estimate stood the
        robot on a rising foot, carrying the other down."""
        if not min(fz_n) >= SOLE_IN_AIR_WEIGHTS * self.weight_n:
            return None
        under_m = left_sunk_m - right_sunk_m  # the left sole's height under the right's
        if not abs(under_m) > SOLE_SUNK_UNDER_OTHER_M:
            return None
        lower, upper = ("left", "right") if under_m < 0 else ("right", "left")
        return ("right-ankle", f"F_z {fz_n[0]:.0f} N and the left-ankle sensor {fz_n[1]:.0f} N, "
                               f"both soles on the floor, which sink the {lower} sole "
                               f"{abs(under_m) * 1000:.1f} mm under the {upper} one since the "
                               "start, before a step (at most "
                               f"{SOLE_SUNK_UNDER_OTHER_M * 1000:g} mm: two soles on the floor "
                               "the robot started on keep their heights; the estimate stands "
                               "the robot on the sole its sensor loads, and a foot that rises "
                               "as the robot rocks carries the other down)",
                "the two ankle sensors are swapped between the feet")

    def _first_swing_air_sole(self, fz_n: list[float]) -> int | None:
        """Follows the first swing as the ankle sensors' F_z read it (``fz_n``: right, left, N):
        judged once both soles have carried SOLE_IN_AIR_WEIGHTS of the robot at once (standing)
        until a sole read in the air (below it) for longer than FIRST_SWING_MIN_S reads load
        again (the first landing), or both soles together read in the air (a bounce). Returns
        the sole read in the air while the other carries SOLE_CARRIES_WEIGHTS (0 right, 1
        left), else None."""
        if not self._judge_air:
            return None
        in_air_n = SOLE_IN_AIR_WEIGHTS * self.weight_n
        self._stood = self._stood or min(fz_n) >= in_air_n
        if not self._stood:
            return None
        if not fz_n[0] + fz_n[1] >= in_air_n:
            self._judge_air = False  # (a bounce, or not finite)
            return None
        for k in (0, 1):
            if fz_n[k] < in_air_n:
                self._air_s[k] += self.period_s
            elif self._air_s[k] > FIRST_SWING_MIN_S + 1e-9:
                self._judge_air = False  # the first landing
                return None
            else:
                self._air_s[k] = 0.0
        for k, other in ((0, 1), (1, 0)):
            if fz_n[k] < in_air_n and fz_n[other] > SOLE_CARRIES_WEIGHTS * self.weight_n:
                return k
        return None

    def _air_sole_under(self, store: Store, wrenches: dict) -> tuple[str, str, str] | None:
        """In the first swing (:meth:`_first_swing_air_sole`), the sole read in the air more
        than AIR_SOLE_UNDER_M under the one read carrying SOLE_CARRIES_WEIGHTS of the robot
        while that one lies flat (SOLES_FLAT): the estimate stood the robot on the rising foot
        (module docstring)."""
        fz_n = [float(wrenches[sensor][2]) for sensor in ANKLE_SENSORS]
        air = self._first_swing_air_sole(fz_n)
        T_world_soles = store.get(T_WORLD_SOLES)
        if air is None or T_world_soles is None:
            return None
        loaded = 1 - air
        if not store.get(SOLES_FLAT, (False, False))[loaded]:
            return None  # (on its edge, the estimate taking it flat tilts the other's height)
        z_m = np.asarray(T_world_soles, dtype=float)[:, 2, 3]
        under_m = float(z_m[loaded] - z_m[air])
        if not under_m > AIR_SOLE_UNDER_M:
            return None
        sides = ("right", "left")
        return (ANKLE_SENSORS[loaded],
                f"F_z {fz_n[loaded]:.0f} N while the {ANKLE_SENSORS[air]} sensor reads "
                f"{fz_n[air]:.0f} N in the first swing, its sole {under_m * 1000:.1f} mm under "
                f"the {sides[loaded]} one (at most {AIR_SOLE_UNDER_M * 1000:g} mm: a foot in "
                "the air does not lie under the sole carrying the robot; the estimate stands the "
                "robot on the sole its sensor loads, and the foot that rose carries the other "
                "down)",
                "the two ankle sensors are swapped between the feet")
