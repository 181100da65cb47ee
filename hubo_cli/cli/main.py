"""The ``hubo`` command group: each subcommand lives in its own module, imported on use."""

from __future__ import annotations

import atexit
import contextlib
import gc
import importlib
import io
import os
import signal
import sys
import threading

import click

from hubo_cli import __version__
from hubo_cli.errors import HuboError, Terminated
from hubo_cli.interrupts import INTERRUPT_SIGNALS, catching_interrupts, run_files
from hubo_cli.outputs import DISK_FULL

# command name -> "module:attribute" (modules are imported only when the command runs)
COMMANDS = {
    "fk": "hubo_cli.cli.kinematics:fk",
    "ik": "hubo_cli.cli.kinematics:ik",
    "fastrak": "hubo_cli.cli.fastrak:fastrak",
    "record": "hubo_cli.cli.fastrak:record",
    "workspace-map": "hubo_cli.cli.workspace:workspace_map",
    "sim": "hubo_cli.cli.sim:sim",
    "walk": "hubo_cli.cli.walk:walk",
    "task": "hubo_cli.cli.task:task",
    "teleop": "hubo_cli.cli.teleop:teleop",
    "sweep": "hubo_cli.cli.sweep:sweep",
    "hardware": "hubo_cli.cli.hardware:hardware",
    "replay": "hubo_cli.cli.replay:replay",
    "export": "hubo_cli.cli.export:export",
    "input": "hubo_cli.cli.input:input_group",
}


EXIT_CODES = ("Exit codes: 0 success, 1 other error or a run that did not complete, 2 bad input "
              "or configuration, 3 device trouble, 4 refused for safety (nothing moved), "
              "5 no IK solution, 130 interrupted (Ctrl-C, SIGTERM, SIGHUP or SIGQUIT).")


ARGS = "hubo.args"  # key of click's ctx.meta: the command line after ``hubo``


def replace_unencodable_output() -> None:
    """Let stdout and stderr replace what their encoding cannot write (``PYTHONIOENCODING=ascii``,
    a C locale) with ``?`` instead of failing: click.echo and rich both write through them."""
    for stream in (sys.stdout, sys.stderr):
        reconfigure = getattr(stream, "reconfigure", None)
        if reconfigure is not None:
            with contextlib.suppress(ValueError, OSError):  # a closed or detached stream
                reconfigure(errors="replace")


class _Stdout(io.RawIOBase):
    """The process's stdout whose reader may go away (``hubo walk | head -1``, ``| true``):
    once a write finds the pipe closed (EPIPE), the rest of the output is dropped, silently,
    and the command goes on to its own end and exit code (the Unix way: what nobody reads is
    not an error; the run's files and exit code still say how it went)."""

    def __init__(self, fd: int) -> None:
        super().__init__()
        self.fd, self.gone = fd, False

    def writable(self) -> bool:
        return True

    def fileno(self) -> int:
        return self.fd

    def isatty(self) -> bool:
        return os.isatty(self.fd)

    def write(self, data) -> int:
        if not self.gone:
            try:
                return os.write(self.fd, data)
            except BrokenPipeError:
                self.gone = True
        return len(data)


def quiet_broken_pipe() -> None:
    """Make ``sys.stdout`` drop what it writes after its reader has gone (see :class:`_Stdout`);
    nothing without a stdout."""
    stream = sys.stdout
    try:
        fd = stream.fileno()
    except (AttributeError, OSError, ValueError):  # none, or not a file (an embedding)
        return
    with contextlib.suppress(Exception):
        stream.flush()
    sys.stdout = io.TextIOWrapper(io.BufferedWriter(_Stdout(fd)), encoding=stream.encoding,
                                  errors=stream.errors, line_buffering=stream.line_buffering,
                                  write_through=getattr(stream, "write_through", False))


def say_now(line: str) -> None:
    """One line on stderr from a signal handler: written whole, unbuffered, no lock taken (the
    interrupted code may be inside a print); nothing if stderr is gone."""
    with contextlib.suppress(OSError, ValueError):
        os.write(sys.stderr.fileno(), f"{line}\n".encode(errors="replace"))


