"""The task file format: shipped tasks load, malformed files name file, line and field."""

import os
import threading

import numpy as np
import pytest
from click.testing import CliRunner
from robot_file_support import robot_file_with

from hubo_cli.cli.main import main
from hubo_cli.errors import ConfigError, SafetyError
from hubo_cli.resources import data_file
from hubo_cli.tasks.moves import check_moves
from hubo_cli.tasks.plan import make_plan
from hubo_cli.tasks.spec import (
    format_override,
    load_task,
    parse_override,
    rectangle_points,
    task_files,
)
from hubo_cli.tasks.toml_lines import field_line

RECTANGLE = data_file("tasks", "cut-rectangle.toml")


def test_shipped_tasks_load():
    names = {p.stem for p in task_files()}
    assert {"cut-rectangle", "cut-slot", "push-wall"} <= names
    for path in task_files():
        spec = load_task(path)
        assert spec.name == path.stem and spec.description
        assert spec.experiment or spec.steps[0].kind == "move"


def test_cut_rectangle_defaults_are_the_papers():
    spec = load_task("cut-rectangle")
    cut = next(s for s in spec.steps if s.kind == "follow")
    assert cut.shape["width_m"] == pytest.approx(0.150)
    assert cut.shape["height_m"] == pytest.approx(0.100)
    assert cut.shape["start"] == "upper-left" and cut.shape["direction"] == "ccw"
    assert spec.safety.wrist_torque_limit_nm == pytest.approx(1.21)
    assert spec.stance.wall_distance_m is None  # auto


def test_counter_clockwise_from_the_upper_left_goes_down_the_left_edge_first():
    # seen from behind the robot, its left (+y) is on the left
    points = rectangle_points(0.15, 0.10, (0.0, 0.0), "upper-left", "ccw")
    assert points == ((0.075, 0.05), (0.075, -0.05), (-0.075, -0.05), (-0.075, 0.05),
                      (0.075, 0.05))
    cw = rectangle_points(0.15, 0.10, (0.0, 0.0), "upper-left", "cw")
    assert cw[1] == (-0.075, 0.05)


def test_overrides_change_parameters_and_are_typed():
    spec = load_task("cut-rectangle", dict([parse_override("speed_mm_s=20"),
                                            parse_override("wall_distance_mm=480")]))
    assert spec.parameters["speed_mm_s"] == 20.0
    assert spec.stance.wall_distance_m == pytest.approx(0.480)
    assert next(s for s in spec.steps if s.kind == "follow").speed_m_s == pytest.approx(0.020)
    assert spec.overridden == {"speed_mm_s": 20.0, "wall_distance_mm": 480.0}


def test_set_reaches_a_stance_field_by_its_dotted_name():
    """``--set stance.start_mm=[-1000,0]``: a TOML list, checked as the file's own field,
    noted in ``overridden`` so the run's task copy can repeat it."""
    spec = load_task("cut-rectangle", dict([parse_override("stance.start_mm=[-1000, 0]")]))
    assert spec.stance.start_m == (-1.0, 0.0)
    assert spec.overridden == {"stance.start_mm": [-1000, 0]}
    assert format_override(spec.overridden["stance.start_mm"]) == "[-1000,0]"
    assert load_task("cut-rectangle").stance.start_m is None
    # review 19: the drill as weighed (kg), which the wrist's force estimate removes
    spec = load_task("cut-rectangle", dict([parse_override("stance.tool_mass_kg=0.9")]))
    assert spec.stance.tool_mass_kg == 0.9
    assert load_task("cut-rectangle").stance.tool_mass_kg is None


@pytest.mark.parametrize("text, message", [
    ("stance.start_mm=[1, 2", "not a list"),
    ("stance.start_mm=[20000, 0]", "within"),
    ("stance.start_mm=behind", "start_mm"),
    ("steps.depth_mm=3", "only fields of"),
    ("stance.start=[1, 2]", "unknown field"),
    ("stance.tool_mass_kg=0", "tool_mass_kg"),
    ("stance.tool_mass_kg=30", "tool_mass_kg"),
])
def test_set_of_a_bad_field_is_refused(text, message):
    with pytest.raises(ConfigError, match=message):
        load_task("cut-rectangle", dict([parse_override(text)]))


