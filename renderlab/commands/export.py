"""``renderlab export TRUTHSET [--oem FILE] [--aem FILE] [--epoch-utc T]``: a truth set's true camera trajectory
back into the user's tools as CCSDS OEM (positions) and AEM (attitude) KVN messages
(:func:`renderlab.trajectory_io.export.export_truthset`)."""

from __future__ import annotations


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("export", help="write a truth set's true camera trajectory as CCSDS OEM/AEM files")
    p.add_argument("truthset", metavar="TRUTHSET", help="truth set folder")
    p.add_argument("--oem", metavar="FILE", help="CCSDS OEM (KVN) of the camera positions")
    p.add_argument("--aem", metavar="FILE", help="CCSDS AEM (KVN) of the camera attitude")
    p.add_argument("--epoch-utc", metavar="ISO", help="epoch of frame time 0 when the frames carry relative times only")
    p.add_argument("--object-name", default="CAMERA", help="OBJECT_NAME of the messages")
    p.add_argument("--overwrite", action="store_true", help="replace existing files")


def run(args) -> int:
    from pathlib import Path

    from renderlab.errors import UserError
    from renderlab.trajectory_io.export import export_truthset
    from renderlab.truthset import TruthSet

    if not args.oem and not args.aem:
        raise UserError("give --oem FILE and/or --aem FILE")
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
