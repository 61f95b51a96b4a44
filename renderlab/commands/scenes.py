"""``renderlab scenes``: the built-in scenarios (``scenes/``) and the studies that can run them.

One row per scenario file: its name, world and trajectory kinds, frames, the registered studies whose ``worlds``
include its world kind (``*`` marks the one ``renderlab campaign`` runs: ``campaign.study`` or the world's
default) and its one-line ``description``; then the registered studies. A scenario the campaign planner refuses
as it is (:func:`renderlab.campaign.plan.make_plan`) gets a note with the reason.

:func:`scenario_file` turns a scenario argument into a file: an existing path, or a built-in name
(``ev5_descent`` or ``ev5_descent.toml``), with "did you mean" for a near miss.
"""

from __future__ import annotations

import difflib
from pathlib import Path

from renderlab.commands.cost import check_path, frame_count
from renderlab.errors import UserError


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("scenes", help="list the built-in scenarios: world, trajectory, frames, studies")
    p.add_argument("--no-check", action="store_true",
                   help="skip the campaign planner's check of each scenario (faster)")


def builtin_names() -> list[str]:
    """Names (file stems) of the built-in scenarios, sorted."""
    from renderlab.builtin import SCENES_DIR

    return sorted(p.stem for p in SCENES_DIR.glob("*.toml") if p.is_file())


def scenario_file(text: str) -> Path:
    """A scenario argument as a file: an existing path, or the name of a built-in scenario.

    Raises
    ------
    UserError
        Neither a file nor a built-in name (with the closest built-in name, if any).
    """
    from renderlab.builtin import SCENES_DIR

    p = check_path(text, "SCENARIO")
    if p.exists():
        return p
    names = builtin_names()
    stem = p.name.removesuffix(".toml")
    if len(p.parts) == 1 and stem in names:
        return SCENES_DIR / f"{stem}.toml"
    close = difflib.get_close_matches(stem, names, n=1)
    hint = f"; did you mean '{close[0]}'?" if close else ""
    raise UserError(f"scenario {text} not found: not a file, nor a built-in scenario "
                    f"({', '.join(names) or 'none'}; see renderlab scenes){hint}")


def _studies_for(kind: str) -> list[str]:
    from renderlab import plugins

    out = []
    for name in plugins.studies.names():
        try:
            study = plugins.studies.get(name)
        except UserError:  # a broken plug-in's entry point: not listed
            continue
        if kind in getattr(study, "worlds", ()):
            out.append(name)
    return out


def scene_rows(check: bool = True) -> tuple[list[tuple[str, ...]], list[str]]:
    """(rows: name, world, trajectory, frames, studies, description; notes) of every built-in scenario."""
    from renderlab.builtin import SCENES_DIR
    from renderlab.scenario import load_scenario, read_toml

    rows, notes = [], []
    for name in builtin_names():
        path = SCENES_DIR / f"{name}.toml"
        try:
            sc, base = load_scenario(path)
        except UserError as err:
            raw = _raw_world(read_toml, path)
            rows.append((name, raw, "?", "?", "", f"(invalid: {err})"))
            continue
        studies = _studies_for(sc.world.kind)
        runs = _campaign_study(sc, base, notes, name) if check else None
        marked = [f"{s}*" if s == runs else s for s in studies]
        rows.append((name, sc.world.kind, sc.trajectory.kind, str(frame_count(sc)), ", ".join(marked) or "—",
                     sc.description or "—"))
    return rows, notes


def _raw_world(read_toml, path: Path) -> str:
    try:
        world = read_toml(path).get("world", {})
        return str(world.get("kind", "analytic")) if isinstance(world, dict) else "?"
    except UserError:
        return "?"


def _campaign_study(sc, base, notes: list[str], name: str) -> str | None:
    """The study ``renderlab campaign`` would run, or None with a note when the planner refuses the scenario."""
    from renderlab.campaign.plan import make_plan

    try:
        return make_plan(sc, base, runs=1).study
    except UserError as err:
        notes.append(f"{name}: renderlab campaign refuses it as it is: {err}")
        return None


def table(header: tuple[str, ...], rows: list[tuple[str, ...]], right: tuple[int, ...] = ()) -> list[str]:
    """Rows aligned in columns (``right``: indices of right-aligned columns); the last column is not padded."""
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]

    def line(r):
        cells = [c.rjust(w) if i in right else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths))]
        cells[-1] = r[-1]
        return "  ".join(cells).rstrip()
    return [line(header), *(line(r) for r in rows)]


def run(args) -> int:
    from renderlab import plugins
    from renderlab.builtin import SCENES_DIR

    rows, notes = scene_rows(check=not args.no_check)
    if not rows:
        raise UserError(f"no built-in scenarios in {SCENES_DIR} (install with ./setup.sh from a checkout)")
    print(f"Built-in scenarios in {SCENES_DIR}:")
    print()
    for line in table(("SCENARIO", "WORLD", "TRAJECTORY", "FRAMES", "STUDIES", "DESCRIPTION"), rows, right=(3,)):
        print(line)
    if not args.no_check:
        print("\n* the study renderlab campaign runs (campaign.study, or the world kind's default)")
    for note in notes:
        print(f"note: {note}")
    studies = []
    for name in plugins.studies.names():
        try:
            st = plugins.studies.get(name)
        except UserError as err:
            studies.append((name, "?", f"(cannot load: {err})"))
            continue
        studies.append((name, ", ".join(getattr(st, "worlds", ())), getattr(st, "description", "") or "—"))
    print()
    for line in table(("STUDY", "WORLDS", "DESCRIPTION"), studies):
        print(line)
    print(f"\nrenderlab show NAME prints a scenario's keys; renderlab render {SCENES_DIR / 'NAME.toml'} --out DIR "
          "renders it (--dry-run: what it would cost); docs/scenario_keys.md explains every key.")
    return 0
