"""The files of one ``renderlab render`` frame, written side by side with the writers' zlib settings new and old.

Real 1 MP EV5 frames (``scenes/ev5_descent.toml`` as ``bench_frame_api.py`` sets it up: ``--size``², ``--spp`` spp,
the frames ``--frames`` of a 4-frame descent) are rendered once through ``renderlab.Renderer``; then each frame's
files (EXR, 16-bit DN PNG, 8-bit preview: :func:`renderlab.files.imageio.write_frame_files`, as the truth-set writer
calls it) are written ``--repeats`` times per arm, the arms interleaved:

* ``new``: the writers as they are (EXR ZIP at :data:`~renderlab.files.imageio.EXR_ZIP_LEVEL`, PNG
  :data:`~renderlab.files.imageio.PNG_PARAMS`);
* ``old``: as they were before (EXR ZIP at OpenEXR's default level 4, PNG level 3 with zlib's default strategy);
* ``none``: ``render.exr_compression = "none"`` with the new PNG settings (the floor of the EXR part).

Per arm and file: wall time and CPU time of the writing thread (``time.thread_time``: the load of other jobs inflates
the wall time, much less the CPU time), bytes; every file is read back and compared with the frame's arrays (OpenEXR's
reader, OpenCV's PNG decoder): lossless in every arm.

Usage::

    .venv/bin/python benchmarks/bench_frame_files.py [--frames 2,3] [--repeats 5] [--size 1024] [--spp 16]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))
ARMS = ("new", "old", "none")
FILES = (("exr", "write_exr"), ("dn", "write_dn_png"), ("dn_preview", "write_dn_preview"))


def render_frames(args) -> list[tuple]:
    """(channels with the id encoded, dn, bits, EXR header) of each frame in ``args.frames``."""
    from bench_frame_api import _sets

    from renderlab.files.imageio import encode_ids, frame_exr_header
    from renderlab.pipeline.frame_api import Renderer

    r = Renderer(REPO / "scenes" / "ev5_descent.toml", overrides=_sets(args.size, args.spp, 4))
    out = []
    for k in args.frames:
        spec = r.plan.frames[k]
        frame = r.render_spec(spec, r.seed_for(spec.index))
        ch = frame.aovs.exr_channels()
        ch["id"] = encode_ids(ch["id"])
        header = frame_exr_header(spec.index, float(spec.pose.time_s), frame.meta, ch)
        out.append((ch, frame.dn, r.options.bits, header))
    return out


def write_once(folder: Path, frame: tuple, arm: str) -> dict:
    """Seconds (wall, thread CPU) and bytes per file of one frame's files written in ``arm``."""
    from bench_frame_api import _file_settings

    from renderlab.files import imageio

    ch, dn, bits, header = frame
    rels = {"exr": "frames/000000.exr", "dn": "frames/000000.png", "dn_preview": "dn_preview/000000.png"}
    (folder / "frames").mkdir(parents=True, exist_ok=True)
    timed, saved = {}, {name: getattr(imageio, name) for _, name in FILES}

    def clock(key, fn):
        def run(*a, **k):
            w0, c0 = time.perf_counter(), time.thread_time()
            try:
                return fn(*a, **k)
            finally:
                timed[key] = (time.perf_counter() - w0, time.thread_time() - c0)
        return run

    for key, name in FILES:
        setattr(imageio, name, clock(key, saved[name]))
    try:
        with _file_settings("old" if arm == "old" else "new"):
            imageio.write_frame_files(folder, rels, ch, header, "none" if arm == "none" else "zip", dn, bits)
    finally:
        for name, fn in saved.items():
            setattr(imageio, name, fn)
    check_lossless(folder, rels, ch, dn, bits)
    return {key: (*timed[key], (folder / rels[key]).stat().st_size) for key, _ in FILES}


def check_lossless(folder: Path, rels: dict, ch: dict, dn: np.ndarray, bits: int) -> None:
    """Every EXR channel and both PNGs read back exactly (OpenEXR's reader, OpenCV's decoder)."""
    import cv2
    import OpenEXR

    with OpenEXR.File(str(folder / rels["exr"]), separate_channels=True) as f:
        back = {k: np.asarray(c.pixels) for k, c in f.channels().items()}
    assert back.keys() == ch.keys() and all(np.array_equal(back[k], ch[k], equal_nan=True) for k in ch)
    assert np.array_equal(cv2.imread(str(folder / rels["dn"]), cv2.IMREAD_UNCHANGED), dn)
    full = 2 ** bits - 1
    preview = ((dn.astype(np.uint32) * 255 + full // 2) // full).astype(np.uint8)
    assert np.array_equal(cv2.imread(str(folder / rels["dn_preview"]), cv2.IMREAD_UNCHANGED), preview)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=lambda v: [int(k) for k in v.split(",")], default=[2, 3])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--spp", type=int, default=16)
    args = ap.parse_args()
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}", flush=True)
    frames = render_frames(args)
    print(f"{len(frames)} frames rendered ({args.size}², {args.spp} spp), load average {os.getloadavg()[0]:.1f}",
          flush=True)
    res = {(arm, k): [] for arm in ARMS for k in range(len(frames))}
    with tempfile.TemporaryDirectory() as tmp:
        for rep in range(args.repeats):
            for k, frame in enumerate(frames):
                for arm in ARMS:
                    res[(arm, k)].append(write_once(Path(tmp) / f"{arm}{k}{rep}", frame, arm))
    for k, idx in enumerate(args.frames):
        print(f"frame {idx}: median over {args.repeats} writes (wall s / thread CPU s / MB)")
        for arm in ARMS:
            cells = []
            for key, _ in FILES:
                a = np.array([r[key] for r in res[(arm, k)]])
                cells.append(f"{key} {np.median(a[:, 0]):.3f} / {np.median(a[:, 1]):.3f} / {a[0, 2] / 1e6:.2f}")
            tot = np.array([[sum(r[key][i] for key, _ in FILES) for i in (0, 1)] for r in res[(arm, k)]])
            print(f"  {arm:5s} all {np.median(tot[:, 0]):.3f} / {np.median(tot[:, 1]):.3f} s; " + "; ".join(cells))
    for arm in ARMS[1:]:
        new = np.array([[sum(r[key][1] for key, _ in FILES) for r in res[("new", k)]] for k in range(len(frames))])
        other = np.array([[sum(r[key][1] for key, _ in FILES) for r in res[(arm, k)]] for k in range(len(frames))])
        print(f"CPU of a frame's files, new / {arm}: {np.median(new) / np.median(other):.2f} "
              f"({np.median(new):.3f} vs {np.median(other):.3f} s, medians over frames and writes)")
    print(f"load average at the end {os.getloadavg()[0]:.1f}; every file read back exactly")


if __name__ == "__main__":
    main()
