#!/usr/bin/env bash
# Lifting by sampling on held-out takes (seed 002, Sections 3-6): does the
# sampler lift the annotations? Ten two-person takes (cmu-interactions' 8,
# z up, and cmu-pairs' 2, y up). For each seed take T:
#
#   prior and seeds: every frame of T (pairs sample --prior T)
#   annotations:     the nine OTHER takes, every 10th frame, one camera each,
#                    2 px noise (pairs annotate's defaults)
#   truth:           the nine takes' in-between frames (every 10th from 5)
#   measure:         pairs coverage's limbs (metres): for each truth, the mean
#                    distance of the 24 limb joints to the nearest sample
#                    after a rigid fit, the better order of the people
#
# Rows: N samples with the default density (ic) and settings, --density
# prior, T's own frames (pairs export), and the oracle (the 3D frames behind
# the annotations). gap closed = (prior - ic) / (prior - oracle). The log
# density's rise: over each run of a chain (from its seed to its next
# restart), log f at the run's last step minus at its first; mean/median
# over the runs. EXTRA (environment) is added to
# every pairs sample command. Prints a table; never passes or fails.
#
# usage: bench/pairs_lifting.sh MIMIC_BINARY [DATA_DIR] [SEED_TAKE ...]
#   SEED_TAKE: a take's name (High_five, 20_11, ...; default High_five)
set -eu
M=${1:?usage: pairs_lifting.sh MIMIC_BINARY [DATA_DIR] [SEED_TAKE ...]}
D=${2:-$(dirname "$0")/../../shared/data}
shift $(( $# >= 2 ? 2 : 1 ))
SEEDS=${*:-High_five}
N=${N:-20000}
EXTRA=${EXTRA:-}
I=$D/cmu-interactions P=$D/cmu-pairs
[ -f "$I/High_five_S1.bvh" ] && [ -f "$P/20_11.bvh" ] || { echo "pairs_lifting: no cmu-interactions or cmu-pairs under $D"; exit 0; }
declare -A TAKE
for t in High_five back_lift001 box_throw greeting002 jump_crawl001 one_leg_back_stretch push_up001 stack_push_up001; do
  TAKE[$t]="$I/${t}_S1.bvh,$I/${t}_S2.bvh"
done
TAKE[20_11]="$P/20_11.bvh,$P/21_11.bvh" TAKE[20_03]="$P/20_03.bvh,$P/21_03.bvh"
W=$(mktemp -d); trap 'rm -rf "$W"' EXIT
cov() { "$M" pairs coverage "${TRUTH[@]}" --every 10 --offset 5 --samples "$1" --measures limbs --json 2>/dev/null |
        python3 -c 'import json,sys; print("%.4f" % json.load(sys.stdin)["limbs"])'; }
# samples/s and the log density's rise over a run (from a seed to the next
# restart): the mean over runs of log f at the run's last step minus at its
# first (chains of equal length, chain after chain)
rep() { python3 - "$1" "$2" <<'PY'
import json, sys
r = json.load(open(sys.argv[1])); c = r["chains"]; R = r["parameters"]["restart_every"]
ld = [json.loads(l).get("log_density") for l in open(sys.argv[2]).read().split("\n")[1:] if l.strip()]
n = len(ld) // c; R = R or n; rise = []
for k in range(c):
    x = ld[k * n:(k + 1) * n]
    rise += [x[s + R - 1] - x[s] for s in range(0, n - R + 1, R) if x[s] is not None]
print("%.0f %+.1f/%+.1f" % (r["samples_per_second"], sum(rise) / len(rise), sorted(rise)[len(rise) // 2]) if rise else "%.0f nan" % r["samples_per_second"])
PY
}
echo "load: $(uptime | sed 's/.*load average: //'); $N samples; EXTRA='$EXTRA'"
printf '%-22s %-9s %-9s %-9s %-9s %-8s %-10s %-9s %s\n' seed_take ic prior seed oracle gap ic_s/s prior_s/s 'ic_logf_rise(mean/median)'
for S in $SEEDS; do
  [ -n "${TAKE[$S]:-}" ] || { echo "pairs_lifting: no take $S"; exit 2; }
  PAIRS=() TRUTH=()
  for t in "${!TAKE[@]}"; do [ "$t" = "$S" ] || PAIRS+=(--pair "${TAKE[$t]}") TRUTH+=(--truth "${TAKE[$t]}"); done
  "$M" pairs annotate "${PAIRS[@]}" -o "$W/ann.json" 2>/dev/null
  "$M" pairs export "${PAIRS[@]}" --every 10 -o "$W/oracle.jsonl" 2>/dev/null
  "$M" pairs export --pair "${TAKE[$S]}" -o "$W/seed.jsonl" 2>/dev/null
  # shellcheck disable=SC2086
  "$M" pairs sample --prior "${TAKE[$S]}" --annotations "$W/ann.json" --samples "$N" $EXTRA --json -o "$W/ic.jsonl" >"$W/ic.json" 2>/dev/null
  # shellcheck disable=SC2086
  "$M" pairs sample --prior "${TAKE[$S]}" --density prior --samples "$N" $EXTRA --json -o "$W/pr.jsonl" >"$W/pr.json" 2>/dev/null
  read -r ics icr <<<"$(rep "$W/ic.json" "$W/ic.jsonl")"
  read -r prs _ <<<"$(rep "$W/pr.json" "$W/pr.jsonl")"
  ic=$(cov "$W/ic.jsonl") pr=$(cov "$W/pr.jsonl") sd=$(cov "$W/seed.jsonl") or=$(cov "$W/oracle.jsonl")
  gap=$(python3 -c "print('%.2f' % (($pr - $ic) / ($pr - $or)))")
  printf '%-22s %-9s %-9s %-9s %-9s %-8s %-10s %-9s %s\n' "$S" "$ic" "$pr" "$sd" "$or" "$gap" "$ics" "$prs" "$icr"
done
