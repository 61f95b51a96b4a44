"""The ``bright_spot`` study: per run, synthetic frames with one spot at a seeded position (or none), every registered
bright_spot method run by renderlab's generic :func:`renderlab.measurement.kinds.measure_frames`, the exact truth
joined. Table ``spots`` (the kind's ``table_names``)."""

from __future__ import annotations

import numpy as np
import pyarrow as pa

from renderlab.contracts.study import Study
from renderlab_toy_kind.kind import SpotFrame
from renderlab_toy_kind.parts import spot_image

FRAMES, SHAPE, READ_NOISE_DN, BACKGROUND_DN, P_BLANK = 8, (36, 40), 2.0, 10.0, 0.25


def draw_frames(rng: np.random.Generator):
    """(frames, truth (n, 2) with NaN for a frame without spot): Poisson signal + Gaussian read noise."""
    frames, truth = [], np.full((FRAMES, 2), np.nan)
    for i in range(FRAMES):
        blank = rng.random() < P_BLANK
        s0, l0 = rng.uniform(8, SHAPE[1] - 8), rng.uniform(8, SHAPE[0] - 8)
        mean = spot_image(SHAPE, s0, l0, 0.0 if blank else rng.uniform(2000, 8000), background=BACKGROUND_DN)
        img = rng.poisson(mean).astype(float) + rng.normal(0.0, READ_NOISE_DN, SHAPE)
        noise = float(np.sqrt(BACKGROUND_DN + READ_NOISE_DN ** 2))  # Poisson of the background + read noise
        frames.append(SpotFrame(img, noise_dn=noise, index=i, seed=int(rng.integers(2 ** 31))))
        if not blank:
            truth[i] = (s0, l0)
    return frames, truth


def run(scenario, base_dir, run_index, seed_sequence, workdir) -> dict:
    from renderlab import plugins
    from renderlab.measurement.kinds import measure_frames

    frames, truth = draw_frames(np.random.default_rng(seed_sequence))
    tables = []
    for name in plugins.method_registry("bright_spot").names():
        t = measure_frames("bright_spot", name, frames, run=run_index)
        idx = np.asarray(t.column("frame").to_pylist())
        for j, axis in enumerate("sl"):
            meas = np.asarray(t.column(f"spot_{axis}").to_numpy(zero_copy_only=False), float)
            t = t.append_column(f"truth_{axis}", pa.array(truth[idx, j]))
            t = t.append_column(f"err_{axis}", pa.array(meas - truth[idx, j]))
        tables.append(t)
    return {"spots": pa.concat_tables(tables)}


STUDY = Study(name="bright_spot", run=run, worlds=("analytic",),
              description="toy: locate one bright spot in synthetic frames (examples/toy_kind)", clusters=("run",))
