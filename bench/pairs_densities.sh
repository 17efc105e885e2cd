#!/usr/bin/env bash
# The four densities (ic, cartesian, shape, prior) on real interactions with
# the sampler's defaults (chains restarted from lifted annotations), and
# prior frames without annotations: seed take High_five of cmu-interactions,
# annotations of the nine other takes (every 10th frame, one camera, 2 px),
# truth their in-between frames; limbs and D_C coverage (metres) at 1000
# and 10000 samples, seeds 1 and 2 (SIZES, SEEDS and MEASURES in the
# environment change them: SIZES=100000 SEEDS=1 for the paper's scale,
# MEASURES=limbs,D_C,D_I,D_S for every distance); the oracle first. Never
# passes or fails.
#
# usage: [SIZES="1000 10000"] [SEEDS="1 2"] [MEASURES=limbs,D_C] bench/pairs_densities.sh MIMIC_BINARY [DATA_DIR]
set -eu
M=${1:?usage: pairs_densities.sh MIMIC_BINARY [DATA_DIR]}
D=${2:-$(dirname "$0")/../../shared/data}
I=$D/cmu-interactions P=$D/cmu-pairs
[ -f "$I/High_five_S1.bvh" ] && [ -f "$P/20_11.bvh" ] || { echo "pairs_densities: no cmu-interactions or cmu-pairs under $D"; exit 0; }
W=$(mktemp -d); trap 'rm -rf "$W"' EXIT
SEED="$I/High_five_S1.bvh,$I/High_five_S2.bvh"
A=(); T=()
for t in back_lift001 box_throw greeting002 jump_crawl001 one_leg_back_stretch push_up001 stack_push_up001; do
  A+=(--pair "$I/${t}_S1.bvh,$I/${t}_S2.bvh"); T+=(--truth "$I/${t}_S1.bvh,$I/${t}_S2.bvh"); done
A+=(--pair "$P/20_11.bvh,$P/21_11.bvh" --pair "$P/20_03.bvh,$P/21_03.bvh")
T+=(--truth "$P/20_11.bvh,$P/21_11.bvh" --truth "$P/20_03.bvh,$P/21_03.bvh")
"$M" pairs annotate "${A[@]}" -o "$W/ann.json" 2>/dev/null >/dev/null
"$M" pairs export "${A[@]}" --every 10 -o "$W/oracle.jsonl" 2>/dev/null >/dev/null
cov() { "$M" pairs coverage "${T[@]}" --every 10 --offset 5 --samples "$1" --measures "${MEASURES:-limbs,D_C}" --json 2>/dev/null |
        python3 -c 'import json,sys; j=json.load(sys.stdin); print("  ".join("%s %.4f" % (k, j[k]) for k in ("limbs", "D_C", "D_I", "D_S") if k in j))'; }
echo "oracle: $(cov "$W/oracle.jsonl")"
echo "load average $(cut -d' ' -f1-3 /proc/loadavg), $(date -u +%H:%M) UTC"
for n in ${SIZES:-1000 10000}; do
  for d in ic cartesian shape prior; do for s in ${SEEDS:-1 2}; do
    "$M" pairs sample --prior "$SEED" --annotations "$W/ann.json" --density $d --samples $n --seed $s --json \
      -o "$W/s.jsonl" 2>/dev/null > "$W/rep.json"
    sps=$(python3 -c 'import json,sys; print("%.0f" % json.load(open(sys.argv[1]))["samples_per_second"])' "$W/rep.json")
    echo "$n $d seed $s: $(cov "$W/s.jsonl")  ($sps samples/s)"
  done; done
  for s in ${SEEDS:-1 2}; do
    "$M" pairs sample --prior "$SEED" --density prior --samples $n --seed $s -o "$W/s.jsonl" 2>/dev/null >/dev/null
    echo "$n prior, no annotations, seed $s: $(cov "$W/s.jsonl")"
  done
done
echo "load average $(cut -d' ' -f1-3 /proc/loadavg), $(date -u +%H:%M) UTC"
