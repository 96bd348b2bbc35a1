#!/usr/bin/env bash
# Exposure invariance of --white auto: for every scene, render a
# 64 × 64, 16-spp dump, scale its radiance by 0.1 and by 10 (tools/pds.py),
# filter all three with the fixed default white (1) and with --white auto,
# and count the decisions that differ from the unscaled dump's.
# Prints a markdown table for docs/RESULTS.md.
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --quiet
render=target/release/render
pd=target/release/pathdensity
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
scale() { # IN OUT FACTOR
    python3 - "$1" "$2" "$3" <<'PY'
import sys
sys.path.insert(0, "tools")
import numpy as np, pds
hdr, rec = pds.read(sys.argv[1])
out = np.array(rec)
for c in "rgb":
    out[c] = (out[c].astype(np.float64) * float(sys.argv[3])).astype(np.float32)
pds.write(sys.argv[2], out, width=hdr["width"], height=hdr["height"], frames=hdr["frames"],
          spp=hdr["spp"], order=hdr["order"], scene=hdr["scene"], seed=hdr["seed"])
PY
}
echo "| scene | white | decisions differing at ×0.1 | at ×10 | of | Y_w at ×1 / ×0.1 / ×10 |"
echo "|---|---|---:|---:|---:|---|"
for s in glossy-room diffuse-room two-lights indirect-room sky moving; do
    frames=1; [ "$s" = moving ] && frames=4
    $render --scene "$s" --width 64 --height 64 --spp 16 --frames $frames -o "$tmp/x1.pds" >/dev/null
    scale "$tmp/x1.pds" "$tmp/x0.1.pds" 0.1
    scale "$tmp/x1.pds" "$tmp/x10.pds" 10
    for white in 1 auto; do
        ws=""
        for e in x1 x0.1 x10; do
            $pd filter "$tmp/$e.pds" -o "$tmp/o-$e" --white $white --no-html --methods mean \
                --decisions "$tmp/d-$e" >/dev/null
            ws="$ws / $(python3 -c "import json;print('%.4g' % json.load(open('$tmp/o-$e/report.json'))['parameters']['space']['white'])")"
        done
        diff01=$( (cmp -l "$tmp/d-x1" "$tmp/d-x0.1" || true) | wc -l)
        diff10=$( (cmp -l "$tmp/d-x1" "$tmp/d-x10" || true) | wc -l)
        n=$(stat -c %s "$tmp/d-x1")
        echo "| $s | $white | $diff01 | $diff10 | $n | ${ws# / } |"
    done
done
