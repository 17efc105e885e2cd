#!/usr/bin/env bash
# Coverage's speed on the shared data (issue 31): bench_pairs_coverage
# (the exhaustive scan against the bounded search, truths x samples per
# second, in one run) on generated sets, on cmu-pairs and on the
# held-out-sized set of cmu-interactions; `mimic pairs sample`'s samples
# per second; `mimic pairs coverage` end to end (reading, preparing, the
# three distances). Prints figures; never passes or fails.
#
#   cmu-pairs:        truth every 10th frame from 5 of both takes (50), as
#                     bench/pairs_coverage.sh; samples of the ic density,
#                     prior and annotations every 10th frame from 0
#   cmu-interactions: truth every 6th frame from 3 of the eight takes
#                     (1446, the size of a held-out set); prior and
#                     annotations (4 video cameras) every 10th from 0;
#                     3000 samples of the ic density, seed jitter 15,0.2
#   --paper:          also 100 000 samples of the prior density against
#                     the same 1446 truths, end to end (minutes), and
#                     their triangulations (bench_ic_build: mimic's own
#                     Delaunay against qhull alone)
#
# usage: bench/coverage_speed.sh BUILD_DIR [DATA_DIR] [--paper]
set -eu
B=${1:?usage: coverage_speed.sh BUILD_DIR [DATA_DIR] [--paper]}
shift
D=$(dirname "$0")/../../shared/data PAPER=0
for a in "$@"; do case $a in --paper) PAPER=1 ;; *) D=$a ;; esac; done
M=$B/cli/mimic X=$B/bench/bench_pairs_coverage
W=$(mktemp -d); trap 'rm -rf "$W"' EXIT
rate() { python3 -c 'import json,sys; print("%.0f" % json.load(sys.stdin)["samples_per_second"])'; }
# the end-to-end seconds of mimic pairs coverage ($1: threads, then its arguments)
cover() {
  local t=$1; shift
  /usr/bin/time -f %e -o "$W/t" "$M" pairs coverage "$@" --threads "$t" --json >"$W/c.json" 2>/dev/null
  echo "$(cat "$W/t") s ($t threads): $(python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); print("D_I %.4f, D_C %.4f, D_S %.4f" % (j["D_I"], j["D_C"], j["D_S"]))' "$W/c.json")"
}
echo "$(date -u '+%F %H:%M') UTC, $(uptime | sed 's/.*load/load/')"

echo; echo "== generated: 200 random pose-pairs x 3000 samples (2 in 5 repeats)"
"$X" --truths 200 --count 3000 --scan 20

if [ -f "$D/cmu-pairs/20_11.bvh" ]; then
  P=$D/cmu-pairs T1="$P/20_11.bvh,$P/21_11.bvh" T2="$P/20_03.bvh,$P/21_03.bvh"
  "$M" pairs annotate --pair "$T1" --pair "$T2" --every 10 --views 8 --video -o "$W/ann.json" 2>/dev/null
  "$M" pairs export --pair "$T1" --pair "$T2" --every 10 --offset 5 -o "$W/truth.jsonl" 2>/dev/null
  r=$("$M" pairs sample --prior "$T1" --prior "$T2" --every 10 --annotations "$W/ann.json" --density ic --samples 3000 \
      --seed-jitter 15,0.2 --json -o "$W/s.jsonl" 2>/dev/null | rate)
  echo; echo "== cmu-pairs: 50 truths x 3000 ic samples (pairs sample: $r samples/s on 2 chains)"
  "$X" --truth "$W/truth.jsonl" --samples "$W/s.jsonl" --scan 50
  echo "mimic pairs coverage: $(cover 2 --truth "$T1" --truth "$T2" --every 10 --offset 5 --samples "$W/s.jsonl")"
else
  echo; echo "(no cmu-pairs under $D)"
fi

I=$D/cmu-interactions
if [ -f "$I/High_five_S1.bvh" ]; then
  args=() priors=()
  for t in High_five back_lift001 box_throw greeting002 jump_crawl001 one_leg_back_stretch push_up001 stack_push_up001; do
    args+=(--truth "$I/${t}_S1.bvh,$I/${t}_S2.bvh") priors+=(--prior "$I/${t}_S1.bvh,$I/${t}_S2.bvh")
  done
  pairs=("${priors[@]/--prior/--pair}")
  "$M" pairs annotate "${pairs[@]}" --every 10 --views 4 --video -o "$W/ann.json" 2>/dev/null
  "$M" pairs export "${pairs[@]}" --every 6 --offset 3 -o "$W/truth.jsonl" 2>/dev/null
  r=$("$M" pairs sample "${priors[@]}" --every 10 --annotations "$W/ann.json" --density ic --samples 3000 \
      --seed-jitter 15,0.2 --json -o "$W/s.jsonl" 2>/dev/null | rate)
  echo; echo "== cmu-interactions: 1446 truths x 3000 ic samples (pairs sample: $r samples/s on 2 chains)"
  "$X" --truth "$W/truth.jsonl" --samples "$W/s.jsonl" --scan 20
  echo "mimic pairs coverage: $(cover 2 "${args[@]}" --every 6 --offset 3 --samples "$W/s.jsonl")"
  echo "mimic pairs coverage: $(cover 1 "${args[@]}" --every 6 --offset 3 --samples "$W/s.jsonl")"
  if [ "$PAPER" = 1 ]; then
    r=$("$M" pairs sample "${priors[@]}" --every 10 --density prior --samples 100000 --seed-jitter 15,0.2 --json \
        -o "$W/p.jsonl" 2>/dev/null | rate)
    echo; echo "== the paper's scale: 1446 truths x 100000 prior samples (pairs sample: $r samples/s on 2 chains)"
    echo "mimic pairs coverage: $(cover 2 "${args[@]}" --every 6 --offset 3 --samples "$W/p.jsonl")"
    "$B/bench/bench_ic_build" --samples "$W/p.jsonl" --runs 3
  fi
else
  echo; echo "(no cmu-interactions under $D)"
fi
