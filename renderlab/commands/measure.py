"""``renderlab measure TRUTHSET --method NAME|module:attr [--out FILE] [--seed S]``: landmark measurements of an
EV5 truth set by any registered landmark method (see :mod:`renderlab.measurement.runner`); writes one Parquet
table and prints a one-line summary: median, robust σ and the mean without gross errors per axis."""

from __future__ import annotations

import math

from renderlab.errors import UserError
from renderlab.inputs import LIMITS, check_regular, short, shown

MAD_TO_SIGMA = 1.482602218505602  # σ of a normal distribution per unit median absolute deviation
GROSS_PX = 1.0  # |err| above this on either axis is a gross error (the reports' default), px


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("measure", help="measure the landmarks of an EV5 truth set (Retina, SPC-style, yours)")
    p.add_argument("truthset", metavar="TRUTHSET", nargs="?", help="truth set folder with a landmark catalog")
    p.add_argument("--images", metavar="APRIORI.json",
                   help="measure your own images instead of a truth set: a JSON file listing the images with their "
                        "a-priori pose, covariance and sun direction, the camera and the body frame (format: "
                        "docs/apriori_file.md; 'renderlab export TRUTHSET --apriori FILE' writes one); needs "
                        "--catalog and --out")
    p.add_argument("--catalog", metavar="DIR", help="with --images: folder holding landmarks.parquet and maplets/")
    p.add_argument("--method", required=True, metavar="NAME",
                   help="landmark method: a registered name (retina, spc, or one an installed package adds through "
                        "the 'renderlab.landmark_methods' entry point) or module:attr of your own class")
    p.add_argument("--out", metavar="FILE", help="output Parquet (default: TRUTHSET_<method>.parquet next to the truth set folder)")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="seed of the a-priori pose draws (default 0)")
    p.add_argument("--sigma-pos-m", type=float, default=0.5, metavar="M",
                   help="a-priori position 1-sigma per axis, m (default 0.5)")
    p.add_argument("--sigma-att-deg", type=float, default=0.05, metavar="DEG",
                   help="a-priori attitude 1-sigma per axis, deg (default 0.05)")
    p.add_argument("--n-sigma", type=float, default=3.0, help="search distance in sigma (default 3)")
    p.add_argument("--max-search-px", type=int, default=48, help="largest search distance, px (default 48)")
    p.add_argument("--peak", metavar="FINDER",
                   help="sub-pixel peak finder of estimators.landmarks.peaks (retina_3x3, parabola_1d, quadric_2d, "
                        "gaussian_2d, gaussian, upsampled; default: the method's own, retina_3x3 for retina)")
    p.add_argument("--min-correlation", type=float, default=0.3, help="correlation threshold (default 0.3)")
    p.add_argument("--photometry", choices=["fitted", "fixed"], default="fitted",
                   help="both methods' McEwen weight: L(phase) fitted to the body's catalogued law (default) or exp(-phase/60 deg)")
    p.add_argument("--psf-sigma-px", type=float, default=0.0, help="Retina's PSF sigma, px (default 0)")
    p.add_argument("--campaign", default="", help="campaign name written in every row")
    p.add_argument("--overwrite", action="store_true", help="replace FILE if it exists")
    p.add_argument("--timings", choices=["inline", "separate"], default="inline",
                   help="separate: timing columns (t_ms) NaN in FILE and their values in FILE's .timings.parquet "
                        "sibling, so the same seed gives a byte-identical FILE")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


#: upper bounds of measure's number flags (physical ranges: a search of 4096 px, 1e6 m of a-priori position error)
FLAG_LIMITS = {"sigma_pos_m": 1e6, "sigma_att_deg": 180.0, "n_sigma": 100.0, "psf_sigma_px": 1000.0,
               "max_search_px": 4096}


