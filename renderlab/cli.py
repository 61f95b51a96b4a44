# PYTHON_ARGCOMPLETE_OK
"""The ``renderlab`` command.

User errors (bad scenario, bad arguments, missing or unwritable files, a full disk) print one line
``renderlab: error: ...`` on stderr and exit with code 2; nothing is left half-written. Before anything
runs or is created, the whole request is checked: paths (non-empty, no NUL, components of at most 255
bytes), the scenario file (a regular file of sane size, TOML nested at most as deep as Python can parse),
``--set`` keys (plain names and list indices), numbers (finite) and the cost of the request
(:mod:`renderlab.commands.cost`; ``--allow-large`` lifts its limits). SIGINT, SIGTERM and SIGHUP clean up and exit
with 130, 143 and 129 (:mod:`renderlab.files.signals`).

Caches: every cache of a run lives under one lab cache folder, ``$RENDERLAB_CACHE`` (default
``~/.cache/renderlab``): Dr.Jit kernels, matplotlib, Blender's user folders, the XDG cache and config
folders (Blender's thumbnails, astropy's cache and config), Dask's scratch space and a per-run temporary
folder (``TMPDIR`` of the run, removed at exit), set before any heavy import; a variable the user has set is
kept. Nothing else is written to ``$HOME``.
Heavy packages (mitsuba, bpy, dask) are imported inside the commands, so ``--help`` is instant.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import secrets
import shutil
import sys
from pathlib import Path

from renderlab import __version__
from renderlab.commands import cost
from renderlab.commands.cost import check_path, load_checked
from renderlab.errors import UserError

#: environment variable → folder under the lab cache (set only when the user has not set it)
CACHE_ENV = {"DRJIT_CACHE_DIR": "drjit", "MPLCONFIGDIR": "matplotlib", "BLENDER_USER_CONFIG": "blender/config",
             "BLENDER_USER_SCRIPTS": "blender/scripts", "BLENDER_USER_DATAFILES": "blender/datafiles",
             "BLENDER_USER_EXTENSIONS": "blender/extensions", "DASK_TEMPORARY_DIRECTORY": "dask-scratch",
             "XDG_CACHE_HOME": "xdg-cache", "XDG_CONFIG_HOME": "xdg-config"}
#: folders made inside those (astropy uses ``$XDG_*_HOME/astropy`` only when it exists, else ``~/.astropy``)
CACHE_SUBFOLDERS = ("xdg-cache/astropy", "xdg-config/astropy")


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line and exit code 2."""

    def error(self, message: str):  # noqa: D401 - argparse API
        import difflib
        import re

        choice = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
        if choice:  # a mistyped command or choice: the closest valid one
            close = difflib.get_close_matches(choice[1], [c.strip(" '") for c in choice[2].split(",")], n=1)
            message += f"; did you mean '{close[0]}'?" if close else ""
        raise UserError(message)


class _DefaultsFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """``--help`` with each option's default, unless it is empty (None, false, []) or the help text gives it."""

    def _get_help_string(self, action):
        d = action.default
        if d is None or d is False or d == [] or d == "" or "default" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)


def _nonneg_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}")
    return value


def _pos_int(text: str) -> int:
    value = _nonneg_int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


#: commands that live in their own module: ``add_parser(subparsers)`` and ``run(args) -> int``.
#: Each module keeps heavy imports inside ``run`` so ``renderlab --help`` stays instant.
EXTRA_COMMANDS = {
    "measure": "renderlab.commands.measure",
    "crosscheck": "renderlab.commands.crosscheck",
    "visibility": "renderlab.commands.visibility",
    "navigation-budget": "renderlab.commands.navigation_budget",
    "campaign": "renderlab.commands.campaign",
    "report": "renderlab.commands.report",
    "publish": "renderlab.commands.report",
    "export": "renderlab.commands.export",
    "scenes": "renderlab.commands.scenes",
    "show": "renderlab.commands.show",
    "info": "renderlab.commands.info",
    "check-method": "renderlab.commands.check_method",
}


def _extra_commands() -> dict:
    import importlib
    import importlib.util

    out = {}
    for name, mod in EXTRA_COMMANDS.items():
        if importlib.util.find_spec(mod) is not None:
            out[name] = importlib.import_module(mod)
    return out


