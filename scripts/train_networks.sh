#!/bin/bash
# Issue 18's training run (docs/networks.md): the three shipped networks fine-tuned on the issue-18
# dataset, one after the other, each in two processes (torchrun) of one thread, so both cores of the
# 2-core machine work on one network. Rerunning it resumes: a finished network is skipped, an
# interrupted one goes on from its last finished epoch.
#   DATA  the dataset (default /work/data/train2); OUT where the run goes (default /work/runs/issue18)
#   E_INVERSE, E_DEPTH, E_REFINE  epochs (default 2, 2, 1); LR the starting learning rate (default 5e-4)
#   PROCS processes per network (default 2; on a GPU machine use DEVICE=cuda and PROCS=1)
set -e
HERE=$(cd "$(dirname "$0")/.." && pwd)
DATA=${DATA:-/work/data/train2}
OUT=${OUT:-/work/runs/issue18}
PROCS=${PROCS:-2}
mkdir -p "$OUT"
run() {  # network, epochs, extra options
    local net=$1 epochs=$2
    shift 2
    OMP_NUM_THREADS=1 "$HERE/.venv/bin/torchrun" --standalone --nproc_per_node "$PROCS" "$HERE/.venv/bin/relight" \
        train "$net" --data "$DATA" --out "$OUT" --epochs "$epochs" --lr "${LR:-5e-4}" --device "${DEVICE:-cpu}" \
        --init "$HERE/assets/networks/$net.safetensors" "$@" > "$OUT/$net.log" 2>&1
    echo "$net: $(tail -n 2 "$OUT/$net.log" | head -n 1)"
}
run inverse "${E_INVERSE:-2}" --batch 4 --width 16
run depth "${E_DEPTH:-2}" --batch 4 --width 16
run refine "${E_REFINE:-1}" --batch 2 --width 8
echo "done: $OUT holds the weights and cards; next: relight bench networks --data HELDOUT --networks $OUT"
