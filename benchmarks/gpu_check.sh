#!/usr/bin/env bash
# GPU check of the Mitsuba render path (issue 19), one short run on a machine with an NVIDIA GPU:
#   1. the renderer tests with every LLVM variant request sent to CUDA (RENDERLAB_MITSUBA_DEVICE=cuda), the
#      direct-sun integrator and the shadows switch (tests/test_shadows_switch.py) included;
#   2. GPU image = LLVM image to 1e-5 relative (benchmarks/bench_mitsuba_gpu_vs_llvm.py, 1024², mono + RGB,
#      box 16 spp and centre 1 spp), with seconds per frame of both;
#      (the lab's default integrator: rl_direct_sun, renderlab/render/mitsuba_direct.py);
#   3. the lab path vs mi.render on the GPU (benchmarks/bench_mitsuba_lab_vs_render.py, 1024², 16 spp): rl_direct_sun
#      and Mitsuba's path in the lab path and in mi.render, and Mitsuba's own direct integrator, side by side;
#   4. the warm frame API on the GPU: its tests and the tiled site in a second scene forced on CUDA
#      (RENDERLAB_MITSUBA_TILE_DESIGN=two: does OptiX trace two scenes in one kernel, and do the images equal the
#      one-scene design's?), then benchmarks/bench_frame_api.py on the descent-navigation world;
#   5. frame files written by the background writer equal the sequential ones on CUDA (tests/test_background_writes.py),
#      and where a full EV5 frame's time goes on the GPU (benchmarks/bench_frame_breakdown.py, 1024², 16 spp, 4 frames:
#      is the tile scene's structure build of the 171 m frame, seconds on 2 CPU cores, still the largest stage?), and
#      that frame's 9.6 M tile facets built flat vs as a shapegroup + instance (benchmarks/bench_tile_structure_build.py);
#   6. the DEM march (the LLVM default for tiled sites, renderlab/render/mitsuba_dem.py) forced on CUDA
#      (RENDERLAB_MITSUBA_TILE_DESIGN=dem: one OptiX scene plus the Dr.Jit march in one kernel): its tests, then
#      benchmarks/bench_dem_march.py on the 171 m frame (march vs tiles vs mi.render on the GPU).
# Needs the project environment (./setup.sh) and a CUDA driver. Figures go to $OUT (default $TMPDIR/renderlab_gpu_check);
# exit status 0 when everything passed, 1 when a step failed, 2 when there is no usable GPU.
# Run from anywhere:  bash benchmarks/gpu_check.sh        (about 10 minutes, more when the EV5 world is not cached yet; each step has its own timeout)
set -uo pipefail
cd "$(dirname "$0")/.."
PY=${PY:-.venv/bin/python}
OUT=${OUT:-${TMPDIR:-/tmp}/renderlab_gpu_check}
mkdir -p "$OUT"
nvidia-smi > "$OUT/nvidia-smi.txt" 2>&1 || { echo "gpu_check: nvidia-smi failed: no GPU here"; exit 2; }
$PY - <<'PY' || { echo "gpu_check: no usable cuda_ad_mono variant"; exit 2; }
from renderlab.render.variant import init_mitsuba
mi = init_mitsuba("cuda_ad_mono")
assert mi.variant() == "cuda_ad_mono", mi.variant()
print("cuda_ad_mono OK")
PY
status=0
step() {  # name, timeout (s), command...
  local name=$1 limit=$2; shift 2
  echo "== $name"
  if ! timeout "$limit" "$@" > "$OUT/$name.txt" 2>&1; then status=1; echo "   FAILED (see $OUT/$name.txt)"; fi
  tail -n 12 "$OUT/$name.txt"
}
step tests 240 env RENDERLAB_MITSUBA_DEVICE=cuda $PY -m pytest -q -p no:cacheprovider \
  tests/test_mitsuba_rays.py tests/test_backend_conformance.py tests/test_render_trimesh.py tests/test_mitsuba_bsdf.py \
  tests/test_shadows_switch.py -k "not cycles"
step gpu_vs_llvm 150 $PY benchmarks/bench_mitsuba_gpu_vs_llvm.py --size 1024 --json "$OUT/gpu_vs_llvm.json"
step lab_vs_render_cuda 180 $PY benchmarks/bench_mitsuba_lab_vs_render.py --variant cuda_ad_mono --size 1024 --repeats 5
step frame_api_tests 300 env RENDERLAB_MITSUBA_DEVICE=cuda $PY -m pytest -q -p no:cacheprovider \
  tests/test_frame_api.py tests/test_mitsuba_two_scene.py
step two_scenes_on_cuda 300 env RENDERLAB_MITSUBA_DEVICE=cuda RENDERLAB_MITSUBA_TILE_DESIGN=two $PY -m pytest -q \
  -p no:cacheprovider tests/test_mitsuba_two_scene.py
step frame_api_bench_cuda 300 env RENDERLAB_MITSUBA_DEVICE=cuda $PY benchmarks/bench_frame_api.py --skip-full
step background_writes_cuda 120 env RENDERLAB_MITSUBA_DEVICE=cuda $PY -m pytest -q -p no:cacheprovider \
  tests/test_background_writes.py
step frame_breakdown_cuda 600 env RENDERLAB_MITSUBA_DEVICE=cuda $PY benchmarks/bench_frame_breakdown.py --frames 4
step tile_structure_build_cuda 300 env RENDERLAB_MITSUBA_DEVICE=cuda $PY benchmarks/bench_tile_structure_build.py --repeats 1
step dem_on_cuda 300 env RENDERLAB_MITSUBA_DEVICE=cuda RENDERLAB_MITSUBA_TILE_DESIGN=dem $PY -m pytest -q \
  -p no:cacheprovider tests/test_mitsuba_dem.py tests/test_frame_api.py
step dem_march_bench_cuda 400 env RENDERLAB_MITSUBA_DEVICE=cuda $PY benchmarks/bench_dem_march.py --frame 1 --repeats 2
echo "gpu_check: $([ $status = 0 ] && echo PASSED || echo FAILED); figures in $OUT/"
exit $status
