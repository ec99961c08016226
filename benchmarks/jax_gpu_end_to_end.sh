#!/usr/bin/env bash
# On one GPU: the JAX recipe as a user runs it (`qube-suite train --task swingup --backend jax`,
# timed from the command's start, compilation included), throughput with the recipe's effects
# (`sim2real_frictionless`), and one run of Brax PPO with settings that spend less time per
# env step on updates (4 updates per batch instead of 8). Every policy comes back in
# OUT/policies.zip for evaluation on the numpy domains (`qube-suite eval`, benchmarks/held_out.py).
#     bash benchmarks/jax_gpu_end_to_end.sh OUT_DIR
set -uo pipefail
out=${1:?usage: jax_gpu_end_to_end.sh OUT_DIR}
mkdir -p "$out"
cd "$(dirname "$0")/.."
python3 -c "import jax; print(jax.devices())"
start=$(date +%s.%N)
timeout 200 python3 -m qube_suite.cli train --task swingup --backend jax --out "$out/recipe"
python3 -c "import sys; print(f'recipe command wall time: {float(sys.argv[2]) - float(sys.argv[1]):.1f} s')" \
    "$start" "$(date +%s.%N)" | tee -a "$out/results.txt"
timeout 45 python3 benchmarks/jax_backend.py throughput --presets sim2real_frictionless \
    --worlds 4096 16384 --steps 200 --numpy-worlds-max 0 --json "$out/results.jsonl"
timeout 120 python3 benchmarks/jax_backend.py train --task swingup --randomization sim2real_frictionless \
    --steps 60000000 --set num_updates_per_batch=4 --num-evals 7 --out "$out/fast" \
    --json "$out/results.jsonl"
python3 benchmarks/pack_runs.py "$out" recipe fast
