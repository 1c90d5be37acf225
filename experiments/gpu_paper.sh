#!/usr/bin/env bash
# The seed's 'paper' networks (B = 24) trained on one lent accelerator, each for a fixed number
# of minutes, on the training scans of the shipped 'mid' bundles (no evaluation scene), then
# brought back as bundles to be evaluated here beside the CPU-trained ones. Nothing else in
# the project needs an accelerator.
#
# Here (with the real scans beside the checkout; open3d renders the embedded rooms):
#     bash experiments/gpu_paper.sh prepare
#         .device_carry/: the training scans packed at 2 cm (18 MB; python -m
#         experiments.make_data --pack) and the ml-collections wheel the device image lacks
# There (the device tool's run, carry=[".device_carry"], $OUT set by it):
#     bash experiments/gpu_paper.sh train 2 [more experiments.train flags]
#         minutes per network (15 min of device time in all: start, compilation and four
#         trainings); each network's bundle, metrics and log as $OUT/<kind>_paper.tar.gz
# Back here, for each kind:
#     mkdir -p W/paper && tar -xzf FILES_AT/lead_paper.tar.gz -C W/paper
#     python -m experiments.evaluate --config=eval_registration --config.bundles.lead=W/paper/lead/bundle ...
# SIZE=tiny CARRY=DIR KINDS=lead_pn runs the same steps at the tests' size
# (tests/test_gpu_script.py; every kind's training itself is tested in tests/test_training.py).
set -euo pipefail
cd "$(dirname "$0")/.."
CARRY=${CARRY:-.device_carry}
SIZE=${SIZE:-paper}
KINDS=${KINDS:-compass lead lead_pn sound}
case "${1:-}" in
prepare)
  mapfile -t rw < <(python -c "from configs import ablation; print(*ablation.training_root(), sep='\n')")
  rm -rf "$CARRY/pack"
  python -m experiments.make_data --pack="${rw[0]}" --out="$CARRY/pack"
  printf '%s\n' "${rw[1]:-}" > "$CARRY/root_weights.txt"
  python -m pip download -q --no-deps --only-binary=:all: -d "$CARRY/wheels" \
    "ml-collections==$(python -c 'import importlib.metadata as m; print(m.version("ml-collections"))')"
  du -sh "$CARRY" ;;
train)
  minutes=${2:-2}
  out=${OUT:?"OUT: the folder the bundles go to (the device tool sets it)"}
  if compgen -G "$CARRY/wheels/*.whl" > /dev/null; then
    python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site "$CARRY"/wheels/*.whl
    export PYTHONPATH=/tmp/site:$PWD
  fi
  export PYTHONUNBUFFERED=1
  root=$(ls -d "$CARRY"/pack/*/ | sed 's:/$::' | paste -sd, -)
  weights=$(cat "$CARRY/root_weights.txt" 2>/dev/null || true)
  budget=$(python3 -c "print(float($minutes) * 60)")
  work=$(mktemp -d)
  for k in $KINDS; do
    python3 -m experiments.train --config="$k:$SIZE" --config.data.root="$root" \
      --config.data.root_weights="$weights" --config.train.time_budget_s="$budget" \
      --workdir="$work/$k" "${@:3}" > "$work/$k.log" 2>&1 || { tail -n 20 "$work/$k.log"; exit 1; }
    tail -n 1 "$work/$k.log"
    mkdir -p "$work/out/$k" && cp -r "$work/$k/bundle" "$work/$k/metrics.jsonl" "$work/$k.log" "$work/out/$k/"
    tar -czf "$out/${k}_$SIZE.tar.gz" -C "$work/out" "$k"
  done ;;
*) echo "usage: $0 prepare | train MINUTES [FLAGS...]" >&2; exit 2 ;;
esac
