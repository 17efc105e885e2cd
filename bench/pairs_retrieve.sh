#!/usr/bin/env bash
# Retrieval (mimic pairs retrieve) on real two-person motion: samples drawn
# from ONE take (prior and seeds) against 2D annotations of OTHER takes,
# each annotation lifted to the sample that projects onto it best; against
# retrieving, the same way, the seed take's own frames. Prints the JSON
# reports' figures (3D error against the true frame, view error against
# the true camera, 2D residual); never passes or fails.
#
#   seed take:   SEED (default High_five) of cmu-interactions, every frame
#   annotated:   TAKES (default greeting002 box_throw back_lift001), every
#                10th frame, one camera each, 2 px noise (pairs annotate's defaults)
#   samples:     N (default 20000) of pairs sample's default density, 2 chains
#
# usage: bench/pairs_retrieve.sh MIMIC_BINARY [DATA_DIR] [N] [SEED] [TAKES...]
set -eu
M=${1:?usage: pairs_retrieve.sh MIMIC_BINARY [DATA_DIR] [N] [SEED] [TAKES...]}
D=${2:-$(dirname "$0")/../../shared/data}/cmu-interactions
N=${3:-20000}
S=${4:-High_five}
shift $(( $# < 4 ? $# : 4 ))
TAKES=${*:-greeting002 box_throw back_lift001}
[ -f "$D/${S}_S1.bvh" ] || { echo "pairs_retrieve: no cmu-interactions under $D"; exit 0; }
W=$(mktemp -d); trap 'rm -rf "$W"' EXIT
spec() { echo "$D/${1}_S1.bvh,$D/${1}_S2.bvh"; }
args=(); for t in $TAKES; do args+=(--pair "$(spec "$t")"); done
truth=(); for t in $TAKES; do truth+=(--truth "$(spec "$t")"); done
"$M" pairs annotate "${args[@]}" --every 10 --seed 1 -o "$W/ann.json" --cameras "$W/cams.json" 2>/dev/null
"$M" pairs export --pair "$(spec "$S")" -o "$W/seed.jsonl" 2>/dev/null
"$M" pairs sample --prior "$(spec "$S")" --annotations "$W/ann.json" --samples "$N" --seed 1 --json \
  -o "$W/samples.jsonl" 2>/dev/null > "$W/sample.json"
sps=$(python3 -c 'import json,sys; print("%.0f" % json.load(open(sys.argv[1]))["samples_per_second"])' "$W/sample.json")
echo "seed take $S; annotated: $TAKES; $N samples at $sps samples/s"
echo "| retrieved from | samples | 3D error mean / median / p95 m | view error median deg | 2D residual median | seconds |"
echo "|---|---:|---|---:|---:|---:|"
for set in seed samples; do
  "$M" pairs retrieve --annotations "$W/ann.json" --samples "$W/$set.jsonl" "${truth[@]}" --cameras "$W/cams.json" \
    --json -o "$W/lifted.jsonl" 2>/dev/null |
  python3 -c 'import json,sys; j=json.load(sys.stdin); e=j["error_m"]; v=j["view_error_deg"]; r=j["residual"]
print("| %s | %d | %.3f / %.3f / %.3f | %.1f | %.4f | %.1f |" % (sys.argv[1], j["samples"], e["mean"], e["median"], e["p95"], v["median"], r["median"], j["seconds"]))' \
    "$([ $set = seed ] && echo "the seed take's frames" || echo "pairs sample (ic)")"
done
