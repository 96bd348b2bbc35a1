#!/usr/bin/env bash
# Peak resident memory of a command, split into anonymous memory (the
# process's own) and file-backed pages (e.g. a mapped dump), sampled from
# /proc/PID/status every 50 ms with shell builtins only (forking two awk
# and a sleep every 20 ms took a fifth of a core: docs/BENCHMARKS.md).
#
#   tools/bench/peak_rss.sh pathdensity filter bench.pds -o out
set -uo pipefail
"$@" >/dev/null 2>&1 &
pid=$!
anon=0 file=0
exec 3<> <(:)  # a pipe nobody writes: `read -t` on it sleeps without a fork
while kill -0 "$pid" 2>/dev/null; do
  while read -r key value _; do
    case $key in
      RssAnon:) [ "$value" -gt "$anon" ] && anon=$value ;;
      RssFile:) [ "$value" -gt "$file" ] && file=$value ;;
    esac
  done 2>/dev/null < "/proc/$pid/status"
  read -rt 0.05 -u 3 || true
done
wait "$pid"
rc=$?
echo "peak RssAnon ${anon} kB, peak RssFile ${file} kB (exit ${rc})"
exit "$rc"
