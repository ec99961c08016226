#!/usr/bin/env bash
# The GPU figures of docs/gpu-training.md in one go: throughput of the JAX backend against the numpy
# vector environment (swing-up; the rotor and a follow task, whose state carries a count or a target),
# then Brax PPO swing-ups on the nominal plant and under sim2real, each policy
# snapshot kept for evaluation on the numpy domains (benchmarks/held_out.py).
#     bash benchmarks/jax_gpu.sh OUT_DIR
set -uo pipefail
out=${1:?usage: jax_gpu.sh OUT_DIR}
mkdir -p "$out"
cd "$(dirname "$0")/.."
python3 -c "import jax; print(jax.devices())"
timeout 110 python3 benchmarks/jax_backend.py throughput --worlds 1024 8192 65536 --steps 200 \
    --numpy-worlds-max 1024 --json "$out/results.jsonl"
timeout 60 python3 benchmarks/jax_backend.py throughput --worlds 1024 8192 --steps 200 --numpy-worlds-max 1024 \
    --tasks rotor swingup_follow --presets none --json "$out/results.jsonl"
timeout 160 python3 benchmarks/jax_backend.py train --task swingup --randomization none --steps 100000000 \
    --num-evals 8 --out "$out/nominal" --json "$out/results.jsonl"
timeout 260 python3 benchmarks/jax_backend.py train --task swingup --randomization sim2real \
    --steps 200000000 --num-evals 10 --out "$out/sim2real" --json "$out/results.jsonl"
python3 benchmarks/pack_runs.py "$out" nominal sim2real
