#!/usr/bin/env bash
# The memory of mimic serve's sessions: N sessions added through the API
# (avatars: the store's templates in turn), one transfer each, then all
# deleted; the serve process's resident memory (VmRSS) after each step.
#   bench/sessions_memory.sh [MIMIC] [N]   (default build/cli/mimic, 256)
# Makes a synth store (4 x 12 bodies, 7026 vertices) in a temp dir.
set -euo pipefail
M=$(realpath "${1:-build/cli/mimic}"); N=${2:-256}; PORT=${PORT:-18555}
D=$(mktemp -d); trap 'kill $SP 2>/dev/null || true; rm -rf "$D"' EXIT
"$M" synth --out "$D/syn" --subjects 4 --poses 12 >/dev/null
"$M" ingest --store "$D/st" "$D/syn" >/dev/null 2>&1
"$M" index --store "$D/st" >/dev/null 2>&1
"$M" serve --store "$D/st" --avatar 1 --listen 127.0.0.1:$PORT >"$D/serve.out" 2>&1 & SP=$!
for _ in $(seq 100); do curl -s -o /dev/null "http://127.0.0.1:$PORT/api/status" && break; sleep 0.1; done
rss() { awk '/VmRSS/ {printf "%.0f MB", $2 / 1024}' /proc/$SP/status; }
echo "serve alone: $(rss)"
for i in $(seq 1 $N); do
  curl -s -o /dev/null -X POST -H 'Content-Type: application/json' \
    -d "{\"name\":\"s$i\",\"avatar\":\"$(( (i % 48) + 1 ))\"}" "http://127.0.0.1:$PORT/api/sessions"
done
echo "$N sessions: $(rss)"
for i in $(seq 1 $N); do
  curl -s -o /dev/null -X POST -H 'Content-Type: application/json' \
    -d "{\"template\": $(( ((i + 7) % 48) + 1 ))}" "http://127.0.0.1:$PORT/api/transfer?session=s$i"
done
echo "$N sessions, one transfer each: $(rss)"
for i in $(seq 1 $N); do curl -s -o /dev/null -X DELETE "http://127.0.0.1:$PORT/api/sessions/s$i"; done
sleep 2
echo "all deleted: $(rss)"
