#!/usr/bin/env bash
# The colour space against k, σ_color, σ_image and the white, on
# every scene of our renderer and the Mitsuba exporter's, at SPPS (default
# "16 64") spp, SIZE² (default 128) pixels. Reuses the references of
# tools/results/oidn_table.sh in OUT (default out/oidn; run that first). Writes
# OUT/NAME.csv (default hdr_sweep): one line per dump, configuration and
# image (filtered, filtered_energy) or baseline. SPACES, FINALS, KS,
# SIGMA_COLORS, SIGMA_IMAGES, WHITES set the grid.
set -euo pipefail
cd "$(dirname "$0")/../.."
threads=${THREADS:-2}
size=${SIZE:-128}
spps=${SPPS:-"16 64"}
ours=${SCENES:-"glossy-room diffuse-room two-lights indirect-room sky moving"}
theirs=${MITSUBA_SCENES:-"caustic glossy-highlight indirect-room"}
grid=(--color-space "${SPACES:-cielab,loglab,logluv}" --final-pass "${FINALS:-stored,all}"
      --k "${KS:-5,10,20}"
      --sigma-color "${SIGMA_COLORS:-50,100,200}" --sigma-image "${SIGMA_IMAGES:-3}"
      --white "${WHITES:-1,auto}")
out=${OUT:-out/oidn}
py=tools/mitsuba/.venv/bin/python
cargo build --release --quiet --bin render --bin pathdensity
csv="$out/${NAME:-hdr_sweep}.csv"
rm -f "$csv"
sweep() { # renderer scene spp ref
    ./target/release/pathdensity sweep "$out/dump.pds" --reference "$4" -o "$out/sweep" \
        --threads "$threads" "${grid[@]}" > /dev/null
    if [ ! -f "$csv" ]; then
        echo "renderer,scene,spp,$(head -1 "$out/sweep/sweep.csv")" > "$csv"
    fi
    tail -n +2 "$out/sweep/sweep.csv" | sed "s/^/$1,$2,$3,/" >> "$csv"
    echo "$1 $2 $3 spp done" >&2
}
for s in $ours; do
    frames=()
    [ "$s" = moving ] && frames=(--frames 4)
    for spp in $spps; do
        ./target/release/render --scene "$s" --width "$size" --height "$size" --spp "$spp" \
            "${frames[@]}" --order pass --threads "$threads" -o "$out/dump.pds" > /dev/null
        sweep ours "$s" "$spp" "$out/ours-$s-ref.exr"
    done
done
for s in $theirs; do
    for spp in $spps; do
        $py tools/mitsuba/export.py "tools/mitsuba/scenes/$s.xml" -o "$out/dump.pds" \
            --size "${size}x${size}" --spp "$spp" --seed 1 --quiet
        sweep mitsuba "$s" "$spp" "$out/mitsuba-$s-ref.exr"
    done
done
rm -f "$out/dump.pds"
