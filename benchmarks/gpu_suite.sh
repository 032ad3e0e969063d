#!/usr/bin/env bash
# The GPU benchmark run as one command: step throughput, 2-D and 3-D
# scaling up to the largest sizes that fit, and jaxmps' side of side_by_side, in
# float32 and float64, results under benchmarks/results/ tagged with the machine
# kind (h100, h200, or the first word of the GPU's name).
#
#   bash benchmarks/gpu_suite.sh            # needs jax with CUDA: pip install -e . "jax[cuda12]"
#   TAG=h200 bash benchmarks/gpu_suite.sh   # name the machine kind yourself
#
# JAX-SPH and PySPH are left out here (their venvs need package downloads and
# PySPH is CPU-only); compare with them on the CPU files.
set -euo pipefail
cd "$(dirname "$0")/.."
python -c "import jax; assert jax.default_backend() == 'gpu', jax.devices()" || {
  echo "gpu_suite.sh: jax sees no GPU (install jax with CUDA support)" >&2; exit 2; }
if [ -z "${TAG:-}" ]; then
  name=$(nvidia-smi --query-gpu=name --format=csv,noheader | head -1)
  case "$name" in
    *H100*) TAG=h100 ;; *H200*) TAG=h200 ;; *) TAG=$(echo "$name" | awk '{print tolower($2)}') ;;
  esac
fi
R=benchmarks/results
python benchmarks/step_throughput.py --out "$R/step_throughput_$TAG"
JAX_ENABLE_X64=1 python benchmarks/step_throughput.py --no-grad \
  --out "$R/step_throughput_x64_$TAG"
python benchmarks/scaling.py --sizes 10000 100000 1000000 4000000 \
  --out "$R/scaling_$TAG"
python benchmarks/scaling.py --dim 3 --solvers explicit \
  --sizes 10000 100000 1000000 4000000 --out "$R/scaling_3d_$TAG"
python benchmarks/scaling.py --dim 3 --solvers explicit --x64 \
  --sizes 10000 100000 1000000 --out "$R/scaling_3d_x64_$TAG"
python benchmarks/side_by_side.py --no-peer --no-pysph --sizes 7k 25k 90k \
  --out "$R/side_by_side_$TAG"
ngpu=$(python -c "import jax; print(jax.device_count())")
devices=1; [ "$ngpu" -gt 1 ] && devices="1 $ngpu"
python benchmarks/sweep_scaling.py --devices $devices --out "$R/sweep_scaling_$TAG"
[ "$ngpu" -gt 1 ] && python benchmarks/sharded_run.py --devices $devices \
  --particles 100000 --out "$R/sharded_run_$TAG"
[ "$ngpu" -gt 1 ] && python benchmarks/slab_run.py --devices $devices \
  --particles 100000 --out "$R/slab_run_$TAG"
echo "gpu_suite.sh: results in $R/*_$TAG.{json,md}"
