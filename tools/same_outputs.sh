#!/usr/bin/env bash
# Outputs that a refactoring must leave byte-identical (issue 44): a render's PNG, EXR and passes
# sheet, a photo bundle's maps and a batch's images, made by the code in the current folder into
# OUT; compare two such folders with `tools/same_outputs.sh --compare A B` (timings, manifests and
# records that hold them are left out).
set -euo pipefail
if [ "${1:-}" = "--compare" ]; then
    a=$2; b=$3; bad=0
    while IFS= read -r f; do
        if ! cmp -s "$a/$f" "$b/$f"; then echo "differs: $f"; bad=1; fi
    done < <(cd "$a" && find . -type f ! -name '*.json' ! -name '*.jsonl' ! -name '*.log' ! -name '*.lock' | sort)
    [ "$bad" = 0 ] && echo "identical: $(cd "$a" && find . -type f ! -name '*.json' ! -name '*.jsonl' ! -name '*.lock' | wc -l) files"
    exit $bad
fi
# one core: the thread pools are sized to the idle cores (viewer/cores.py), and a float sum split
# over another number of threads rounds differently
out=$(realpath -m "$1"); py="taskset -c 0 ${PYTHON:-python}"
rm -rf "$out"; mkdir -p "$out/photos"
export RELIGHT_CACHE="$out.cache"  # a fresh cache: a bundle or lights cached by an earlier run are not compared
rm -rf "$RELIGHT_CACHE"
cp assets/photos/underpass.jpg "$out/photos/"
$py -m viewer.cli.main render assets/sample_scene --env assets/envmaps/venice_sunset_256.hdr --size 256 --yaw 0 -o "$out/render.png" >/dev/null
$py -m viewer.cli.main render assets/sample_scene assets/envmaps/studio_small_03_256.lights.json --size 256 --yaw 30 \
    --background color -o "$out/render_lights.png" >/dev/null
$py -m viewer.cli.main infer assets/photos/underpass.jpg --size 256 --max-size 768 -o "$out/bundle" >/dev/null
$py -m viewer.cli.main render "$out/bundle" --env assets/envmaps/immenstadter_horn_256.hdr --yaw 0 -o "$out/photo.png" >/dev/null
$py -m viewer.cli.main batch "$out/photos" --env assets/envmaps/venice_sunset_256.hdr --max-size 768 --workers 1 \
    -o "$out/batch" >/dev/null
rm -rf "$out/photos" "$RELIGHT_CACHE"
echo "wrote $out"
