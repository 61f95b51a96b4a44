# PYTHON_ARGCOMPLETE_OK
"""The ``renderlab`` command.

User errors (bad scenario, bad arguments, missing or unwritable files) print one line
``renderlab: error: ...`` on stderr and exit with code 2; nothing is left half-written.
Heavy packages (mitsuba, bpy, dask) are imported inside the commands, so ``--help`` is instant.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from pathlib import Path

from renderlab import __version__
from renderlab.errors import UserError


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
    "campaign": "renderlab.commands.campaign",
    "report": "renderlab.commands.report",
    "publish": "renderlab.commands.report",
    "scenes": "renderlab.commands.scenes",
    "show": "renderlab.commands.show",
    "info": "renderlab.commands.info",
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
    r.add_argument("--renderer", choices=["mitsuba", "cycles"], help="override render.renderer")
    r.add_argument("--frames", type=_pos_int, metavar="N", help="render only the first N frames")
    r.add_argument("--seed", type=_nonneg_int, metavar="S", help="override render.seed")
    r.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", dest="overrides",
                   help="override a scenario key (TOML value), e.g. --set camera.width=128; repeatable")
    r.add_argument("--overwrite", action="store_true", help="replace DIR (and the --save-blend file) if it exists")
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


def cmd_render(args) -> int:
    from renderlab.pipeline import render_truthset
    from renderlab.scenario import load_scenario

    scenario, base = load_scenario(args.scenario, args.overrides)
    if getattr(args, "dry_run", False):
        from renderlab.commands.dryrun import render_dry_run

        return render_dry_run(scenario, args)
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
    from renderlab.demo import run_demo

    report, html = run_demo(Path(args.out), progress=not args.quiet)
    print(f"renderlab: demo finished; open the campaign report {html} (summary: {report})")
    return 0


def main(argv: list[str] | None = None) -> int:
    if argv is None and os.environ.get("_ARGCOMPLETE"):  # shell completion: answers and exits, before any set-up
        with contextlib.suppress(ImportError):
            import argcomplete

            argcomplete.autocomplete(build_parser())
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            raise UserError(f"a command is required ({', '.join(['render', 'demo', *_extra_commands()])}); see renderlab --help")
        handlers = {"render": cmd_render, "demo": cmd_demo}
        if args.command in handlers:
            return handlers[args.command](args)
        return _extra_commands()[args.command].run(args)
    except UserError as err:
        print(f"renderlab: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("renderlab: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
