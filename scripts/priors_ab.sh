#!/bin/bash
# The geometry priors A/B of docs/networks.md: the same small networks, data, seed and budget, with
# and without the silhouette and body priors, in two slots of one thread each.
#   DATA  a dataset made by `relight dataset make` (default /work/data/train2)
#   N     people taken from it (default 150), E epochs (default 5)
#   SUB   the folder of links to those people; OUT where the runs go (default /work/runs)
set -e
HERE=$(cd "$(dirname "$0")/.." && pwd)
DATA=${DATA:-/work/data/train2}
SUB=${SUB:-/work/data/ab_subset}
OUT=${OUT:-/work/runs}
R=$HERE/.venv/bin/relight
mkdir -p "$OUT"
rm -rf "$SUB" && mkdir -p "$SUB/samples"
ln -s "$DATA/maps" "$SUB/maps"
for f in $(ls "$DATA"/samples/*/sample.json | head -n "${N:-150}"); do ln -s "$(dirname "$f")" "$SUB/samples/"; done
echo "subset: $(ls "$SUB/samples" | wc -l) people"
# the body priors first (anny), so that no run pays for making them
"$HERE/.venv/bin/python" -c "
import pathlib, sys
from viewer.lab.data.body_prior import cached_body_prior
for s in sorted(pathlib.Path(sys.argv[1], 'samples').iterdir()):
    cached_body_prior(s, 256)
" "$SUB" > "$OUT/ab_body_priors.log" 2>&1
echo "body priors made"
COMMON="--data $SUB --res 128 --width 8 --levels 5 --batch 4 --epochs ${E:-5} --seed 0"
run() { OMP_NUM_THREADS=1 "$R" train "$1" $COMMON --out "$OUT/ab_$2" ${3:-} ${4:-} > "$OUT/ab_$2.log" 2>&1; }
( run inverse inverse_plain ; run depth depth_plain ; run depth depth_body --body-prior ) &
( run inverse inverse_sil --silhouette ; run depth depth_sil --silhouette ; run depth depth_sil_body --silhouette --body-prior ) &
wait
echo "done: $OUT/ab_*/*.json hold the validation history"
