"""``renderlab info PATH``: what a truth set, a campaign folder or a published study folder holds.

- truth set (``manifest.json``): scenario, world, frames, camera, renderer and variant, seed, size on disk and
  its tables (Parquet files, with row counts);
- campaign folder (``campaign.json`` and ``runs/``): scenario, study, runs finished / failed / missing, root
  seed, size on disk and the tables of the finished runs with their row counts;
- published study folder (:func:`renderlab.campaign.publish.is_published`): the same, plus the headline rows
  of ``report/summary.csv`` (else of the report's one ``*_summary.csv``) when there is one.

Nothing is written. Reading only metadata (Parquet footers, JSON), it is quick on any size of folder.
"""

from __future__ import annotations

import csv
from pathlib import Path

from renderlab.commands.cost import check_path
from renderlab.errors import UserError
from renderlab.inputs import LIMITS, check_regular

HEADLINE_ROWS = 8
_HEADLINE_NUMBERS = ("n_rows", "runs", "bias_px", "robust_sigma_px", "std_px", "gross_rate", "mean", "std",
                     "rms", "median", "mc_3sig_r_m", "anees_mean")


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("info", help="describe a truth set, a campaign folder or a published study folder")
    p.add_argument("path", metavar="PATH", help="truth set, campaign or published study folder")