def _broken(tmp_path, old, new):
    text = RECTANGLE.read_text()
    assert old in text
    path = tmp_path / "broken.toml"
    path.write_text(text.replace(old, new, 1))
    return path, text[:text.index(old)].count("\n") + 1


@pytest.mark.parametrize("old, new, field", [
    ('speed_mm_s = 20.0', 'speed_mm_s = "fast"', "steps[4].speed_mm_s"),
    ('path = "rectangle"', 'path = "circle"', "steps[3].path"),
    ('thickness_mm = 5.0', 'thicknes_mm = 5.0', "scene.wall.thicknes_mm"),
    ('wrist_torque_limit_nm = 1.21', 'wrist_torque_limit_nm = -1', "safety.wrist_torque_limit_nm"),
    ('kind = "plunge"', 'kind = "hover"', "steps[2].kind"),
])
def test_malformed_task_names_file_line_and_field(tmp_path, old, new, field):
    path, line = _broken(tmp_path, old, new)
    with pytest.raises(ConfigError) as caught:
        load_task(path)
    error = caught.value
    assert error.path == str(path) and error.field == field and error.line == line
    assert str(error).startswith(f"{path}:{line}: [{field}]")


@pytest.mark.parametrize("old, new, field, value", [
    # a cut-rectangle written in metres (review 19): each size below what physics allows
    ("thickness_mm = 5.0", "thickness_mm = 0.005", "scene.wall.thickness_mm", "0.005 mm"),
    ("width_mm = 150.0 ", "width_mm = 0.15 ", "steps[3].width_mm", "0.15 mm"),
    ("height_mm = 100.0", "height_mm = 5.9", "steps[3].height_mm", "5.9 mm"),
    ("width_mm = 1200.0", "width_mm = 1.2", "scene.wall.width_mm", "1.2 mm"),
    ("height_mm = 2000.0", "height_mm = 2.0", "scene.wall.height_mm", "2 mm"),
    ('wall_distance_mm = "auto"', "wall_distance_mm = 0.45", "stance.wall_distance_mm",
     "0.45 mm is below the front of the robot's chest (80 mm)"),
])
def test_a_size_below_physical_sense_asks_for_the_units(tmp_path, old, new, field, value):
    path, _ = _broken(tmp_path, old, new)
    with pytest.raises(ConfigError) as caught:
        load_task(path)
    error = caught.value
    assert error.field == field and value in str(error)
    assert error.hint == "units? values are in mm"


def test_a_slot_shorter_than_the_bit_asks_for_the_units(tmp_path):
    path = tmp_path / "slot.toml"
    path.write_text(data_file("tasks", "cut-slot.toml").read_text().replace(
        "points_mm = [[150.0, 0.0], [-150.0, 0.0]]", "points_mm = [[0.15, 0.0], [-0.15, 0.0]]"))
    with pytest.raises(ConfigError, match=r"\[steps\[3\]\.points_mm\] 0\.3 mm is below the bit"):
        load_task(path)


def _robot_with(model, folder, table, key, value):
    """The robot file with ``[table] key = value``, loaded (each in its own folder:
    load_model keeps what it read by path)."""
    from hubo_cli.model import load_model

    folder.mkdir()
    return load_model(path=robot_file_with(model, folder, table, key, value))


def test_the_bounds_are_the_robot_files_the_task_runs_on(tmp_path, model):
    """The drill bit's diameter and the stop settings a task is judged against are those of
    the robot it runs on, not the shipped robot file's (main judged every task against the
    shipped 6 mm bit and 1.21 N m limit, whatever robot it was loaded for)."""
    small = {"width_mm": 15.0, "height_mm": 15.0}
    load_task("cut-rectangle", small, model=model)  # the shipped bit: 6 mm
    big_bit = _robot_with(model, tmp_path / "big", "tools.drill", "bit_radius_m", "0.01")
    with pytest.raises(ConfigError, match=r"\[steps\[3\]\.width_mm\] 15\.0 mm is below the bit's "
                                          r"diameter: no hole is that small \(20 mm\)"):
        load_task("cut-rectangle", small, model=big_bit)
    thin_bit = _robot_with(model, tmp_path / "thin", "tools.drill", "bit_radius_m", "0.001")
    with pytest.raises(ConfigError, match=r"4\.0 mm is below the bit's diameter.*\(6 mm\)"):
        load_task("cut-rectangle", {"width_mm": 4.0}, model=model)
    spec = load_task("cut-rectangle", {"width_mm": 4.0}, model=thin_bit)
    assert next(s for s in spec.steps if s.kind == "follow").shape["width_m"] == 0.004
    path, _ = _broken(tmp_path, "wrist_torque_limit_nm = 1.21", "wrist_torque_limit_nm = 1.1")
    load_task(path, model=model)  # a task may lower the robot's 1.21 N m
    weak = _robot_with(model, tmp_path / "weak", "safety", "wrist_torque_limit_nm", "1.0")
    with pytest.raises(ConfigError, match=r"1\.1 N m is above the robot file's limit of 1\.0"):
        load_task(path, model=weak)


