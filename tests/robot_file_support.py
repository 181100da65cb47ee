"""A robot file with one value changed, for the tests of the tables the modules read."""


def robot_file_with(model, tmp_path, table: str, key: str, value: str):
    """A copy of the robot file with ``[table] key = value``."""
    text = model.source.read_text()
    head, rest = text.split(f"[{table}]\n", 1)
    lines = rest.split("\n")
    for i, line in enumerate(lines):
        if line.startswith(f"{key} ="):
            lines[i] = f"{key} = {value}"
            break
    else:
        raise AssertionError(f"no {key} in [{table}]")
    path = tmp_path / "robot.toml"
    path.write_text(head + f"[{table}]\n" + "\n".join(lines))
    return path
