#!/usr/bin/env bash
# Networks trained on one lent accelerator, side by side, each within a budget of minutes, on
# the training scans of the shipped 'mid' bundles (no evaluation scene), then brought back as
# bundles to be evaluated here: the seed's 'paper' networks (B = 24; SIZE=paper, the default)
# or the 'mid' recipes themselves (SIZE=mid: their one command, with the data read from the
# pack). Nothing else in the project needs an accelerator.
#
# Here (with the real scans beside the checkout; open3d renders the embedded rooms):
#     bash experiments/gpu_train.sh prepare
#         .device_carry/: the training scans packed at 2 cm (python -m experiments.make_data
#         --pack; 46 MB as pack.tar.xz) and the wheels of this checkout's ml-collections (the
#         device image lacks it), flax, optax and orbax (bundles written there load here)
# There (the device tool's run, carry=[".device_carry"], $OUT set by it):
#     bash experiments/gpu_train.sh train 2 [more experiments.train flags]
#         minutes per network (15 min of device time in all: start, compilation and the
#         trainings); each network's bundle, metrics and log as $OUT/<kind>_<size>.tar.gz
# Back here, for each kind:
#     mkdir -p W && tar -xzf FILES_AT/lead_paper.tar.gz -C W
#     python -m experiments.whiten --bundle=W/lead/bundle      (it reads the rooms: here)
#     python -m experiments.evaluate --config=eval_registration --config.bundles.lead=W/lead/bundle ...
# A 'mid' recipe the budget cut short goes on here from its bundle on the same schedule:
#     python -m experiments.train --config=lead:mid --config.train.init_bundle=W/lead/bundle --workdir=...
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
  rm -rf "$CARRY/pack" "$CARRY/pack.tar.xz"
  python -m experiments.make_data --pack="${rw[0]}" --out="$CARRY/pack"
  # xz: 61 MB of scans to 46, inside what a device call carries (64 MiB with the checkout)
  tar -cf - -C "$CARRY" pack | xz -9 -T0 > "$CARRY/pack.tar.xz" && rm -r "$CARRY/pack"
  printf '%s\n' "${rw[0]}" > "$CARRY/root.txt"
  printf '%s\n' "${rw[1]:-}" > "$CARRY/root_weights.txt"
  for p in ml-collections flax optax orbax-checkpoint; do   # this checkout's versions
    python -m pip download -q --no-deps --only-binary=:all: -d "$CARRY/wheels" \
      "$p==$(python -c "import importlib.metadata as m; print(m.version('$p'))")"
  done
  du -sh "$CARRY" ;;
train)
  minutes=${2:-2}
  out=${OUT:?"OUT: the folder the bundles go to (the device tool sets it)"}
  if compgen -G "$CARRY/wheels/*.whl" > /dev/null; then
    python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site "$CARRY"/wheels/*.whl
    export PYTHONPATH=/tmp/site:$PWD
  fi
  export PYTHONUNBUFFERED=1
  # Full float32 products, as on the CPUs that use the bundles (XLA's GPU default, TF32, rounds
  # them to 1e-3).
  export JAX_DEFAULT_MATMUL_PRECISION=${JAX_DEFAULT_MATMUL_PRECISION:-highest}
  work=$(mktemp -d)
  pack="$CARRY/pack"
  if [ -f "$CARRY/pack.tar.xz" ]; then
    tar -xJf "$CARRY/pack.tar.xz" -C "$work" && pack="$work/pack"
  fi
  # The 'mid' recipes name their own rooms; the others train on the packed ones. Either way
  # the bundle records data.root as named here and reads it from the pack (train.pack).
  data=(--config.train.pack="$pack")
  if [ "$SIZE" != mid ]; then
    data+=(--config.data.root="$(cat "$CARRY/root.txt")"
           --config.data.root_weights="$(cat "$CARRY/root_weights.txt" 2>/dev/null || true)")
  fi
  budget=$(python3 -c "print(float($minutes) * 60)")
  # The kinds train side by side: each loop waits on its CPU-made batches as much as on the
  # GPU, so one card serves them all; each takes GPU memory as it needs it.
  export XLA_PYTHON_CLIENT_PREALLOCATE=false
  for k in $KINDS; do
    python3 -m experiments.train --config="$k:$SIZE" "${data[@]}" --nowhiten \
      --config.train.time_budget_s="$budget" --workdir="$work/$k" "${@:3}" \
      > "$work/$k.log" 2>&1 &
  done
  failed=0
  for k in $KINDS; do
    wait -n || failed=1
  done
  for k in $KINDS; do
    tail -n 1 "$work/$k.log"
    if [ -f "$work/$k/bundle/config.json" ]; then
      mkdir -p "$work/out/$k" && cp -r "$work/$k/bundle" "$work/$k/metrics.jsonl" "$work/$k.log" "$work/out/$k/"
      tar -czf "$out/${k}_$SIZE.tar.gz" -C "$work/out" "$k"
    else
      tail -n 20 "$work/$k.log"; cp "$work/$k.log" "$out/" ; failed=1
    fi
  done
  exit $failed ;;
*) echo "usage: $0 prepare | train MINUTES [FLAGS...]" >&2; exit 2 ;;
esac
