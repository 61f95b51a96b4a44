"""``renderlab export TRUTHSET [--oem FILE] [--aem FILE] [--epoch-utc T]``: a truth set's true camera trajectory
back into the user's tools as CCSDS OEM (positions) and AEM (attitude) KVN messages
(:func:`renderlab.trajectory_io.export.export_truthset`); ``--apriori FILE``: the a-priori file of the set's own
images for ``renderlab measure --images`` (:func:`renderlab.measurement.apriori.write_apriori`)."""

from __future__ import annotations


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("export", help="write a truth set's true camera trajectory as CCSDS OEM/AEM files")
    p.add_argument("truthset", metavar="TRUTHSET", help="truth set folder")
    p.add_argument("--oem", metavar="FILE", help="CCSDS OEM (KVN) of the camera positions")
    p.add_argument("--aem", metavar="FILE", help="CCSDS AEM (KVN) of the camera attitude")
    p.add_argument("--epoch-utc", metavar="ISO", help="epoch of frame time 0 when the frames carry relative times only")
    p.add_argument("--object-name", default="CAMERA", help="OBJECT_NAME of the messages")
    p.add_argument("--apriori", metavar="FILE", help="the a-priori JSON of the set's own DN images for "
                   "'renderlab measure --images' (format: docs/apriori_file.md)")
    p.add_argument("--apriori-sigma-pos-m", type=float, default=0.5, metavar="M",
                   help="with --apriori: declared position 1-sigma per axis, m (default 0.5)")
    p.add_argument("--apriori-sigma-att-deg", type=float, default=0.05, metavar="DEG",
                   help="with --apriori: declared attitude 1-sigma per axis, deg (default 0.05)")
    p.add_argument("--apriori-seed", type=int, metavar="S",
                   help="with --apriori: perturb each true pose by one draw of those sigmas, as 'renderlab measure "
                        "TRUTHSET --seed S' draws it (default: the true pose)")
    p.add_argument("--overwrite", action="store_true", help="replace existing files")


def run(args) -> int:
    from pathlib import Path

    from renderlab.errors import UserError
    from renderlab.trajectory_io.export import export_truthset
    from renderlab.truthset import TruthSet

    if not args.oem and not args.aem and not args.apriori:
        raise UserError("give --oem FILE, --aem FILE and/or --apriori FILE")
    if args.apriori_seed is not None and args.apriori_seed < 0:
        raise UserError(f"--apriori-seed must be >= 0, got {args.apriori_seed}")
    if not args.oem and not args.aem:
        from renderlab.measurement.apriori import write_apriori

        n = write_apriori(args.truthset, Path(args.apriori), position_sigma_m=args.apriori_sigma_pos_m,
                          attitude_sigma_deg=args.apriori_sigma_att_deg, seed=args.apriori_seed,
                          overwrite=args.overwrite)
        print(f"renderlab: {n} images -> {args.apriori}")
        return 0
    if args.apriori:
        raise UserError("write --apriori FILE on its own (not with --oem/--aem)")
    outs = [Path(p) for p in (args.oem, args.aem) if p]
    for out in outs:
        if out.exists() and not args.overwrite:
            raise UserError(f"output {out} exists (use --overwrite to replace it)")
        if not out.parent.is_dir():
            raise UserError(f"cannot write {out}: directory {out.parent} does not exist")
    ts = TruthSet.open(args.truthset)
    series = export_truthset(ts.path, oem=args.oem, aem=args.aem, epoch_utc=args.epoch_utc,
                             object_name=args.object_name)
    print(f"renderlab: {len(series.times_s)} poses -> "
          + ", ".join(str(o) for o in outs))
    return 0
