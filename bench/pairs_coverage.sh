#!/usr/bin/env bash
# Seed 002's Fig. 9 experiment on cmu-pairs (issue 14): coverage (eq. 13)
# of the true pose-pairs between the annotated frames by the samples of
# each density, against the floor C(truth, prior frames). Prints a table;
# never passes or fails.
#
#   annotations: every 10th frame of both takes from 0, 8 video cameras each
#   prior:       the same frames (joint limits, torso, eta's allowances, seeds)
#   truth:       every 10th frame from 5 (the frames in between)
#   samples:     1000 and 3000 per density, 2 chains, seeds 1..S (paired:
#                every density starts its chains from the same prior frames)
#
# usage: bench/pairs_coverage.sh MIMIC_BINARY [DATA_DIR] [SEEDS]
set -eu
M=${1:?usage: pairs_coverage.sh MIMIC_BINARY [DATA_DIR] [SEEDS]}
D=${2:-$(dirname "$0")/../../shared/data}/cmu-pairs
S=${3:-3}
[ -f "$D/20_11.bvh" ] || { echo "pairs_coverage: no cmu-pairs under $D"; exit 0; }
W=$(mktemp -d); trap 'rm -rf "$W"' EXIT
T1="$D/20_11.bvh,$D/21_11.bvh" T2="$D/20_03.bvh,$D/21_03.bvh"
"$M" pairs annotate --pair "$T1" --pair "$T2" --every 10 --views 8 --video -o "$W/ann.json" 2>/dev/null
"$M" pairs export --pair "$T1" --pair "$T2" --every 10 -o "$W/prior.jsonl" 2>/dev/null
cov() { "$M" pairs coverage --truth "$T1" --truth "$T2" --every 10 --offset 5 --samples "$1" --json |
        python3 -c 'import json,sys; j=json.load(sys.stdin); print("%.4f %.4f %.4f" % (j["D_I"], j["D_C"], j["D_S"]))'; }
echo "floor C(truth, prior frames): $(cov "$W/prior.jsonl")  (D_I m, D_C m, D_S)"
printf '%-6s %-10s %-5s %-8s %-8s %-8s %-10s %s\n' samples density seed D_I D_C D_S "samples/s" acceptance
for n in 1000 3000; do
  for d in prior ic cartesian shape; do
    for s in $(seq 1 "$S"); do
      rep=$("$M" pairs sample --prior "$T1" --prior "$T2" --every 10 --annotations "$W/ann.json" --density $d \
            --samples $n --chains 2 --seed $s --json -o "$W/s.jsonl" 2>/dev/null |
            python3 -c 'import json,sys; j=json.load(sys.stdin); print("%.0f %s" % (j["samples_per_second"], ",".join("%.2f" % a for a in j["acceptance"])))')
      read -r di dc ds <<<"$(cov "$W/s.jsonl")"
      printf '%-6s %-10s %-5s %-8s %-8s %-8s %-10s %s\n' $n $d $s $di $dc $ds $rep
    done
  done
done