def read_checked_catalog(folder):
    """The maplets of a catalogue folder (:func:`renderlab.worlds.ev5.catalog.read_catalog`) with its table's schema
    (:data:`renderlab.contracts.schemas.LANDMARK_CATALOG`) checked first and every centre finite and bounded."""
    from pathlib import Path

    import numpy as np

    from renderlab.contracts.file_models import POSITION_MAX_M
    from renderlab.contracts.schemas import LANDMARK_CATALOG, read_parquet
    from renderlab.worlds.ev5.catalog import read_catalog

    table_path = Path(folder) / "landmarks.parquet"
    if table_path.exists() or table_path.is_symlink():
        read_parquet(table_path, f"landmark catalogue {shown(table_path)}", schema=LANDMARK_CATALOG)
    maplets = read_catalog(Path(folder))
    for m in maplets:
        c = np.asarray(m.center_m, float)
        if not (np.all(np.isfinite(c)) and np.all(np.abs(c) <= POSITION_MAX_M)):
            raise UserError(f"landmark catalogue {shown(table_path)}: landmark {m.landmark_id} has a centre that is "
                            "not finite or not physical")
    return maplets


def run(args) -> int:
    from pathlib import Path

    import numpy as np

    from renderlab.files.truthset import TruthSet
    from renderlab.measurement.runner import MeasureOptions, make_method, measure_truthset, write_table

    if args.seed < 0:
        raise UserError(f"--seed must be >= 0, got {args.seed}")
    if args.peak is not None:
        from estimators.landmarks.peaks import FINDERS

        if args.peak not in FINDERS:
            raise UserError(f"--peak: unknown peak finder {short(args.peak)} (choose from {', '.join(FINDERS)})")
    for name, hi in FLAG_LIMITS.items():
        v = getattr(args, name)
        if not math.isfinite(v) or not 0 <= v <= hi:
            raise UserError(f"--{name.replace('_', '-')} must be a finite number in 0..{hi:g}, got {v:g}")
    if not -1.0 <= args.min_correlation <= 1.0:
        raise UserError(f"--min-correlation must be in -1..1, got {args.min_correlation:g}")
    opts = MeasureOptions(sigma_pos_m=(args.sigma_pos_m,) * 3, sigma_att_rad=(math.radians(args.sigma_att_deg),) * 3,
                          n_sigma=args.n_sigma, max_search_px=args.max_search_px, peak=args.peak,
                          min_correlation=args.min_correlation, psf_sigma_px=args.psf_sigma_px,
                          photometry=args.photometry, campaign=args.campaign)
    from renderlab import plugins
    from renderlab.commands.references import check_landmark_method

    if args.method not in plugins.landmark_methods and ":" in str(args.method):
        check_landmark_method(args.method)  # imported and checked against the protocol before anything calls it
    try:  # an unknown name fails before anything is read; the user's class is constructed once here
        method = make_method(args.method, opts, allow_reference=True)
    except UserError:
        raise
    except Exception as exc:  # noqa: BLE001 - the user's method class failed to construct
        raise UserError(f"--method {short(args.method)}: constructing it raised {type(exc).__name__}: "
                        f"{short(str(exc), 120)}") from None
    if args.images is not None or args.truthset is None:
        return _run_images(args, opts)
    ts = TruthSet.open(args.truthset)
    if not (ts.path / "landmarks.parquet").is_file():
        raise UserError(f"truth set {ts.path} has no landmark catalog (landmarks.parquet); "
                        "measure needs an EV5 truth set")
    try:
        import renderlab.worlds.ev5.catalog  # noqa: F401  (the catalogue reader is installed)
    except ImportError:
        raise UserError("the EV5 catalog reader (renderlab.worlds.ev5.catalog) is not installed") from None
    maplets = read_checked_catalog(ts.path)
    out = Path(args.out) if args.out else ts.path.parent / f"{ts.path.name}_{method.name}.parquet"
    if out.exists() and not args.overwrite:
        raise UserError(f"output {out} exists (use --overwrite to replace it)")
    table = measure_truthset(ts, maplets, args.method, opts, np.random.default_rng(args.seed), progress=not args.quiet,
                             allow_reference=True)
    write_table(*_split(table, out, args), overwrite=args.overwrite)
    print(f"renderlab: {table.num_rows} {method.name} measurements -> {out}")
    print(f"renderlab: {summary_line(table)}")
    return 0