def build_parser() -> argparse.ArgumentParser:
    import functools

    p = _Parser(prog="renderlab", description="renderlab: truth images and estimator validation for optical navigation.",
                formatter_class=_DefaultsFormatter)
    p.add_argument("--version", action="version", version=f"renderlab {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND",  # every sub-command's --help shows its defaults
                           parser_class=functools.partial(_Parser, formatter_class=_DefaultsFormatter))

    r = sub.add_parser("render", help="render a scenario into a truth set")
    r.add_argument("scenario", metavar="SCENARIO", help="scenario TOML file (see scenes/)")
    r.add_argument("--out", required=True, metavar="DIR", help="truth set folder to create")
    r.add_argument("--renderer", metavar="NAME", help="override render.renderer: a registered renderer (mitsuba, "
                   "cycles, or a plug-in's)")
    r.add_argument("--frames", type=_pos_int, metavar="N", help="render only the first N frames")
    r.add_argument("--seed", type=_nonneg_int, metavar="S", help="override render.seed")
    r.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="overrides",
                   help="override a scenario key (TOML value), e.g. --set camera.width=128; repeatable")
    r.add_argument("--overwrite", action="store_true", help="replace DIR (and the --save-blend file) if it exists")
    r.add_argument("--allow-large", action="store_true",
                   help="run past the cost limits (pixels × spp × frames, memory, disk; see renderlab.commands.cost)")
    r.add_argument("--save-blend", metavar="FILE.blend",
                   help="also save the first frame's Blender scene (Cycles only), to open in Blender's GUI")
    r.add_argument("--dry-run", action="store_true",
                   help="check the request and print what would be made (frames, rays, disk), creating nothing")
    r.add_argument("--quiet", action="store_true", help="no progress bar")

    for module in dict.fromkeys(_extra_commands().values()):  # one add_parser per module (report adds publish)
        module.add_parser(sub)

    d = sub.add_parser("demo", help="the main job on built-in defaults: render, check, preview, report")
    d.add_argument("--out", default="demo_out", metavar="DIR", help="output folder (default: demo_out)")
    d.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


# ----------------------------------------------------------------------------------------- request checks
#: command → its path arguments (positional ones by their metavar)
PATH_ARGS = {"render": ("scenario", "out"), "crosscheck": ("scenario", "out"), "campaign": ("scenario", "out"),
             "measure": ("truthset", "out"), "report": ("campaign", "out"), "publish": ("campaign", "out"),
             "visibility": ("out",), "demo": ("out",), "navigation-budget": ("folder", "scenario")}


def _check_args(args) -> None:
    """Paths and numbers of any command, before it runs."""
    for name in PATH_ARGS.get(args.command, ()):
        value = getattr(args, name, None)
        if value is not None:
            check_path(value, "--out" if name == "out" else name.upper())
    for name, value in vars(args).items():
        if isinstance(value, float) and not math.isfinite(value):
            raise UserError(f"--{name.replace('_', '-')} must be a finite number, got {value}")
        if name == "seed" and isinstance(value, int) and not isinstance(value, bool) and value < 0:
            raise UserError(f"--seed must be a non-negative integer, got {value}")


def _check_overwrite_target(out: Path, scenario: Path) -> None:
    """``--overwrite`` never replaces the current folder, the scenario's folder or one holding them."""
    target = out.resolve()
    for keep in (Path.cwd().resolve(), scenario.resolve().parent):
        if keep == target or target in keep.parents:
            raise UserError(f"--overwrite would replace {target}, which holds {keep}; choose another --out")


def sweep_out(out, *, own: bool = False) -> None:
    """Remove leftover staging folders of ``out`` (earlier crashes; ``own``: this process's, after an interrupt)."""
    from renderlab.files.signals import sweep_staging

    out = Path(os.path.abspath(out))
    sweep_staging(out.parent, out.name, own=own)


# ----------------------------------------------------------------------------------------- commands
def cmd_render(args) -> int:
    from renderlab import plugins

    if args.renderer is not None:
        plugins.renderers.get(args.renderer, where="--renderer: ")  # a registered name, checked before anything
    from renderlab.commands.inputs import check_scenario_inputs

    scenario, base = load_checked(args.scenario, args.overrides)
    check_scenario_inputs(scenario, base)
    if args.overwrite:
        _check_overwrite_target(Path(args.out), Path(args.scenario))
    if getattr(args, "dry_run", False):
        from renderlab.commands.dryrun import render_dry_run

        return render_dry_run(scenario, args)
    cost.check_scenario(scenario, frames=args.frames, out=args.out, allow_large=args.allow_large,
                        what=f"render of {Path(args.scenario).name}")
    from renderlab.pipeline import render_truthset
    from renderlab.render.cycles_backend import check_blend_target, saving_blend

    blend = None
    if getattr(args, "save_blend", None):
        blend = check_blend_target(args.save_blend, args.renderer or scenario.render.renderer,
                                   overwrite=args.overwrite)
    with saving_blend(blend) as saved:
        out = render_truthset(
            scenario, base, Path(args.out), frames=args.frames, seed=args.seed, renderer=args.renderer,
            progress=not args.quiet, overwrite=args.overwrite,
        )
    print(f"renderlab: wrote truth set {out}")
    if saved is not None:
        print(f"renderlab: saved the Blender scene of the first frame to {blend}" if saved["saved"] else
              f"renderlab: warning: no Cycles frame was rendered, {blend} not written")
    return 0


