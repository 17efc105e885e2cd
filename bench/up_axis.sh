#!/usr/bin/env bash
# Motion files' up axis on real takes: for each two-person take of
# cmu-interactions (z up) and cmu-pairs (y up), the axis `mimic pairs
# export` found, the share of people-frames standing (head above the middle
# of the ankles along mimic's y), the lowest ankle's height (median, metres:
# feet on a floor at y ~ 0), and the share of `pairs annotate`'s cameras
# above that floor. Run it with two binaries to compare; never passes or fails.
#
# usage: bench/up_axis.sh MIMIC_BINARY [DATA_DIR]
set -eu
M=${1:?usage: up_axis.sh MIMIC_BINARY [DATA_DIR]}
D=${2:-$(dirname "$0")/../../shared/data}
[ -d "$D/cmu-interactions" ] || { echo "up_axis: no cmu-interactions under $D"; exit 0; }
W=$(mktemp -d); trap 'rm -rf "$W"' EXIT
printf '| take | axis found | standing | lowest ankle y, median m | cameras above the floor |\n|---|---|---:|---:|---:|\n'
takes() {
  for a in "$D"/cmu-interactions/*_S1.bvh; do echo "$a,${a%_S1.bvh}_S2.bvh"; done
  [ -f "$D/cmu-pairs/20_03.bvh" ] && echo "$D/cmu-pairs/20_03.bvh,$D/cmu-pairs/21_03.bvh"
  [ -f "$D/cmu-pairs/20_11.bvh" ] && echo "$D/cmu-pairs/20_11.bvh,$D/cmu-pairs/21_11.bvh"
}
takes | while read -r T; do
  name=$(basename "${T%%,*}" .bvh)
  "$M" pairs export --pair "$T" --every 10 -o "$W/f.jsonl" 2>"$W/said" >/dev/null
  "$M" pairs annotate --pair "$T" --every 10 --views 4 --seed 1 -o "$W/a.json" --cameras "$W/c.json" 2>/dev/null >/dev/null
  axis=$(grep -o '[-+][xyz] is up' "$W/said" | head -1 | cut -d' ' -f1); axis=${axis:-"(none said)"}
  python3 - "$W/f.jsonl" "$W/c.json" "$name" "$axis" <<'PY'
import json, sys
f, c, name, axis = sys.argv[1:]
rows = [json.loads(l) for l in open(f)][1:]
up = n = 0; low = []
for r in rows:
    J = r["joints"]
    for w in (0, 17):
        up += J[w][1] > (J[w + 13][1] + J[w + 14][1]) / 2; n += 1
        low.append(min(J[w + 13][1], J[w + 14][1]))
low.sort(); floor = low[len(low) // 2]
cams = json.load(open(c))
def centres(o):
    if isinstance(o, dict):
        for k, v in o.items():
            if k in ("centre", "center", "position") and isinstance(v, list) and len(v) == 3: yield v
            else: yield from centres(v)
    elif isinstance(o, list):
        for v in o: yield from centres(v)
cc = list(centres(cams))
above = sum(1 for p in cc if p[1] > floor)
print("| %s | %s | %d / %d | %.3f | %s |" % (name, axis, up, n, floor, "%d / %d" % (above, len(cc)) if cc else "n/a"))
PY
done