@pytest.mark.parametrize("depth_mm, into_mm", [("2.5", "22.5"), ("-19.0", "1")])
def test_a_move_into_the_wall_is_refused_before_planning(tmp_path, model, depth_mm, into_mm):
    # review 19: the approach went straight to the cutting depth (no plunge), ran and completed
    path, _ = _broken(tmp_path, "depth_mm = -50.0            # 5 cm",
                      f"depth_mm = {depth_mm}            # 5 cm")
    with pytest.raises(SafetyError, match=rf"step 1 'raise the drill' \(a move\) takes the "
                                          rf"bit's tip {into_mm} mm into the wall"):
        make_plan(load_task(path), model)  # refused before the placement: no workspace map
    for shipped in task_files():  # a tip on the face (the tests' -20 mm) or before it is fine
        spec = load_task(shipped)
        if not spec.experiment:
            check_moves(spec, model)


@pytest.mark.parametrize("retract_to_mm, refused", [(None, True), ("-19.0", True),
                                                     ("-20.0", False)])
def test_a_move_out_of_the_wall_is_refused_before_planning(tmp_path, model, retract_to_mm,
                                                           refused):
    # review 20 (/tmp/review20/cases/tasks/move_while_in.toml): after the cut, a move slid the
    # bit 300 mm sideways out of the cardboard in 1 s (its goal at depth -25 mm, outside) and
    # main planned it: a move that starts in the wall cuts at a transfer's speed
    slide = ('[[steps]]\nkind = "move"\nname = "slide"\nto_mm = [300.0, 0.0]\n'
             'depth_mm = -25.0\nduration_s = 1.0\n\n')
    if retract_to_mm is not None:  # pull out along the bit first, to the given depth
        slide = ('[[steps]]\nkind = "retract"\nname = "out"\ndepth_mm = '
                 f'{retract_to_mm}\nspeed_mm_s = 20.0\n\n') + slide
    path = tmp_path / "slide.toml"
    path.write_text(RECTANGLE.read_text().replace('[[steps]]\nkind = "retract"',
                                                  slide + '[[steps]]\nkind = "retract"', 1))
    spec = load_task(path)
    if not refused:
        check_moves(spec, model)
        return
    left_mm = "2.5" if retract_to_mm is None else retract_to_mm.removesuffix(".0")
    with pytest.raises(SafetyError) as caught:
        make_plan(spec, model)  # refused before the placement: no workspace map
    assert (f"'slide' (a move) starts with the bit's tip {float(left_mm) + 20:g} mm in the "
            f"wall (the steps before leave it at depth_mm = {left_mm}") in str(caught.value)
    assert caught.value.hint == "pull out first with a retract step to depth_mm = -20 or less"


def test_toml_syntax_error_names_the_line(tmp_path):
    path, line = _broken(tmp_path, "height_mm = 100.0", "height_mm = = 100")
    with pytest.raises(ConfigError) as caught:
        load_task(path)
    assert caught.value.line == line and "not valid TOML" in str(caught.value)


def test_a_bad_override_names_the_parameter():
    with pytest.raises(ConfigError, match="from parameter speed_mm_s, set on the command line"):
        load_task("cut-rectangle", {"speed_mm_s": "-5"})
    with pytest.raises(ConfigError, match="no parameter 'sped_mm_s'"):
        load_task("cut-rectangle", {"sped_mm_s": 5})


def test_malformed_file_through_the_cli_is_one_line_and_exit_2(tmp_path):
    path, line = _broken(tmp_path, 'path = "rectangle"', 'path = "circle"')
    result = CliRunner().invoke(main, ["task", "run", str(path)])
    assert result.exit_code == 2
    assert f"{path}:{line}: [steps[3].path]" in result.output
    assert "Traceback" not in result.output