def _size(n: float) -> str:
    for unit, scale in (("GiB", 1024 ** 3), ("MiB", 1024 ** 2), ("KiB", 1024)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{int(n)} B"


def disk_usage(folder: Path) -> tuple[int, int]:
    """(bytes, files) under ``folder``; links are not followed."""
    total = count = 0
    for p in Path(folder).rglob("*"):
        if p.is_file() and not p.is_symlink():
            total += p.stat().st_size
            count += 1
    return total, count


def _rows(path: Path) -> int | None:
    """Rows a Parquet footer states, or None when the file is unreadable (or not a regular file: never opened)."""
    import pyarrow.parquet as pq

    try:
        check_regular(path, "table", LIMITS["table"])
        return pq.read_metadata(str(path)).num_rows
    except (OSError, ValueError, UserError):
        return None


def _tables_text(counts: dict[str, int | None]) -> str:
    if not counts:
        return "none"
    return ", ".join(f"{n} ({'unreadable' if c is None else f'{c} rows'})" for n, c in sorted(counts.items()))


def folder_kind(path: Path) -> str:
    """``"truthset"``, ``"campaign"`` or ``"published"``; UserError for anything else (one line)."""
    from renderlab.campaign.publish import is_published

    if not path.exists():
        raise UserError(f"{path} not found")
    if path.is_file():
        hint = "; for a scenario file use renderlab show" if path.suffix == ".toml" else ""
        raise UserError(f"{path} is a file; renderlab info reads a truth set, campaign or published study folder{hint}")
    if (path / "manifest.json").is_file():
        return "truthset"
    if (path / "campaign.json").is_file():
        return "published" if is_published(path) else "campaign"
    raise UserError(f"{path} is not a truth set, campaign or published study folder (no manifest.json or "
                    "campaign.json)")


def _line(label: str, text) -> str:
    return f"  {label:<13} {text}"


def truthset_lines(path: Path) -> list[str]:
    """The description of truth set ``path``."""
    from renderlab.files.truthset import TruthSet

    ts = TruthSet.open(path)
    m, sc = ts.manifest, ts.manifest.get("scenario") or {}
    rend, world, traj = m.get("renderer") or {}, sc.get("world") or {}, sc.get("trajectory") or {}
    render = sc.get("render") or {}
    frames = ts.frames
    times = [f.get("time_s") for f in frames if isinstance(f.get("time_s"), (int, float))]
    cam = frames[0].get("camera", {}) if frames else {}
    size, files = disk_usage(ts.path)
    lines = [f"truth set {ts.path} ({m.get('format')})",
             _line("scenario", f"{sc.get('name', '?')}: {sc.get('description') or '—'}"),
             _line("world", f"{world.get('kind', '?')}, trajectory {traj.get('kind', '?')}")]
    span = f" (t = {min(times):g} … {max(times):g} s)" if times else ""
    lines.append(_line("frames", f"{len(frames)}{span}"))
    if cam:
        lines.append(_line("camera", f"{cam.get('width')} × {cam.get('height')} px, {cam.get('model', 'pinhole')}, "
                                     f"fx {cam.get('fx'):g} fy {cam.get('fy'):g}, cx {cam.get('cx'):g} "
                                     f"cy {cam.get('cy'):g}"))
    lines.append(_line("renderer", f"{rend.get('name', '?')} {rend.get('version', '')}".rstrip()
                       + (f", variant {rend['variant']}" if rend.get("variant") else "")
                       + (f"; {render['spp']} spp, max depth {render.get('max_depth')}" if "spp" in render else "")))
    lines.append(_line("seed", m.get("seed", render.get("seed", "?"))))
    lines.append(_line("size on disk", f"{_size(size)} in {files} files"))
    tables = {p.stem: _rows(p) for p in sorted(ts.path.glob("*.parquet"))}
    lines.append(_line("tables", _tables_text(tables)))
    return lines


def campaign_lines(path: Path, published: bool) -> list[str]:
    """The description of campaign (or published study) folder ``path``."""
    from renderlab.campaign import publish, store

    m = store.read_manifest(path)
    plan = m["plan"]
    sc = plan.get("scenario") or {}
    statuses = store.run_statuses(path)
    by = {s: [r for r in statuses if r.get("status") == s] for s in ("ok", "error")}
    missing = len(statuses) - len(by["ok"]) - len(by["error"])
    seed = plan.get("seed")
    entropy = seed.get("entropy") if isinstance(seed, dict) else seed
    size, files = disk_usage(path)
    what = "published study folder" if published else "campaign"
    lines = [f"{what} {path} ({m.get('format')})",
             _line("scenario", f"{sc.get('name', m.get('name', '?'))}: {sc.get('description') or '—'}"),
             _line("study", plan.get("study")),
             _line("world", f"{(sc.get('world') or {}).get('kind', '?')}, trajectory "
                            f"{(sc.get('trajectory') or {}).get('kind', '?')}"),
             _line("runs", f"{plan['runs']} planned: {len(by['ok'])} finished, {len(by['error'])} failed, "
                           f"{missing} missing"),
             _line("seed", f"{entropy} (run i: {_run_seed(seed, entropy)})")]
    if by["error"]:
        first = by["error"][0]
        lines.append(_line("first failure", f"run {first.get('run')}: {' '.join(str(first.get('error')).split())[:160]}"))
    lines.append(_line("size on disk", f"{_size(size)} in {files} files"))
    if published:
        counts = {p.stem: _rows(p) for p in sorted((path / publish.TABLES).glob("*.parquet"))}
    else:
        counts = {}
        for st in by["ok"]:
            for name in st.get("tables") or []:
                if isinstance(name, str) and name.isidentifier():
                    n = _rows(store.run_dir(path, int(st["run"])) / f"{name}.parquet")
                    counts[name] = None if n is None or counts.get(name, 0) is None else counts.get(name, 0) + n
    lines.append(_line("tables", _tables_text(counts)))
    return lines


def headline_lines(summary: Path) -> list[str]:
    """The first rows of a report's ``summary.csv``: its label columns and a few headline numbers."""
    from renderlab.commands.scenes import table

    try:
        with summary.open(newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        return [f"  (cannot read {summary}: {exc})"]
    if not rows:
        return [f"  ({summary} has no rows)"]

    def number(v: str) -> bool:
        try:
            float(v)
            return True
        except ValueError:
            return False
    cols = list(rows[0])
    labels = [c for c in cols if not number(rows[0][c] or "x")][:4]
    numbers = [c for c in _HEADLINE_NUMBERS if c in cols][:5] or [c for c in cols if c not in labels][:5]
    keep = labels + numbers

    def cell(v: str) -> str:
        v = v or ""
        if number(v) and not v.isdigit():
            v = f"{float(v):.4g}"
        return v if len(v) <= 40 else v[:39] + "…"
    body = [tuple(cell(r.get(c, "")) for c in keep) for r in rows[:HEADLINE_ROWS]]
    out = [f"headline rows of {summary}:"] + ["  " + ln for ln in table(tuple(keep), body)]
    if len(rows) > HEADLINE_ROWS:
        out.append(f"  … {len(rows) - HEADLINE_ROWS} more rows")
    return out


def run(args) -> int:
    path = check_path(args.path, "PATH")
    kind = folder_kind(path)
    if kind == "truthset":
        lines = truthset_lines(path)
    else:
        lines = campaign_lines(path, published=kind == "published")
        summary = path / "report" / "summary.csv"
        own = sorted((path / "report").glob("*_summary.csv")) if not summary.is_file() else []
        summary = own[0] if len(own) == 1 else summary  # a study's one summary under its own name
        if kind == "published" and summary.is_file():
            lines += [""] + headline_lines(summary)
    print("\n".join(lines))
    return 0


def _run_seed(seed, entropy) -> str:
    """How run i is seeded: the engine's spawn key, or the plan's own ``run_seed`` text when it differs."""
    own = seed.get("run_seed") if isinstance(seed, dict) else None
    if isinstance(own, str) and own and own != "SeedSequence(entropy, spawn_key=(run,))":
        return own.replace("entropy", str(entropy)).replace("[run]", "[i]")
    return f"SeedSequence({entropy}, spawn_key=(i,))"