def report_error(exc: HuboError) -> None:
    """Print a library error on one line (plus its hint) on stderr; what else its run saw
    (``exc.events``) on one line each, in the order it happened."""
    said = str(exc)
    mine = exc.events.index(said) if said in exc.events else 0
    for event in exc.events[:mine]:
        click.echo(f"first: {event}", err=True)
    click.secho(f"error: {exc}", fg="red", err=True)
    for event in exc.events[mine + 1:]:
        click.echo(f"then: {event}", err=True)
    if exc.hint:
        click.echo(f"hint: {exc.hint}", err=True)


def _json_error(ctx: click.Context, message: str, exit_code: int, hint: str = "") -> None:
    """A command asked for ``--json`` that ends in an error before printing its document
    prints one saying so (stdout gone: nothing, as for any output)."""
    from hubo_cli.cli.output import print_json_error

    with contextlib.suppress(OSError, ValueError):
        print_json_error(ctx, message, exit_code, hint)


def _named_command(ctx: click.Context, args: list[str]) -> tuple[click.Command, str]:
    """The (sub)command a command line names, from the group of ``ctx`` down, and its path
    (``hubo hardware fake-daemon``)."""
    command, path = ctx.command, ctx.command_path
    for word in args:
        if not isinstance(command, click.Group):
            break
        if not word.startswith("-"):
            sub = command.get_command(ctx, word)
            if sub is None:
                break
            command, path = sub, f"{path} {word}"
    return command, path


def _usage_hint(exc: click.ClickException, ctx: click.Context) -> str:
    """What click's usage error tells the reader to do next: see the command's help."""
    if not isinstance(exc, click.UsageError):
        return ""
    path = (exc.ctx.command_path if exc.ctx is not None
            else _named_command(ctx, ctx.meta.get(ARGS, []))[1])
    return f"see '{path} -h'"


def with_exit_codes(command: click.Command) -> click.Command:
    """Give a command (and a group's registered subcommands) the exit codes as its epilog."""
    from hubo_cli.cli.output import note_json

    if not command.epilog:
        command.epilog = EXIT_CODES
    for param in command.params:  # an error ending a --json command prints JSON too
        if param.name == "as_json" and param.callback is None:
            param.callback = note_json
    if isinstance(command, click.Group):
        for sub in command.commands.values():
            with_exit_codes(sub)
    return command


def json_asked(exc: click.ClickException, ctx: click.Context) -> bool:
    """Whether the command a click error ends asked for ``--json``: noted by its callback, or,
    for an error while its command line was parsed (before any callback ran: an unknown
    option, a missing or bad value), a ``--json`` flag on that line (before a ``--``) of a
    command that has one."""
    from hubo_cli.cli.output import JSON_WANTED

    if ctx.meta.get(JSON_WANTED):
        return True
    args = ctx.meta.get(ARGS, [])
    command = exc.ctx.command if getattr(exc, "ctx", None) is not None else None
    if command is None:  # (click's parser leaves some out: "--to requires 3 arguments")
        command = _named_command(ctx, args)[0]
    if not any(p.name == "as_json" for p in command.params):
        return False
    return _json_on_line(ctx)


def _json_on_line(ctx: click.Context) -> bool:
    """A ``--json`` flag on the command line (before a ``--``), noted as its callback would
    note it: for an error before the callback ran."""
    from hubo_cli.cli.output import JSON_WANTED

    args = ctx.meta.get(ARGS, [])
    if "--json" in args[:args.index("--") if "--" in args else len(args)]:
        ctx.meta[JSON_WANTED] = True
    return bool(ctx.meta.get(JSON_WANTED))