def test_field_line_finds_keys_inside_array_tables():
    text = "a = 1\n[[steps]]\nkind = 'x'\n[[steps]]\nkind = 'y'\nspeed = 2\n[t.u]\nv = 3\n"
    assert field_line(text, "a") == 1
    assert field_line(text, "steps[2].speed") == 6
    assert field_line(text, "steps[2].missing") == 4   # the table's header
    assert field_line(text, "t.u.v") == 8


def test_list_and_show():
    runner = CliRunner()
    listed = runner.invoke(main, ["task", "list"])
    assert listed.exit_code == 0
    assert "cut-rectangle" in listed.output and "push-wall" in listed.output
    shown = runner.invoke(main, ["task", "show", "cut-rectangle"])
    assert shown.exit_code == 0
    assert "rectangle 150 x 100 mm from the upper-left corner, ccw" in shown.output
    assert "speed_mm_s = 10.0" in shown.output
    assert runner.invoke(main, ["task", "show", "nope"]).exit_code == 2


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs as on Linux")
def test_a_task_from_a_fifo_is_read_once_and_keeps_its_text(tmp_path):
    """A FIFO task file loads (main: 'no such task file') and the spec keeps the text read, so
    the run's copy of the task (task.toml) does not read the FIFO a second time."""
    fifo = tmp_path / "task.toml"
    os.mkfifo(fifo)
    text = data_file("tasks", "cut-slot.toml").read_text()
    writer = threading.Thread(target=fifo.write_text, args=(text,), daemon=True)
    writer.start()
    spec = load_task(fifo)
    writer.join(timeout=5)
    assert spec.text == text and spec.name == "cut-slot"


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs as on Linux")
def test_a_task_fifo_nobody_writes_is_refused_within_its_wait(tmp_path, monkeypatch):
    """A FIFO task file with no writer is refused after STREAM_WAIT_S (round 12's review: a
    blocking open waited for ever, deaf to Ctrl-C and SIGTERM)."""
    import time

    import hubo_cli.streams as streams
    from hubo_cli.errors import InputError

    monkeypatch.setattr(streams, "STREAM_WAIT_S", 0.3)
    fifo = tmp_path / "silent.toml"
    os.mkfifo(fifo)
    raised: list[BaseException] = []

    def load() -> None:
        try:
            load_task(fifo)
        except BaseException as exc:  # noqa: BLE001 (handed to the test's thread)
            raised.append(exc)

    loader = threading.Thread(target=load, daemon=True)
    started = time.monotonic()
    loader.start()
    loader.join(timeout=3.0)
    if loader.is_alive():  # (the old code: unblock it, so the test fails instead of hanging)
        with open(fifo, "wb"):
            pass
        pytest.fail("a FIFO task file nobody writes was waited on past 3 s")
    assert time.monotonic() - started < 3.0
    assert len(raised) == 1 and isinstance(raised[0], InputError), raised
    assert "nothing arrived from" in str(raised[0]) and "silent.toml" in str(raised[0])


@pytest.mark.parametrize("body_front, deepest_mm", [(None, 60.0), ("-0.125", 95.0)])
def test_a_plunge_deeper_than_the_bit_allows_is_refused_at_load(tmp_path, model, body_front,
                                                               deepest_mm):
    """Review 20: a plunge was bounded by the file's 1000 mm alone (150 mm was refused only by
    the arm's reach). The drill's body meets the wall face at depth -body_front_m; the hand
    may yield 30 mm (max_offset_m) further along the bit under a thrust."""
    robot = model
    if body_front is not None:  # a longer bit: 145 mm out of the chuck
        robot = _robot_with(model, tmp_path / "long", "tools.drill", "body_front_m", body_front)
    assert deepest_mm == pytest.approx(-1000 * robot.drill.body_front_m
                                       - 1000 * robot.raw_impedance["max_offset_m"])
    plunge = "depth_mm = 2.5              # the middle of the bit"
    inside, _ = _broken(tmp_path, plunge, f"depth_mm = {deepest_mm - 0.01}  #")
    assert load_task(inside, model=robot).steps[1].depth_m == pytest.approx(deepest_mm / 1000
                                                                            - 1e-5)
    beyond, line = _broken(tmp_path, plunge, f"depth_mm = {deepest_mm + 0.01}  #")
    with pytest.raises(ConfigError) as caught:
        load_task(beyond, model=robot)
    error = caught.value
    assert error.field == "steps[2].depth_mm" and error.line == line
    assert (f"step 2 'drill in' (a plunge) to depth_mm = {deepest_mm + 0.01:g} is deeper than "
            f"the bit allows: at most depth_mm = {deepest_mm:g}") in str(error)
    assert error.hint.startswith(f"plunge to depth_mm = {deepest_mm:g} or less")
    # a retract that goes in instead of out is bounded the same
    retract = tmp_path / "retract.toml"
    retract.write_text(RECTANGLE.read_text().replace(
        "depth_mm = -50.0\nspeed_mm_s = 20.0",
        f"depth_mm = {deepest_mm + 0.01}\nspeed_mm_s = 20.0"))
    with pytest.raises(ConfigError, match=r"step 4 'pull out' \(a retract\) to depth_mm"):
        load_task(retract, model=robot)


