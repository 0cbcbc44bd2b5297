"""The ``lightprobe`` command: a thin layer over the Python API (argparse; rich for tables), one module a command.

Every error caused by the input or the command line prints one line ``lightprobe: error: …`` on stderr and exits
with status 2, with no traceback and no partial output file; warnings print one line ``lightprobe: warning: …``
(once per message; numpy's own runtime warnings are not shown). SIGTERM and SIGHUP end the command cleanly
(temporary files removed) with status 128 + the signal number. Each command module has ``register(sub)`` adding its
parser and ``run(args)`` doing the work; a new command adds a module and a line in :data:`COMMANDS`.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # idle OpenBLAS threads spin and slow numba's parallel kernels

import atexit
import contextlib
import importlib
import signal
import sys
import warnings

from ..util.errors import LightprobeError
from .common import Parser

# The commands, each a module of this package named as the command.
COMMANDS = ("info", "convert", "sh", "irradiance", "lights", "radiance", "error", "export", "bake", "design",
            "render", "compare", "view", "batch", "demo")


def command_module(name: str):
    """The module of command ``name`` (imported on first use)."""
    return importlib.import_module(f"{__name__}.{name}")


def build_parser(only: str | None = None) -> Parser:
    """The command line's parser: every command's, or with ``only`` that command's alone — all that running one
    command needs; the others' modules are then not imported (14 parsers and their imports were 20 ms of a 200 ms
    ``lightprobe sh``)."""
    parser = Parser(prog="lightprobe",
                    description="HDR environment maps (light probes) → lighting for real-time renderers, "
                                "checked against ground truth.")
    parser.add_argument("--version", action="version", version=f"lightprobe {_version()}")
    sub = parser.add_subparsers(title="commands", metavar="COMMAND", parser_class=Parser)
    for name in COMMANDS:
        if only is None or name == only:
            command_module(name).register(sub)
    return parser


def _named_command(argv: list[str] | None) -> str | None:
    """The command ``argv`` runs when it starts with one's name; None for anything else (``--help``, a typo), which
    the whole parser answers."""
    args = sys.argv[1:] if argv is None else argv
    return args[0] if args and args[0] in COMMANDS else None


def _version() -> str:
    from .. import __version__

    return __version__


def _one_line_warnings():
    shown: set[str] = set()

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        from ..util.errors import LightprobeWarning

        text = " ".join(str(message).split())[:500]
        if issubclass(category, LightprobeWarning) and text not in shown:
            shown.add(text)
            print(f"lightprobe: warning: {text}", file=sys.stderr)

    return show


# The optional parts of lightprobe, by the module a command found missing: the extra that installs it.
EXTRAS = {"trimesh": "render", "embreex": "render", "yaml": "render", "flip_evaluator": "render",
          "mitsuba": "reference", "drjit": "reference", "pyarrow": "batch", "distributed": "batch", "dask": "batch"}
VIEWER_MODULES = ("trimesh",)  # what `lightprobe view` needs of them: the viewer extra has it


def missing_extra(error: ModuleNotFoundError, command: str | None) -> str | None:
    """The one-line message for a command that needs an extra this installation lacks, or None when ``error`` is
    not about an optional part (a real bug: it is raised as is)."""
    top = (error.name or "").split(".")[0]
    extra = EXTRAS.get(top)
    if extra is None:
        return None
    if command == "view" and top in VIEWER_MODULES:
        extra = "viewer"
    return (f"'lightprobe {command or ''}' needs the optional {top!r} package: "
            f"pip install 'lightprobe[{extra}]'").replace("lightprobe '", "lightprobe'")


def _error(message: str) -> None:
    print(f"lightprobe: error: {' '.join(str(message).split())[:1000]}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (0 ok, 2 bad input or usage, 128 + N after signal N)."""
    from ..util.files import Terminated, raise_on_termination

    from ..util.jit import lean

    warnings.showwarning = _one_line_warnings()
    raise_on_termination()
    lean()  # numba, if a kernel runs, without scipy's BLAS: only lightprobe's kernels run here
    try:
        from ..util.limits import threads

        threads()  # a malformed LIGHTPROBE_THREADS is one line now, whether or not a kernel runs later
        parser = build_parser(_named_command(argv))
        args = parser.parse_args(argv)
        if not hasattr(args, "run"):
            parser.print_help()
            return 2
        args.run(args)
        return 0
    except SystemExit as e:  # --help and --version
        return int(e.code or 0)
    except KeyboardInterrupt:
        _error("interrupted")
        return 130
    except ModuleNotFoundError as e:
        message = missing_extra(e, _named_command(argv))
        if message is None:
            raise
        _error(message)
        return 2
    except Terminated as e:
        _error(f"stopped by {signal.Signals(e.signum).name}; no partial output was left")
        return 128 + e.signum
    except LightprobeError as e:
        _error(str(e))
        return 2
    except MemoryError:
        _error("out of memory; lower LIGHTPROBE_MAX_MEMORY so such work is refused before it starts, or use "
               "smaller sizes")
        return 2
    except OSError as e:
        _error(f"{e.strerror or e}" + (f": {e.filename}" if e.filename else ""))
        return 2


def entry() -> None:
    """The ``lightprobe`` command: :func:`main`, then an immediate exit with its status.

    Once the command returns, every output is written (atomically) and the standard streams are flushed here; what
    the interpreter's finalisation would do after that can only change the exit status, never the result. Two
    libraries make it do so: Arrow's reader threads (``batch``'s Parquet tables) can still be alive when the C++
    runtime tears their pool down, which aborts the process with SIGABRT ("terminate called without an active
    exception", apache/arrow#34314), and once numba has run a kernel, module teardown and LLVM's static objects take
    0.2–0.3 s, a fifth of a ``lightprobe lights`` run. So the command leaves with ``os._exit`` from an atexit handler
    registered first, which runs last: the handlers registered after it (numba's, tempfile's, multiprocessing's)
    have run by then. ``main`` called from Python (tests, other programs) is left to exit normally."""
    code = None

    def leave() -> None:
        if code is not None:
            for stream in (sys.stdout, sys.stderr):
                with contextlib.suppress(Exception):
                    stream.flush()
            os._exit(code)

    atexit.register(leave)
    code = main()
    sys.exit(code)


if __name__ == "__main__":
    entry()