class LazyGroup(click.Group):
    """A click group whose subcommands are imported when used (fast ``--help``)."""

    def resolve_command(self, ctx: click.Context, args: list[str]):
        ctx.meta.setdefault(ARGS, list(args))  # the outermost group's: the whole command line
        return super().resolve_command(ctx, args)

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(COMMANDS)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        target = COMMANDS.get(name)
        if target is None:
            return None
        module, attr = target.split(":")
        return with_exit_codes(getattr(importlib.import_module(module), attr))

    def main(self, *args, **kwargs):
        replace_unencodable_output()  # before anything is written, --help included
        # Ctrl-C and SIGTERM noted as well as raised from the start, the command's imports
        # included: one swallowed in a numba compile still ends the run before it moves
        with catching_interrupts(say=say_now):
            return super().main(*args, **kwargs)

    def invoke(self, ctx: click.Context):
        late = None
        try:  # an interrupt after a run's loop ended waits until its files and stdout are whole
            with run_files(deliver=False) as late:
                return super().invoke(ctx)
        except HuboError as exc:
            report_error(exc)
            _json_error(ctx, str(exc), exc.exit_code, exc.hint)
            ctx.exit(exc.exit_code)
        except KeyboardInterrupt as exc:
            said = "interrupted" + (f" ({exc.cause})" if isinstance(exc, Terminated) else "")
            with contextlib.suppress(OSError):  # (SIGHUP: the terminal may be gone)
                click.echo(said, err=True)
                _json_on_line(ctx)  # interrupted before its callback ran: while importing
                _json_error(ctx, said, 130)
            ctx.exit(130)
        except MemoryError:
            said = "out of memory: an input asks for far more than the machine holds"
            click.secho(f"error: {said}", fg="red", err=True)
            _json_error(ctx, said, 2)
            ctx.exit(2)
        except OSError as exc:
            where = f" ({exc.filename})" if exc.filename else ""
            click.secho(f"error: {exc.strerror or exc}{where}", fg="red", err=True)
            if exc.errno in DISK_FULL:  # the disk is the device in trouble, not the input
                hint = "free space on that disk or write elsewhere"
                click.echo(f"hint: {hint}", err=True)
                _json_error(ctx, f"{exc.strerror or exc}{where}", 3, hint)
                ctx.exit(3)
            _json_error(ctx, f"{exc.strerror or exc}{where}", 2)
            ctx.exit(2)
        except click.ClickException as exc:  # click says it on stderr (usage errors: exit 2)
            if json_asked(exc, ctx):
                _json_error(ctx, exc.format_message(), exc.exit_code, _usage_hint(exc, ctx))
            raise
        except (click.exceptions.Exit, click.exceptions.Abort):  # --help, --version: text
            raise
        except Exception as exc:  # noqa: BLE001 (a bug: say so on one line, never a traceback)
            if os.environ.get("HUBO_DEBUG"):
                raise
            said = f"internal error ({type(exc).__name__}: {exc})"
            click.secho(f"error: {said}", fg="red", err=True)
            hint = "please report this with the command line; HUBO_DEBUG=1 shows the traceback"
            click.echo(f"hint: {hint}", err=True)
            _json_error(ctx, said, 1, hint)
            ctx.exit(1)
        finally:
            if late is not None and late.cause is not None:
                click.echo(f"note: {late.cause} came after the run had ended; the run finished "
                           "and its files are complete", err=True)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]},
             epilog=EXIT_CODES)
@click.version_option(__version__, prog_name="hubo")
def main() -> None:
    """Teleoperation and task execution for the HUBO 2+ humanoid.

    Runs on the simulated Hubo by default (no hardware needed).
    """


def entry() -> None:
    """The ``hubo`` console script: :func:`main`, then a quick exit.

    Once a command has returned, its files are written and closed; what is left is the
    interpreter tearing down some 800 modules, 0.4-0.6 s on a loaded 2-core machine (measured
    against 0.02 s with ``os._exit``), which would delay the exit after SIGTERM or a dead
    robot past the second the operator is promised. So the exit handlers run, stray objects
    are finalised (an unclosed file flushes), the standard streams are flushed, and the
    process ends with ``os._exit``, Ctrl-C and SIGTERM ignored from then on (the exit code
    stands). While a non-daemon thread still runs, the normal exit (which waits for it) is
    taken instead.
    """
    quiet_broken_pipe()
    try:
        main()
        code: object = 0
    except SystemExit as exc:
        code = exc.code
    if any(thread.is_alive() and not thread.daemon and thread is not threading.main_thread()
           for thread in threading.enumerate()):
        sys.exit(code)
    if code is None:
        code = 0
    elif not isinstance(code, int):  # sys.exit("message") prints the message, exits 1
        print(code, file=sys.stderr)
        code = 1
    # the command has ended and its exit code stands: an interrupt now would only print a
    # traceback from a finaliser ("Exception ignored in: WeakKeyDictionary...") and change nothing
    for s in INTERRUPT_SIGNALS:
        signal.signal(s, signal.SIG_IGN)
    atexit._run_exitfuncs()
    gc.collect()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(code)


if __name__ == "__main__":  # pragma: no cover
    entry()