def test_generated_plunges_are_refused_exactly_past_the_bit(tmp_path, model, rng):
    """Task files written from random depths and bits (beyond the shipped tasks' 2.5 mm),
    each judged against the bound worked out here; the command line's exit code is 2."""
    robots = {front: _robot_with(model, tmp_path / f"r{i}", "tools.drill", "body_front_m",
                                 repr(front)) for i, front in enumerate((-0.06, -0.09, -0.2))}
    text = RECTANGLE.read_text()
    refused = []
    for i in range(24):
        front = list(robots)[i % 3]
        depth_mm = float(np.round(rng.uniform(-40.0, 250.0), 3))
        path = tmp_path / f"plunge_{i}.toml"
        path.write_text(text.replace("depth_mm = 2.5 ", f"depth_mm = {depth_mm!r} ", 1))
        refused.append(depth_mm > -1000 * front - 30.0)
        if not refused[-1]:
            assert load_task(path, model=robots[front]).steps[1].depth_m == depth_mm / 1000
        else:
            with pytest.raises(ConfigError, match="deeper than the bit allows"):
                load_task(path, model=robots[front])
    assert 6 <= sum(refused) <= 18  # both sides drawn
    path.write_text(text.replace("depth_mm = 2.5 ", "depth_mm = 150.0 ", 1))
    result = CliRunner().invoke(main, ["task", "show", str(path)])
    assert result.exit_code == 2 and "at most depth_mm = 60 " in result.output
    no_yield = _robot_with(model, tmp_path / "text", "impedance", "max_offset_m", '"30 mm"')
    with pytest.raises(ConfigError, match=r"\[impedance\] needs a number max_offset_m"):
        load_task(path, model=no_yield)


@pytest.fixture(scope="module")
def hand_front_mm(model) -> float:
    """How far the hand's front lies past the hand point along the hand frame's x (mm), worked
    out here from the URDF's collision box as pinocchio places it and the arm's DH forward
    kinematics, in an arbitrary pose."""
    import pinocchio as pin

    from hubo_cli.kinematics.limb import Limb
    from hubo_cli.pin_robot import load_pin_robot
    from hubo_cli.posture import home_posture

    robot = load_pin_robot(model)
    geom = pin.buildGeomFromUrdf(robot.model, str(robot.urdf_path), pin.GeometryType.COLLISION)
    q = home_posture(model)
    arm = model.limb_slice("right-arm")
    q[arm] = [-0.5, -0.3, 0.2, -1.2, 0.3, 0.4]
    geom_data = pin.GeometryData(geom)
    pin.updateGeometryPlacements(robot.model, robot.model.createData(), geom, geom_data,
                                 robot.configuration(q))
    index = geom.getGeometryId("RWP_link_0")
    half = np.asarray(geom.geometryObjects[index].geometry.halfSide)
    box = geom_data.oMg[index]
    corners_N = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
                         ) * half @ box.rotation.T + box.translation
    T_N_hand = Limb(model, "right-arm", "hand").fk(q[arm])
    return 1000 * float(((corners_N - T_N_hand[:3, 3]) @ T_N_hand[:3, :3])[:, 0].max())


