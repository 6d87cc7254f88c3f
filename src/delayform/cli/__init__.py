"""The ``delayform`` command line.

Every subcommand takes an optional scenario file (TOML, see
:mod:`delayform.scenario`; without one, the paper's example) and options that
override it, calls the library, writes figures (PNG and SVG), data (CSV and
NPZ) and summaries (JSON) into ``--out`` and prints a short summary, or the
summary as JSON on stdout with ``--json``. Progress goes to stderr.

Every input error (a bad option, a malformed scenario file, an argument the
library rejects) is one line on stderr naming the problem and exit code 2;
no traceback reaches the user for an input error. So is a command that needs
an optional package not installed: the line names the extra to install.
"""

from __future__ import annotations

import re
import sys
import warnings
from typing import Any

import click

# the command modules register their commands on the group when imported
from delayform.cli import analysis, check, design, explore, gains, montecarlo, region, reports, simulation, sweep  # noqa: F401
from delayform.cli import guarantees  # noqa: F401  (guarantees for real networks)
from delayform.cli._common import _fail, cli
from delayform.errors import DelayformError, InputError, MissingExtraError

__all__ = ["cli", "main"]

# ------------------------------------------------------------------- entry
#: click >= 8.2 raises this for a group called without a command; older click prints help itself
_NO_ARGS_IS_HELP: Any = getattr(click.exceptions, "NoArgsIsHelpError", ())


#: an option quoted in a message, with the separator before it (", --dt" or " --dt")
_QUOTED_OPTION = re.compile(r"(,\s*|\s+)?(--[a-z][a-z0-9-]*)")


def command_options(argv: list[str] | None) -> set[str] | None:
    """The option names of the subcommand ``argv`` invokes; None when it names no command."""
    args = sys.argv[1:] if argv is None else argv
    name = next((a for a in args if not a.startswith("-")), None)
    command = cli.commands.get(name) if name is not None else None
    if command is None:
        return None
    return {opt for param in command.params for opt in (*param.opts, *param.secondary_opts)} | {"--help"}


def own_options(message: str, argv: list[str] | None) -> str:
    """A library message with the options the invoked command does not have left out.

    The library names the options that change a setting once for every command
    (``the window (chart.tau1_max, --tau1-max)``); ``region`` has no
    ``--tau1-max``, so its message must not advise it. Parentheses left empty
    are dropped with it.
    """
    own = command_options(argv)
    if own is None:
        return message

    def keep(match: re.Match[str]) -> str:
        return match.group(0) if match.group(2) in own else ""

    text = _QUOTED_OPTION.sub(keep, message)
    text = re.sub(r"\(\s*,\s*", "(", text)
    return re.sub(r"\s*\(\s*\)", "", text)


def _one_line_warning(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                      file: Any = None, line: str | None = None) -> None:  # fmt: skip
    """delayform's own warnings (e.g. a label the figure font cannot draw) as one line on stderr."""
    if category.__module__.startswith("delayform"):
        click.echo(f"delayform: note: {message}", err=True)
    else:
        _show_warning(message, category, filename, lineno, file, line)


_show_warning = warnings.showwarning


def main(argv: list[str] | None = None) -> None:
    """Entry point of the console script: one line and exit code 2 for every input error.

    Parameters
    ----------
    argv
        The arguments after the program name; None reads ``sys.argv``.
    """
    # a label the terminal's encoding cannot show (CJK on a latin-1 terminal) is escaped, not a crash
    for stream in (sys.stdout, sys.stderr):
        reconfigure = getattr(stream, "reconfigure", None)
        if reconfigure is not None:
            reconfigure(errors="backslashreplace")
    with warnings.catch_warnings():
        warnings.showwarning = _one_line_warning
        # a note for the user, not an error, even where warnings are errors (a test run)
        warnings.filterwarnings("always", message="the figure font")
        _main(argv)


def _main(argv: list[str] | None) -> None:
    # no file name or number holds a NUL; the operating system would refuse it with a raw ValueError
    if any("\x00" in a for a in (sys.argv[1:] if argv is None else argv)):
        _fail("an argument contains a NUL character (\\x00)")
    try:
        code = cli.main(args=argv, prog_name="delayform", standalone_mode=False)
    except _NO_ARGS_IS_HELP as exc:  # plain `delayform`: show the help
        click.echo(exc.ctx.get_help() if exc.ctx is not None else str(exc))
        sys.exit(0)
    except click.UsageError as exc:  # bad option, missing value, bad parameter
        hint = f" (see: delayform {exc.ctx.info_name} --help)" if exc.ctx is not None and exc.ctx.parent else ""
        _fail(exc.format_message().replace("\n", " ") + hint)
    except click.ClickException as exc:
        _fail(exc.format_message().replace("\n", " "))
    except click.Abort as exc:
        # click turns Ctrl-C into Abort (after the blank line that ends the terminal's ^C echo)
        interrupted = isinstance(exc.__cause__, KeyboardInterrupt)
        click.echo("delayform: interrupted; files being written were discarded, earlier outputs are intact"
                   if interrupted else "delayform: aborted", err=True)  # fmt: skip
        sys.exit(130)
    except KeyboardInterrupt:  # outside click's own handling (e.g. while it prints)
        click.echo("delayform: interrupted; files being written were discarded, earlier outputs are intact", err=True)
        sys.exit(130)
    except InputError as exc:
        _fail(own_options(str(exc).replace("\n", " "), argv))
    except MissingExtraError as exc:  # a core install: the one line says which extra to install
        _fail(str(exc))
    except DelayformError as exc:  # a computation that did not succeed: not the user's input
        _fail(own_options(str(exc).replace("\n", " "), argv), code=1)
    except OSError as exc:  # e.g. an output file name taken by a folder, a full disk
        where = f" {exc.filename}" if exc.filename else ""
        _fail(f"cannot read or write{where}: {exc.strerror or exc}")
    except MemoryError:
        _fail("ran out of memory; make the job smaller (fewer agents, a smaller grid or window)", code=1)
    sys.exit(code if isinstance(code, int) else 0)
