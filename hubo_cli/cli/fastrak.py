"""``hubo fastrak decode|emulate`` and ``hubo record``: FASTRAK recordings and a test tracker."""

from __future__ import annotations

import time
from pathlib import Path

import click

from hubo_cli.cli.checks import check_baud, check_seconds
from hubo_cli.cli.options import force_option
from hubo_cli.cli.output import console, err_console, interactive, print_json
from hubo_cli.errors import DeviceError, InputError, quoted

JSON = click.option("--json", "as_json", is_flag=True, help="Print JSON instead of text.")


def _station_rates(batch) -> dict[str, dict]:
    """Per-station record count and rate (Hz) of a decoded batch."""
    import numpy as np

    rows = {}
    for s in sorted(set(batch.station.tolist())):
        t = batch.t_s[batch.station == s]
        span = float(t[-1] - t[0]) if t.size > 1 else 0.0
        rows[str(s)] = {"records": int(t.size),
                        "rate_hz": (t.size - 1) / span if span > 0 else None,
                        "first_s": float(t[0]), "last_s": float(t[-1]),
                        "max_gap_s": float(np.max(np.diff(t))) if t.size > 1 else None}
    return rows


def _print_report(title: str, report: dict) -> None:
    from rich.table import Table

    console.print(title)
    for key in ("format", "output_list", "units", "baud", "duration_s", "good_records",
                "bad_bytes_skipped", "status_letters", "pose_log", "capture"):
        if key in report and report[key] not in (None, {}, ""):
            value = report[key]
            if key == "output_list":
                value = ",".join(map(str, value))
            elif key == "duration_s":
                value = f"{value:.3f}"
            console.print(f"  {key.replace('_', ' '):<18} {value}")
    table = Table("station", "records", "rate (Hz)", "max gap (ms)", box=None, padding=(0, 2))
    for station, row in report["stations"].items():
        rate = "-" if row["rate_hz"] is None else f"{row['rate_hz']:.1f}"
        gap = "-" if row["max_gap_s"] is None else f"{row['max_gap_s'] * 1000:.1f}"
        table.add_row(station, str(row["records"]), rate, gap)
    console.print(table)


@click.group("fastrak")
def fastrak() -> None:
    """FASTRAK tools: decode raw captures, emulate a tracker on a serial line."""


@fastrak.command("decode")
@click.argument("file", type=click.Path(path_type=Path))
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Pose-log CSV to write (default: FILE with the suffix .csv; an existing "
                   "file is not overwritten without --force).")
@force_option
@JSON
def decode(file: Path, out: Path | None, force: bool, as_json: bool) -> None:
    """Turn a raw capture FILE into a pose log and report what it holds.

    Reports good records, bytes skipped while resynchronising and per-station rates.
    """
    from hubo_cli.fastrak.capture import (
        MAGIC,
        no_records_error,
        parse_capture,
        read_recording_bytes,
        write_pose_log,
    )
    from hubo_cli.outputs import OutputFile

    blob = read_recording_bytes(file)
    if not blob.startswith(MAGIC) and blob[:40].lstrip().lower().startswith((b"t_s", b"#")):
        raise InputError(f"{file} is already a pose log (CSV), not a raw capture",
                         hint="replay it directly with `hubo teleop --replay FILE`")
    if out is None:
        out = file.with_suffix(".csv")
    pose_log = OutputFile(out, inputs=(file,), force=force)
    cap = parse_capture(blob, str(file))
    batch, bad = cap.decode()
    if len(batch) == 0:
        raise no_records_error(file, cap)
    with pose_log.writing() as temporary:
        write_pose_log(temporary, batch)
    h = cap.header
    letters: dict[str, int] = {}
    for c in batch.status_chars():
        if c != " ":
            letters[c] = letters.get(c, 0) + 1
    duration = float(cap.chunk_times[-1] - cap.chunk_times[0]) if cap.chunk_times.size else 0.0
    report = {"file": str(file), "format": h.fmt, "output_list": list(h.output_list),
              "units": h.units, "baud": h.baud, "header_stations": list(h.stations),
              "bytes": len(cap.data), "duration_s": duration, "good_records": len(batch),
              "bad_bytes_skipped": bad, "truncated": cap.truncated,
              "status_letters": letters, "stations": _station_rates(batch),
              "pose_log": str(out)}
    if as_json:
        print_json(report)
        return
    _print_report(f"decoded {file}", report)
    if cap.truncated:
        err_console.print("[yellow]warning:[/] the capture ends inside a chunk (cut short); "
                          "decoded what is there")
    console.print(f"wrote {out}", soft_wrap=True)


@fastrak.command("emulate")
@click.option("--pty", "use_pty", is_flag=True, help="Create a pseudo-terminal and print its path.")
@click.option("--port", default=None, help="Serve on this serial device instead of a pty.")
@click.option("--baud", type=int, default=115200, show_default=True, callback=check_baud,
              help="Rate for --port.")
@click.option("--from", "from_file", type=click.Path(path_type=Path), default=None,
              help="Play poses from a raw capture or pose log (looped).")
@click.option("--stations", type=int, default=None,
              help="Emulate stations 1..N (default 1, or the recording's stations).")
@click.option("--streaming", is_flag=True,
              help="Start like a unit saved in continuous binary cm mode (list 52,61,50).")