def _split(table, out, args):
    """(table, out) to write; with ``--timings separate`` the timings go to ``<out>.timings.parquet`` first."""
    if getattr(args, "timings", "inline") != "separate":
        return table, out
    from renderlab.campaign.executors import split_timings
    from renderlab.measurement.runner import write_table

    tables, side = split_timings({"measurements": table})
    if side is not None:
        write_table(side, out.with_name(out.stem + ".timings.parquet"), overwrite=args.overwrite)
    return tables["measurements"], out


def summary_line(table, gross_px: float = GROSS_PX) -> str:
    """One line of robust statistics of ``err = meas − truth`` among the rows with a result.

    Per axis: the median (robust location) and the robust σ (1.4826 · MAD about the median), then the mean over the
    results that are not gross errors. A gross error is a result with ``|err| > gross_px`` on either axis (the
    reports' definition, :mod:`renderlab.report.landmark_stats`); how many were excluded from that mean is stated,
    and the mean over all results is printed only labelled as such (one wild match moves it by far more than the
    median: −0.346 px beside a median of −0.021 px on a published table).
    """
    import numpy as np

    has = np.asarray(table.column("has_result").to_pylist(), bool)
    es, el = (np.asarray(table.column(f"err_{a}").to_numpy(zero_copy_only=False), float) for a in "sl")
    ok = has & np.isfinite(es) & np.isfinite(el)
    gross = ok & ((np.abs(es) > gross_px) | (np.abs(el) > gross_px))
    n_ok, n_gross = int(ok.sum()), int(gross.sum())
    parts = [f"{int(has.sum())}/{table.num_rows} with a result"]
    if n_ok:
        parts.append(f"{n_gross} gross error{'s' if n_gross != 1 else ''} (|err| > {gross_px:g} px) excluded from "
                     "the mean")
    for e, name in ((es, "sample"), (el, "line")):
        e_ok, e_kept = e[ok], e[ok & ~gross]
        if not e_ok.size:
            continue
        med = float(np.median(e_ok))
        text = (f"{name} median {med:+.3f} px, robust sigma {MAD_TO_SIGMA * float(np.median(np.abs(e_ok - med))):.3f}"
                f" px, mean without gross errors ")
        text += f"{float(e_kept.mean()):+.3f} px" if e_kept.size else "n/a"
        parts.append(text + f" (mean of all results {float(e_ok.mean()):+.3f} px)")
    return "; ".join(parts)


def _run_images(args, opts) -> int:
    """``--images APRIORI.json --catalog DIR --out FILE``: own images, no truth set."""
    from pathlib import Path

    from renderlab.measurement.apriori import check_frame
    from renderlab.measurement.images import measure_images, read_apriori
    from renderlab.measurement.runner import write_table

    if args.truthset is not None:
        raise UserError("give either TRUTHSET or --images, not both")
    if args.images is None or args.catalog is None or args.out is None:
        raise UserError("measuring own images needs --images APRIORI.json, --catalog DIR and --out FILE")
    out = Path(args.out)
    if out.exists() and not args.overwrite:
        raise UserError(f"output {out} exists (use --overwrite to replace it)")
    check_regular(Path(args.images), "a-priori file", LIMITS["json"])  # no FIFO, no device, bounded size
    _, _, frame, _ = read_apriori(Path(args.images))  # validated before anything else is read
    check_frame(frame, Path(args.catalog), Path(args.images).name)
    maplets = read_checked_catalog(Path(args.catalog))
    table = measure_images(Path(args.images), maplets, args.method, opts, allow_reference=True, progress=not args.quiet)
    write_table(table, out, overwrite=args.overwrite)
    print(f"renderlab: {table.num_rows} measurements of {Path(args.images).name}'s images -> {out}")
    return 0
