"""``renderlab export TRUTHSET [--oem FILE] [--aem FILE] [--epoch-utc T]``: a truth set's true camera trajectory
back into the user's tools as CCSDS OEM (positions) and AEM (attitude) KVN messages
(:func:`renderlab.trajectory_io.export.export_truthset`); ``--apriori FILE``: the a-priori file of the set's own
images for ``renderlab measure --images`` (:func:`renderlab.measurement.apriori.write_apriori`)."""

from __future__ import annotations

from renderlab.commands.cost import check_path
from renderlab.errors import UserError
from renderlab.inputs import epoch_text, shown


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("export", help="write a truth set's true camera trajectory as CCSDS OEM/AEM files")
    p.add_argument("truthset", metavar="TRUTHSET", help="truth set folder")
    p.add_argument("--oem", metavar="FILE", help="CCSDS OEM (KVN) of the camera positions")
    p.add_argument("--aem", metavar="FILE", help="CCSDS AEM (KVN) of the camera attitude")
    p.add_argument("--epoch-utc", metavar="ISO", help="epoch of frame time 0 when the frames carry relative times only")
    p.add_argument("--object-name", help="OBJECT_NAME of the messages (default: the body the set was made for, "
                   "e.g. the SPICE observer or the OEM's OBJECT_NAME, else CAMERA)")
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


def _check_outputs(outs: list, overwrite: bool) -> None:
    """The output files: distinct (``--oem x --aem x`` would overwrite one message with the other), in an existing
    folder, not existing unless ``overwrite``, and never a folder, a FIFO or a device."""
    import os
    from pathlib import Path

    seen = {}
    for flag, out in outs:
        real = os.path.realpath(out)
        if real in seen:
            raise UserError(f"{flag} and {seen[real]} name the same file {shown(out)}; give two files")
        seen[real] = flag
        p = Path(out)
        if os.path.lexists(p):
            if not p.is_file() or p.is_symlink():
                raise UserError(f"{flag} {shown(p)} exists and is not a regular file")
            if not overwrite:
                raise UserError(f"output {shown(p)} exists (use --overwrite to replace it)")
        if not p.parent.is_dir():
            raise UserError(f"cannot write {shown(p)}: directory {shown(p.parent)} does not exist")


def run(args) -> int:
    from pathlib import Path

    from renderlab.files.truthset import TruthSet
    from renderlab.trajectory_io.export import export_truthset, kvn_text

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
    outs = [(flag, check_path(p, flag)) for flag, p in (("--oem", args.oem), ("--aem", args.aem)) if p]
    if args.object_name is not None:
        kvn_text(args.object_name, "--object-name")
    if args.epoch_utc is not None:
        epoch_text(args.epoch_utc, "--epoch-utc")
    _check_outputs(outs, args.overwrite)
    ts = TruthSet.open(args.truthset)
    series = export_truthset(ts.path, oem=args.oem, aem=args.aem, epoch_utc=args.epoch_utc,
                             object_name=args.object_name)
    print(f"renderlab: {len(series.times_s)} poses -> " + ", ".join(str(o) for _, o in outs))
    return 0