@click.option("--duration", type=float, default=None,
              help="Stop after this many seconds (default: run until Ctrl-C).")
def emulate(use_pty: bool, port: str | None, baud: int, from_file: Path | None,
            stations: int | None, streaming: bool, duration: float | None) -> None:
    """Behave like a FASTRAK on a serial line (records at 120 Hz shared by the stations).

    With --pty the path of the pseudo-terminal is printed on stdout, so
    `hubo teleop --port <path>` exercises the real serial path with no hardware.
    """
    from hubo_cli.fastrak.emulator import make_emulator

    check_seconds("--duration", duration, 7 * 24 * 3600)
    if use_pty == (port is not None):
        raise InputError("choose one of --pty or --port DEV",
                         hint="--pty creates a pseudo-terminal; --port serves a real serial port")
    emu = make_emulator(pty=use_pty, port=port, baud=baud, stations=stations,
                        from_file=from_file, streaming=streaming)
    try:
        click.echo(emu.port_name)
        motion = f"poses from {from_file}" if from_file else "built-in motion"
        err_console.print(f"emulating a FASTRAK with stations {list(emu.device.plugged)} "
                          f"({motion}) on {emu.port_name}")
        if duration is None:
            err_console.print(f"connect with: hubo teleop --port {emu.port_name}   "
                              "(Ctrl-C stops)")
        try:
            emu.serve(duration)
        except KeyboardInterrupt:
            pass
    finally:
        emu.close()
    err_console.print(f"sent {emu.records_sent} records")


def _parse_stations(text: str | None) -> tuple[int, ...] | None:
    if text is None:
        return None
    try:
        return tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise InputError(f"--stations {quoted(text)} is not a list of numbers",
                         hint="write e.g. --stations 1,2") from None


@click.command("record")
@click.option("--port", required=True, help="Serial device of the FASTRAK (or an emulator's pty).")
@click.option("--out", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Raw capture file to write.")
@click.option("--duration", type=float, default=None,
              help="Seconds to record (default: until Ctrl-C).")
@click.option("--baud", type=int, default=115200, show_default=True, callback=check_baud,
              help="Serial rate.")
@click.option("--format", "fmt", type=click.Choice(["binary", "ascii"]), default="binary",
              show_default=True, help="Record format to configure.")
@click.option("--list", "output_list", default="2,11,1", show_default=True,
              help="Output list (O command) for every station.")
@click.option("--units", type=click.Choice(["cm", "in"]), default="cm", show_default=True,
              help="Position units to configure.")
@click.option("--stations", default=None, help="Stations to enable, e.g. 1,2 (default: active).")
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Also write a pose-log CSV.")
@force_option
@JSON
def record(port: str, out: Path, duration: float | None, baud: int, fmt: str, output_list: str,
           units: str, stations: str | None, csv_path: Path | None, force: bool,
           as_json: bool) -> None:
    """Record a live FASTRAK to a raw capture (decode it later with `hubo fastrak decode`)."""
    from hubo_cli.fastrak.capture import samples_batch, write_pose_log
    from hubo_cli.fastrak.opener import open_source
    from hubo_cli.outputs import OutputFile

    check_seconds("--duration", duration, 7 * 24 * 3600)
    capture = OutputFile(out, inputs=(port,), others=(csv_path,), force=force)
    pose_log = None if csv_path is None else OutputFile(csv_path, option="--csv",
                                                         inputs=(port,), others=(out,),
                                                         force=force)
    with capture.writing(keep_partial=True) as temporary:  # a recording cut short is kept
        src = open_source(port=port, baud=baud, fmt=fmt, output_list=output_list, units=units,
                          stations=_parse_stations(stations), capture=temporary)
        samples = []
        next_note = 1.0
        lost = None  # the device lost mid-recording: what arrived is kept, then it is said
        try:
            while duration is None or src.now_s() < duration:
                samples += src.read_until(src.now_s())
                if interactive() and src.now_s() >= next_note:
                    err_console.print(f"  {src.now_s():6.1f} s  {src.stats.good_records} "
                                      "records", end="\r")
                    next_note += 1.0
                time.sleep(0.02)
            samples += src.read_until(src.now_s())
        except KeyboardInterrupt:
            pass
        except DeviceError as exc:
            lost = exc
        finally:
            src.close()
        if lost is None:
            samples += src.read_until(src.now_s())  # what closing completed (in its stats)
    batch = samples_batch(samples)
    if pose_log is not None:
        with pose_log.writing() as temporary:
            write_pose_log(temporary, batch)
    if lost is not None:
        kept = f"{out} and {csv_path}" if pose_log is not None else str(out)
        raise DeviceError(f"{lost.message}; what arrived before is kept in {kept}",
                          hint=lost.hint) from None
    stats = src.stats
    report = {"capture": str(out), "port": port, "format": fmt,
              "output_list": list(src.layout.output_list), "units": units, "baud": baud,
              "duration_s": float(batch.t_s[-1]) if len(batch) else 0.0,
              "good_records": stats.good_records, "bad_bytes_skipped": stats.bad_bytes,
              "reconnects": stats.reconnects, "status_letters": stats.status_letters,
              "stations": _station_rates(batch), "unit_status": src.unit_status,
              "pose_log": str(csv_path) if csv_path else None}
    if as_json:
        print_json(report)
        return
    _print_report(f"recorded {port} to {out}", report)
