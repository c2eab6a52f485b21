#!/usr/bin/env bash
# GPU figures for the book's performance page in one run, on a machine with an NVIDIA GPU:
# `ipfn bench` for every GPU device and both GPU engines (our generator kernel, burn's path),
# then the peak device memory of `ipfn synth` at growing sizes, polled from nvidia-smi.
#
#   benches/gpu.sh [IPFN_BINARY] [DEVICES]      e.g. benches/gpu.sh ./ipfn wgpu,cuda
#
# The binary must be built with `--features cuda` for the cuda rows (`cargo build-cuda`). Bench rows print our time
# beside the matmul floor measured in the same run and the authors' H100 figures.
set -uo pipefail
ipfn="${1:-ipfn}"
devices="${2:-wgpu,cuda}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader

# Warm the driver's shader caches outside the timed runs. (Autotune results are no longer kept
# on disk since burn's default features were dropped: each process tunes again, so a timed
# process that autotunes pays for it.)
for d in ${devices//,/ }; do
  "$ipfn" synth --size 256 --device "$d" -o "$work/warm.png" >/dev/null 2>&1 ||
    echo "warm-up on $d failed"
done

echo
echo "## ipfn bench (synth, training iterations, 512³ volume)"
"$ipfn" bench --devices "$devices" --sizes 256,512,1024,2048 --runs 10 --batches 4,8 \
  --volumes 512

# Peak device memory used while `ipfn synth` runs (the whole device, context included).
peak_during() {
  local peak=0 used
  "$@" >/dev/null 2>&1 &
  local pid=$!
  while kill -0 "$pid" 2>/dev/null; do
    used=$(nvidia-smi --query-gpu=memory.used --format=csv,noheader,nounits | head -1)
    [ "${used:-0}" -gt "$peak" ] && peak=$used
    sleep 0.01
  done
  wait "$pid" || echo "(failed: $*)" >&2
  echo "$peak"
}

echo
echo "## Peak GPU memory of ipfn synth (MiB, nvidia-smi every 10 ms)"
echo "| size | device | kernel | burn |"
echo "|---|---|---|---|"
for d in ${devices//,/ }; do
  for n in 1024 2048 4096; do
    k=$(peak_during "$ipfn" synth --size "$n" --device "$d" -o "$work/k.png")
    b=$(IPFN_GPU_KERNEL=0 peak_during "$ipfn" synth --size "$n" --device "$d" -o "$work/b.png")
    echo "| ${n}² | $d | $k | $b |"
  done
done
