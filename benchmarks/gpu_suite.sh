#!/usr/bin/env bash
# The GPU benchmark run as one command, sized to a lease: stages in order of
# priority, each under what is left of a wall-clock budget (BUDGET_S, default
# 3000 s), so that a short lease still returns the stages it reached. Results go
# to RESULTS (default benchmarks/results/), tagged with the machine kind (h100,
# h200, or the first word of the GPU's name); each stage's output is also in
# RESULTS/gpu_suite_<tag>.log.
#
#   bash benchmarks/gpu_suite.sh              # needs jax with CUDA: pip install -e . "jax[cuda12]"
#   BUDGET_S=500 RESULTS=/tmp/r bash benchmarks/gpu_suite.sh
#
# Stages: a smoke run; 2-D and 3-D explicit scaling 1e4-1e6 particles; 2-D
# semi-implicit scaling; the tsunami scene's 3-D step cost (reduced, then at
# the seed's l0 = 1 m); 2-D explicit at 4e6;
# float64 explicit (jaxmps' side of side_by_side); the sweep; several-GPU runs
# where there are several. JAX-SPH and PySPH are left out (their venvs need
# package downloads and PySPH is CPU-only); compare with them on the CPU files.
set -uo pipefail
cd "$(dirname "$0")/.."
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}" PYTHONUNBUFFERED=1
python -c "import jax; assert jax.default_backend() == 'gpu', jax.devices()" || {
  echo "gpu_suite.sh: jax sees no GPU (install jax with CUDA support)" >&2; exit 2; }
if [ -z "${TAG:-}" ]; then
  name=$(nvidia-smi --query-gpu=name --format=csv,noheader | head -1)
  case "$name" in
    *H100*) TAG=h100 ;; *H200*) TAG=h200 ;; *) TAG=$(echo "$name" | awk '{print tolower($2)}') ;;
  esac
fi
R=${RESULTS:-benchmarks/results}
mkdir -p "$R"
LOG="$R/gpu_suite_$TAG.log"
: >"$LOG"
END=$(($(date +%s) + ${BUDGET_S:-3000}))

# stage NAME MAX_S COMMAND...: run COMMAND under the smaller of MAX_S and the
# time left (less 10 s for the caller), logging its output and its fate.
stage() {
  local name=$1 max=$2
  shift 2
  local left=$((END - $(date +%s) - 10))
  [ "$left" -lt "$max" ] && max=$left
  if [ "$max" -lt 20 ]; then
    echo "== $name: skipped (budget spent)" | tee -a "$LOG"
    return
  fi
  echo "== $name (at most ${max} s): $*" | tee -a "$LOG"
  local t0=$(date +%s)
  timeout "$max" "$@" 2>&1 | grep -v "^WARNING: All log messages" | tee -a "$LOG"
  echo "== $name: exit ${PIPESTATUS[0]} after $(($(date +%s) - t0)) s" | tee -a "$LOG"
}

nvidia-smi --query-gpu=name,memory.total,driver_version,clocks.sm,clocks.mem \
  --format=csv | tee -a "$LOG"
stage smoke 60 python -c "
import jax, jaxmps
c = jaxmps.scenes.dam_break(spacing=0.0146)
r = jaxmps.simulate(c.scene, c.params, c.state, 10, 10)
print(jax.devices(), jax.__version__, 'steps', int(r.state.step), 'ok')"
stage scaling_2d 120 python benchmarks/scaling.py --solvers explicit \
  --sizes 10000 100000 1000000 --out "$R/scaling_explicit_$TAG"
stage scaling_3d 120 python benchmarks/scaling.py --dim 3 --solvers explicit \
  --sizes 10000 100000 1000000 --out "$R/scaling_3d_$TAG"
stage scaling_2d_semi 120 python benchmarks/scaling.py --solvers semi_implicit \
  --sizes 10000 100000 1000000 --out "$R/scaling_semi_implicit_$TAG"
stage tsunami_3d 100 python benchmarks/tsunami_cost.py --steps 100 \
  --configs "3-D reduced, l0 = 2 m" "3-D reduced, l0 = 1.5 m" \
  --out "$R/tsunami_cost_$TAG"
stage tsunami_3d_seed 300 python benchmarks/tsunami_cost.py --steps 100 \
  --configs "3-D, l0 = 1 m (seed's resolution)" --out "$R/tsunami_cost_seed_$TAG"
stage scaling_2d_4m 80 python benchmarks/scaling.py --solvers explicit \
  --sizes 4000000 --out "$R/scaling_explicit_4m_$TAG"
stage side_by_side_x64 150 python benchmarks/side_by_side.py --no-peer --no-pysph \
  --sizes 7k 25k 90k --out "$R/side_by_side_$TAG"
stage step_throughput 200 python benchmarks/step_throughput.py \
  --out "$R/step_throughput_$TAG"
ngpu=$(python -c "import jax; print(jax.device_count())")
devices=1; [ "$ngpu" -gt 1 ] && devices="1 $ngpu"
stage sweep 200 python benchmarks/sweep_scaling.py --devices $devices \
  --out "$R/sweep_scaling_$TAG"
if [ "$ngpu" -gt 1 ]; then
  stage sharded 200 python benchmarks/sharded_run.py --devices $devices \
    --particles 100000 --out "$R/sharded_run_$TAG"
  stage slabs 200 python benchmarks/slab_run.py --devices $devices \
    --particles 100000 --out "$R/slab_run_$TAG"
fi
echo "gpu_suite.sh: results in $R/*_$TAG.{json,md}, log $LOG" | tee -a "$LOG"