def cmd_demo(args) -> int:
    from renderlab.commands.demo import run_demo

    report, html = run_demo(Path(args.out), progress=not args.quiet)
    print(f"renderlab: demo finished; open the campaign report {html} (summary: {report})")
    return 0


# ----------------------------------------------------------------------------------------- environment
def cache_root(environ=None) -> Path:
    """The lab cache folder: ``$RENDERLAB_CACHE`` or ``~/.cache/renderlab``."""
    environ = os.environ if environ is None else environ
    return Path(environ.get("RENDERLAB_CACHE") or Path("~/.cache/renderlab").expanduser()).absolute()


@contextlib.contextmanager
def lab_environment():
    """Point every cache at the lab cache folder and give the run its own temporary folder (removed at exit,
    with those of earlier runs whose process is gone); the environment is restored afterwards."""
    import tempfile

    from renderlab.files.signals import sweep_staging

    root = cache_root()
    saved = {k: os.environ.get(k) for k in (*CACHE_ENV, "TMPDIR")}
    saved_tempdir = tempfile.tempdir
    tmp = root / "tmp" / f".run.staging-{os.getpid()}-{secrets.token_hex(4)}"
    try:
        for key, sub in CACHE_ENV.items():
            if not os.environ.get(key):
                (root / sub).mkdir(parents=True, exist_ok=True)  # some readers ignore a missing folder, noisily
                os.environ[key] = str(root / sub)
        for sub in CACHE_SUBFOLDERS:
            (root / sub).mkdir(parents=True, exist_ok=True)
        tmp.mkdir(parents=True, exist_ok=True)
        sweep_staging(tmp.parent, "run")
        os.environ["TMPDIR"] = str(tmp)  # Python's tempfile (when not yet used), Blender, Dask workers
    except OSError:  # an unwritable cache folder: keep the system's temporary folder
        tmp = None
    try:
        yield root
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
        tempfile.tempdir = saved_tempdir


def _os_error_line(exc: OSError) -> str:
    """One line for an OSError that reached the command (a full or read-only disk, a missing permission)."""
    import errno

    what = exc.strerror or type(exc).__name__
    name = getattr(exc, "filename", None)
    if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EROFS):
        return f"cannot write {name or 'the output'}: {what} (the disk is full or read-only)"
    return f"{what}: {name}" if name else what


def _dispatch(args, parser) -> int:
    if args.command is None:
        parser.print_help()
        raise UserError(f"a command is required ({', '.join(['render', 'demo', *_extra_commands()])}); see renderlab --help")
    _check_args(args)
    if getattr(args, "out", None):
        sweep_out(args.out)
    handlers = {"render": cmd_render, "demo": cmd_demo}
    if args.command in handlers:
        return handlers[args.command](args)
    return _extra_commands()[args.command].run(args)


def main(argv: list[str] | None = None) -> int:
    """Run one command; every failure the user or the machine causes is one line on stderr."""
    from renderlab.files import signals

    if argv is None and os.environ.get("_ARGCOMPLETE"):  # shell completion: answers and exits, before any set-up
        with contextlib.suppress(ImportError):
            import argcomplete

            argcomplete.autocomplete(build_parser())
    with signals.handled_signals(), lab_environment():
        args = None
        try:
            parser = build_parser()
            args = parser.parse_args(argv)
            return _dispatch(args, parser)
        except UserError as err:
            print(f"renderlab: error: {err}", file=sys.stderr)
            return 2
        except KeyboardInterrupt as exc:  # also SIGTERM and SIGHUP (renderlab.files.signals.Terminated)
            if args is not None and getattr(args, "out", None):
                sweep_out(args.out, own=True)
            print(f"renderlab: {signals.describe(exc)}", file=sys.stderr)
            return signals.exit_code(exc)
        except RecursionError:
            print("renderlab: error: input nested too deeply", file=sys.stderr)
            return 2
        except MemoryError:
            print("renderlab: error: out of memory (the request is too large for this machine)", file=sys.stderr)
            return 2
        except OSError as exc:
            print(f"renderlab: error: {' '.join(_os_error_line(exc).split())}", file=sys.stderr)
            return 2


if __name__ == "__main__":
    sys.exit(main())
