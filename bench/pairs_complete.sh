#!/usr/bin/env bash
# Pose-pair completion (mimic pairs complete) against single-person
# completion of the same joints, on real two-person takes: for each take,
# the samples are its every 10th frame from 0 and the truth its frames in
# between (every 10th from 5), each with an occluded set of joints removed:
# B's left arm (elbow, wrist), A's two arms (elbows, wrists), B's left leg
# (knee, ankle). Prints the mean error of the filled joints (metres) for
# matching on the pair (the default) and on the person alone, at K samples
# blended, per take and over all; never passes or fails.
#
# usage: bench/pairs_complete.sh MIMIC_BINARY [DATA_DIR] [K...]
set -eu
M=${1:?usage: pairs_complete.sh MIMIC_BINARY [DATA_DIR] [K...]}
D=${2:-$(dirname "$0")/../../shared/data}
shift $(( $# < 2 ? $# : 2 ))
KS=${*:-1 3 8}
[ -d "$D/cmu-interactions" ] || { echo "pairs_complete: no cmu-interactions under $D"; exit 0; }
W=$(mktemp -d); trap 'rm -rf "$W"' EXIT
takes() {
  for a in "$D"/cmu-interactions/*_S1.bvh; do echo "$(basename "${a%_S1.bvh}") $a,${a%_S1.bvh}_S2.bvh"; done
  [ -f "$D/cmu-pairs/20_03.bvh" ] && echo "20_03 $D/cmu-pairs/20_03.bvh,$D/cmu-pairs/21_03.bvh"
  [ -f "$D/cmu-pairs/20_11.bvh" ] && echo "20_11 $D/cmu-pairs/20_11.bvh,$D/cmu-pairs/21_11.bvh"
}
OCC="B.l_elbow,B.l_wrist A.l_elbow,A.l_wrist,A.r_elbow,A.r_wrist B.l_knee,B.l_ankle"
printf '| take | occluded |'; for k in $KS; do printf ' pair k%s | person k%s |' "$k" "$k"; done; printf '\n|---|---|'
for k in $KS; do printf -- '---:|---:|'; done; printf '\n'
takes | while read -r name T; do
  "$M" pairs export --pair "$T" --every 10 -o "$W/s.jsonl" 2>/dev/null >/dev/null
  "$M" pairs export --pair "$T" --every 10 --offset 5 -o "$W/t.jsonl" 2>/dev/null >/dev/null
  for occ in $OCC; do
    printf '| %s | %s |' "$name" "$occ"
    for k in $KS; do for m in pair person; do
      "$M" pairs complete --pairs "$W/t.jsonl" --samples "$W/s.jsonl" --missing "$occ" --k "$k" --match "$m" \
        --json -o "$W/o.jsonl" | python3 -c 'import json,sys; print(" %.4f |" % json.load(sys.stdin)["moved_m"], end="")'
    done; done
    printf '\n'
  done
done | tee "$W/rows"
python3 - "$W/rows" $KS <<'PY'
import sys
rows = [l.split("|")[3:-1] for l in open(sys.argv[1]) if l.startswith("| ")]
ks = sys.argv[2:]
cols = list(zip(*[[float(x) for x in r] for r in rows]))
print("| **mean over %d cases** | |" % len(rows) + "".join(" **%.4f** |" % (sum(c) / len(c)) for c in cols))
for i, k in enumerate(ks):
    wins = sum(1 for a, b in zip(cols[2 * i], cols[2 * i + 1]) if a < b)
    print("k %s: the pair matched better in %d of %d cases" % (k, wins, len(rows)))
PY
