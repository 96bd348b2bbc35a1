#!/usr/bin/env bash
# Peak resident memory of a command, split into anonymous memory (the
# process's own) and file-backed pages (e.g. a mapped dump), sampled from
# /proc/PID/status every 20 ms.
#
#   tools/bench/peak_rss.sh pathdensity filter bench.pds -o out
set -uo pipefail
"$@" >/dev/null 2>&1 &
pid=$!
anon=0 file=0
while kill -0 "$pid" 2>/dev/null; do
  a=$(awk '/RssAnon/ {print $2}' "/proc/$pid/status" 2>/dev/null || true)
  f=$(awk '/RssFile/ {print $2}' "/proc/$pid/status" 2>/dev/null || true)
  [ -n "$a" ] && [ "$a" -gt "$anon" ] && anon=$a
  [ -n "$f" ] && [ "$f" -gt "$file" ] && file=$f
  sleep 0.02
done
wait "$pid"
rc=$?
echo "peak RssAnon ${anon} kB, peak RssFile ${file} kB (exit ${rc})"
exit "$rc"