def _hand_task(path, depth_mm, thrust_n=0.0, retract_mm=-50.0, arm="right"):
    """cut-rectangle with the hand on ``arm``: its plunge to ``depth_mm`` (pressing
    ``thrust_n``), its retract to ``retract_mm``."""
    thrust = f"\nthrust_n = {thrust_n!r}" if thrust_n else ""
    text = (RECTANGLE.read_text().replace('tool = "drill"', 'tool = "hand"', 1)
            .replace('arm = "right"', f'arm = "{arm}"', 1)
            .replace("depth_mm = 2.5 ", f"depth_mm = {depth_mm!r}{thrust}  #", 1)
            .replace("depth_mm = -50.0\nspeed_mm_s = 20.0",
                     f"depth_mm = {retract_mm!r}\nspeed_mm_s = 20.0", 1))
    path.write_text(text)
    return path


@pytest.mark.parametrize("thrust_n, arm", [(0.0, "right"), (3.0, "left")])
def test_a_hand_plunge_past_the_wall_face_is_refused_at_load(tmp_path, model, hand_front_mm,
                                                              thrust_n, arm):
    """Review 21: a task with the hand had no plunge bound (the drill's alone): 60 mm planned
    and ran into the wall until the wrist-torque stop. The hand's front meets the face at
    depth -14.35 mm; pressing is a thrust's, not the plan's."""
    assert hand_front_mm == pytest.approx(14.35)
    deepest_mm = round(-hand_front_mm, 6)
    inside = _hand_task(tmp_path / "inside.toml", deepest_mm - 0.01, thrust_n, arm=arm)
    assert load_task(inside, model=model).steps[1].depth_m == pytest.approx(
        deepest_mm / 1000 - 1e-5)
    beyond = _hand_task(tmp_path / "beyond.toml", deepest_mm + 0.01, thrust_n, arm=arm)
    with pytest.raises(ConfigError) as caught:
        load_task(beyond, model=model)
    error = caught.value
    assert error.field == "steps[2].depth_mm" and error.line == field_line(
        beyond.read_text(), "steps[2].depth_mm")
    assert (f"step 2 'drill in' (a plunge) to depth_mm = {deepest_mm + 0.01:g} is deeper than "
            f"the hand allows: at most depth_mm = {deepest_mm:g} (the hand's front, 14.35 mm "
            "ahead of the hand point, meets the wall face there") in str(error)
    assert "bit" not in str(error) and "bit" not in error.hint
    assert error.hint == (f"plunge to depth_mm = {deepest_mm:g} or less; to press on the wall, "
                          "give the plunge a thrust_n (N): the hand presses with it wherever "
                          "the face is, up to 30 mm past its plan")
    # a retract that goes in instead of out is bounded the same
    retract = _hand_task(tmp_path / "retract.toml", deepest_mm - 0.01, thrust_n,
                         retract_mm=deepest_mm + 0.01, arm=arm)
    with pytest.raises(ConfigError, match=r"step 4 'pull out' \(a retract\) to depth_mm .* "
                                          "deeper than the hand allows"):
        load_task(retract, model=model)


def test_generated_hand_plunges_are_refused_exactly_past_the_face(tmp_path, model,
                                                                  hand_front_mm):
    """Task files with the hand written from random depths, thrusts and arms, each judged
    against the bound worked out here; review 21's 60 mm through the command line exits 2."""
    rng = np.random.default_rng(2121)
    refused = []
    for i in range(30):
        depth_mm = float(np.round(rng.uniform(-45.0, 15.0), 3))
        thrust_n = float(np.round(rng.uniform(0.5, 15.0), 1)) if rng.random() < 0.5 else 0.0
        path = _hand_task(tmp_path / f"hand_{i}.toml", depth_mm, thrust_n,
                          arm=("right", "left")[i % 2])
        refused.append(depth_mm > -hand_front_mm)
        if not refused[-1]:
            assert load_task(path, model=model).steps[1].depth_m == depth_mm / 1000
        else:
            with pytest.raises(ConfigError, match="deeper than the hand allows"):
                load_task(path, model=model)
    assert 8 <= sum(refused) <= 22  # both sides drawn
    result = CliRunner().invoke(main, ["task", "show", str(_hand_task(path, 60.0))])
    assert result.exit_code == 2 and "at most depth_mm = -14.35 " in result.output


