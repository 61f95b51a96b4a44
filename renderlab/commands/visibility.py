"""``renderlab visibility``: coastline visibility vs inclination and FOV (Straub & Christian Fig. 4)."""

from __future__ import annotations

from pathlib import Path

from renderlab.errors import UserError


def _floats(text: str) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise UserError(f"expected a comma-separated list of numbers, got {text!r}") from None
    if not vals:
        raise UserError(f"expected a comma-separated list of numbers, got {text!r}")
    return vals


def add_parser(sub) -> None:
    p = sub.add_parser("visibility", help="share of nadir images containing coastline vs inclination and FOV")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (table, contour plot)")
    p.add_argument("--altitude-km", type=float, default=1000.0, metavar="KM",
                   help="circular orbit altitude, km (150..40000)")
    p.add_argument("--inclinations", default="0,10,20,30,40,50,60,70,80,90", help="degrees, comma-separated")
    p.add_argument("--fovs", default="5,10,15,20,30,40,50,60", help="full FOV in degrees, comma-separated")
    p.add_argument("--hours", type=float, default=24.0, metavar="H", help="length of each orbit track, hours")
    p.add_argument("--cadence-s", type=float, default=30.0, metavar="S", help="time between images, seconds")
    p.add_argument("--epoch", default="2024-03-20T00:00:00Z", help="UTC epoch of the elements (sun, Earth angle)")
    p.add_argument("--daylight", action="store_true", help="count only coast lit by the sun")
    p.add_argument("--cloud-cover", type=float, default=0.0, help="cloud cover fraction in [0, 1)")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="seed of the cloud field (with --cloud-cover)")
    p.add_argument("--allow-large", action="store_true",
                   help="run past the cost limit (images per track × inclinations × FOVs; see renderlab.commands.cost)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _check(args) -> tuple[list[float], list[float]]:
    """Every argument, before anything is read or created (numbers finite, ranges, the sweep's cost)."""
    import math

    from renderlab.commands import cost
    from renderlab.worlds.earth import wgs84

    incs, fovs = _floats(args.inclinations), _floats(args.fovs)
    if not all(math.isfinite(i) and 0 <= i <= 180 for i in incs):
        raise UserError("--inclinations must be within 0..180 degrees")
    if not all(math.isfinite(f) and 0 < f < 120 for f in fovs):
        raise UserError("--fovs must be within (0, 120) degrees")
    if not (150 <= args.altitude_km <= 40000):
        raise UserError(f"--altitude-km must be 150..40000, got {args.altitude_km}")
    if not (0 <= args.cloud_cover < 1):
        raise UserError(f"--cloud-cover must be in [0, 1), got {args.cloud_cover}")
    if args.seed < 0:
        raise UserError(f"--seed must be a non-negative integer, got {args.seed}")
    cost.check_visibility(args.hours, args.cadence_s, len(incs), len(fovs), allow_large=args.allow_large)
    try:
        wgs84.parse_epoch(args.epoch)
    except ValueError:
        raise UserError(f"--epoch: not an ISO 8601 time: {args.epoch!r}") from None
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} exists and is not a folder")
    return incs, fovs


def run(args) -> int:
    from renderlab.worlds.earth.gshhg import load_gshhg
    from renderlab.worlds.earth.visibility import VisibilityOptions, visibility_sweep

    incs, fovs = _check(args)
    out = Path(args.out)
    opt = VisibilityOptions(altitude_m=args.altitude_km * 1e3, hours=args.hours, cadence_s=args.cadence_s,
                            epoch_utc=args.epoch, daylight_only=args.daylight, cloud_cover=args.cloud_cover,
                            seed=args.seed)
    rows = visibility_sweep(incs, fovs, opt, load_gshhg(), progress=not args.quiet)
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    try:
        _write_atomic(out / "visibility.csv", lambda p: _write_csv(rows, p))
        _write_atomic(out / "visibility_contour.png", lambda p: _plot(rows, p, opt))
    except BaseException:
        if created and not any(out.iterdir()):
            out.rmdir()
        raise
    print(f"renderlab: wrote {out / 'visibility.csv'} and {out / 'visibility_contour.png'}")
    return 0


def _write_csv(rows, path) -> None:
    import csv

    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def _write_atomic(path: Path, write) -> None:
    """``write(tmp)`` then rename ``tmp`` to ``path``: a full disk never leaves half a file."""
    import os
    import secrets

    tmp = path.with_name(f".{path.name}.{os.getpid()}-{secrets.token_hex(4)}")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def _plot(rows, path, opt) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from renderlab.contracts.result_folder import figure_png

    incs = sorted({r["inclination_deg"] for r in rows})
    fovs = sorted({r["fov_deg"] for r in rows})
    key = "fraction_usable" if "fraction_usable" in rows[0] else "fraction_coast"
    Z = np.array([[next(r[key] for r in rows if r["inclination_deg"] == i and r["fov_deg"] == f) for i in incs]
                  for f in fovs]) * 100
    fig, ax = plt.subplots(figsize=(6, 4.5), constrained_layout=True)
    what = "images with coastline [%]"
    if key == "fraction_usable":
        what = "images with " + ("lit " if opt.daylight_only else "") + ("clear " if opt.cloud_cover else "") + \
            "coastline [%]"
    if len(incs) > 1 and len(fovs) > 1:
        levels = np.arange(0, 5 * np.ceil(Z.max() / 5) + 5, 5)
        cs = ax.contourf(incs, fovs, Z, levels=levels, cmap="viridis")
        lines = ax.contour(incs, fovs, Z, levels=levels[::2], colors="k", linewidths=0.4)
        ax.clabel(lines, fmt="%g", fontsize=7)
        fig.colorbar(cs, label=what)
    else:
        sc = ax.scatter(np.repeat(incs, len(fovs)), np.tile(fovs, len(incs)), c=Z.T.ravel())
        fig.colorbar(sc, label=what)
    ax.set_xlabel("inclination [deg]")
    ax.set_ylabel("field of view [deg]")
    extra = (" daylight" if opt.daylight_only else "") + (f" clouds {opt.cloud_cover:.2f}" if opt.cloud_cover else "")
    ax.set_title(f"{opt.altitude_m / 1e3:.0f} km, {opt.hours:g} h from {opt.epoch_utc}, every {opt.cadence_s:g} s{extra}",
                 fontsize=9)
    try:
        path.write_bytes(figure_png(fig))  # the lab's one figure writer (100-dpi palette PNG)
    finally:
        plt.close(fig)
