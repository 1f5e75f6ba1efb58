#!/bin/bash
# The checks for a lent GPU machine, in one call: bash scripts/device_checks.sh COMMIT [PART0_DIR]
# Unpacks Warp and the wheels from scripts/device_bundle.sh's parts (PART0_DIR: where an earlier call copied
# .wp/part-00, default /tmp/p; skipped when Warp already imports), then the CUDA tests, the bench and doctor, each
# under its own time limit, each step's output appended to $OUT/gpu.log as it goes.
# No `exec > >(tee ...)` here: with it, bash 5.2's `wait` waits for the tee too and the script hangs.
export PYTHONUNBUFFERED=1 MAGSORO_COMMIT=${1:-unknown}
OUT=${OUT:-/tmp/device_out}; mkdir -p "$OUT"
PY=${PY:-python3}
LOG="$OUT/gpu.log"
T0=$(date +%s)
log() { echo "[$(( $(date +%s) - T0 ))s] $*" | tee -a "$LOG"; }
nvidia-smi > "$OUT/nvidia-smi.txt" 2>&1
if ! $PY -c "import warp" 2>/dev/null; then
    mkdir -p /tmp/b /tmp/site/warp/bin
    cat "${2:-/tmp/p}/part-00" .wp2/part-01 | tar xf - -C /tmp/b || { log "bundle parts missing or broken"; exit 3; }
    tar xJf /tmp/b/warp-py.tar.xz -C /tmp/site
    xz -dc /tmp/b/warp.so.xz > /tmp/site/warp/bin/warp.so
    xz -dc /tmp/b/warp-clang.so.xz > /tmp/site/warp/bin/warp-clang.so
    $PY -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --target /tmp/site /tmp/b/deps/*.whl >> "$LOG" 2>&1
    export PYTHONPATH=/tmp/site:$PWD/src
fi
log "warp: $($PY -c 'import warp as wp; wp.config.quiet = True; wp.init(); print(wp.__version__, wp.get_cuda_device_count(), "CUDA devices")' 2>&1 | tail -1)"
step() {  # step NAME SECONDS COMMAND...: run, log its exit status; output to $OUT/NAME.log
    local name=$1 limit=$2; shift 2
    log "$name: start (limit ${limit} s)"
    timeout "$limit" "$@" > "$OUT/$name.log" 2>&1
    log "$name: exit $?"; tail -5 "$OUT/$name.log" >> "$LOG"
}
# The kernel cache is cold on a fresh machine and compiling (NVRTC and clang, one module at a time per process)
# takes most of a call: the tests, doctor and a throw-away bench compile side by side on the machine's cores,
# then the bench runs alone for its timings. `wait` names its processes (no other child is waited for).
step pytest-cuda "${PYTEST_LIMIT:-360}" $PY -m pytest -v -p no:cacheprovider --durations=0 -m cuda \
    tests/test_scatter_threads.py tests/test_graph_windows.py tests/test_fields_sources.py tests/test_doctor.py &
p1=$!
step doctor "${DOCTOR_LIMIT:-300}" $PY -m magsoro doctor --device cuda --json &
p2=$!
step bench-warmup "${WARM_LIMIT:-300}" $PY -m magsoro bench walker block1m sweep --device cuda --steps 20 --json &
p3=$!
wait $p1 $p2 $p3
left=$(( ${CALL_LIMIT:-580} - ($(date +%s) - T0) ))
step bench $(( left > 30 ? left : 30 )) $PY -m magsoro bench walker block1m sweep --device cuda --json
log end
