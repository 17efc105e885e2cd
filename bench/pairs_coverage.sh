#!/usr/bin/env bash
# Seed 002's Fig. 9 experiment on cmu-pairs (issue 14): coverage (eq. 13)
# of the true pose-pairs between the annotated frames by the samples of
# each density, against the floor C(truth, prior frames). Prints a table,
# the means over the seeds and ic against prior seed by seed (paired); never
# passes or fails.
#
#   annotations: every 10th frame of both takes from 0, 8 video cameras each
#   prior:       the same frames (joint limits, torso, eta's allowances, seeds)
#   truth:       every 10th frame from 5 (the frames in between)
#   samples:     1000 and 3000 per density, CHAINS chains, the default restarts,
#                seeds 1..S (paired: every density starts its chains from the
#                same prior frames, edited the same way with JITTER)
#   JITTER:      --seed-jitter DEG,M (default 15,0.2: rough seeds, as the
#                paper's are made by hand); 0,0 starts from the true frames
#
# usage: bench/pairs_coverage.sh MIMIC_BINARY [DATA_DIR] [SEEDS] [JITTER] [CHAINS]
set -eu
M=${1:?usage: pairs_coverage.sh MIMIC_BINARY [DATA_DIR] [SEEDS] [JITTER] [CHAINS]}
D=${2:-$(dirname "$0")/../../shared/data}/cmu-pairs
S=${3:-8}
J=${4:-15,0.2}
C=${5:-4}
[ -f "$D/20_11.bvh" ] || { echo "pairs_coverage: no cmu-pairs under $D"; exit 0; }
W=$(mktemp -d); trap 'rm -rf "$W"' EXIT
T1="$D/20_11.bvh,$D/21_11.bvh" T2="$D/20_03.bvh,$D/21_03.bvh"
"$M" pairs annotate --pair "$T1" --pair "$T2" --every 10 --views 8 --video -o "$W/ann.json" 2>/dev/null
"$M" pairs export --pair "$T1" --pair "$T2" --every 10 -o "$W/prior.jsonl" 2>/dev/null
cov() { "$M" pairs coverage --truth "$T1" --truth "$T2" --every 10 --offset 5 --samples "$1" --json |
        python3 -c 'import json,sys; j=json.load(sys.stdin); print("%.4f %.4f %.4f" % (j["D_I"], j["D_C"], j["D_S"]))'; }
echo "floor C(truth, prior frames): $(cov "$W/prior.jsonl")  (D_I m, D_C m, D_S); seed jitter $J, $C chains"
printf '%-6s %-10s %-5s %-8s %-8s %-8s %-10s %s\n' samples density seed D_I D_C D_S "samples/s" acceptance | tee "$W/table"
for n in 1000 3000; do
  for d in prior ic cartesian shape; do
    for s in $(seq 1 "$S"); do
      rep=$("$M" pairs sample --prior "$T1" --prior "$T2" --every 10 --annotations "$W/ann.json" --density $d \
            --samples $n --chains "$C" --seed $s --seed-jitter "$J" --json -o "$W/s.jsonl" 2>/dev/null |
            python3 -c 'import json,sys; j=json.load(sys.stdin); print("%.0f %s" % (j["samples_per_second"], ",".join("%.2f" % a for a in j["acceptance"])))')
      read -r di dc ds <<<"$(cov "$W/s.jsonl")"
      printf '%-6s %-10s %-5s %-8s %-8s %-8s %-10s %s\n' $n $d $s $di $dc $ds $rep | tee -a "$W/table"
    done
  done
done
python3 - "$W/table" <<'EOF'
import sys, statistics as st
rows = [l.split() for l in open(sys.argv[1]).read().splitlines()[1:]]
cov = {(int(r[0]), r[1], int(r[2])): [float(x) for x in r[3:6]] for r in rows}
sizes = sorted({k[0] for k in cov}); dens = ["prior", "ic", "cartesian", "shape"]
print("\nmeans over the seeds (D_I, D_C, D_S):")
for n in sizes:
    for d in dens:
        v = [cov[k] for k in cov if k[0] == n and k[1] == d]
        print("  %5d %-10s %s" % (n, d, " ".join("%.4f" % st.mean(x[i] for x in v) for i in range(3))))
print("\nic - prior, paired by seed (negative: ic covers better):")
for n in sizes:
    seeds = sorted(k[2] for k in cov if k[0] == n and k[1] == "ic")
    for i, name in enumerate(["D_I", "D_C", "D_S"]):
        diff = [cov[(n, "ic", s)][i] - cov[(n, "prior", s)][i] for s in seeds]
        t = st.mean(diff) / (st.stdev(diff) / len(diff) ** 0.5) if len(diff) > 1 and st.stdev(diff) > 0 else float("nan")
        print("  %5d %s mean %+.4f (%+.1f %%), ic better for %d of %d seeds, paired t %.2f" %
              (n, name, st.mean(diff), 100 * st.mean(diff) / st.mean(cov[(n, "prior", s)][i] for s in seeds),
               sum(x < 0 for x in diff), len(diff), t))
EOF
