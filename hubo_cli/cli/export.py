"""``hubo export RUN --rrd FILE | --mcap FILE``: a run for the Rerun viewer or Foxglove Studio."""

from __future__ import annotations

import dataclasses

import click
from rich.markup import escape

from hubo_cli.cli.options import force_option
from hubo_cli.cli.output import busy, console, err_console, print_json, report_log_warnings


@click.command("export")
@click.argument("run", type=click.Path(exists=True))
@click.option("--rrd", type=click.Path(dir_okay=False), default=None, metavar="FILE.rrd",
              help="Write a Rerun recording (open with: rerun FILE.rrd).")
@click.option("--mcap", type=click.Path(dir_okay=False), default=None, metavar="FILE.mcap",
              help="Write an MCAP file in Foxglove's schemas (open in Foxglove Studio).")
@force_option
@click.option("--json", "as_json", is_flag=True, help="Print what was written as JSON.")
def export(run, rrd, mcap, force, as_json) -> None:
    """Export a run folder to Rerun (.rrd) and/or Foxglove (.mcap); needs hubo-cli[viz].

    The .rrd holds the URDF animated, the goal and measured tool paths, the hole and the walls
    in 3-D, and on the same timeline the tracking error, wrist torque, capture-point margin,
    torso pitch and events, laid out by its blueprint. The .mcap (UTC times) holds the URDF,
    joint states and frame transforms (Foxglove schemas), the scene, the scalar series and the
    events; import hubo_cli/viz/foxglove_layout.json in Foxglove for its panels.

    Example: hubo export runs/<run> --rrd run.rrd --mcap run.mcap
    """
    from hubo_cli.errors import InputError
    from hubo_cli.outputs import OutputFile
    from hubo_cli.viz.scene import load_scene

    if rrd is None and mcap is None:
        raise InputError("nothing to export: give --rrd FILE.rrd and/or --mcap FILE.mcap",
                         hint="e.g. hubo export RUN --rrd run.rrd")
    rrd_out, mcap_out = (None if path is None else OutputFile(
        path, option=option, inputs=(run,), others=(other,), force=force)
        for path, option, other in ((rrd, "--rrd", mcap), (mcap, "--mcap", rrd)))
    scene = load_scene(run)
    report: dict = {"run_dir": str(scene.run_dir), "periods": len(scene)}
    if scene.log.unfinished:  # a killed run in a folder it cannot write: nothing written there
        report["log_unfinished"] = scene.log.unfinished
        if not as_json:
            err_console.print(escape(scene.log.unfinished), soft_wrap=True)
    report_log_warnings(scene.log, report, as_json)
    if rrd_out is not None:
        from hubo_cli.viz.rerun_export import export_rrd

        with (busy(f"writing {rrd_out.path} (Rerun)", quiet=as_json),
              rrd_out.writing() as temporary):
            result = dataclasses.replace(export_rrd(scene, temporary), path=rrd_out.path)
        report["rrd"] = {"path": str(result.path), "joints": result.joints,
                         "series": result.series, "wall_s": result.wall_s}
        if not as_json:
            console.print(f"rrd   {result.path} ({len(scene)} periods, {result.joints} joints; "
                          f"open with: rerun {result.path})", soft_wrap=True)
    if mcap_out is not None:
        from hubo_cli.viz.mcap_export import LAYOUT_PATH, export_mcap

        with (busy(f"writing {mcap_out.path} (MCAP)", quiet=as_json),
              mcap_out.writing() as temporary):
            result = dataclasses.replace(export_mcap(scene, temporary), path=mcap_out.path)
        report["mcap"] = {"path": str(result.path), "messages": result.messages,
                          "wall_s": result.wall_s, "layout": str(LAYOUT_PATH)}
        if not as_json:
            counts = ", ".join(f"{t} {n}" for t, n in result.messages.items())
            console.print(f"mcap  {result.path} ({counts}; open in Foxglove with the layout "
                          f"{LAYOUT_PATH})", soft_wrap=True)
    if as_json:
        print_json(report)
