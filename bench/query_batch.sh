#!/usr/bin/env bash
# `mimic query --landmarks` on a landmark batch just under the 64 MiB cap:
# peak resident memory and seconds of each binary given, text and --json
# output. The batch: the 16 landmarks of every body of a synth store (4
# subjects x 12 poses, ingested and indexed by the first binary), cycled,
# each frame moved by up to 1 mm so that no two frames are alike, written
# as {"frames": [...]} with 9 significant digits, as a tracker's float32
# recording is (FORMAT=%.3f: millimetres, shorter numbers and so more of
# them). The binaries' outputs are compared byte for byte. Never passes or
# fails on time.
#
# usage: bench/query_batch.sh MIMIC_BINARY [MORE_BINARIES...]
#   MIB=63.9 (the batch's size in MiB), FORMAT=%.9g (a coordinate),
#   RUNS=3 (each binary and output: the largest peak, the fewest seconds),
#   KEEP=DIR (keep the store and batch; a kept batch is used as it is)
set -eu
[ $# -ge 1 ] || { echo "usage: query_batch.sh MIMIC_BINARY [MORE_BINARIES...]" >&2; exit 2; }
MIB=${MIB:-63.9}
RUNS=${RUNS:-3}
FORMAT=${FORMAT:-%.9g}
W=${KEEP:-$(mktemp -d)}
[ -n "${KEEP:-}" ] || trap 'rm -rf "$W"' EXIT
mkdir -p "$W"
M=$1
if [ ! -f "$W/batch.json" ]; then
  "$M" synth --out "$W/bodies" --subjects 4 --poses 12 --vertices 2000 >/dev/null
  "$M" ingest --store "$W/store" "$W/bodies" >/dev/null 2>&1
  "$M" index --store "$W/store" >/dev/null 2>&1
  for f in "$W"/bodies/*.ply; do
    "$M" landmarks show "$f" --landmarks "$W/bodies/landmarks.json" --json
  done >"$W/shown.json"
  python3 - "$W/shown.json" "$W/batch.json" "$MIB" "$FORMAT" <<'EOF'
import json, random, sys
text, dec, at, bodies = open(sys.argv[1]).read(), json.JSONDecoder(), 0, []
while text[at:].strip():  # one indented document per body
    j, at = dec.raw_decode(text, at + len(text[at:]) - len(text[at:].lstrip()))
    bodies.append([l["position"] for l in j["landmarks"]])
limit = int(float(sys.argv[3]) * (1 << 20))
rnd = random.Random(1)
with open(sys.argv[2], "w") as out:
    out.write('{"frames": [\n')
    size, i = 13, 0
    while True:
        b = bodies[i % len(bodies)]
        d = [rnd.uniform(-0.001, 0.001) for _ in range(3)]
        lm = ", ".join(("[%s, %s, %s]" % ((sys.argv[4],) * 3)) % (p[0] + d[0], p[1] + d[1], p[2] + d[2]) for p in b)
        frame = '  {"landmarks": [%s]}' % lm
        if size + len(frame) + 5 > limit:
            break
        out.write((",\n" if i else "") + frame)
        size += len(frame) + 2
        i += 1
    out.write("\n]}\n")
print("batch: %d frames, %d bytes" % (i, size + 2), file=sys.stderr)
EOF
fi
echo "batch: $(stat -c %s "$W/batch.json") bytes; $(uptime)"
printf '%-40s %-6s %10s %10s %8s\n' binary output "peak MiB" seconds exit
for b in "$@"; do
  for mode in text json; do
    opt=""; [ $mode = json ] && opt=--json
    best_s="" peak=0
    for run in $(seq 1 "$RUNS"); do
      set +e
      /usr/bin/time -f '%M %e' -o "$W/time" "$b" query --store "$W/store" --landmarks "$W/batch.json" $opt \
        >"$W/out.$mode" 2>"$W/err.$mode"
      rc=$?
      set -e
      read -r kb s <"$W/time" || true
      [ "$kb" -gt "$peak" ] && peak=$kb
      if [ -z "$best_s" ] || [ "$(echo "$s < $best_s" | bc)" = 1 ]; then best_s=$s; fi
    done
    printf '%-40s %-6s %10.1f %10s %8s\n' "$b" $mode "$(echo "$peak / 1024" | bc -l)" "$best_s" $rc
    if [ -f "$W/ref.$mode" ]; then
      cmp -s "$W/ref.$mode" "$W/out.$mode" || echo "  $mode output differs from $1's"
    else
      mv "$W/out.$mode" "$W/ref.$mode"
    fi
  done
done