@pytest.mark.parametrize("depth_mm, refused", [(-14.34, True), (-14.35, False)])
def test_a_hand_move_is_refused_once_its_front_passes_the_face(tmp_path, model, depth_mm,
                                                               refused):
    """A move stops with the hand's front (14.35 mm past the hand point) on the face at most;
    main took the hand point for its front."""
    path = _hand_task(tmp_path / "move.toml", -20.0)
    path.write_text(path.read_text().replace("depth_mm = -50.0            # 5 cm",
                                             f"depth_mm = {depth_mm}  #", 1))
    spec = load_task(path)
    if not refused:
        check_moves(spec, model)
        return
    with pytest.raises(SafetyError, match=r"step 1 'raise the drill' \(a move\) takes the hand "
                                          r"0\.01 mm into the wall \(depth_mm = -14\.34: its "
                                          r"front reaches 14\.35 mm past the hand point\)"):
        check_moves(spec, model)


def test_the_load_and_the_move_bounds_read_one_hand_front(tmp_path, model, monkeypatch):
    """The hand's front has one home (hubo_cli.tasks.tool.tool_front_m): a hand 10 mm longer
    moves both the loader's plunge bound and the planner's move bound 10 mm back (main worked
    it out in the loader and in moves.py apart: the move kept the built hand's 14.35 mm)."""
    import hubo_cli.urdf
    from hubo_cli.tasks.tool import tool_front_m

    assert tool_front_m("drill", model) == model.drill.bit_tip_m
    built_m = tool_front_m("hand", model)
    monkeypatch.setattr(hubo_cli.urdf, "hand_front_m", lambda _: built_m + 0.010)
    assert tool_front_m("hand", model) == pytest.approx(0.02435)
    with pytest.raises(ConfigError, match="at most depth_mm = -24.35 "):
        load_task(_hand_task(tmp_path / "plunge.toml", -20.0), model=model)
    path = _hand_task(tmp_path / "move.toml", -30.0)
    path.write_text(path.read_text().replace("depth_mm = -50.0            # 5 cm",
                                             "depth_mm = -20.0  #", 1))
    with pytest.raises(SafetyError, match=r"takes the hand 4\.35 mm into the wall"):
        check_moves(load_task(path, model=model), model)


PRESS_THEN_SLIDE = ('[[steps]]\nkind = "plunge"\nname = "press"\ndepth_mm = -21.0\n'
                    'speed_mm_s = 5.0\nthrust_n = 3.0\n\n{between}'
                    '[[steps]]\nkind = "move"\nname = "slide"\nto_mm = [120.0, 0.0]\n'
                    'depth_mm = -21.0\nduration_s = 1.0\n\n')


@pytest.mark.parametrize("between, refused", [
    ("", True),  # review 28: the bit yielded 19.9 mm into the cardboard and was dragged
    ('[[steps]]\nkind = "wait"\nname = "hold"\nduration_s = 1.0\n\n', True),
    ('[[steps]]\nkind = "plunge"\nname = "ease"\ndepth_mm = -21.0\nspeed_mm_s = 5.0\n\n', False),
    ('[[steps]]\nkind = "retract"\nname = "out"\ndepth_mm = -30.0\nspeed_mm_s = 20.0\n\n',
     False)])
def test_a_move_after_a_press_counts_the_hands_yield(tmp_path, model, between, refused):
    """A step pressing with a thrust may carry the tool up to the hand's yield (the robot
    file's 30 mm) past its plan, until a plunge, retract or move without a thrust takes it to a
    depth again: a move straight after it is refused (main planned it: its plan ends 1 mm
    before the face)."""
    path = tmp_path / "press.toml"
    path.write_text(RECTANGLE.read_text().replace(
        '[[steps]]\nkind = "plunge"', PRESS_THEN_SLIDE.format(between=between)
        + '[[steps]]\nkind = "plunge"', 1))
    spec = load_task(path, model=model)
    if not refused:
        check_moves(spec, model)
        return
    yield_mm = 1000 * model.impedance_max_offset_m
    with pytest.raises(SafetyError) as caught:
        check_moves(spec, model)
    assert (f"'slide' (a move) starts with the bit's tip up to {yield_mm - 1:g} mm in the wall "
            f"(the steps before leave it at depth_mm = -21, and a thrust before it may carry it "
            f"{yield_mm:g} mm past that") in str(caught.value)


