"""Compare two copies of ``results/`` (before and after a report regeneration) and write the comparison as Markdown.

Every file is compared byte for byte. Tables (CSV), Markdown and JSON must be identical or be listed as changed
with their differing lines; an HTML page is compared as text with the SVG links taken out (``(<a href="x.svg">SVG
</a>)``), and every number in it (a regular expression over the text between tags) is compared in order. PNG and SVG
are counted and sized (the figures are redrawn, so their bytes change).

    .venv/bin/python investigations/results_compaction/compare_results_trees.py BEFORE_ROOT AFTER_ROOT > comparison.md

where each root holds a ``results/`` folder (e.g. ``git worktree``-free: ``git archive HEAD results | tar -x -C
/tmp/before``).
"""

from __future__ import annotations

import argparse
import difflib
import re
from collections import Counter, defaultdict
from pathlib import Path

SVG_LINK = re.compile(r' \(<a href="[^"]+\.svg">SVG</a>\)')
NUMBER = re.compile(r"[-+−]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")
TAG = re.compile(r"<[^>]+>")


def _files(root: Path) -> dict[str, Path]:
    res = root / "results"
    return {p.relative_to(root).as_posix(): p for p in res.rglob("*") if p.is_file() and not p.is_symlink()}


def _numbers(html: str) -> list[str]:
    return NUMBER.findall(TAG.sub(" ", html))


def _diff(a: str, b: str, n: int = 6) -> list[str]:
    out = [ln for ln in difflib.unified_diff(a.splitlines(), b.splitlines(), lineterm="", n=0)
           if not ln.startswith(("---", "+++", "@@"))]
    return out[:n] + ([f"… {len(out) - n} more lines"] if len(out) > n else [])


def main(before: Path, after: Path) -> int:
    b, a = _files(before), _files(after)
    size = defaultdict(lambda: [0, 0])
    for p in b.values():
        size[p.suffix.lower() or "(none)"][0] += p.stat().st_size
    for p in a.values():
        size[p.suffix.lower() or "(none)"][1] += p.stat().st_size
    print("## results/ by file type (bytes, decimal MB)\n")
    print("| type | before (MB) | after (MB) |\n|---|---|---|")
    for ext, (x, y) in sorted(size.items(), key=lambda kv: -kv[1][0]):
        print(f"| {ext} | {x / 1e6:.2f} | {y / 1e6:.2f} |")
    print(f"| all | {sum(v[0] for v in size.values()) / 1e6:.2f} | {sum(v[1] for v in size.values()) / 1e6:.2f} |\n")
    verdict = Counter()
    lines = []
    for k in sorted(set(b) | set(a)):
        ext = Path(k).suffix.lower()
        if ext in (".png", ".svg"):
            verdict[f"{ext} " + ("kept" if k in a and k in b else "removed" if k in b else "added")] += 1
            continue
        if k not in a:
            verdict["removed"] += 1
            lines.append(f"- `{k}`: removed")
            continue
        if k not in b:
            verdict["added"] += 1
            lines.append(f"- `{k}`: added")
            continue
        x, y = b[k].read_bytes(), a[k].read_bytes()
        if x == y:
            verdict[f"{ext} identical"] += 1
            continue
        tx, ty = x.decode("utf-8", "replace"), y.decode("utf-8", "replace")
        if ext == ".html":
            nx, ny = _numbers(SVG_LINK.sub("", tx)), _numbers(SVG_LINK.sub("", ty))
            if SVG_LINK.sub("", tx) == ty:
                verdict[".html identical but for its SVG links"] += 1
                lines.append(f"- `{k}`: identical but for {len(SVG_LINK.findall(tx))} SVG links taken out")
                continue
            verdict[".html changed"] += 1
            same = "every number the same, in order" if nx == ny else f"NUMBERS DIFFER ({len(nx)} → {len(ny)})"
            lines.append(f"- `{k}`: text changed, {same}:")
            lines += [f"    `{d[:200]}`" for d in _diff(SVG_LINK.sub("", tx), ty)]
            continue
        verdict[f"{ext} changed"] += 1
        lines.append(f"- `{k}`: changed:")
        lines += [f"    `{d[:200]}`" for d in _diff(tx, ty)]
    print("## Files compared\n")
    for key, n in sorted(verdict.items()):
        print(f"- {key}: {n}")
    print("\n## Differences (every file not byte-identical, figures aside)\n")
    print("\n".join(lines) if lines else "none")
    return 0


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description="Compare two copies of results/ and print the comparison as Markdown.")
    ap.add_argument("before", type=Path, help="root holding the results/ folder before")
    ap.add_argument("after", type=Path, help="root holding the results/ folder after")
    a = ap.parse_args()
    raise SystemExit(main(a.before, a.after))
