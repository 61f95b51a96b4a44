"""Cross-renderer truth check: the same frames rendered by Mitsuba 3 and Blender Cycles must agree.

Two independent renderers (different ray tracers, samplers, shading code: Dr.Jit BSDF plugins vs OSL
shaders, analytic sphere vs tessellated sphere) render the same scenario; truth is trusted where they
agree. Per frame (both truth sets read back from disk):

* radiometric: over lit pixels (radiance ≥ ``LIT_FRACTION`` × the frame's 99.9th percentile in both),
  the median and 99th percentile of |L_cycles / L_mitsuba − 1|; and the count of pixels lit in one
  renderer but below 10 % of it in the other (shadow disagreements the ratio statistics exclude). Interior pixels are noise-free (direct
  sunlight); pixels straddling an edge carry each renderer's own sampling noise, which the p99 shows.
* geometric: at every pixel both renderers hit the same body, the gap between the hit points split
  into its part across the line of sight, in pixels f·|ΔP⊥|/range (what moves an image point), and its
  part along it, |Δrange|/range (surface depth: the analytic sphere vs its tessellation shows here,
  largest at grazing rays near the silhouette); plus the re-projection error of each renderer's P
  through the lab's :class:`CameraModel` (the AOV must lie on the ray through the pixel centre: this
  pins Cycles' camera built from the intrinsics); on EV5 sets also at the landmark truth pixels
  (``landmark_truth.parquet``, visible landmarks, nearest pixel).
* shadow edges: pixels on a cast-shadow edge (a bright pixel and a dark pixel whose normal faces the
  sun nearby, all on one body): the edge shift between the renderers from the change of lit fraction
  (see :func:`shadow_edge_shift_px`). Median and 99th percentile.
* the referee (:mod:`renderlab.render.ray_oracle`, float64 ray casting against the exact geometry,
  no renderer code): at every pixel lit in one renderer only it decides which renderer agrees with
  the truth within sampling noise (:func:`~renderlab.render.ray_oracle.consistent`; a verdict against
  a renderer is confirmed with 64² sub-samples): ``oracle_mitsuba_off``, ``oracle_cycles_off``, and
  ``oracle_both_ok`` (sub-pixel slivers that both renderers sample correctly), and at the shadow-edge pixels it gives
  each renderer's own edge error |L − L_oracle|/step in px (``edge_vs_oracle_*_p99_px``). Scenes
  with albedo maps or mesh files are not refereed (NaN).

Targets, set before the renderers were compared (what sub-pixel navigation truth needs): median radiometric
≤ 1 %, geometric ≤ 0.05 px, shadow edges ≤ 0.5 px (:data:`~renderlab.crosscheck.agreement.TARGETS`).
"""

from renderlab.crosscheck.agreement import (  # noqa: F401
                                            LIT_FRACTION,
                                            TARGETS,
                                            FrameAgreement,
                                            frame_agreement,
                                            position_gap,
                                            radiometric_agreement,
                                            reprojection_px,
                                            shadow_edge_shift_px,
)
from renderlab.crosscheck.run import compare_truthsets, figure, markdown_table, referee, run_crosscheck  # noqa: F401