def test_a_retract_deeper_than_the_tool_is_refused(tmp_path, model):
    """Review 28: a 'pull out' retract to depth_mm = 50 drove the bit through the wall and
    the run completed. A retract pulls back: one deeper than where the steps before leave the
    tool is a contradiction (exit 2); one to the same depth changes nothing and stays."""
    path, _ = _broken(tmp_path, 'name = "pull out"\ndepth_mm = -50.0',
                      'name = "pull out"\ndepth_mm = 50.0')
    with pytest.raises(ConfigError, match=r"step 4 'pull out' \(a retract\) goes deeper, to "
                                          r"depth_mm = 50, than the steps before leave the bit "
                                          r"\(depth_mm = 2\.5\)") as caught:
        check_moves(load_task(path, model=model), model)
    assert caught.value.exit_code == 2 and caught.value.hint
    path, _ = _broken(tmp_path, 'name = "pull out"\ndepth_mm = -50.0',
                      'name = "pull out"\ndepth_mm = 2.5')
    check_moves(load_task(path, model=model), model)


@pytest.mark.parametrize("depth_mm, thrust_n, cutting", [
    ("2.5", None, True), ("-10.0", None, True),  # review 28: the flutes 10 mm past the face
    ("-19.0", None, True), ("-20.0", None, False), ("-25.0", "3.0", True)])
def test_a_follow_cuts_once_the_tools_front_is_past_the_face_or_it_presses(
        tmp_path, model, depth_mm, thrust_n, cutting):
    """The plan's cutting periods (the cut's checks and figures) are where the tool's front is
    past the face (tasks.moves.in_wall, the move check's own rule) or a thrust presses it
    there; main took the bit's middle past the face, so a slot planned 10 mm before it cut the
    wall with no path check and no cut figures."""
    from hubo_cli.tasks.plan import _pieces
    from hubo_cli.tasks.tool import tool_front_m

    path, _ = _broken(tmp_path, "depth_mm = 2.5 ", f"depth_mm = {depth_mm} ")
    if thrust_n is not None:
        path.write_text(path.read_text().replace('path = "rectangle"',
                                                 f'path = "rectangle"\nthrust_n = {thrust_n}'))
    spec = load_task(path, model=model)
    _, pieces = _pieces(spec, np.eye(4), tool_front_m("drill", model))
    follow = [p for p in pieces if spec.steps[p.step].kind == "follow"]
    assert follow and all(p.cutting == cutting for p in follow)
    assert not any(p.cutting for p in pieces if spec.steps[p.step].kind != "follow")


def test_an_experiment_file_declares_only_what_its_procedure_reads(tmp_path, model):
    """Review 28: push-door with wrist_torque_limit_nm = 0.1 and a misspelt door_dge ran on
    the defaults, with no word; estop = "true" (text) was called turning the stopper off."""
    door = data_file("tasks", "push-door.toml").read_text()
    for line, message in (
            ("wrist_torque_limit_nm = 0.1", r"push-door\.toml:\d+: \[parameters\."
             r"wrist_torque_limit_nm\] the push-door experiment reads no parameter "
             r"'wrist_torque_limit_nm': setting it would change nothing"),
            ("door_dge = 30", r"reads no parameter 'door_dge'")):
        path = tmp_path / "push-door.toml"
        path.write_text(door.replace("[parameters]\n", f"[parameters]\n{line}\n", 1))
        with pytest.raises(ConfigError, match=message) as caught:
            load_task(path, model=model)
        assert caught.value.hint == "its parameters: door_opens, door_deg, impedance, estop"
    path.write_text(door.replace("estop = true", 'estop = "true"', 1))
    with pytest.raises(ConfigError, match="parameter estop must be true or false, got 'true'"):
        load_task(path, model=model)


def test_a_ramp_too_gentle_to_be_a_number_is_refused(tmp_path, model):
    """Review 28: accel_mm_s2 = 5e-324 passed as positive, became 0 m/s^2 and the planner
    took its 50 mm/s^2 instead; the gentlest ramp is the slowest speed in a second."""
    for value, refused in (("5e-324", True), ("0.09", True), ("0.1", False)):
        path, _ = _broken(tmp_path, 'direction = "ccw"',
                          f'direction = "ccw"\naccel_mm_s2 = {value}')
        if not refused:
            load_task(path, model=model)
            continue
        with pytest.raises(ConfigError, match=r"accel_mm_s2\] must be at least 0\.1") as caught:
            load_task(path, model=model)
        assert caught.value.hint == "give 0.1 or more"
